//! Push-only contacts on points tied to several particles (a fine contact surface's points,
//! `interact::PointContact`): the mechanics of `Hold::contact` (`contact::push_only`) over
//! the particles a point follows, decided at the end of every (sub)step.
//!
//! A point p = c + Σ wᵢ xᵢ whose normal coordinate q = Σ wᵢ n·xᵢ went below its plane's
//! level is put back on the plane by the least mass-weighted move of its particles
//! (Δxᵢ ∝ wᵢ/mᵢ n, the standard constraint projection), and its inward velocity along n is
//! removed the same way; a point short of its plane keeps at most the inward velocity that
//! reaches it in one more (sub)step; one that stays out is left free. Along its normal the
//! point moves as a particle of mass M = 1 / Σ wᵢ²/mᵢ (the inverse of its response), so a
//! point on one particle (weights 1, 0, 0) is exactly `Hold::contact` on that particle.
//! Points sharing particles are settled by projected Gauss-Seidel sweeps (positions, then
//! velocities), each point's total push kept ≥ 0: the push over the step (its momentum /
//! dt) is never negative.
//!
//! The energy ledger counts a point's normal coordinate as `place_holds` counts a contact
//! particle's: the change of ½ M q̇² over the (sub)step and the work of the generalized force
//! F_q = Σ wᵢ n·fᵢ/mᵢ / Σ wᵢ²/mᵢ along q are the contact's work (`held_work`), or the growth
//! watch would read the undone kicks along n as growth.

use crate::error::SimError;
use crate::interact::PointContact;
use crate::math::{Real, Vec3, is_finite_vec};

use super::Workspace;

/// Projected Gauss-Seidel sweeps over the points at most per (sub)step, for the positions
/// and again for the velocities. Points on one coarse face share all three particles; a
/// sweep that moves nothing (to round-off) ends it.
const SWEEPS: usize = 50;

/// A point left further than this past its plane when the position sweeps reach `SWEEPS`
/// makes the run capped (`PointProjection::take_capped`): a nanometre, far below what any
/// tissue scale resolves, so that a cap reached only by round-off is not reported.
pub const CAPPED_DEPTH: Real = 1e-9;

/// A point tied to three particles that a plane may push but not pull, frictionless:
/// Σ wᵢ n·xᵢ ≥ `level`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointHold {
    pub particles: [usize; 3],
    pub weights: [Real; 3],
    /// The plane's outward unit normal (toward the point's side).
    pub normal: Vec3,
    /// The least value of the point's normal coordinate Σ wᵢ n·xᵢ, m.
    pub level: Real,
}

impl PointHold {
    /// The point rest + Σ wᵢ (xᵢ − Xᵢ) (`interact::PointContact`) on `particles`, whose rest
    /// positions are `rest`, that must move by `reach` along n from its rest:
    /// Σ wᵢ n·xᵢ ≥ reach + Σ wᵢ n·Xᵢ.
    pub fn tied(
        particles: [usize; 3],
        weights: [Real; 3],
        normal: Vec3,
        reach: Real,
        rest: [Vec3; 3],
    ) -> Self {
        let level = reach
            + (0..3)
                .map(|k| weights[k] * normal.dot(rest[k]))
                .sum::<Real>();
        Self {
            particles,
            weights,
            normal,
            level,
        }
    }

    /// A scene's point contacts (`interact::PointContact`, on surface vertices) as holds on
    /// the particles `nodes[v]` of their vertices, whose rest positions are `rest[v]`: what
    /// every kind on this integrator does in `Deformable::set_point_contacts`.
    pub fn from_contacts(
        points: &[PointContact],
        nodes: &[u32],
        rest: &[Vec3],
    ) -> Result<Vec<Self>, SimError> {
        let count = nodes.len().min(rest.len());
        points
            .iter()
            .map(|pt| {
                pt.check(count)?;
                Ok(Self::tied(
                    pt.vertices.map(|v| nodes[v as usize] as usize),
                    pt.weights,
                    pt.normal,
                    pt.reach(),
                    pt.vertices.map(|v| rest[v as usize]),
                ))
            })
            .collect()
    }

    /// The point's normal coordinate at `x`, less its level (negative: past the plane).
    fn gap(&self, x: &[Vec3]) -> Real {
        self.coordinate(x) - self.level
    }

    /// Σ wᵢ n·yᵢ: the point's normal coordinate (positions) or velocity (velocities).
    fn coordinate(&self, y: &[Vec3]) -> Real {
        (0..3)
            .map(|k| self.weights[k] * self.normal.dot(y[self.particles[k]]))
            .sum()
    }

    /// Σ wᵢ²/mᵢ: the point's inverse mass along n (0 when every particle is held).
    fn inverse_mass(&self, inv_mass: &[Real]) -> Real {
        (0..3)
            .map(|k| self.weights[k] * self.weights[k] * inv_mass[self.particles[k]])
            .sum()
    }

    /// The generalized force along the point's normal coordinate: Σ wᵢ n·fᵢ/mᵢ / Σ wᵢ²/mᵢ.
    fn force(&self, f: &[Vec3], inv_mass: &[Real], inverse: Real) -> Real {
        let s: Real = (0..3)
            .map(|k| {
                let p = self.particles[k];
                self.weights[k] * inv_mass[p] * self.normal.dot(f[p])
            })
            .sum();
        s / inverse
    }

    /// Moves the point's particles so that its normal coordinate changes by `dq` (positions)
    /// or its normal velocity by `dq` (velocities), in the least mass-weighted way.
    fn shift(&self, y: &mut [Vec3], inv_mass: &[Real], inverse: Real, dq: Real) {
        for k in 0..3 {
            let p = self.particles[k];
            y[p] += self.normal * (self.weights[k] * inv_mass[p] * (dq / inverse));
        }
    }

    /// Checks the particles exist among `count` and every number is finite.
    pub(super) fn check(&self, count: usize) -> Result<(), SimError> {
        if let Some(&p) = self.particles.iter().find(|&&p| p >= count) {
            return Err(SimError::BadConstraint { vertex: p, count });
        }
        if !(self.weights.iter().all(|w| w.is_finite())
            && self.level.is_finite()
            && is_finite_vec(self.normal)
            && (self.normal.length() - 1.0).abs() < 1e-6)
        {
            return Err(SimError::BadParameter {
                name: "point contact",
                value: format!("on particles {:?}", self.particles),
                reason: "its weights and level must be finite and its normal a unit vector".into(),
            });
        }
        Ok(())
    }
}

/// The projection of `project` over plain slices, for every scheme that keeps positions and
/// velocities per particle (the integrator's state, `fem-explicit`'s central difference,
/// `fem-corotational`'s implicit step): written once, called by each.
///
/// After `run`, each point's pushes over the (sub)step are kept (`acted`, `momentum`) until
/// the next `run`.
#[derive(Clone, Debug, Default)]
pub struct PointProjection {
    /// Per point: the least normal velocity it may keep (0 past its plane, else the inward
    /// speed that reaches the plane in one more (sub)step), and what its position and
    /// velocity projections have given so far (≥ 0), in the point's mass units.
    lambda: Vec<[Real; 3]>,
    /// Whether a run since the last `take_capped` stopped its position sweeps at `SWEEPS`
    /// with a point more than `CAPPED_DEPTH` past its plane.
    capped: bool,
}

impl PointProjection {
    /// Whether a run since the last call stopped at its sweep cap with a point left past
    /// its plane (by more than `CAPPED_DEPTH`), and forgets it: the step that ran them says
    /// so in `StepInfo::capped` rather than passing the points off as held.
    pub fn take_capped(&mut self) -> bool {
        std::mem::take(&mut self.capped)
    }

    /// Projects `points` after a (sub)step of length `h` on the positions `x` and velocities
    /// `v` of their particles, whose inverse masses are `inv_mass` (0 for a held particle,
    /// which takes none of a point's move): see the module documentation. Only the points'
    /// particles are read and written. `x` may be displacements if the points' levels are
    /// (`PointHold::tied` with zero rest positions).
    pub fn run(
        &mut self,
        points: &[PointHold],
        x: &mut [Vec3],
        v: &mut [Vec3],
        inv_mass: &[Real],
        h: Real,
    ) {
        self.lambda.clear();
        self.lambda.extend(points.iter().map(|pt| {
            let gap = pt.gap(x);
            [if gap < 0.0 { 0.0 } else { -gap / h }, 0.0, 0.0]
        }));
        // Projected Gauss-Seidel: a point's total push may shrink again (never below zero)
        // when its neighbours' pushes did its work, so that points sharing particles end on
        // their planes without over-correcting them; accumulated pushes only, a sweep that
        // moved a point's particles the wrong way left them moving into the tissue, and the
        // mass damping of that motion read as 3 % less push on a block under a flat plane.
        for stage in [1, 2] {
            let mut converged = false;
            for _ in 0..SWEEPS {
                let mut largest: Real = 0.0;
                for (k, pt) in points.iter().enumerate() {
                    let inverse = pt.inverse_mass(inv_mass);
                    if inverse <= 0.0 {
                        continue;
                    }
                    let lambda = &mut self.lambda[k];
                    let (y, short) = if stage == 1 {
                        let short = -pt.gap(x);
                        (&mut *x, short)
                    } else {
                        let short = lambda[0] - pt.coordinate(v);
                        (&mut *v, short)
                    };
                    let total = (lambda[stage] + short / inverse).max(0.0);
                    let delta = total - lambda[stage];
                    if delta != 0.0 {
                        lambda[stage] = total;
                        pt.shift(y, inv_mass, inverse, delta * inverse);
                        largest = largest.max((delta * inverse).abs());
                    }
                }
                // Round-off, in m (positions) or m per (sub)step (velocities).
                let tolerance = if stage == 1 { 1e-15 } else { 1e-15 / h };
                if largest <= tolerance {
                    converged = true;
                    break;
                }
            }
            if stage == 1 && !converged {
                let deepest = points.iter().fold(0.0, |d: Real, pt| d.max(-pt.gap(x)));
                self.capped |= deepest > CAPPED_DEPTH;
            }
        }
    }

    /// Whether point `k` was moved (back onto its plane, or slowed) by the last `run`.
    pub fn acted(&self, k: usize) -> bool {
        self.lambda.get(k).is_some_and(|l| l[1] > 0.0 || l[2] > 0.0)
    }

    /// The momentum the last `run` gave point `k` along its normal (≥ 0; N·s when the
    /// inverse masses are in 1/kg): its velocity projection's, as `Hold::contact` counts a
    /// particle's (the position projection changes no velocity).
    pub fn momentum(&self, k: usize) -> Real {
        self.lambda.get(k).map_or(0.0, |l| l[2])
    }
}

/// Projects the points after a (sub)step of length `h` (see the module documentation):
/// positions and velocities in `w.x1`, `w.v1`, each point's momentum added to
/// `w.point_impulse`, whether it acted in `w.point_active`, and its ledger term in
/// `w.along_work` (which `place_holds` has just reset).
pub(super) fn project(w: &mut Workspace, points: &[PointHold], h: Real) {
    w.point_active.clear();
    w.point_active.resize(points.len(), false);
    w.point_impulse.resize(points.len(), 0.0);
    if points.is_empty() {
        return;
    }
    w.points.run(points, &mut w.x1, &mut w.v1, &w.inv_mass, h);
    for (k, pt) in points.iter().enumerate() {
        if !w.points.acted(k) {
            continue;
        }
        w.point_active[k] = true;
        w.point_impulse[k] += w.points.momentum(k);
        let inverse = pt.inverse_mass(&w.inv_mass);
        let (kept, v0n) = (pt.coordinate(&w.v1), pt.coordinate(&w.v0));
        w.along_work += 0.5 * (kept * kept - v0n * v0n) / inverse;
    }
}

/// (signed, absolute) work of the active points' generalized forces over the (sub)step,
/// −½ (F_q0 + F_q1)(q1 − q0), as `held_work` counts a contact particle's along n.
pub(super) fn work(w: &Workspace, points: &[PointHold]) -> (Real, Real) {
    let (mut s, mut a) = (0.0, 0.0);
    for (k, pt) in points.iter().enumerate() {
        if !w.point_active.get(k).copied().unwrap_or(false) {
            continue;
        }
        let inverse = pt.inverse_mass(&w.inv_mass);
        if inverse <= 0.0 {
            continue;
        }
        let f = pt.force(&w.f0, &w.inv_mass, inverse) + pt.force(&w.f1, &w.inv_mass, inverse);
        let dw = -0.5 * f * (pt.coordinate(&w.x1) - pt.coordinate(&w.x0));
        s += dw;
        a += dw.abs();
    }
    (s, a)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One point on one particle, past its plane: projected onto it in one sweep, not
    /// capped. Two points on the same particle with opposite planes 1 mm apart (no position
    /// satisfies both): the sweeps reach their cap with a point still 1 mm past its plane,
    /// and the run says so (once: `take_capped` forgets it).
    #[test]
    fn a_projection_that_stops_at_its_sweep_cap_says_so() {
        let on = |normal: Vec3, level: Real| PointHold {
            particles: [0, 0, 0],
            weights: [1.0, 0.0, 0.0],
            normal,
            level,
        };
        let mut p = PointProjection::default();
        let (mut x, mut v) = (vec![Vec3::ZERO], vec![Vec3::ZERO]);
        p.run(&[on(Vec3::Z, 1e-3)], &mut x, &mut v, &[1.0], 1e-3);
        assert!((x[0].z - 1e-3).abs() < 1e-15, "{}", x[0]);
        assert!(!p.take_capped());
        let (mut x, mut v) = (vec![Vec3::ZERO], vec![Vec3::ZERO]);
        let clash = [on(Vec3::Z, 1e-3), on(-Vec3::Z, 0.0)];
        p.run(&clash, &mut x, &mut v, &[1.0], 1e-3);
        assert!(p.take_capped());
        assert!(!p.take_capped());
    }
}
