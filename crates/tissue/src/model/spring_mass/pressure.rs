//! Volume preservation for a closed surface of particles: an internal pressure that resists
//! changes of the enclosed volume, with the stiffness of the material's bulk modulus.
//!
//! Energy W = K (V − V₀)² / (2 V₀), so a uniform dilation δ = (V − V₀)/V₀ stores K δ² V₀ / 2,
//! the continuum value. V = Σ a·(b×c)/6 over the outward triangles, ∂V/∂x_a = Σ (b×c)/6 over
//! the triangles (a, b, c) around a, and f = −K (V − V₀)/V₀ ∂V/∂x. The Jacobian keeps only the
//! rank-one term (K/V₀) ∇V ∇Vᵀ, which is positive semidefinite; the term with the second
//! derivative of V is dropped (it is small near V₀ and indefinite).

use crate::math::{Real, Vec3};

#[derive(Clone, Debug)]
pub struct Pressure {
    /// Outward triangles over particle indices.
    pub triangles: Vec<[u32; 3]>,
    pub rest_volume: Real,
    /// Bulk modulus K, in Pa.
    pub bulk_modulus: Real,
    /// ∇V at the last `prepare`.
    gradient: Vec<Vec3>,
}

impl Pressure {
    /// `None` when the enclosed rest volume is not positive (open or inward surface).
    pub fn new(triangles: Vec<[u32; 3]>, x: &[Vec3], bulk_modulus: Real) -> Option<Self> {
        let rest_volume = volume(&triangles, x);
        (rest_volume > 0.0 && rest_volume.is_finite()).then(|| Self {
            triangles,
            rest_volume,
            bulk_modulus,
            gradient: Vec::new(),
        })
    }

    pub fn volume(&self, x: &[Vec3]) -> Real {
        volume(&self.triangles, x)
    }

    pub fn energy(&self, x: &[Vec3]) -> Real {
        let dv = self.volume(x) - self.rest_volume;
        0.5 * self.bulk_modulus * dv * dv / self.rest_volume
    }

    /// Adds the pressure forces at `x` to `f`; returns the energy at `x`.
    pub fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Real {
        let dv = self.volume(x) - self.rest_volume;
        let s = -self.bulk_modulus * dv / self.rest_volume / 6.0;
        for &[a, b, c] in &self.triangles {
            let (pa, pb, pc) = (x[a as usize], x[b as usize], x[c as usize]);
            f[a as usize] += s * pb.cross(pc);
            f[b as usize] += s * pc.cross(pa);
            f[c as usize] += s * pa.cross(pb);
        }
        0.5 * self.bulk_modulus * dv * dv / self.rest_volume
    }

    pub fn prepare(&mut self, x: &[Vec3]) {
        self.gradient.clear();
        self.gradient.resize(x.len(), Vec3::ZERO);
        for &[a, b, c] in &self.triangles {
            let (pa, pb, pc) = (x[a as usize], x[b as usize], x[c as usize]);
            self.gradient[a as usize] += pb.cross(pc) / 6.0;
            self.gradient[b as usize] += pc.cross(pa) / 6.0;
            self.gradient[c as usize] += pa.cross(pb) / 6.0;
        }
    }

    /// out += (K/V₀) ∇V (∇V·dx).
    pub fn add_stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        self.add_scaled_stiffness_product(1.0, dx, out);
    }

    /// Adds `scale`·K·dx.
    pub fn add_scaled_stiffness_product(&self, scale: Real, dx: &[Vec3], out: &mut [Vec3]) {
        let g = &self.gradient;
        let s: Real = g.iter().zip(dx).map(|(a, b)| a.dot(*b)).sum::<Real>()
            * (scale * self.bulk_modulus)
            / self.rest_volume;
        for (o, gi) in out.iter_mut().zip(g) {
            *o += s * *gi;
        }
    }

    pub fn add_diagonal(&self, stiffness: &mut [Vec3]) {
        let c = self.bulk_modulus / self.rest_volume;
        for (d, gi) in stiffness.iter_mut().zip(&self.gradient) {
            *d += c * *gi * *gi;
        }
    }
}

fn volume(triangles: &[[u32; 3]], x: &[Vec3]) -> Real {
    triangles
        .iter()
        .map(|&[a, b, c]| x[a as usize].dot(x[b as usize].cross(x[c as usize])))
        .sum::<Real>()
        / 6.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tet() -> (Vec<[u32; 3]>, Vec<Vec3>) {
        (
            vec![[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]],
            vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
        )
    }

    #[test]
    fn force_is_minus_gradient_and_conserves_momentum() {
        let (t, x0) = tet();
        let p = Pressure::new(t, &x0, 2000.0).unwrap();
        assert!((p.rest_volume - 1.0 / 6.0).abs() < 1e-15);
        let x: Vec<Vec3> = x0
            .iter()
            .map(|q| *q * 1.2 + Vec3::new(0.1, 0.0, 0.3))
            .collect();
        let mut f = vec![Vec3::ZERO; 4];
        p.add_forces(&x, &mut f);
        let total: Vec3 = f.iter().copied().sum();
        assert!(total.length() < 1e-10);
        let h = 1e-7;
        for i in 0..4 {
            for a in 0..3 {
                let (mut xp, mut xm) = (x.clone(), x.clone());
                xp[i][a] += h;
                xm[i][a] -= h;
                let g = (p.energy(&xp) - p.energy(&xm)) / (2.0 * h);
                assert!((g + f[i][a]).abs() < 1e-5 * f[i][a].abs().max(1.0));
            }
        }
        // An inflated body is pulled back in: corner 0 moves toward the others.
        assert!(f[0].dot(Vec3::ONE) > 0.0);
    }

    #[test]
    fn inward_surface_is_refused() {
        let (mut t, x) = tet();
        for tri in &mut t {
            tri.swap(1, 2);
        }
        assert!(Pressure::new(t, &x, 1.0).is_none());
    }
}
