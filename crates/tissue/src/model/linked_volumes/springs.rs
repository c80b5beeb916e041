//! The spring-damper lattice of linked volumes and its `ParticleSystem` forces.
//!
//! Stiffness from E (central springs on a cubic lattice, spacing a, energy density
//! ½ Σ k L² (n·ε·n)² / a³): with k₁ on axis links, k₂ on face diagonals and k₃ on body
//! diagonals, C₁₁ = (k₁ + 2k₂ + 4k₃/3)/a and C₁₂ = C₄₄ = (k₂ + 4k₃/3)/a. Isotropy
//! (C₁₁ − C₁₂ = 2C₄₄) then fixes λ = μ, so ν = 1/4 whatever the material says (the Cauchy
//! relation of central-force lattices), and E = 5μ/2 sets the scale:
//! - 18 neighbours: k₁ = k₂ = 2Ea/5;
//! - 26 neighbours: k₁ = 22Ea/35, k₂ = k₃ = 6Ea/35 (the split k₂ = k₃ is our choice);
//! - 6 neighbours: k₁ = Ea gives E under uniaxial stress, but the lattice has no shear
//!   stiffness at all (it folds freely), as the survey warns for plain linked volumes.
//!
//! To honour the material's ν ≥ 1/4 the "E" in these formulas is 5μ/2 with the material's μ,
//! and the volume term (`volume_term`, κ = λ − μ) supplies the rest of λ
//! (`volume_term::lattice_moduli`).
//!
//! For unequal spacings each spring keeps k·L²/V of its cubic family (V the voxel volume).
//! Dampers act along the springs, c = β·k (β the material's stiffness damping), plus the
//! mass-proportional α·m drag; relative-velocity dampers leave rigid motion undamped.
//! Implicit Euler gets K = Σ k[n nᵀ + max(0, 1 − L/l)(I − n nᵀ)] (the compressive
//! geometric term dropped to keep K positive semi-definite) and C = Σ c n nᵀ + α M.

use crate::error::SimError;
use crate::integrate::{ParticleSystem, RankOneJacobians};
use crate::math::{Mat3, Real, Vec3};
use crate::model::spring_mass::springs::outer;

use super::volume_term::{LatticeModuli, VolumeTerm};

/// One spring between elements a and b.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    pub a: u32,
    pub b: u32,
    pub k: Real,
    pub rest: Real,
    pub c: Real,
}

/// The linearisation of one spring: K = (ka − kb) n nᵀ + kb I.
#[derive(Clone, Copy, Debug, Default)]
struct Linear {
    n: Vec3,
    ka: Real,
    kb: Real,
}

/// Springs, masses and loads, as the integrator sees them.
#[derive(Clone, Debug)]
pub struct SpringLattice {
    pub springs: Vec<Spring>,
    pub masses: Vec<Real>,
    /// Mass-proportional damping α, 1/s.
    pub alpha: Real,
    /// Constant external force per element (gravity and point loads), N.
    pub external: Vec<Vec3>,
    /// The volume energy that supplies λ − μ (empty at ν = 1/4).
    pub volume: VolumeTerm,
    /// The moduli and the voxel volume (m³) the volume term was built with.
    volume_moduli: Option<(LatticeModuli, Real)>,
    linear: Vec<Linear>,
    /// Rest positions (given with the volume term), for implicit Euler's rest-matrix
    /// preconditioner; empty: none.
    rest: Vec<Vec3>,
    /// Counts edits of the springs and the volume term: the rest matrix's version.
    edits: u64,
}

/// The (k L²/V) coefficients per family (axis, face diagonal, body diagonal) in units of E.
pub fn family_coefficients(neighbours: usize) -> Result<[Real; 3], SimError> {
    // k L² / V for the cubic lattice: axis L² = a², face 2a², body 3a²; V = a³.
    match neighbours {
        6 => Ok([1.0, 0.0, 0.0]),
        18 => Ok([2.0 / 5.0, 4.0 / 5.0, 0.0]),
        26 => Ok([22.0 / 35.0, 12.0 / 35.0, 18.0 / 35.0]),
        n => Err(SimError::BadParameter {
            name: "neighbours",
            value: n.to_string(),
            reason: "must be 6, 18 or 26".into(),
        }),
    }
}

impl SpringLattice {
    pub fn new(springs: Vec<Spring>, masses: Vec<Real>, alpha: Real) -> Self {
        let n = masses.len();
        Self {
            linear: vec![Linear::default(); springs.len()],
            springs,
            masses,
            alpha,
            external: vec![Vec3::ZERO; n],
            volume: VolumeTerm::default(),
            volume_moduli: None,
            rest: Vec::new(),
            edits: 0,
        }
    }

    /// Topology edits: keeps the springs for which `keep` holds and appends `added` (call
    /// `rebuild_volume_term` afterwards).
    pub fn edit_springs(&mut self, keep: impl FnMut(&Spring) -> bool, added: &[Spring]) {
        self.springs.retain(keep);
        self.springs.extend_from_slice(added);
        // Reset in place: a fresh vector per edit costs more in page faults than the edit.
        self.linear.clear();
        self.linear.resize(self.springs.len(), Linear::default());
        self.edits += 1;
    }

    /// Adds the volume term of `moduli` on voxels of `voxel_volume` (m³), its stencils and
    /// weights taken from the springs between the `rest` positions.
    pub fn with_volume_term(
        mut self,
        rest: &[Vec3],
        moduli: LatticeModuli,
        voxel_volume: Real,
    ) -> Self {
        self.volume_moduli = Some((moduli, voxel_volume));
        self.rebuild_volume_term(rest);
        self
    }

    /// Rebuilds the volume term's stencils and weights from the springs left (after links
    /// were cut), so no volume couples voxels across a cut.
    pub fn rebuild_volume_term(&mut self, rest: &[Vec3]) {
        if let Some((moduli, volume)) = self.volume_moduli {
            self.volume = VolumeTerm::from_springs(&self.springs, rest, &moduli, volume);
        }
        if rest.len() == self.masses.len() {
            self.rest.clear();
            self.rest.extend_from_slice(rest);
        }
        self.edits += 1;
    }

    /// Σ ½ k (l − L)² plus the volume energy.
    pub fn elastic_energy(&self, x: &[Vec3]) -> Real {
        let springs: Real = self
            .springs
            .iter()
            .map(|s| {
                let l = (x[s.b as usize] - x[s.a as usize]).length();
                0.5 * s.k * (l - s.rest) * (l - s.rest)
            })
            .sum();
        springs + self.volume.energy(x)
    }
}

impl ParticleSystem for SpringLattice {
    fn masses(&self) -> &[Real] {
        &self.masses
    }

    fn forces(&mut self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        for s in &self.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = x[b] - x[a];
            let l = d.length();
            if l <= 0.0 {
                continue;
            }
            let n = d / l;
            let t = s.k * (l - s.rest) + s.c * (v[b] - v[a]).dot(n);
            f[a] += t * n;
            f[b] -= t * n;
        }
        self.volume.add_forces(x, f);
        for (((fi, m), vi), e) in f.iter_mut().zip(&self.masses).zip(v).zip(&self.external) {
            *fi += *e - self.alpha * m * *vi;
        }
    }

    fn potential_energy(&self, x: &[Vec3]) -> Option<Real> {
        let load: Real = self.external.iter().zip(x).map(|(e, p)| e.dot(*p)).sum();
        Some(self.elastic_energy(x) - load)
    }

    fn prepare_jacobians(&mut self, x: &[Vec3], _v: &[Vec3]) -> Result<(), SimError> {
        for (lin, s) in self.linear.iter_mut().zip(&self.springs) {
            let d = x[s.b as usize] - x[s.a as usize];
            let l = d.length();
            *lin = if l > 0.0 {
                Linear {
                    n: d / l,
                    ka: s.k,
                    kb: s.k * (1.0 - s.rest / l).max(0.0),
                }
            } else {
                Linear::default()
            };
        }
        self.volume.prepare(x);
        Ok(())
    }

    fn stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        out.fill(Vec3::ZERO);
        for (lin, s) in self.linear.iter().zip(&self.springs) {
            let (a, b) = (s.a as usize, s.b as usize);
            let r = dx[a] - dx[b];
            let y = (lin.ka - lin.kb) * lin.n.dot(r) * lin.n + lin.kb * r;
            out[a] += y;
            out[b] -= y;
        }
        self.volume.add_stiffness_product(dx, out);
    }

    fn damping_product(&self, dv: &[Vec3], out: &mut [Vec3]) {
        out.fill(Vec3::ZERO);
        for (lin, s) in self.linear.iter().zip(&self.springs) {
            let (a, b) = (s.a as usize, s.b as usize);
            let y = s.c * lin.n.dot(dv[a] - dv[b]) * lin.n;
            out[a] += y;
            out[b] -= y;
        }
        for ((o, m), d) in out.iter_mut().zip(&self.masses).zip(dv) {
            *o += self.alpha * m * *d;
        }
    }

    /// One pass over the springs: each contributes (a_c c + a_k (k_a − k_b)) n nᵀ + a_k k_b I.
    fn system_product(
        &self,
        a_c: Real,
        a_k: Real,
        x: &[Vec3],
        out: &mut [Vec3],
        _scratch: &mut [Vec3],
    ) {
        for ((o, m), d) in out.iter_mut().zip(&self.masses).zip(x) {
            *o = (a_c * self.alpha * m) * *d;
        }
        for (lin, s) in self.linear.iter().zip(&self.springs) {
            let (a, b) = (s.a as usize, s.b as usize);
            let r = x[a] - x[b];
            let along = a_c * s.c + a_k * (lin.ka - lin.kb);
            let y = (along * lin.n.dot(r)) * lin.n + (a_k * lin.kb) * r;
            out[a] += y;
            out[b] -= y;
        }
        self.volume.add_scaled_stiffness_product(a_k, x, out);
    }

    fn rest_jacobians_version(&self) -> Option<u64> {
        (self.rest.len() == self.masses.len()).then_some(self.edits)
    }

    /// At rest each spring is k n₀n₀ᵀ (no transverse part: l = L) with damper c n₀n₀ᵀ, and
    /// each voxel's volume term κV₀w g₀g₀ᵀ.
    fn rest_jacobians(&self, out: &mut RankOneJacobians) {
        for s in &self.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let (Some(pa), Some(pb)) = (self.rest.get(a), self.rest.get(b)) else {
                continue;
            };
            let d = *pb - *pa;
            let l = d.length();
            if l.is_nan() || l <= 0.0 {
                continue;
            }
            let n = d / l;
            out.push([(s.a, n), (s.b, -n)], s.k, s.c);
        }
        self.volume.rest_jacobians(&self.rest, out);
        for (d, m) in out.damping_diagonal.iter_mut().zip(&self.masses) {
            *d += self.alpha * m;
        }
    }

    fn jacobian_blocks(&self, stiffness: &mut [Mat3], damping: &mut [Mat3]) {
        stiffness.fill(Mat3::ZERO);
        for (d, m) in damping.iter_mut().zip(&self.masses) {
            *d = Mat3::from_diagonal(Vec3::splat(self.alpha * m));
        }
        for (lin, s) in self.linear.iter().zip(&self.springs) {
            let nn = outer(lin.n, lin.n);
            let kb = (lin.ka - lin.kb) * nn + Mat3::from_diagonal(Vec3::splat(lin.kb));
            let cb = s.c * nn;
            for e in [s.a as usize, s.b as usize] {
                stiffness[e] += kb;
                damping[e] += cb;
            }
        }
        self.volume.add_blocks(stiffness);
    }

    fn jacobian_diagonal(&self, stiffness: &mut [Vec3], damping: &mut [Vec3]) {
        stiffness.fill(Vec3::ZERO);
        for (d, m) in damping.iter_mut().zip(&self.masses) {
            *d = Vec3::splat(self.alpha * m);
        }
        for (lin, s) in self.linear.iter().zip(&self.springs) {
            let nn = lin.n * lin.n;
            let kd = (lin.ka - lin.kb) * nn + Vec3::splat(lin.kb);
            let cd = s.c * nn;
            for e in [s.a as usize, s.b as usize] {
                stiffness[e] += kd;
                damping[e] += cd;
            }
        }
        self.volume.add_diagonal(stiffness);
    }
}
