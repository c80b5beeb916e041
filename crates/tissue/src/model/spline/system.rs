//! The control net as a particle system for the shared integrators: lumped masses
//! ρ h ∫ N_i dA₀, elastic forces from the shell energy, mass-proportional damping, constant
//! nodal loads, and penalty springs that hold surface vertices.
//!
//! Holding a surface vertex. A rendered vertex is a combination of 16 control points, so it
//! cannot be held by holding one particle. We hold it with a stiff zero-length spring from the
//! vertex to its target, acting on the control points through the tessellation's transpose:
//! energy ½ k |S_s(x) − t|², force −k w_i (S_s − t) on control point i. The reaction the
//! instrument feels is exactly the spring force k (S_s − t), so it is honest; the price is
//! that the vertex sits a distance |f|/k from its target. k defaults to 100 E h (the membrane
//! stiffness scale, N/m), which keeps that gap a small fraction of the indentation; the
//! explicit schemes need a time step a few times below the membrane limit because of it.
//!
//! A target moves over the step, in a straight line from where the step starts (`from`: the
//! spring's last target, or its vertex for a new spring) to its new place, as a held
//! particle does (`ParticleSystem::set_step_time`). Jumping at the start of every step
//! instead, the target of a pressing probe kicked its vertex by the step's whole motion:
//! the vertex then rang on its spring (ω = √(k w²/m) ≈ 4e3 rad/s on the shipped tube) and
//! explicit schemes reported the reaction at one phase of the ringing, biased by ~k·δ/2 per
//! vertex (δ the target's motion in one step) against the probe: −0.029 N, pulling the probe
//! in, where the tube pushes back with +0.003 N at 1 ms steps.
//!
//! A frictionless contact (`Spring::normal`, from `Deformable::set_constraints_along`) is the
//! same spring acting along the instrument's normal n only (free across it: it slides), and
//! only while it is engaged (`Spring::engaged`): energy ½ k (n·(S_s − t))², force
//! −k (n·(S_s − t)) n. The model settles which contacts are engaged within its step, as
//! `fem-semi-implicit` settles its active set (`SplineModel::advance`): one that pulls after
//! the solve is let go for the rest of the step, one that ends past its plane is taken, and
//! the step is solved again. A penalty force switched on and off by the state inside one
//! linearised implicit solve (k min(0, gap)) is not what the solve sees: a vertex free at
//! the step's start crossed its plane unopposed and was thrown back at the next step (the
//! sheet's energy grew tenfold in one step as the probe began to slide, and the growth
//! watch refused it). Only under implicit Euler (`SplineModel::set_constraints_along`): with
//! the explicit schemes the penalty contact bounced and the force read at a step's end was
//! mostly 0, so they keep the relaxation of full holds.
use crate::error::SimError;
use crate::integrate::ParticleSystem;
use crate::math::{Real, Vec3};

use super::energy::ShellEnergy;

/// A surface vertex held by a penalty spring.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    pub vertex: u32,
    pub nodes: [u32; 16],
    pub weights: [Real; 16],
    /// Where the spring pulls to at the end of the step.
    pub target: Vec3,
    /// Where it pulled at the start of the step.
    pub from: Vec3,
    /// A frictionless contact: the unit normal of the plane through the target it keeps the
    /// vertex out of; `None`, held in all three directions.
    pub normal: Option<Vec3>,
    /// A contact acts only while engaged (decided by the model within each step).
    pub engaged: bool,
}

impl Spring {
    /// The spring's vertex position for control positions `x`.
    pub fn position(&self, x: &[Vec3]) -> Vec3 {
        let mut s = Vec3::ZERO;
        for k in 0..16 {
            s += self.weights[k] * x[self.nodes[k] as usize];
        }
        s
    }

    /// Where the spring pulls at fraction `t` of the step.
    pub fn target_at(&self, t: Real) -> Vec3 {
        if t >= 1.0 {
            self.target
        } else {
            self.from + (self.target - self.from) * t
        }
    }

    /// The spring's pull on its vertex, k (t − S) (N per unit weight): all of it, or for a
    /// contact its part along n while engaged, else 0.
    pub fn pull(&self, stiffness: Real, position: Vec3, target: Vec3) -> Vec3 {
        let d = position - target;
        match self.normal {
            None => -stiffness * d,
            Some(n) if self.engaged => -stiffness * n.dot(d) * n,
            Some(_) => Vec3::ZERO,
        }
    }

    /// Whether the spring acts at all: a full hold always, a contact while engaged.
    pub fn acts(&self) -> bool {
        self.normal.is_none() || self.engaged
    }

    /// A contact's gap to its plane at the end of the step (negative: past it).
    pub fn gap(&self, x: &[Vec3]) -> Option<Real> {
        self.normal.map(|n| n.dot(self.position(x) - self.target))
    }
}

/// Control net mechanics (see the module doc).
#[derive(Clone, Debug)]
pub struct ControlNet {
    pub energy: ShellEnergy,
    masses: Vec<Real>,
    /// Mass-proportional damping α, 1/s.
    pub damping: Real,
    /// Constant nodal loads (gravity share, mapped point loads), N.
    pub external: Vec<Vec3>,
    pub springs: Vec<Spring>,
    /// Penalty stiffness of the springs, N/m.
    pub stiffness: Real,
    /// The fraction of the step the springs' targets are at (`ParticleSystem::set_step_time`).
    time: Real,
}

impl ControlNet {
    /// Masses from the density ρ (kg/m³) and thickness h (m) of the shell.
    pub fn new(
        energy: ShellEnergy,
        density: Real,
        thickness: Real,
        damping: Real,
        stiffness: Real,
    ) -> Result<Self, SimError> {
        if !(stiffness.is_finite() && stiffness > 0.0) {
            return Err(SimError::BadParameter {
                name: "hold_stiffness",
                value: stiffness.to_string(),
                reason: "must be a finite value > 0 N/m".into(),
            });
        }
        let masses: Vec<Real> = energy
            .node_areas()
            .iter()
            .map(|a| density * thickness * a)
            .collect();
        let n = masses.len();
        Ok(Self {
            energy,
            masses,
            damping,
            external: vec![Vec3::ZERO; n],
            springs: Vec::new(),
            stiffness,
            time: 1.0,
        })
    }

    /// Total mass, kg.
    pub fn total_mass(&self) -> Real {
        self.masses.iter().sum()
    }

    /// Force the tissue exerts on the holder of spring `s` at positions `x`: k (S_s − t).
    /// For a contact, its component along n while the vertex is past the plane, else 0.
    pub fn spring_reaction(&self, s: &Spring, x: &[Vec3]) -> Vec3 {
        -s.pull(self.stiffness, s.position(x), s.target)
    }
}

impl ParticleSystem for ControlNet {
    fn masses(&self) -> &[Real] {
        &self.masses
    }

    fn forces(&mut self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        self.energy.add_forces(x, f);
        for (i, fi) in f.iter_mut().enumerate() {
            *fi += self.external[i] - self.damping * self.masses[i] * v[i];
        }
        for s in &self.springs {
            let pull = s.pull(self.stiffness, s.position(x), s.target_at(self.time));
            for k in 0..16 {
                f[s.nodes[k] as usize] += s.weights[k] * pull;
            }
        }
    }

    fn potential_energy(&self, x: &[Vec3]) -> Option<Real> {
        let springs: Real = self
            .springs
            .iter()
            .map(|s| {
                let pull = s.pull(self.stiffness, s.position(x), s.target_at(self.time));
                0.5 * pull.length_squared() / self.stiffness
            })
            .sum();
        let loads: Real = self.external.iter().zip(x).map(|(f, p)| f.dot(*p)).sum();
        Some(self.energy.energy(x) + springs - loads)
    }

    fn prepare_jacobians(&mut self, x: &[Vec3], _v: &[Vec3]) -> Result<(), SimError> {
        self.energy.prepare(x);
        Ok(())
    }

    fn stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        out.fill(Vec3::ZERO);
        self.energy.product(dx, out);
        for s in self.springs.iter().filter(|s| s.acts()) {
            let d = s.position(dx);
            let d = self.stiffness
                * match s.normal {
                    None => d,
                    Some(n) => n * n.dot(d),
                };
            for k in 0..16 {
                out[s.nodes[k] as usize] += s.weights[k] * d;
            }
        }
    }

    fn set_step_time(&mut self, s: Real) {
        self.time = s;
    }

    fn damping_product(&self, dv: &[Vec3], out: &mut [Vec3]) {
        for ((o, d), m) in out.iter_mut().zip(dv).zip(&self.masses) {
            *o = self.damping * m * *d;
        }
    }

    fn jacobian_diagonal(&self, stiffness: &mut [Vec3], damping: &mut [Vec3]) {
        stiffness.fill(Vec3::ZERO);
        self.energy.diagonal(stiffness);
        for s in self.springs.iter().filter(|s| s.acts()) {
            let axes = s.normal.map_or(Vec3::ONE, |n| n * n);
            for k in 0..16 {
                stiffness[s.nodes[k] as usize] +=
                    axes * (self.stiffness * s.weights[k] * s.weights[k]);
            }
        }
        for (d, m) in damping.iter_mut().zip(&self.masses) {
            *d = Vec3::splat(self.damping * m);
        }
    }
}
