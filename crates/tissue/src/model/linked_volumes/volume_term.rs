//! The volume term that lets linked volumes honour Poisson's ratio.
//!
//! Central springs on a cubic lattice obey the Cauchy relation λ = μ (ν = 1/4, see
//! `springs`). So the springs are scaled to give the material's shear modulus μ, and a
//! per-voxel volume energy supplies the rest of λ: with κ = λ − μ,
//!
//!   E_vol = Σ_voxels ½ κ V₀ (J − 1)²,   J = det F,
//!
//! where F is the voxel's deformation gradient from its six axis neighbours: column d is
//! (x₊ − x₋)/(2h_d) with both neighbours, the one-sided difference with one (so surface
//! voxels count fully, like their masses), and a voxel lacking neighbours along an axis has
//! no term (a one-voxel sheet has no volume to keep). For a small uniform strain ε,
//! J − 1 = tr ε, adding ½ κ (tr ε)² per volume: exactly the missing ½ (λ − μ)(tr ε)².
//!
//! J is invariant under rotation and translation, so rigid motion gives zero force and the
//! forces conserve linear and angular momentum. ν < 1/4 would need κ < 0 (an unstable
//! energy), so it is refused (`lattice_moduli`).
//!
//! Jacobian for implicit Euler: K = κ V₀ g gᵀ (g = ∂J/∂x, Gauss-Newton), exact at J = 1;
//! the curvature term κ V₀ (J − 1) ∂²J/∂x², indefinite, is dropped to keep K positive
//! semi-definite (as the springs drop their compressive geometric term).
//!
//! The neighbours come from the axis springs, so removing the springs between two voxels
//! (a cut) also removes them from each other's stencils when the term is rebuilt.

use crate::error::SimError;
use crate::material::Material;
use crate::math::{Mat3, Real, Vec3};
use crate::model::spring_mass::springs::outer;

use super::springs::Spring;

/// Spring scale and volume stiffness that reproduce a material on the lattice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatticeModuli {
    /// Replaces E in the springs' k = c·E·V/L² (`family_coefficients`), in Pa.
    pub spring_modulus: Real,
    /// κ = λ − μ of the volume term, in Pa (0: springs alone).
    pub kappa: Real,
    /// The Poisson ratio the lattice then has (0 for 6 neighbours: no shear stiffness).
    pub poisson_ratio: Real,
    /// Σ k·L²/V over the links of a voxel with all its neighbours, in Pa: a voxel's volume
    /// term is weighted by the share of this its links have (see `VolumeTerm`).
    pub full_links: Real,
}

/// The lattice constants for `material` with 6, 18 or 26 neighbours.
///
/// 18 and 26 neighbours honour E and ν for ν ≥ 1/4: springs give μ = E / 2(1+ν) (their own
/// E is 5μ/2), the volume term λ − μ. Six neighbours have no shear stiffness whatever the
/// springs, so they keep k = E·a (E under uniaxial stress, ν = 0) and no volume term.
pub fn lattice_moduli(material: &Material, neighbours: usize) -> Result<LatticeModuli, SimError> {
    let c = super::springs::family_coefficients(neighbours)?;
    // 6 axis, 12 face-diagonal and 8 body-diagonal neighbours, each link shared by two.
    let links = 3.0 * c[0] + 6.0 * c[1] + 4.0 * c[2];
    let nu = material.poisson_ratio;
    if neighbours == 6 {
        return Ok(LatticeModuli {
            spring_modulus: material.young_modulus,
            kappa: 0.0,
            poisson_ratio: 0.0,
            full_links: links * material.young_modulus,
        });
    }
    if nu < 0.25 {
        return Err(SimError::BadParameter {
            name: "poisson_ratio",
            value: nu.to_string(),
            reason: "linked volumes represent 0.25 <= nu < 0.5: central springs alone give \
                     1/4, and the volume term can only stiffen compression"
                .into(),
        });
    }
    let mu = material.mu();
    Ok(LatticeModuli {
        spring_modulus: 2.5 * mu,
        // λ − μ = 0 at ν = 1/4; the rounding of λ there must not make it negative.
        kappa: (material.lambda() - mu).max(0.0),
        poisson_ratio: nu,
        full_links: links * 2.5 * mu,
    })
}

/// One voxel's stencil: F's column d is (x[plus[d]] − x[minus[d]]) · inv_len[d]; its energy
/// is ½ κ V₀ · weight · (J − 1)².
#[derive(Clone, Copy, Debug, PartialEq)]
struct Stencil {
    plus: [u32; 3],
    minus: [u32; 3],
    inv_len: [Real; 3],
    weight: Real,
}

/// The per-voxel volume energy (see the module doc).
#[derive(Clone, Debug, Default)]
pub struct VolumeTerm {
    stencils: Vec<Stencil>,
    /// κ·V₀, in J (N·m).
    stiffness: Real,
    /// Per stencil, ∂J/∂(column d)·inv_len[d] at the state given to `prepare`.
    grads: Vec<[Vec3; 3]>,
}

impl VolumeTerm {
    /// Stencils from the axis springs between the rest positions; `kappa` in Pa, `volume`
    /// the voxel volume in m³. No stencils when κ = 0.
    pub fn from_springs(
        springs: &[Spring],
        rest: &[Vec3],
        moduli: &LatticeModuli,
        volume: Real,
    ) -> Self {
        let kappa = moduli.kappa;
        if kappa <= 0.0 || moduli.full_links <= 0.0 {
            return Self::default();
        }
        const NONE: u32 = u32::MAX;
        let n = rest.len();
        // plus[v][d]: the neighbour one step along +axis d, and minus likewise.
        let mut plus = vec![[NONE; 3]; n];
        let mut minus = vec![[NONE; 3]; n];
        // Half of Σ k·L² over each voxel's links (each link is shared by its two ends).
        let mut links = vec![0.0; n];
        for s in springs {
            for e in [s.a, s.b] {
                if let Some(l) = links.get_mut(e as usize) {
                    *l += 0.5 * s.k * s.rest * s.rest;
                }
            }
            let (Some(pa), Some(pb)) = (rest.get(s.a as usize), rest.get(s.b as usize)) else {
                continue;
            };
            let d = *pb - *pa;
            let Some(axis) = axis_of(d) else { continue };
            let (lo, hi) = if d[axis] > 0.0 {
                (s.a, s.b)
            } else {
                (s.b, s.a)
            };
            plus[lo as usize][axis] = hi;
            minus[hi as usize][axis] = lo;
        }
        let mut stencils = Vec::new();
        'voxel: for v in 0..n {
            let mut st = Stencil {
                plus: [0; 3],
                minus: [0; 3],
                inv_len: [0.0; 3],
                weight: (links[v] / (moduli.full_links * volume)).min(1.0),
            };
            for d in 0..3 {
                let (p, m) = match (plus[v][d], minus[v][d]) {
                    (NONE, NONE) => continue 'voxel,
                    (p, NONE) => (p, v as u32),
                    (NONE, m) => (v as u32, m),
                    (p, m) => (p, m),
                };
                st.plus[d] = p;
                st.minus[d] = m;
                st.inv_len[d] = 1.0 / (rest[p as usize][d] - rest[m as usize][d]);
            }
            stencils.push(st);
        }
        Self {
            grads: vec![[Vec3::ZERO; 3]; stencils.len()],
            stencils,
            stiffness: kappa * volume,
        }
    }

    /// Voxels carrying the term.
    pub fn len(&self) -> usize {
        self.stencils.len()
    }

    pub fn is_empty(&self) -> bool {
        self.stencils.is_empty()
    }

    /// Σ ½ κ V₀ (J − 1)².
    pub fn energy(&self, x: &[Vec3]) -> Real {
        self.stencils
            .iter()
            .map(|s| {
                let j = jacobian(s, x).0 - 1.0;
                0.5 * self.stiffness * s.weight * j * j
            })
            .sum()
    }

    /// Adds −∂E/∂x to `f`.
    pub fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) {
        for s in &self.stencils {
            let (j, g) = jacobian(s, x);
            let t = self.stiffness * s.weight * (j - 1.0);
            for d in 0..3 {
                f[s.plus[d] as usize] -= t * g[d];
                f[s.minus[d] as usize] += t * g[d];
            }
        }
    }

    /// Stores ∂J/∂x at `x` for the products.
    pub fn prepare(&mut self, x: &[Vec3]) {
        for (g, s) in self.grads.iter_mut().zip(&self.stencils) {
            *g = jacobian(s, x).1;
        }
    }

    /// Adds K·dx with K = κ V₀ g gᵀ (the Gauss-Newton part, see the module doc).
    pub fn add_stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        self.add_scaled_stiffness_product(1.0, dx, out);
    }

    /// Adds `scale`·K·dx.
    pub fn add_scaled_stiffness_product(&self, scale: Real, dx: &[Vec3], out: &mut [Vec3]) {
        let stiffness = scale * self.stiffness;
        for (g, s) in self.grads.iter().zip(&self.stencils) {
            let r: Real = (0..3)
                .map(|d| g[d].dot(dx[s.plus[d] as usize] - dx[s.minus[d] as usize]))
                .sum();
            let t = stiffness * s.weight * r;
            for d in 0..3 {
                out[s.plus[d] as usize] += t * g[d];
                out[s.minus[d] as usize] -= t * g[d];
            }
        }
    }

    /// K at the `rest` positions (J = 1, so exact there) as rank-one terms κV₀w g₀g₀ᵀ.
    pub fn rest_jacobians(&self, rest: &[Vec3], out: &mut crate::integrate::RankOneJacobians) {
        let n = rest.len();
        for s in &self.stencils {
            let in_range = (0..3).all(|d| (s.plus[d] as usize) < n && (s.minus[d] as usize) < n);
            if !in_range {
                continue;
            }
            let g = jacobian(s, rest).1;
            let parts = (0..3).flat_map(|d| [(s.plus[d], g[d]), (s.minus[d], -g[d])]);
            out.push(parts, self.stiffness * s.weight, 0.0);
        }
    }

    /// Adds the diagonals of K's 3x3 diagonal blocks.
    pub fn add_diagonal(&self, diag: &mut [Vec3]) {
        self.each_block_part(|p, w, v| diag[p] += w * v * v);
    }

    /// Adds K's 3x3 diagonal blocks.
    pub fn add_blocks(&self, blocks: &mut [Mat3]) {
        self.each_block_part(|p, w, v| blocks[p] += w * outer(v, v));
    }

    /// Calls `f(particle, κV₀w, v)` for each particle of each stencil, v the particle's
    /// part of ∂J/∂x: its diagonal block of the term is κV₀w v vᵀ.
    fn each_block_part(&self, mut f: impl FnMut(usize, Real, Vec3)) {
        for (g, s) in self.grads.iter().zip(&self.stencils) {
            // A particle can appear in several columns (the voxel itself at a surface):
            // its block is built from the sum of its gradient entries.
            let mut parts: [(u32, Vec3); 6] = [(u32::MAX, Vec3::ZERO); 6];
            let mut used = 0;
            for (d, gd) in g.iter().enumerate() {
                for (p, sign) in [(s.plus[d], 1.0), (s.minus[d], -1.0)] {
                    match parts[..used].iter_mut().find(|e| e.0 == p) {
                        Some(e) => e.1 += sign * *gd,
                        None => {
                            parts[used] = (p, sign * *gd);
                            used += 1;
                        }
                    }
                }
            }
            for (p, v) in &parts[..used] {
                f(*p as usize, self.stiffness * s.weight, *v);
            }
        }
    }

    /// K·dx including the dropped curvature term: the exact Hessian, for tests.
    #[cfg(test)]
    pub(crate) fn exact_stiffness_product(&self, x: &[Vec3], dx: &[Vec3], out: &mut [Vec3]) {
        for s in &self.stencils {
            let (j, g) = jacobian(s, x);
            let f = columns(s, x);
            let df: [Vec3; 3] = std::array::from_fn(|d| {
                (dx[s.plus[d] as usize] - dx[s.minus[d] as usize]) * s.inv_len[d]
            });
            let r: Real = (0..3)
                .map(|d| g[d].dot(dx[s.plus[d] as usize] - dx[s.minus[d] as usize]))
                .sum();
            // d(∂J/∂F_d) along dF: the derivative of the cross products.
            let dc = [
                df[1].cross(f[2]) + f[1].cross(df[2]),
                df[2].cross(f[0]) + f[2].cross(df[0]),
                df[0].cross(f[1]) + f[0].cross(df[1]),
            ];
            for d in 0..3 {
                let y = self.stiffness * s.weight * (r * g[d] + (j - 1.0) * s.inv_len[d] * dc[d]);
                out[s.plus[d] as usize] += y;
                out[s.minus[d] as usize] -= y;
            }
        }
    }
}

/// The lattice axis a rest link lies along, if it lies along one.
fn axis_of(d: Vec3) -> Option<usize> {
    let a = d.abs();
    let len = a.max_element();
    if len <= 0.0 {
        return None;
    }
    let axis = (0..3).find(|&k| a[k] == len)?;
    // The other two components vanish (up to rounding of the centres).
    let off = a.element_sum() - len;
    (off <= 1e-9 * len).then_some(axis)
}

fn columns(s: &Stencil, x: &[Vec3]) -> [Vec3; 3] {
    std::array::from_fn(|d| (x[s.plus[d] as usize] - x[s.minus[d] as usize]) * s.inv_len[d])
}

/// J = det F and ∂J/∂(x[plus[d]]) = inv_len[d] · (∂J/∂F_d) for d = 0, 1, 2.
fn jacobian(s: &Stencil, x: &[Vec3]) -> (Real, [Vec3; 3]) {
    let f = columns(s, x);
    let c = [f[1].cross(f[2]), f[2].cross(f[0]), f[0].cross(f[1])];
    let j = f[0].dot(c[0]);
    (j, std::array::from_fn(|d| c[d] * s.inv_len[d]))
}

#[cfg(test)]
#[path = "volume_term_tests.rs"]
mod tests;
