//! The mechanical system every spring-mass kind shares: particles with lumped masses, a
//! spring network, viscous friction, an optional pressure and the external loads. It is what
//! the shared integrators (`crate::integrate`) step.
//!
//! Eq. 1 of the survey: m ẍ + γ ẋ + f_int = f_ext, with the friction γ_i = α m_i taken
//! proportional to the mass (α = `material.damping`, in 1/s) so that it damps every mode at
//! the same rate whatever the mesh resolution.

use crate::error::SimError;
use crate::integrate::ParticleSystem;
use crate::integrate::split_damping::SplitDamping;
use crate::math::{Real, Vec3};

use super::pressure::Pressure;
use super::springs::SpringNetwork;

#[derive(Debug)]
pub struct SpringBody {
    pub network: SpringNetwork,
    pub masses: Vec<Real>,
    /// α of the viscous friction −α m v, in 1/s.
    pub friction: Real,
    pub pressure: Option<Pressure>,
    /// Constant external force per particle (gravity share and point loads), in N.
    pub external: Vec<Vec3>,
    /// Positions of the last `forces` call and the elastic energy there: the integrators ask
    /// for the energy where they just evaluated forces, which saves a pass over the springs.
    energy_at: Vec<Vec3>,
    energy: Option<Real>,
    /// Explicit schemes: the spring damping taken out of `forces` and applied once per step
    /// implicitly (`integrate::split_damping`), with the springs' rest directions; `None`
    /// when off or when no spring is damped. Rebuilt after a change of springs.
    split: Option<Box<SplitDamping>>,
    /// Rest positions the split's directions come from (empty: split off).
    split_rest: Vec<Vec3>,
    split_dirty: bool,
}

impl Clone for SpringBody {
    fn clone(&self) -> Self {
        Self {
            network: self.network.clone(),
            masses: self.masses.clone(),
            friction: self.friction,
            pressure: self.pressure.clone(),
            external: self.external.clone(),
            energy_at: self.energy_at.clone(),
            energy: self.energy,
            split: None,
            split_rest: self.split_rest.clone(),
            split_dirty: true,
        }
    }
}

impl SpringBody {
    pub fn new(network: SpringNetwork, masses: Vec<Real>, friction: Real) -> Self {
        let n = masses.len();
        Self {
            network,
            masses,
            friction,
            pressure: None,
            external: vec![Vec3::ZERO; n],
            energy_at: Vec::new(),
            energy: None,
            split: None,
            split_rest: Vec::new(),
            split_dirty: false,
        }
    }

    /// Forgets the energy kept from the last force evaluation: call after changing springs,
    /// pressure or masses.
    pub fn changed(&mut self) {
        self.energy = None;
        self.split_dirty = true;
    }

    /// Takes the spring damping out of the forces and applies it once per step implicitly
    /// (`on`: what explicit schemes need, see `integrate::split_damping`; its directions are
    /// the springs' at `rest`), or puts it back (implicit Euler, which integrates it in its
    /// own solve). Call again with the new rest positions after a cut.
    pub fn set_split_damping(&mut self, on: bool, rest: &[Vec3]) {
        self.split_rest.clear();
        if on && rest.len() == self.masses.len() {
            self.split_rest.extend_from_slice(rest);
        }
        self.split = None;
        self.split_dirty = true;
        self.energy = None;
    }

    /// Whether the spring damping is split off (see `set_split_damping`).
    pub fn split_damping(&self) -> bool {
        !self.split_rest.is_empty() && self.network.springs.iter().any(|s| s.damping > 0.0)
    }

    /// The damping matrix of the springs at their rest directions, factorisable.
    fn build_split(&self) -> Option<Box<SplitDamping>> {
        let rest = &self.split_rest;
        let damped = |s: &&super::springs::Spring| {
            s.damping > 0.0 && (s.a as usize) < rest.len() && (s.b as usize) < rest.len()
        };
        let edges: Vec<[u32; 2]> = self
            .network
            .springs
            .iter()
            .filter(damped)
            .map(|s| [s.a, s.b])
            .collect();
        if edges.is_empty() {
            return None;
        }
        let mut split = SplitDamping::for_edges(rest.len(), &edges).with_positions(rest);
        split.assemble_edges(self.network.springs.iter().filter(damped).map(|s| {
            let d = rest[s.b as usize] - rest[s.a as usize];
            let l = d.length();
            let c = if l > 0.0 {
                let u = d / l;
                super::springs::outer(u, u) * s.damping
            } else {
                crate::math::Mat3::ZERO
            };
            ([s.a, s.b], c)
        }));
        Some(Box::new(split))
    }

    /// Internal (elastic + pressure) forces only, without damping or loads.
    pub fn elastic_forces(&self, x: &[Vec3], f: &mut [Vec3]) {
        f.fill(Vec3::ZERO);
        self.network.add_elastic_forces(x, f);
        if let Some(p) = &self.pressure {
            let _ = p.add_forces(x, f);
        }
    }

    /// Elastic energy of springs and pressure, in J.
    pub fn elastic_energy(&self, x: &[Vec3]) -> Real {
        self.network.energy(x) + self.pressure.as_ref().map_or(0.0, |p| p.energy(x))
    }
}

impl ParticleSystem for SpringBody {
    fn masses(&self) -> &[Real] {
        &self.masses
    }

    fn forces(&mut self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        let damped = !self.split_damping();
        let mut energy = self.network.add_forces_with(x, v, f, damped);
        if let Some(p) = &self.pressure {
            energy += p.add_forces(x, f);
        }
        self.energy_at.clear();
        self.energy_at.extend_from_slice(x);
        self.energy = Some(energy);
        let alpha = self.friction;
        for (((fi, vi), m), e) in f.iter_mut().zip(v).zip(&self.masses).zip(&self.external) {
            *fi += *e - alpha * *m * *vi;
        }
    }

    fn potential_energy(&self, x: &[Vec3]) -> Option<Real> {
        let load: Real = self.external.iter().zip(x).map(|(e, p)| e.dot(*p)).sum();
        let elastic = match self.energy {
            Some(e) if self.energy_at.as_slice() == x => e,
            _ => self.elastic_energy(x),
        };
        Some(elastic - load)
    }

    fn prepare_jacobians(&mut self, x: &[Vec3], _v: &[Vec3]) -> Result<(), SimError> {
        self.network.prepare(x);
        if let Some(p) = &mut self.pressure {
            p.prepare(x);
        }
        Ok(())
    }

    fn stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        out.fill(Vec3::ZERO);
        self.network.add_stiffness_product(dx, out);
        if let Some(p) = &self.pressure {
            p.add_stiffness_product(dx, out);
        }
    }

    fn damping_product(&self, dv: &[Vec3], out: &mut [Vec3]) {
        for ((o, d), m) in out.iter_mut().zip(dv).zip(&self.masses) {
            *o = self.friction * *m * *d;
        }
        self.network.add_damping_product(dv, out);
    }

    fn system_product(
        &self,
        a_c: Real,
        a_k: Real,
        x: &[Vec3],
        out: &mut [Vec3],
        _scratch: &mut [Vec3],
    ) {
        for ((o, d), m) in out.iter_mut().zip(x).zip(&self.masses) {
            *o = (a_c * self.friction * *m) * *d;
        }
        self.network.add_system_product(a_c, a_k, x, out);
        if let Some(p) = &self.pressure {
            p.add_scaled_stiffness_product(a_k, x, out);
        }
    }

    fn prepare_velocity_split(&mut self, dt: Real, held: &[bool]) -> Result<bool, SimError> {
        if !self.split_damping() {
            return Ok(false);
        }
        if self.split_dirty || self.split.is_none() {
            self.split = self.build_split();
            self.split_dirty = false;
        }
        match self.split.as_mut() {
            Some(split) => {
                split.prepare(dt, &self.masses, held)?;
                Ok(true)
            }
            None => Ok(false),
        }
    }

    /// The damping is that of the springs' current directions (as in the force it replaces,
    /// so a rotating body is not damped), solved with the rest matrix's factor as the
    /// preconditioner; the positions are those of the last force evaluation, the step's end
    /// (the integrators evaluate the forces there last).
    fn apply_velocity_split(&mut self, v: &mut [Vec3], force: &mut [Vec3]) -> bool {
        let Some(split) = self.split.as_mut() else {
            return false;
        };
        let x = &self.energy_at;
        if x.len() == self.masses.len() {
            split.set_current_edges(self.network.springs.iter().filter(|s| s.damping > 0.0).map(
                |s| {
                    let d = x[s.b as usize] - x[s.a as usize];
                    let l = d.length();
                    let c = if l > 0.0 && l.is_finite() {
                        let u = d / l;
                        super::springs::outer(u, u) * s.damping
                    } else {
                        crate::math::Mat3::ZERO
                    };
                    ([s.a, s.b], c)
                },
            ));
        }
        split.apply(&self.masses, v, force)
    }

    /// The damping's CG at the current directions stops at its cap on membranes under load
    /// (docs/performance.md, "Session 21"): said, not hidden.
    fn velocity_split_capped(&self) -> bool {
        self.split.as_ref().is_some_and(|s| !s.last_converged())
    }

    fn jacobian_diagonal(&self, stiffness: &mut [Vec3], damping: &mut [Vec3]) {
        stiffness.fill(Vec3::ZERO);
        for (d, m) in damping.iter_mut().zip(&self.masses) {
            *d = Vec3::splat(self.friction * *m);
        }
        self.network.add_diagonal(stiffness, damping);
        if let Some(p) = &self.pressure {
            p.add_diagonal(stiffness);
        }
    }
}
