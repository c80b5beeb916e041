//! The elastic energy of a deformable spline surface, after Terzopoulos, Platt, Barr &
//! Fleischer (1987): the deviation of the first fundamental form (the metric a_αβ = S_α·S_β:
//! stretching and shear) and of the second fundamental form (b_αβ = n·S_αβ: bending) from
//! their values at rest, integrated over the parameter domain.
//!
//! Terzopoulos leaves the weights of the two terms free. We take them from a thin elastic
//! shell of thickness h (Koiter's energy), so that E, ν and h fix them:
//!
//!   W = ∫ ½ (E h / (1−ν²)) εᵀ H ε + ½ (E h³ / (12 (1−ν²))) κᵀ H κ  dA₀,
//!   ε_αβ = ½ (a_αβ − A_αβ),   κ_αβ = b_αβ − B_αβ,
//!
//! where H is the plane-stress tensor ν A^αβ A^γδ + ½(1−ν)(A^αγ A^βδ + A^αδ A^βγ) written in
//! the rest contravariant metric A^αβ (so the parameterisation does not matter), acting on
//! (ε₁₁, ε₂₂, ε₁₂). On a flat plate with small deflection w this is Kirchhoff's plate energy
//! ½ D ((Δw)² − 2(1−ν)(w_xx w_yy − w_xy²)), D = E h³ / (12 (1−ν²)). Both forms are invariant
//! under rigid motions, so a rigid motion costs nothing.
//!
//! Quadrature: 4 × 4 Gauss–Legendre points per knot span pair. Forces are the exact negative
//! gradient. For implicit integration `prepare`/`product`/`diagonal` give the Gauss–Newton
//! stiffness Jᵀ C J (J: the derivative of (ε, κ) with respect to the control points), which is
//! symmetric positive semi-definite; it drops the terms stress × second derivative of the
//! strains, which vanish at rest (so it is the exact Hessian for small displacements).

use crate::error::SimError;
use crate::material::Material;
use crate::math::{Real, Vec3};

use super::surface::{Deriv, SplineSurface, Stencil};

/// Gauss–Legendre abscissae on [0, 1] and weights (4 points, exact to degree 7).
const GAUSS: [(Real, Real); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_87, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

/// Rest data at one quadrature point.
#[derive(Clone, Debug)]
pub struct QuadPoint {
    pub stencil: Stencil,
    /// Gauss weight × parameter area × rest area element |S_u × S_v|: ∫ … dA₀ ≈ Σ weight ….
    pub weight: Real,
    /// Plane-stress tensor (without E/(1−ν²)) on (·₁₁, ·₂₂, ·₁₂).
    h: [[Real; 3]; 3],
    rest_metric: [Real; 3],
    rest_curvature: [Real; 3],
    pub rest_point: Vec3,
    pub rest_normal: Vec3,
    /// Parameter coordinates (for messages and loads).
    pub param: (Real, Real),
}

/// The tangent frame of the deformed surface at a quadrature point.
#[derive(Clone, Copy, Debug, Default)]
struct Frame {
    a1: Vec3,
    a2: Vec3,
    /// Second derivatives S_uu, S_vv, S_uv.
    aa: [Vec3; 3],
    n: Vec3,
    inv_len: Real,
    /// Tangential parts of aa (aa − (n·aa) n).
    p: [Vec3; 3],
}

impl Frame {
    fn at(st: &Stencil, w: &[[Real; 16]; 6], x: &[Vec3]) -> Frame {
        let a1 = st.combine(x, &w[Deriv::U as usize]);
        let a2 = st.combine(x, &w[Deriv::V as usize]);
        let aa = [
            st.combine(x, &w[Deriv::UU as usize]),
            st.combine(x, &w[Deriv::VV as usize]),
            st.combine(x, &w[Deriv::UV as usize]),
        ];
        let m = a1.cross(a2);
        let len = m.length();
        let inv_len = if len > 0.0 { 1.0 / len } else { 0.0 };
        let n = m * inv_len;
        let p = aa.map(|v| v - n.dot(v) * n);
        Frame {
            a1,
            a2,
            aa,
            n,
            inv_len,
            p,
        }
    }

    fn metric(&self) -> [Real; 3] {
        [
            self.a1.length_squared(),
            self.a2.length_squared(),
            self.a1.dot(self.a2),
        ]
    }

    fn curvature(&self) -> [Real; 3] {
        self.aa.map(|v| self.n.dot(v))
    }

    /// Adds Σ_c s_c ∂ε_c/∂x_i + Σ_c m_c ∂κ_c/∂x_i, times `sign`, to `out` for each node.
    fn scatter(
        &self,
        st: &Stencil,
        w: &[[Real; 16]; 6],
        s: [Real; 3],
        m: [Real; 3],
        sign: Real,
        out: &mut [Vec3],
    ) {
        let big = m[0] * self.p[0] + m[1] * self.p[1] + m[2] * self.p[2];
        let c1 = self.a2.cross(big) * self.inv_len;
        let c2 = big.cross(self.a1) * self.inv_len;
        let t1 = s[0] * self.a1 + 0.5 * s[2] * self.a2 + c1;
        let t2 = s[1] * self.a2 + 0.5 * s[2] * self.a1 + c2;
        for k in 0..16 {
            let nb = m[0] * w[3][k] + m[1] * w[4][k] + m[2] * w[5][k];
            let g = w[1][k] * t1 + w[2][k] * t2 + nb * self.n;
            out[st.node(k)] += sign * g;
        }
    }
}

fn mat_vec(h: &[[Real; 3]; 3], e: [Real; 3], scale: Real) -> [Real; 3] {
    std::array::from_fn(|r| scale * (h[r][0] * e[0] + h[r][1] * e[1] + h[r][2] * e[2]))
}

fn dot3(a: [Real; 3], b: [Real; 3]) -> Real {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The shell energy of a spline surface at rest (see the module doc).
#[derive(Clone, Debug)]
pub struct ShellEnergy {
    points: Vec<QuadPoint>,
    /// E h / (1 − ν²), N/m.
    membrane: Real,
    /// E h³ / (12 (1 − ν²)), N·m.
    bending: Real,
    nodes: usize,
    /// Frames cached by `prepare` for the stiffness products.
    frames: Vec<Frame>,
}

impl ShellEnergy {
    /// Quadrature and rest forms of `rest`; E and ν from `material`, thickness in m.
    pub fn new(
        rest: &SplineSurface,
        material: &Material,
        thickness: Real,
    ) -> Result<Self, SimError> {
        let material = material.validated()?;
        if !(thickness.is_finite() && thickness > 0.0) {
            return Err(SimError::BadParameter {
                name: "thickness",
                value: thickness.to_string(),
                reason: "must be a finite value > 0 m".into(),
            });
        }
        let (e, nu) = (material.young_modulus, material.poisson_ratio);
        let plane = e / (1.0 - nu * nu);
        let (su, sv) = (rest.u.spans(), rest.v.spans());
        let mut points = Vec::with_capacity(su * sv * 16);
        for j in 0..sv {
            let (v0, v1) = rest.v.span_range(j);
            for i in 0..su {
                let (u0, u1) = rest.u.span_range(i);
                for &(gv, wv) in &GAUSS {
                    for &(gu, wu) in &GAUSS {
                        let (s, t) = (u0 + gu * (u1 - u0), v0 + gv * (v1 - v0));
                        points.push(rest_point(rest, s, t, wu * wv * (u1 - u0) * (v1 - v0), nu)?);
                    }
                }
            }
        }
        let frames = vec![Frame::default(); points.len()];
        Ok(Self {
            points,
            membrane: plane * thickness,
            bending: plane * thickness.powi(3) / 12.0,
            nodes: rest.control.len(),
            frames,
        })
    }

    pub fn points(&self) -> &[QuadPoint] {
        &self.points
    }

    /// Number of control points.
    pub fn nodes(&self) -> usize {
        self.nodes
    }

    /// Membrane stiffness E h / (1 − ν²) (N/m) and bending stiffness D (N·m).
    pub fn stiffnesses(&self) -> (Real, Real) {
        (self.membrane, self.bending)
    }

    /// Rest area ∫ dA₀.
    pub fn area(&self) -> Real {
        self.points.iter().map(|q| q.weight).sum()
    }

    /// ∫ N_i dA₀ per control point: the lumped share of the area (sums to the area).
    pub fn node_areas(&self) -> Vec<Real> {
        let mut a = vec![0.0; self.nodes];
        for q in &self.points {
            let w = q.stencil.weights(Deriv::Value);
            for (k, wk) in w.iter().enumerate() {
                a[q.stencil.node(k)] += q.weight * wk;
            }
        }
        a
    }

    /// Consistent nodal forces of a traction (N/m², a function of rest point and rest normal)
    /// over the rest surface: f_i = ∫ N_i t dA₀.
    pub fn area_load(&self, traction: impl Fn(Vec3, Vec3) -> Vec3) -> Vec<Vec3> {
        let mut f = vec![Vec3::ZERO; self.nodes];
        for q in &self.points {
            let t = traction(q.rest_point, q.rest_normal) * q.weight;
            let w = q.stencil.weights(Deriv::Value);
            for (k, wk) in w.iter().enumerate() {
                f[q.stencil.node(k)] += *wk * t;
            }
        }
        f
    }

    fn strains(&self, q: &QuadPoint, f: &Frame) -> ([Real; 3], [Real; 3]) {
        let (a, b) = (f.metric(), f.curvature());
        (
            std::array::from_fn(|c| 0.5 * (a[c] - q.rest_metric[c])),
            std::array::from_fn(|c| b[c] - q.rest_curvature[c]),
        )
    }

    /// Elastic energy of the control positions `x`, in J.
    pub fn energy(&self, x: &[Vec3]) -> Real {
        let mut total = 0.0;
        for q in &self.points {
            let w = q.stencil.all_weights();
            let f = Frame::at(&q.stencil, &w, x);
            let (e, k) = self.strains(q, &f);
            total += 0.5
                * q.weight
                * (self.membrane * dot3(e, mat_vec(&q.h, e, 1.0))
                    + self.bending * dot3(k, mat_vec(&q.h, k, 1.0)));
        }
        total
    }

    /// Adds the elastic forces −∂W/∂x to `f` and returns W.
    pub fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Real {
        let mut total = 0.0;
        for q in &self.points {
            let w = q.stencil.all_weights();
            let fr = Frame::at(&q.stencil, &w, x);
            let (e, k) = self.strains(q, &fr);
            let s = mat_vec(&q.h, e, q.weight * self.membrane);
            let m = mat_vec(&q.h, k, q.weight * self.bending);
            total += 0.5 * (dot3(e, s) + dot3(k, m));
            fr.scatter(&q.stencil, &w, s, m, -1.0, f);
        }
        total
    }

    /// Caches the deformed frames at `x` for `product` and `diagonal`.
    pub fn prepare(&mut self, x: &[Vec3]) {
        for (q, fr) in self.points.iter().zip(self.frames.iter_mut()) {
            *fr = Frame::at(&q.stencil, &q.stencil.all_weights(), x);
        }
    }

    /// out += K dx with K the Gauss–Newton stiffness at the prepared state.
    pub fn product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        for (q, fr) in self.points.iter().zip(&self.frames) {
            let w = q.stencil.all_weights();
            let d: [Vec3; 6] = std::array::from_fn(|c| q.stencil.combine(dx, &w[c]));
            let (d1, d2) = (d[Deriv::U as usize], d[Deriv::V as usize]);
            let de = [
                fr.a1.dot(d1),
                fr.a2.dot(d2),
                0.5 * (fr.a2.dot(d1) + fr.a1.dot(d2)),
            ];
            let dk: [Real; 3] = std::array::from_fn(|c| {
                fr.n.dot(d[3 + c])
                    + fr.inv_len * (d1.dot(fr.a2.cross(fr.p[c])) + d2.dot(fr.p[c].cross(fr.a1)))
            });
            let s = mat_vec(&q.h, de, q.weight * self.membrane);
            let m = mat_vec(&q.h, dk, q.weight * self.bending);
            fr.scatter(&q.stencil, &w, s, m, 1.0, out);
        }
    }

    /// Adds the diagonal of the Gauss–Newton stiffness (per node, per axis) to `diag`.
    pub fn diagonal(&self, diag: &mut [Vec3]) {
        for (q, fr) in self.points.iter().zip(&self.frames) {
            let w = q.stencil.all_weights();
            let (cm, cb) = (q.weight * self.membrane, q.weight * self.bending);
            for k in 0..16 {
                let (n1, n2) = (w[1][k], w[2][k]);
                let rm = [n1 * fr.a1, n2 * fr.a2, 0.5 * (n1 * fr.a2 + n2 * fr.a1)];
                let rb: [Vec3; 3] = std::array::from_fn(|c| {
                    w[3 + c][k] * fr.n
                        + fr.inv_len * (n1 * fr.a2.cross(fr.p[c]) + n2 * fr.p[c].cross(fr.a1))
                });
                let mut acc = Vec3::ZERO;
                for r in 0..3 {
                    for c in 0..3 {
                        acc += cm * q.h[r][c] * rm[r] * rm[c] + cb * q.h[r][c] * rb[r] * rb[c];
                    }
                }
                diag[q.stencil.node(k)] += acc;
            }
        }
    }
}

/// Rest forms and plane-stress tensor at (s, t).
fn rest_point(
    rest: &SplineSurface,
    s: Real,
    t: Real,
    param_weight: Real,
    nu: Real,
) -> Result<QuadPoint, SimError> {
    let stencil = rest.stencil(s, t);
    let w = stencil.all_weights();
    let f = Frame::at(&stencil, &w, &rest.control);
    let area = if f.inv_len > 0.0 {
        1.0 / f.inv_len
    } else {
        0.0
    };
    let [g11, g22, g12] = f.metric();
    let det = g11 * g22 - g12 * g12;
    let scale = g11.max(g22);
    if !(area.is_finite() && det > 1e-12 * scale * scale) {
        return Err(SimError::BadParameter {
            name: "control",
            value: format!("surface at (u, v) = ({s:.4}, {t:.4})"),
            reason: "the rest surface is degenerate there (S_u and S_v are parallel or zero)"
                .into(),
        });
    }
    // Contravariant metric A^αβ.
    let inv = [[g22 / det, -g12 / det], [-g12 / det, g11 / det]];
    let pair = [(0, 0), (1, 1), (0, 1)];
    let factor = [1.0, 1.0, 2.0];
    let c = |a: usize, b: usize, g: usize, d: usize| {
        nu * inv[a][b] * inv[g][d]
            + 0.5 * (1.0 - nu) * (inv[a][g] * inv[b][d] + inv[a][d] * inv[b][g])
    };
    let h = std::array::from_fn(|r| {
        std::array::from_fn(|col| {
            let ((a, b), (g, d)) = (pair[r], pair[col]);
            factor[r] * factor[col] * c(a, b, g, d)
        })
    });
    Ok(QuadPoint {
        stencil,
        weight: param_weight * area,
        h,
        rest_metric: f.metric(),
        rest_curvature: f.curvature(),
        rest_point: stencil.combine(&rest.control, &w[Deriv::Value as usize]),
        rest_normal: f.n,
        param: (s, t),
    })
}
