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
//! Points sharing particles are settled together (positions, then velocities), each point's
//! total push kept ≥ 0: the push over the step (its momentum / dt) is never negative. Each
//! stage is solved exactly, as a complementarity problem on the points' response to each
//! other (`solve::lcp`, which takes the many dependent rows of a fine surface); projected
//! Gauss-Seidel sweeps are the fallback where it refuses. The sweeps alone stopped at their
//! cap on the liver's k = 3 fine surface with up to 1e-7 m left past the planes every
//! substep, a chatter that kept `fem-explicit`'s deep press from settling.
//!
//! The energy ledger (`held_work`) counts what the projection itself did to the energy as
//! the contact's work, over the points' particles (each once): the change of their kinetic
//! energy Σ ½ mᵢ(|vᵢ|² − |vᵢ*|²) from before the projection (v*) to after it, and the work
//! −Σ fᵢ·(xᵢ − xᵢ*) of its move of the positions against the forces at the projected end
//! (the trapezoid's other end is not evaluated: second order in the move, which is that of
//! one (sub)step). Counted per point instead, as `place_holds` counts a contact particle's
//! normal coordinate (½ M q̇² and the work of the force along q), points sharing particles
//! each count the same motion as their own: on a fine surface's dependent points the sum is
//! the energy of nothing, and the growth watch refused `tests/dynamic_points`' block press
//! under the exact projection (1e-8 J a step counted taken while the energy fell 1e-10 J).

use crate::error::SimError;
use crate::interact::PointContact;
use crate::math::{Real, Vec3, is_finite_vec};

use super::Workspace;

/// The largest particle move of `PointProjection::exact`, in units of the deepest
/// shortfall it corrects: tilting a face so that points an eighth of it apart both reach
/// their planes moves its corners about 10 times their shortfall; a solution past this
/// is an ill-conditioned set of nearly dependent rows, not a geometry.
const SANE_MOVE: Real = 1e3;

/// Rounds of `PointProjection::exact` (rows added that the last solution left short) at
/// most per stage before the sweeps take over.
const ROUNDS: usize = 20;

/// Projected Gauss-Seidel sweeps over the points at most per (sub)step, for the positions
/// and again for the velocities, where the exact solve refuses (`PointProjection::exact`).
/// Points on one coarse face share all three particles; a sweep that moves nothing (to
/// round-off) ends it.
const SWEEPS: usize = 50;

/// A point left further than this past its plane when the position stage ends makes the run
/// capped (`PointProjection::take_capped`): a nanometre, far below what any tissue scale
/// resolves, so that a cap reached only by round-off is not reported.
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
    pub(super) fn gap(&self, x: &[Vec3]) -> Real {
        self.coordinate(x) - self.level
    }

    /// Σ wᵢ n·yᵢ: the point's normal coordinate (positions) or velocity (velocities).
    pub(super) fn coordinate(&self, y: &[Vec3]) -> Real {
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
    /// Whether a run since the last `take_capped` ended its position stage with a point
    /// more than `CAPPED_DEPTH` past its plane.
    capped: bool,
    /// The points' particles (each once) with their positions and velocities before the
    /// last projection of the shared integrator (`project`), for its energy ledger.
    before: Vec<(usize, Vec3, Vec3)>,
}

impl PointProjection {
    /// Whether a run since the last call ended with a point left past its plane (by more
    /// than `CAPPED_DEPTH`), and forgets it.
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
        for stage in [1, 2] {
            let y: &mut [Vec3] = if stage == 1 { &mut *x } else { &mut *v };
            if !self.exact(points, y, inv_mass, stage) {
                self.sweeps(points, y, inv_mass, h, stage);
            }
            // Either way, a point left past its plane beyond a nanometre is said.
            if stage == 1 {
                let deepest = points
                    .iter()
                    .filter(|pt| pt.inverse_mass(inv_mass) > 0.0)
                    .fold(0.0, |d: Real, pt| d.max(-pt.gap(y)));
                self.capped |= deepest > CAPPED_DEPTH;
            }
        }
    }

    /// What point `k` still lacks at stage 1 (its gap below zero, positions `y`) or stage 2
    /// (its normal velocity below the least it may keep, velocities `y`): negative when
    /// short.
    fn excess(&self, pt: &PointHold, k: usize, y: &[Vec3], stage: usize) -> Real {
        if stage == 1 {
            pt.gap(y)
        } else {
            pt.coordinate(y) - self.lambda[k][0]
        }
    }

    /// One stage solved exactly: the least mass-weighted change of `y` (positions at stage
    /// 1, velocities at stage 2) that leaves no point short, each point's total push ≥ 0
    /// and zero where it ends beyond what it needs. Its optimality conditions are a linear
    /// complementarity problem on the points' response to each other's pushes,
    /// M_ab = Σ over shared particles p of w_a w_b (n_a·n_b) / m_p, singular when many
    /// points ride on one coarse face (a fine surface's), which `solve::lcp::solve_mixed`
    /// takes by construction. False (nothing changed) when the solver refuses it.
    fn exact(
        &mut self,
        points: &[PointHold],
        y: &mut [Vec3],
        inv_mass: &[Real],
        stage: usize,
    ) -> bool {
        use std::collections::BTreeMap;
        // Most (sub)steps leave no point short: nothing to build then.
        let short_now = |(k, pt): (usize, &PointHold)| {
            pt.inverse_mass(inv_mass) > 0.0 && self.excess(pt, k, y, stage) < 0.0
        };
        if !points.iter().enumerate().any(short_now) {
            return true;
        }
        let b_all: Vec<Real> = points
            .iter()
            .enumerate()
            .map(|(k, pt)| {
                if pt.inverse_mass(inv_mass) > 0.0 {
                    self.excess(pt, k, y, stage)
                } else {
                    Real::INFINITY
                }
            })
            .collect();
        let largest = b_all
            .iter()
            .filter(|g| g.is_finite())
            .fold(0.0, |m: Real, g| m.max(g.abs()));
        let tolerance = crate::solve::lcp::GAP_TOLERANCE * largest;
        // The rows solved: the points short now, then those the solution leaves short (a
        // few rounds; a fine surface gives a hundred points near an instrument, of which a
        // handful push: solving them all, densely, cost 20 times the step of `spring-mass`).
        let mut rows: Vec<usize> = (0..points.len()).filter(|&k| b_all[k] < 0.0).collect();
        let mut pushing: Vec<bool> = Vec::new();
        for _ in 0..ROUNDS {
            // The rows on each particle, with their weights there.
            let mut on: BTreeMap<usize, Vec<(usize, Real)>> = BTreeMap::new();
            for (a, &k) in rows.iter().enumerate() {
                let pt = &points[k];
                for i in 0..3 {
                    if pt.weights[i] != 0.0 && inv_mass[pt.particles[i]] > 0.0 {
                        on.entry(pt.particles[i])
                            .or_default()
                            .push((a, pt.weights[i]));
                    }
                }
            }
            let n = rows.len();
            let mut m = faer::Mat::<Real>::zeros(n, n);
            for (&p, list) in &on {
                for &(a, wa) in list {
                    for &(c, wc) in list {
                        if c < a {
                            continue;
                        }
                        let na = points[rows[a]].normal;
                        let nc = points[rows[c]].normal;
                        let add = wa * wc * inv_mass[p] * na.dot(nc);
                        m[(a, c)] += add;
                        if c != a {
                            m[(c, a)] += add;
                        }
                    }
                }
            }
            let b: Vec<Real> = rows.iter().map(|&k| b_all[k]).collect();
            let Ok(solved) = crate::solve::lcp::solve_mixed(m.as_ref(), &b, 0, &pushing) else {
                return false;
            };
            // The particles' moves, and the rows left out that they leave short.
            let mut moved: BTreeMap<usize, Vec3> = BTreeMap::new();
            for (a, &k) in rows.iter().enumerate() {
                let mu = solved.lambda[a];
                if mu != 0.0 {
                    let pt = &points[k];
                    for i in 0..3 {
                        let p = pt.particles[i];
                        *moved.entry(p).or_insert(Vec3::ZERO) +=
                            pt.normal * (pt.weights[i] * inv_mass[p] * mu);
                    }
                }
            }
            let mut solved_row = vec![false; points.len()];
            rows.iter().for_each(|&k| solved_row[k] = true);
            let short: Vec<usize> = (0..points.len())
                .filter(|&k| !solved_row[k] && b_all[k].is_finite())
                .filter(|&k| {
                    let pt = &points[k];
                    let shift: Real = (0..3)
                        .map(|i| {
                            moved
                                .get(&pt.particles[i])
                                .map_or(0.0, |d| pt.weights[i] * pt.normal.dot(*d))
                        })
                        .sum();
                    b_all[k] + shift < -tolerance
                })
                .collect();
            // A near-dependent set of rows (within `lcp::DEPENDENT` of its span) may be
            // solved with pushes far larger than the shortfall needs: a move beyond
            // `SANE_MOVE` times the deepest shortfall is refused, and the sweeps take the
            // stage.
            let reach = moved.values().fold(0.0, |m: Real, d| m.max(d.length()));
            let deepest = b.iter().fold(0.0, |m: Real, g| m.max(-g));
            if reach.is_nan() || reach > SANE_MOVE * deepest {
                return false;
            }
            if short.is_empty() {
                for (a, &k) in rows.iter().enumerate() {
                    self.lambda[k][stage] = solved.lambda[a];
                }
                for (p, d) in moved {
                    y[p] += d;
                }
                return true;
            }
            pushing = solved.lambda.iter().map(|mu| *mu > 0.0).collect();
            rows.extend(short);
        }
        false
    }

    /// One stage by projected Gauss-Seidel sweeps (`exact`'s fallback): a point's total
    /// push may shrink again (never below zero) when its neighbours' pushes did its work,
    /// so that points sharing particles end on their planes without over-correcting them;
    /// accumulated pushes only, a sweep that moved a point's particles the wrong way left
    /// them moving into the tissue, and the mass damping of that motion read as 3 % less
    /// push on a block under a flat plane.
    fn sweeps(
        &mut self,
        points: &[PointHold],
        y: &mut [Vec3],
        inv_mass: &[Real],
        h: Real,
        stage: usize,
    ) {
        for k in 0..points.len() {
            self.lambda[k][stage] = 0.0;
        }
        for _ in 0..SWEEPS {
            let mut largest: Real = 0.0;
            for (k, pt) in points.iter().enumerate() {
                let inverse = pt.inverse_mass(inv_mass);
                if inverse <= 0.0 {
                    continue;
                }
                let short = -self.excess(pt, k, y, stage);
                let lambda = &mut self.lambda[k];
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
                break;
            }
        }
    }

    /// Keeps the positions and velocities of the points' particles (each once) before a
    /// projection, for `project`'s ledger.
    fn keep_before(&mut self, points: &[PointHold], x: &[Vec3], v: &[Vec3]) {
        self.before.clear();
        self.before.extend(
            points
                .iter()
                .flat_map(|pt| pt.particles)
                .map(|p| (p, Vec3::ZERO, Vec3::ZERO)),
        );
        self.before.sort_unstable_by_key(|b| b.0);
        self.before.dedup_by_key(|b| b.0);
        for b in &mut self.before {
            (b.1, b.2) = (x[b.0], v[b.0]);
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
/// `w.point_impulse`, and the change of the particles' kinetic energy in `w.along_work`
/// (which `place_holds` has just reset).
pub(super) fn project(w: &mut Workspace, points: &[PointHold], h: Real) {
    w.point_impulse.resize(points.len(), 0.0);
    if points.is_empty() {
        w.points.before.clear();
        return;
    }
    w.points.keep_before(points, &w.x1, &w.v1);
    w.points.run(points, &mut w.x1, &mut w.v1, &w.inv_mass, h);
    for (k, impulse) in w.point_impulse.iter_mut().enumerate() {
        *impulse += w.points.momentum(k);
    }
    w.along_work += w
        .points
        .before
        .iter()
        .filter(|b| w.inv_mass[b.0] > 0.0)
        .map(|&(p, _, v)| 0.5 * (w.v1[p].length_squared() - v.length_squared()) / w.inv_mass[p])
        .sum::<Real>();
}

/// (signed, absolute) work of the last projection's move of the positions (`project`)
/// against the forces `w.f1` at its end: −Σ fᵢ·(xᵢ − xᵢ*) over the points' particles.
pub(super) fn work(w: &Workspace) -> (Real, Real) {
    let s: Real = w
        .points
        .before
        .iter()
        .filter(|b| w.inv_mass[b.0] > 0.0)
        .map(|&(p, x, _)| -w.f1[p].dot(w.x1[p] - x))
        .sum();
    (s, s.abs())
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
