//! The mechanical system every spring-mass kind shares: particles with lumped masses, a
//! spring network, viscous friction, an optional pressure and the external loads. It is what
//! the shared integrators (`crate::integrate`) step.
//!
//! Eq. 1 of the survey: m ẍ + γ ẋ + f_int = f_ext, with the friction γ_i = α m_i taken
//! proportional to the mass (α = `material.damping`, in 1/s) so that it damps every mode at
//! the same rate whatever the mesh resolution.

use crate::error::SimError;
use crate::integrate::ParticleSystem;
use crate::math::{Real, Vec3};

use super::pressure::Pressure;
use super::springs::SpringNetwork;

#[derive(Clone, Debug)]
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
        }
    }

    /// Forgets the energy kept from the last force evaluation: call after changing springs,
    /// pressure or masses.
    pub fn changed(&mut self) {
        self.energy = None;
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
        let mut energy = self.network.add_forces(x, v, f);
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
