//! Per-element corotational forces, stiffness products and energy, matrix-free.
//!
//! With the rest shape matrix Dm (columns X₁−X₀, X₂−X₀, X₃−X₀), F = Ds Dm⁻¹ and the rows g₁..g₃
//! of Dm⁻¹ are the gradients of the shape functions (g₀ = −g₁−g₂−g₃). The linear element
//! stiffness applied to a displacement u is K_e u = V σ(ε) g_a per node, ε = sym(Σ u_b g_bᵀ):
//! so K_e never needs to be stored. In the corotated frame the local displacement is
//! Rᵀx − X, whose gradient is RᵀF − I; hence the element force is
//! f = −V R σ(sym(RᵀF) − I) Dm⁻ᵀ (columns: nodes 1..3; node 0 gets minus their sum), and the
//! stiffness product with R held fixed is K dx = V R σ(sym(Rᵀ dF)) Dm⁻ᵀ (SOFA's choice: the
//! derivative of R is dropped; it is exact at rest and at any rigid motion of the rest shape).
//! With the polar R this force is the exact gradient of the energy
//! V (μ ‖S − I‖² + λ/2 tr(S − I)²), S = RᵀF, which the tests use.

use crate::math::{Mat3, Real, Vec3};

use super::rotation::{polar_rotation, polar_rotation_near};

/// Rest data of one tetrahedron.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementRest {
    pub nodes: [u32; 4],
    /// Inverse of the rest shape matrix [X₁−X₀, X₂−X₀, X₃−X₀].
    pub dm_inv: Mat3,
    /// Rest volume, in m³ (> 0).
    pub volume: Real,
}

impl ElementRest {
    /// `None` for a flat or inverted rest element.
    pub fn new(nodes: [u32; 4], x: &[Vec3; 4]) -> Option<Self> {
        let dm = Mat3::from_cols(x[1] - x[0], x[2] - x[0], x[3] - x[0]);
        let det = dm.determinant();
        (det.is_finite() && det > 0.0).then(|| Self {
            nodes,
            dm_inv: dm.inverse(),
            volume: det / 6.0,
        })
    }

    /// F = Ds Dm⁻¹ for positions given flat (x₀, y₀, z₀, x₁, ...).
    #[inline]
    pub fn gradient_flat(&self, x: &[Real]) -> Mat3 {
        let p = |k: usize| {
            let i = 3 * self.nodes[k] as usize;
            Vec3::new(x[i], x[i + 1], x[i + 2])
        };
        let x0 = p(0);
        Mat3::from_cols(p(1) - x0, p(2) - x0, p(3) - x0) * self.dm_inv
    }

    #[inline]
    pub fn gradient(&self, x: &[Vec3]) -> Mat3 {
        self.gradient_flat(crate::math::flatten(x))
    }

    /// g₀..g₃, the gradients of the four shape functions.
    #[inline]
    pub(super) fn shape_gradients(&self) -> [Vec3; 4] {
        per_node(self.dm_inv.transpose())
    }
}

/// The columns of `m` as nodes 1..3 and minus their sum as node 0: node 0's shape function
/// is 1 minus the others'.
#[inline]
fn per_node(m: Mat3) -> [Vec3; 4] {
    [
        -(m.x_axis + m.y_axis + m.z_axis),
        m.x_axis,
        m.y_axis,
        m.z_axis,
    ]
}

/// tr m.
#[inline]
pub fn trace(m: &Mat3) -> Real {
    m.x_axis.x + m.y_axis.y + m.z_axis.z
}

/// The Lamé parameters of the material, in Pa.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lame {
    pub lambda: Real,
    pub mu: Real,
}

/// The Lamé parameters of every element: one pair for the whole body (one material: the
/// same arithmetic as before per-region materials), or one pair per element.
#[derive(Clone, Debug, PartialEq)]
pub struct Lames {
    uniform: Lame,
    per_element: Vec<Lame>,
}

impl Lames {
    /// The same pair for every element.
    pub fn uniform(lame: Lame) -> Self {
        Self {
            uniform: lame,
            per_element: Vec::new(),
        }
    }

    /// Each element's pair from its material (`Uniform` gives `uniform`).
    pub fn of_materials(materials: &crate::material::ElementMaterials, elements: usize) -> Self {
        let pair = |m: &crate::material::Material| Lame {
            lambda: m.lambda(),
            mu: m.mu(),
        };
        match materials.uniform() {
            Some(m) => Self::uniform(pair(m)),
            None => Self {
                uniform: pair(materials.default_material()),
                per_element: (0..elements).map(|e| pair(materials.of(e))).collect(),
            },
        }
    }

    /// Element `e`'s pair.
    #[inline]
    pub fn at(&self, e: usize) -> Lame {
        match self.per_element.get(e) {
            Some(l) => *l,
            None => self.uniform,
        }
    }
}

impl Lame {
    /// σ(sym(h)) = λ tr(h) I + μ (h + hᵀ).
    #[inline]
    fn stress(&self, h: &Mat3) -> Mat3 {
        Mat3::from_diagonal(Vec3::splat(self.lambda * trace(h))) + (*h + h.transpose()) * self.mu
    }
}

/// Adds the node forces −P Dm⁻ᵀ (and their opposite sum on node 0) into `out` (flat).
#[inline]
fn scatter(e: &ElementRest, p: &Mat3, sign: Real, out: &mut [Real]) {
    let f = per_node(*p * e.dm_inv.transpose() * sign);
    for (n, fa) in e.nodes.iter().zip(f) {
        let i = 3 * *n as usize;
        out[i] += fa.x;
        out[i + 1] += fa.y;
        out[i + 2] += fa.z;
    }
}

/// Below this many elements the force loop stays on the calling thread: handing work to
/// rayon costs more than it saves on small meshes.
pub const PARALLEL_MIN_ELEMENTS: usize = 4096;

/// The element's rotation updated from `x` (kept where F is singular: returns 1) and its
/// first Piola-like stress R σ(sym(RᵀF) − I) V.
#[inline]
fn element_stress(e: &ElementRest, lame: Lame, x: &[Real], r: &mut Mat3) -> (usize, Mat3) {
    let f = e.gradient_flat(x);
    let kept = match polar_rotation_near(&f, r) {
        Some(new) => {
            *r = new;
            0
        }
        None => 1,
    };
    let h = r.transpose() * f - Mat3::IDENTITY;
    (kept, *r * lame.stress(&h) * e.volume)
}

/// Updates each element's rotation from the positions `x` (keeping the previous one where F
/// is singular or not finite) and adds the elastic forces into `forces` (flat). Returns the
/// number of elements that kept their previous rotation. On large meshes (and the `parallel`
/// feature) the elements run on rayon's threads, each writing its four node forces into
/// `scratch`, which is then summed into `forces` in element order: the result does not
/// depend on the number of threads.
pub fn elastic_forces(
    elements: &[ElementRest],
    lame: &Lames,
    x: &[Real],
    rotations: &mut [Mat3],
    forces: &mut [Real],
    scratch: &mut Vec<[Vec3; 4]>,
) -> usize {
    #[cfg(feature = "parallel")]
    if elements.len() >= PARALLEL_MIN_ELEMENTS && rayon::current_num_threads() > 1 {
        use rayon::prelude::*;
        scratch.resize(elements.len(), [Vec3::ZERO; 4]);
        let kept: usize = elements
            .par_iter()
            .zip(rotations.par_iter_mut())
            .zip(scratch.par_iter_mut())
            .enumerate()
            .with_min_len(256)
            .map(|(i, ((e, r), out))| {
                let (kept, p) = element_stress(e, lame.at(i), x, r);
                *out = per_node(p * e.dm_inv.transpose() * -1.0);
                kept
            })
            .sum();
        for (e, f) in elements.iter().zip(scratch.iter()) {
            for (n, fa) in e.nodes.iter().zip(f) {
                let i = 3 * *n as usize;
                forces[i] += fa.x;
                forces[i + 1] += fa.y;
                forces[i + 2] += fa.z;
            }
        }
        return kept;
    }
    let _ = scratch;
    let mut kept = 0;
    for (i, (e, r)) in elements.iter().zip(rotations.iter_mut()).enumerate() {
        let (k, p) = element_stress(e, lame.at(i), x, r);
        kept += k;
        scatter(e, &p, -1.0, forces);
    }
    kept
}

/// y += K dx with the stiffness corotated by the given element rotations (flat slices).
pub fn add_stiffness_product(
    elements: &[ElementRest],
    lame: &Lames,
    rotations: &[Mat3],
    dx: &[Real],
    y: &mut [Real],
) {
    add_stiffness_product_where(elements, lame, rotations, dx, y, |_| true);
}

/// `add_stiffness_product` over the elements `keep` accepts (the others' terms left out;
/// each kept element adds the same terms in the same order as the full product).
pub fn add_stiffness_product_where(
    elements: &[ElementRest],
    lame: &Lames,
    rotations: &[Mat3],
    dx: &[Real],
    y: &mut [Real],
    keep: impl Fn(&ElementRest) -> bool,
) {
    for (i, (e, r)) in elements.iter().zip(rotations).enumerate() {
        if !keep(e) {
            continue;
        }
        let h = r.transpose() * e.gradient_flat(dx);
        let p = *r * lame.at(i).stress(&h) * e.volume;
        scatter(e, &p, 1.0, y);
    }
}

/// diag += the diagonal of the corotated stiffness: per node a, the diagonal of
/// V R ((λ+μ) g gᵀ + μ |g|² I) Rᵀ with g = g_a.
pub fn add_stiffness_diagonal(
    elements: &[ElementRest],
    lame: &Lames,
    rotations: &[Mat3],
    diag: &mut [Real],
) {
    for (i, (e, r)) in elements.iter().zip(rotations).enumerate() {
        let lame = lame.at(i);
        for (n, ga) in e.nodes.iter().zip(e.shape_gradients()) {
            let rg = *r * ga;
            let d =
                (rg * rg) * (lame.lambda + lame.mu) + Vec3::splat(lame.mu * ga.length_squared());
            let i = 3 * *n as usize;
            diag[i] += e.volume * d.x;
            diag[i + 1] += e.volume * d.y;
            diag[i + 2] += e.volume * d.z;
        }
    }
}

/// The corotational elastic energy at positions `x`, in J (polar rotations recomputed).
pub fn energy(elements: &[ElementRest], lame: &Lames, x: &[Vec3]) -> Real {
    elements
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let lame = lame.at(i);
            let f = e.gradient(x);
            let r = polar_rotation(&f).unwrap_or(Mat3::IDENTITY);
            let s = r.transpose() * f;
            let eps = (s + s.transpose()) * 0.5 - Mat3::IDENTITY;
            let tr = trace(&eps);
            let eps2 = eps.x_axis.length_squared()
                + eps.y_axis.length_squared()
                + eps.z_axis.length_squared();
            e.volume * (lame.mu * eps2 + 0.5 * lame.lambda * tr * tr)
        })
        .sum()
}
