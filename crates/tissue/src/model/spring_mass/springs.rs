//! A network of linear springs between particles (eq. 2 of the survey), with spring damping,
//! and the Jacobians implicit Euler needs (Baraff & Witkin 1998).
//!
//! The force of a spring (a, b) of stiffness k, rest length L and damping c on particle a is
//! f_a = [k (l − L) + c (v_b − v_a)·u] u with d = x_b − x_a, l = |d|, u = d / l, and f_b = −f_a,
//! so internal forces sum to zero (momentum is conserved) and a rigid motion produces none.
//!
//! Jacobian: ∂f_a/∂x_b = k [(1 − L/l)(I − u uᵀ) + u uᵀ]. The transverse factor (1 − L/l) is
//! negative for a compressed spring, which makes the system matrix indefinite and conjugate
//! gradients unreliable; it is clamped at zero (Choi & Ko 2002), which keeps implicit Euler
//! unconditionally solvable at the cost of softer buckling. The damping Jacobian is
//! ∂f_a/∂v_b = c u uᵀ (the derivative of u in the damping term is dropped).

use crate::math::{Mat3, Real, Vec3};

/// One spring between particles `a` and `b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    pub a: u32,
    pub b: u32,
    /// Length at which the spring exerts no force, in m.
    pub rest_length: Real,
    /// Stiffness k, in N/m.
    pub stiffness: Real,
    /// Damping c along the spring, in N·s/m.
    pub damping: Real,
}

/// Below this length (relative to the rest length) a spring has no direction; it then exerts
/// no force rather than a NaN.
const DEGENERATE: Real = 1e-12;

/// Springs and their linearisation at the last `prepare` call.
#[derive(Clone, Debug, Default)]
pub struct SpringNetwork {
    pub springs: Vec<Spring>,
    /// Per spring: ∂f_a/∂x_b (clamped) and ∂f_a/∂v_b, valid after `prepare`.
    blocks: Vec<(Mat3, Mat3)>,
}

impl SpringNetwork {
    pub fn new(springs: Vec<Spring>) -> Self {
        Self {
            springs,
            blocks: Vec::new(),
        }
    }

    pub fn len(&self) -> usize {
        self.springs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.springs.is_empty()
    }

    /// Adds the spring and damping forces at positions `x`, velocities `v` to `f`; returns
    /// the elastic energy at `x` (the lengths are at hand, so it comes almost free).
    pub fn add_forces(&self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) -> Real {
        self.add_forces_with(x, v, f, true)
    }

    /// `add_forces`, with the spring damping left out unless `damped` (the explicit schemes
    /// apply it once per step implicitly, `integrate::split_damping`).
    pub fn add_forces_with(&self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3], damped: bool) -> Real {
        let mut energy = 0.0;
        for s in &self.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = x[b] - x[a];
            let l = d.length();
            let stretch = l - s.rest_length;
            energy += 0.5 * s.stiffness * stretch * stretch;
            if l <= DEGENERATE * s.rest_length.max(DEGENERATE) {
                continue;
            }
            let u = d / l;
            let mut magnitude = s.stiffness * stretch;
            if damped {
                magnitude += s.damping * (v[b] - v[a]).dot(u);
            }
            let fa = magnitude * u;
            f[a] += fa;
            f[b] -= fa;
        }
        energy
    }

    /// Adds only the elastic forces (no damping) to `f`.
    pub fn add_elastic_forces(&self, x: &[Vec3], f: &mut [Vec3]) {
        for s in &self.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = x[b] - x[a];
            let l = d.length();
            if l <= DEGENERATE * s.rest_length.max(DEGENERATE) {
                continue;
            }
            let fa = (s.stiffness * (l - s.rest_length) / l) * d;
            f[a] += fa;
            f[b] -= fa;
        }
    }

    /// Elastic energy Σ k (l − L)² / 2, in J.
    pub fn energy(&self, x: &[Vec3]) -> Real {
        self.springs
            .iter()
            .map(|s| {
                let stretch = (x[s.b as usize] - x[s.a as usize]).length() - s.rest_length;
                0.5 * s.stiffness * stretch * stretch
            })
            .sum()
    }

    /// Linearises every spring at `x` for the products below.
    pub fn prepare(&mut self, x: &[Vec3]) {
        self.blocks.clear();
        self.blocks.reserve(self.springs.len());
        for s in &self.springs {
            let d = x[s.b as usize] - x[s.a as usize];
            let l = d.length();
            if l <= DEGENERATE * s.rest_length.max(DEGENERATE) {
                // No direction: an isotropic stiffness k keeps the step well posed.
                self.blocks
                    .push((Mat3::from_diagonal(Vec3::splat(s.stiffness)), Mat3::ZERO));
                continue;
            }
            let u = d / l;
            let uu = outer(u, u);
            let transverse = (1.0 - s.rest_length / l).max(0.0);
            let k = s.stiffness * (uu + transverse * (Mat3::IDENTITY - uu));
            self.blocks.push((k, s.damping * uu));
        }
    }

    /// out += −(∂f/∂x) dx with the blocks of the last `prepare`.
    pub fn add_stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        for (s, (k, _)) in self.springs.iter().zip(&self.blocks) {
            let (a, b) = (s.a as usize, s.b as usize);
            let y = *k * (dx[a] - dx[b]);
            out[a] += y;
            out[b] -= y;
        }
    }

    /// out += −(∂f/∂v) dv (spring damping only).
    pub fn add_damping_product(&self, dv: &[Vec3], out: &mut [Vec3]) {
        for (s, (_, c)) in self.springs.iter().zip(&self.blocks) {
            if s.damping == 0.0 {
                continue;
            }
            let (a, b) = (s.a as usize, s.b as usize);
            let y = *c * (dv[a] - dv[b]);
            out[a] += y;
            out[b] -= y;
        }
    }

    /// out += (a_c·C + a_k·K) dx in one pass over the springs (the implicit solve's operator).
    pub fn add_system_product(&self, a_c: Real, a_k: Real, dx: &[Vec3], out: &mut [Vec3]) {
        for (s, (k, c)) in self.springs.iter().zip(&self.blocks) {
            let (a, b) = (s.a as usize, s.b as usize);
            let r = dx[a] - dx[b];
            let mut y = a_k * (*k * r);
            if s.damping != 0.0 {
                y += a_c * (*c * r);
            }
            out[a] += y;
            out[b] -= y;
        }
    }

    /// Adds the diagonals of −∂f/∂x and −∂f/∂v (for a Jacobi preconditioner).
    pub fn add_diagonal(&self, stiffness: &mut [Vec3], damping: &mut [Vec3]) {
        for (s, (k, c)) in self.springs.iter().zip(&self.blocks) {
            let kd = diagonal(k);
            let cd = diagonal(c);
            for p in [s.a as usize, s.b as usize] {
                stiffness[p] += kd;
                damping[p] += cd;
            }
        }
    }

    /// Bytes held (springs and Jacobian blocks).
    pub fn memory_bytes(&self) -> usize {
        self.springs.capacity() * std::mem::size_of::<Spring>()
            + self.blocks.capacity() * std::mem::size_of::<(Mat3, Mat3)>()
    }
}

#[inline]
pub(crate) fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

#[inline]
fn diagonal(m: &Mat3) -> Vec3 {
    Vec3::new(m.x_axis.x, m.y_axis.y, m.z_axis.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn network() -> (SpringNetwork, Vec<Vec3>, Vec<Vec3>) {
        let x0 = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.3, 0.2, 1.0)];
        let mut springs = Vec::new();
        for a in 0..4u32 {
            for b in a + 1..4 {
                springs.push(Spring {
                    a,
                    b,
                    rest_length: (x0[b as usize] - x0[a as usize]).length(),
                    stiffness: 10.0 + (a + 2 * b) as Real,
                    damping: 0.5 + 0.1 * b as Real,
                });
            }
        }
        let x = vec![
            Vec3::new(0.05, -0.02, 0.01),
            Vec3::new(1.1, 0.1, -0.05),
            Vec3::new(-0.1, 0.9, 0.07),
            Vec3::new(0.35, 0.15, 1.2),
        ];
        let v = vec![
            Vec3::new(0.1, 0.0, 0.3),
            Vec3::new(-0.2, 0.5, 0.0),
            Vec3::new(0.0, 0.1, -0.4),
            Vec3::new(0.3, -0.3, 0.2),
        ];
        (SpringNetwork::new(springs), x, v)
    }

    #[test]
    fn internal_forces_have_zero_sum_and_zero_torque() {
        let (n, x, v) = network();
        let mut f = vec![Vec3::ZERO; 4];
        n.add_forces(&x, &v, &mut f);
        let total: Vec3 = f.iter().copied().sum();
        let torque: Vec3 = x.iter().zip(&f).map(|(p, q)| p.cross(*q)).sum();
        assert!(total.length() < 1e-12, "{total}");
        assert!(torque.length() < 1e-12, "{torque}");
        assert!(f.iter().map(|q| q.length()).sum::<Real>() > 1.0);
    }

    #[test]
    fn rigid_motion_gives_zero_force() {
        let (n, _, _) = network();
        let x0 = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.3, 0.2, 1.0)];
        let r = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 1.1);
        let t = Vec3::new(0.4, -2.0, 7.0);
        let x: Vec<Vec3> = x0.iter().map(|p| r * *p + t).collect();
        // Rigid velocity: ω × x + t'.
        let w = Vec3::new(0.3, -0.7, 0.2);
        let v: Vec<Vec3> = x.iter().map(|p| w.cross(*p) + Vec3::X).collect();
        let mut f = vec![Vec3::ZERO; 4];
        n.add_forces(&x, &v, &mut f);
        for q in f {
            assert!(q.length() < 1e-12, "{q}");
        }
        assert!(n.energy(&x) < 1e-24);
    }

    #[test]
    fn forces_are_minus_the_energy_gradient() {
        let (n, x, _) = network();
        let v = vec![Vec3::ZERO; 4];
        let mut f = vec![Vec3::ZERO; 4];
        n.add_forces(&x, &v, &mut f);
        let h = 1e-6;
        for p in 0..4 {
            for axis in 0..3 {
                let mut xp = x.clone();
                let mut xm = x.clone();
                xp[p][axis] += h;
                xm[p][axis] -= h;
                let g = (n.energy(&xp) - n.energy(&xm)) / (2.0 * h);
                assert!(
                    (g + f[p][axis]).abs() < 1e-6,
                    "{p} {axis}: {g} {}",
                    f[p][axis]
                );
            }
        }
    }

    #[test]
    fn stiffness_product_matches_finite_differences_when_stretched() {
        // Every spring is stretched here, so the clamp is inactive and the product is exact.
        let (n, x0, _) = network();
        let x: Vec<Vec3> = x0.iter().map(|p| *p * 1.3).collect();
        let v = vec![Vec3::ZERO; 4];
        let mut m = n.clone();
        m.prepare(&x);
        let dx = [
            Vec3::new(0.3, -0.1, 0.2),
            Vec3::new(-0.2, 0.4, 0.1),
            Vec3::new(0.1, 0.1, -0.3),
            Vec3::new(0.0, -0.2, 0.5),
        ];
        let mut out = vec![Vec3::ZERO; 4];
        m.add_stiffness_product(&dx, &mut out);
        let h = 1e-6;
        let force = |s: Real| {
            let xs: Vec<Vec3> = x.iter().zip(&dx).map(|(p, d)| *p + s * *d).collect();
            let mut f = vec![Vec3::ZERO; 4];
            n.add_forces(&xs, &v, &mut f);
            f
        };
        let (fp, fm) = (force(h), force(-h));
        for p in 0..4 {
            let fd = -(fp[p] - fm[p]) / (2.0 * h);
            assert!((fd - out[p]).length() < 1e-6, "{p}: {fd} vs {}", out[p]);
        }
        // The diagonal is the diagonal of the same operator.
        let (mut ks, mut cs) = (vec![Vec3::ZERO; 4], vec![Vec3::ZERO; 4]);
        m.add_diagonal(&mut ks, &mut cs);
        let mut e = vec![Vec3::ZERO; 4];
        e[2] = Vec3::Y;
        let mut col = vec![Vec3::ZERO; 4];
        m.add_stiffness_product(&e, &mut col);
        assert!((col[2].y - ks[2].y).abs() < 1e-12);
    }

    #[test]
    fn damping_product_matches_velocity_derivative() {
        let (mut n, x, v) = network();
        n.prepare(&x);
        let dv = [
            Vec3::X,
            Vec3::new(0.0, 0.5, -0.2),
            Vec3::Z,
            Vec3::new(0.2, 0.2, 0.2),
        ];
        let mut out = vec![Vec3::ZERO; 4];
        n.add_damping_product(&dv, &mut out);
        let force = |s: Real| {
            let vs: Vec<Vec3> = v.iter().zip(&dv).map(|(p, d)| *p + s * *d).collect();
            let mut f = vec![Vec3::ZERO; 4];
            n.add_forces(&x, &vs, &mut f);
            f
        };
        let (f1, f0) = (force(1.0), force(0.0));
        for p in 0..4 {
            // The damping force is linear in v: the difference is exact.
            assert!(((f0[p] - f1[p]) - out[p]).length() < 1e-12);
        }
    }

    #[test]
    fn the_fused_product_is_the_two_products() {
        let (mut n, x0, _) = network();
        // Stretched and sheared, so K has its transverse part.
        let x: Vec<Vec3> = x0
            .iter()
            .enumerate()
            .map(|(i, p)| *p * 1.3 + Vec3::new(0.1 * i as Real, 0.0, -0.05))
            .collect();
        n.prepare(&x);
        let dx: Vec<Vec3> = (0..4)
            .map(|i| Vec3::new((i as Real).sin(), 0.3, (2.0 * i as Real).cos()))
            .collect();
        let (a_c, a_k) = (0.01, 1e-4);
        let (mut k, mut c, mut fused) = (
            vec![Vec3::ZERO; 4],
            vec![Vec3::ZERO; 4],
            vec![Vec3::ZERO; 4],
        );
        n.add_stiffness_product(&dx, &mut k);
        n.add_damping_product(&dx, &mut c);
        n.add_system_product(a_c, a_k, &dx, &mut fused);
        for p in 0..4 {
            let want = a_k * k[p] + a_c * c[p];
            assert!(
                (fused[p] - want).length()
                    <= 1e-15 * (a_k * k[p].length() + a_c * c[p].length()) + 1e-300
            );
        }
    }

    #[test]
    fn compressed_springs_keep_a_positive_semidefinite_jacobian() {
        let (mut n, x0, _) = network();
        let x: Vec<Vec3> = x0.iter().map(|p| *p * 0.5).collect();
        n.prepare(&x);
        // dxᵀ K dx ≥ 0 for a few directions.
        for seed in 0..20 {
            let dx: Vec<Vec3> = (0..4)
                .map(|i| {
                    let t = (seed * 4 + i) as Real;
                    Vec3::new((t * 1.7).sin(), (t * 2.3).cos(), (t * 0.7).sin())
                })
                .collect();
            let mut out = vec![Vec3::ZERO; 4];
            n.add_stiffness_product(&dx, &mut out);
            let q: Real = dx.iter().zip(&out).map(|(a, b)| a.dot(*b)).sum();
            assert!(q >= -1e-12, "{q}");
        }
    }
}
