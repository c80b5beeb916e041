//! Driving a model through a scenario: ramps to a target and holds until it settles
//! (quasi-static), with the probe through `Simulation` (contact as a user gets it) or with
//! prescribed vertices directly (plate, rotation, bar).

use std::time::Instant;

use crate::error::{Error, SimError};
use crate::interact::{
    Constraints, Instrument, InstrumentKind, Keyframe, Loads, MappedSurface, Prescribed, Trajectory,
};
use crate::math::{Real, Vec3, is_finite_vec};
use crate::model::Deformable;
use crate::sim::Simulation;

use super::Settings;

/// How the comparison's probe touches the organ.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ContactLaw {
    /// A touched vertex is held at its point of the probe (`Instrument::sticking`). No
    /// scenario uses it now; kept for regression tests of the sticking probe.
    Sticking,
    /// Frictionless at the model's surface vertices (`contact = "sliding"`): a touched
    /// vertex is held along the probe's normal only, slides across it and is let go when it
    /// pulls. The reference's law (quadratic `fem-static`, every surface node touchable).
    Frictionless,
    /// Every kind's law: frictionless against a fine contact surface, the model's own rest
    /// surface subdivided flat (`fine_contact_surface`) and set with
    /// `Simulation::set_fine_surface`. A kind that solves point contacts
    /// (`Deformable::holds_point_contacts`) holds the fine points exactly; the others get
    /// the simulation's per-coarse-vertex planes built from the fine surface's face contacts.
    /// On a coarse surface a frictionless vertex can slide off a sphere and let it pass
    /// between vertices (the dynamic kinds lost the probe so); the fine surface's points
    /// cover the faces between the vertices.
    #[default]
    FineSurface,
}

/// Solves a static model's contact loop may take per step with a frictionless probe (the
/// targets or the fine points' planes slide to their equilibrium: one back-substitution
/// each).
pub const FRICTIONLESS_CONTACT_ITERATIONS: usize = 60;

impl ContactLaw {
    /// As written in the record (`contact_law`'s value).
    pub fn code(self) -> Real {
        match self {
            Self::Sticking => 0.0,
            Self::Frictionless => 1.0,
            Self::FineSurface => 2.0,
        }
    }

    /// As written in the record.
    pub fn name(self) -> &'static str {
        match self {
            Self::Sticking => "sticking (a touched vertex is held at its point of the probe)",
            Self::Frictionless => {
                "frictionless at the surface vertices (held along the probe's normal, never \
                 pulling)"
            }
            Self::FineSurface => {
                "frictionless on a fine contact surface (the rest surface subdivided flat)"
            }
        }
    }

    /// The probe instrument frictionless (every law but sticking).
    pub fn frictionless(self) -> bool {
        self != Self::Sticking
    }
}

/// The fine contact surface's subdivision for a probe of `radius` on a surface whose
/// median edge is `edge` (both m): the fewest levels k (each triangle into 4^k) that bring
/// the fine edge, edge / 2^k, to at most a sixteenth of the radius (`FINE_EDGE_PER_RADIUS`).
///
/// Why so fine: the contact answer must be the model's, not the contact surface's. On the
/// built-in liver the probe presses a cone point of the coarse polyhedron, whose patch is
/// about 3 mm across (R = 24.7 mm), and the press converges only at k = 3
/// (`reference::tests::fine_surface_refinement_study`, the linear FEM kinds, shallow:
/// k = 1 1.307 mN, k = 2 1.726, k = 3 1.640, k = 4 1.619; deep: 19.3, 15.8, 14.4, 14.6 mN);
/// k = 3's deep press is within 1 % of the full reference's 14.29 mN. A quarter of the
/// radius (k = 1, the rule until session 18) was 19 % off in the shallow press. Finer
/// surfaces give many dependent rows (a flat-subdivided face adds no direction its three
/// vertices do not have), which `solve::lcp`'s dual active set and the BEM's splitting with
/// Lemke's method take in milliseconds (docs/contact.md). At most `MAX_FINE_LEVELS`, and
/// fewer while the fine surface would have more than `MAX_FINE_TRIANGLES` (a finely meshed
/// organ needs little or no subdivision).
pub fn fine_levels(edge: Real, radius: Real, coarse_triangles: usize) -> u32 {
    let mut k = 0;
    while k < MAX_FINE_LEVELS && edge / Real::from(1u32 << k) > radius * FINE_EDGE_PER_RADIUS {
        k += 1;
    }
    while k > 0 && coarse_triangles << (2 * k) > MAX_FINE_TRIANGLES {
        k -= 1;
    }
    k
}

/// The fine contact surface's longest median edge, in probe radii (`fine_levels`).
pub const FINE_EDGE_PER_RADIUS: Real = 1.0 / 16.0;
/// The most subdivision levels of the fine contact surface.
pub const MAX_FINE_LEVELS: u32 = 4;
/// The most triangles of the fine contact surface.
pub const MAX_FINE_TRIANGLES: usize = 200_000;

/// The fine contact surface of `model` for a probe of `radius` (m): its rest surface
/// subdivided flat `fine_levels` times, each fine vertex tied to its coarse triangle. Also
/// returns the levels.
pub fn fine_contact_surface(
    model: &dyn Deformable,
    radius: Real,
) -> Result<(MappedSurface, u32), Error> {
    let rest = model.rest_surface();
    let triangles = model.surface().triangles;
    let mut edges: Vec<Real> = triangles
        .iter()
        .flat_map(|t| (0..3).map(move |i| (t[i], t[(i + 1) % 3])))
        .filter_map(|(a, b)| Some(rest.get(a as usize)?.distance(*rest.get(b as usize)?)))
        .filter(|l| *l > 0.0)
        .collect();
    edges.sort_by(Real::total_cmp);
    let edge = edges.get(edges.len() / 2).copied().unwrap_or(0.0);
    let k = fine_levels(edge, radius, triangles.len());
    let fine = MappedSurface::subdivided(rest, triangles, 1 << k).ok_or_else(|| {
        Error::from(SimError::Unsupported {
            model: model.kind(),
            operation: "a fine contact surface",
            reason: "its surface has no triangle to subdivide".into(),
        })
    })?;
    Ok((fine, k))
}

/// A simulation of `model` held at `fixed`, ready for the probe's law: with the fine
/// contact surface of a probe of `radius` set for `ContactLaw::FineSurface`.
pub fn probe_simulation(
    model: Box<dyn Deformable>,
    fixed: Vec<u32>,
    radius: Real,
    law: ContactLaw,
) -> Result<Simulation, Error> {
    let fine = match law {
        ContactLaw::FineSurface => Some(fine_contact_surface(model.as_ref(), radius)?.0),
        _ => None,
    };
    let mut sim = Simulation::new(model, fixed, Loads::default())?;
    if let Some(fine) = fine {
        sim.set_fine_surface(fine)?;
    }
    Ok(sim)
}

/// `probe_simulation` for scenario `sc`: the organ held as `sc` holds it, and its probe
/// touching the probe point, still (a path of depth 0): for callers that move the probe
/// themselves (`Simulation::set_instrument_position`), as the settling studies do.
pub fn touching_probe(
    model: Box<dyn Deformable>,
    sc: &super::setup::Scenario,
    law: ContactLaw,
) -> Result<Simulation, Error> {
    let fixed = sc.fixed(model.rest_surface());
    let mut sim = probe_simulation(model, fixed, sc.probe_radius, law)?;
    sim.add_instrument(probe_instrument(
        sc.probe(),
        sc.probe_radius,
        0.0,
        1.0,
        law,
    )?);
    Ok(sim)
}

/// How a model is stepped through a quasi-static scenario.
#[derive(Clone, Copy, Debug)]
pub struct Stepping {
    pub is_static: bool,
    /// Step of dynamic models, s.
    pub dt: Real,
    /// Ramp time of dynamic models, s (static models take `increments` solves).
    pub ramp: Real,
    /// Longest simulated time of dynamic models, s.
    pub max_time: Real,
    pub increments: usize,
    /// Computing time a dynamic run may take, s: past it the run stops with an error that
    /// says so (the cell shows it), and the comparison goes on.
    pub budget: Real,
    /// The probe's contact law.
    pub contact: ContactLaw,
    /// Dynamic models with velocities (`Deformable::kinetic_energy`): kinetic damping, every
    /// velocity zeroed at each peak of the kinetic energy (`Deformable::stop_motion`). The
    /// comparison runs them so with no mass damping (`measure::relaxing`); see `run`.
    pub kinetic_damping: bool,
    /// Settled: the watched quantity moved less than 0.5 % over this share of `max_time`,
    /// and the kinetic energy stayed below `rest_energy` times the run's largest.
    pub window: Real,
    pub rest_energy: Real,
    /// Dynamic runs follow the smoothstep ramp (`smooth_ramp`); false: the linear ramp the
    /// comparison used with mass damping before kinetic damping (the rigid rotation and the
    /// fallback runs of `measure::relaxed` keep it).
    pub smooth_ramp: bool,
}

/// Computing time of one quasi-static run of a dynamic model, s (`--quick`, full run). A
/// model that needs more (a tiny stable step on the refined organ) gets a cell saying so.
pub const BUDGET_SECONDS: [Real; 2] = [60.0, 240.0];

impl Stepping {
    pub fn new(is_static: bool, dt: Real, s: &Settings) -> Self {
        Self {
            is_static,
            dt,
            ramp: s.ramp,
            max_time: s.settle_time,
            increments: s.increments,
            budget: BUDGET_SECONDS[usize::from(!s.quick)],
            contact: ContactLaw::default(),
            kinetic_damping: true,
            window: SETTLE_WINDOW,
            rest_energy: REST_ENERGY,
            smooth_ramp: true,
        }
    }
}

/// The end of a quasi-static run.
#[derive(Clone, Debug, Default)]
pub struct Settled {
    /// (load fraction, watched quantity) along the run.
    pub curve: Vec<[Real; 2]>,
    /// The watched quantity at the end.
    pub value: Real,
    /// False when a dynamic model was still moving at `max_time`.
    pub settled: bool,
    pub steps: usize,
    pub seconds: Real,
    /// Probe runs: the surface vertices the probe held at the end.
    pub contacts: usize,
    /// Probe runs: false when a static contact loop stopped at its cap with the contact set
    /// still changing or the sliding targets still moving, at some increment.
    pub contact_converged: bool,
    /// Kinetic damping: the peaks of the kinetic energy at which the velocities were zeroed
    /// (0 where it was off or the model has no velocities).
    pub motion_stops: usize,
}

/// What `run` needs of a dynamic model besides stepping it: its kinetic energy (`None`:
/// no velocities) and stopping its motion, for kinetic damping.
trait Motion {
    fn kinetic_energy(&self) -> Option<Real>;
    fn stop_motion(&mut self) -> bool;
}

impl Motion for Simulation {
    fn kinetic_energy(&self) -> Option<Real> {
        self.model().kinetic_energy()
    }
    fn stop_motion(&mut self) -> bool {
        self.model_mut().stop_motion()
    }
}

impl Motion for dyn Deformable + '_ {
    fn kinetic_energy(&self) -> Option<Real> {
        Deformable::kinetic_energy(self)
    }
    fn stop_motion(&mut self) -> bool {
        Deformable::stop_motion(self)
    }
}

/// A model at rest after the ramp has at most this share of the run's largest kinetic
/// energy (a ten-thousandth of its speed). After a motion stop the slow mode starts again
/// from rest with a flat force, a plateau the window can take for rest: at 4 ms steps the
/// linear kinds were called settled up to 4.8 % off their equilibrium at 1e-4 and within
/// 0.26 % at 1e-6; at `Settings::settle_dt_max`'s 1 ms (the stops then nearer the peaks,
/// the plateaus quieter) 1e-6 called `fem-explicit`'s shallow press settled 1.18 % off, and
/// 1e-8 within 0.06 % (`compare::tests_settle`).
pub const REST_ENERGY: Real = 1e-8;
/// The share of the time limit over which a settled quantity moves less than 0.5 %.
pub const SETTLE_WINDOW: Real = 0.05;

/// The load fraction of a dynamic run at `x` = time / ramp time: the smoothstep 3x² − 2x³,
/// 1 from x = 1 on. Its rate is zero at both ends, so the load starts and stops without a
/// jerk: a linear ramp's sudden stop threw the organ off the deep probe (its kinetic energy
/// peaked at 5e-4 J on `fem-explicit`, against 3e-6 J after the smooth ramp), and the
/// undamped organ took most of a second to come back. The end load, so the equilibrium,
/// is the same.
pub fn smooth_ramp(x: Real) -> Real {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Steps until the watched quantity is steady after the ramp; `apply(s)` sets the load
/// at fraction s ∈ [0, 1], `watch` reads the quantity.
///
/// Dynamic models settle by dynamic relaxation with kinetic damping
/// (`Stepping::kinetic_damping`) where they have velocities: the model runs undamped
/// (`measure::relaxing`) and, each time its kinetic energy falls below the last step's (a
/// peak has passed), every velocity is set to zero. It adds no force, so the equilibrium
/// is the model's own; it takes out the energy of the mode that dominates the motion at
/// each peak, whatever its frequency. The mass damping it replaces (2ω for a first mode
/// estimated at π√(E/ρ)/(2·height), 110 /s on the built-in liver) overdamped the organ's
/// real slowest mode (about 17 rad/s measured: `compare::tests_settle`), whose motion then
/// decays at ω²/c ≈ 2.6 /s: the probe force was still 9 times the equilibrium at 0.6 s.
fn run<M: ?Sized + Motion>(
    m: &mut M,
    st: &Stepping,
    mut apply: impl FnMut(&mut M, Real) -> Result<(), Error>,
    mut step: impl FnMut(&mut M, Real) -> Result<(), Error>,
    watch: impl Fn(&M) -> Real,
) -> Result<Settled, Error> {
    let start = Instant::now();
    let mut out = Settled::default();
    if st.is_static {
        for k in 1..=st.increments.max(1) {
            let s = k as Real / st.increments.max(1) as Real;
            apply(m, s)?;
            step(m, st.dt)?;
            out.steps += 1;
            out.curve.push([s, watch(m)]);
        }
        out.value = watch(m);
        out.settled = true;
        out.seconds = start.elapsed().as_secs_f64();
        return Ok(out);
    }
    let dt = st.dt;
    let steps = (st.max_time / dt).ceil() as usize;
    let record_every = ((st.ramp / dt) / 20.0).ceil().max(1.0) as usize;
    // Steady: the quantity moved less than 0.5 % (of its size) over the last `window` share
    // (5 %) of the time limit.
    let window = ((st.window * st.max_time / dt).ceil() as usize).max(2);
    let mut history: Vec<Real> = Vec::new();
    // Kinetic energy: the last step's, the largest so far, and per step after the ramp.
    let (mut last_energy, mut peak_energy) = (0.0, 0.0);
    let mut energies: Vec<Real> = Vec::new();
    for k in 1..=steps {
        let t = k as Real * dt;
        if k % 16 == 0 && start.elapsed().as_secs_f64() > st.budget {
            return Err(SimError::Unsupported {
                model: "(comparison)",
                operation: "this run within its time budget",
                reason: format!(
                    "stopped after {:.0} s of computing at t = {t:.3} s of {:.3} s \
                     (dt = {dt:.2e} s)",
                    st.budget, st.max_time
                ),
            }
            .into());
        }
        let s = if st.smooth_ramp {
            smooth_ramp(t / st.ramp)
        } else {
            (t / st.ramp).min(1.0)
        };
        apply(m, s)?;
        step(m, dt)?;
        out.steps = k;
        let energy = m.kinetic_energy();
        if let Some(e) = energy {
            peak_energy = Real::max(peak_energy, e);
            if s >= 1.0 {
                energies.push(e);
            }
            if st.kinetic_damping {
                if e < last_energy && m.stop_motion() {
                    out.motion_stops += 1;
                    last_energy = 0.0;
                } else {
                    last_energy = e;
                }
            }
        }
        let q = watch(m);
        if !q.is_finite() {
            return Err(SimError::Diverged {
                step: k as u64,
                node: 0,
                reason: "the measured quantity is not finite".into(),
            }
            .into());
        }
        if k % record_every == 0 || k == steps {
            out.curve.push([s, q]);
        }
        if s >= 1.0 {
            history.push(q);
            if history.len() > window {
                let old = history[history.len() - 1 - window];
                let scale = q.abs().max(old.abs()).max(1e-12);
                // And at rest: a body thrown off the probe holds a steady zero force while
                // it flies, and right after a motion stop the slow mode restarts from rest
                // with a flat force; a settled one moves with a thousandth of its peak speed.
                let resting = energies
                    .iter()
                    .rev()
                    .take(window)
                    .all(|e| *e <= st.rest_energy * peak_energy);
                if (q - old).abs() <= 5e-3 * scale && resting {
                    out.settled = true;
                    break;
                }
            }
        }
    }
    out.value = watch(m);
    out.seconds = start.elapsed().as_secs_f64();
    Ok(out)
}

/// The probe pressing `depth` m straight down at `point` (touching at the start).
pub fn probe_instrument(
    point: Vec3,
    radius: Real,
    depth: Real,
    ramp: Real,
    law: ContactLaw,
) -> Result<Instrument, Error> {
    let top = point + Vec3::Y * radius;
    let bottom = top - Vec3::Y * depth;
    let key = |t: Real, p: Vec3| Keyframe {
        t,
        position: p.into(),
    };
    let path = Trajectory::new(vec![key(0.0, top), key(ramp, bottom)]).map_err(|e| {
        SimError::BadParameter {
            name: "path",
            value: "probe".into(),
            reason: e.to_string(),
        }
    })?;
    let probe = Instrument::new("probe", InstrumentKind::Probe, radius, path)?;
    Ok(if law.frictionless() {
        probe.with_friction(0.0)?
    } else {
        probe.sticking()
    })
}

/// Quasi-static indentation with the probe through `Simulation`; watches the probe force
/// (up, N). Returns the simulation for the displacement field.
pub fn indent(
    model: Box<dyn Deformable>,
    fixed: Vec<u32>,
    point: Vec3,
    radius: Real,
    depth: Real,
    st: &Stepping,
) -> Result<(Settled, Simulation), Error> {
    let sim = probe_simulation(model, fixed, radius, st.contact)?;
    indent_sim(sim, point, radius, 0.0, depth, st)
}

/// `indent` on a simulation that may already hold the probe pressed `from` m in (its first
/// instrument, left where it is): the probe is then moved on from there to `depth` through
/// its live position, so a deeper indentation continues the shallow one's model, contact set,
/// factorisation and contact columns instead of starting again. A simulation with no
/// instrument gets the probe touching at `point` (`from` must then be 0).
pub fn indent_sim(
    mut sim: Simulation,
    point: Vec3,
    radius: Real,
    from: Real,
    depth: Real,
    st: &Stepping,
) -> Result<(Settled, Simulation), Error> {
    if st.is_static && st.contact.frictionless() {
        sim.set_max_contact_iterations(FRICTIONLESS_CONTACT_ITERATIONS);
    }
    // Static models: `increments` solves over a unit ramp; dynamic ones follow the ramp.
    let (ramp, dt) = if st.is_static {
        (1.0, 1.0 / st.increments.max(1) as Real)
    } else {
        (st.ramp, st.dt)
    };
    let top = point + Vec3::Y * radius;
    // A static model's increments follow the probe's path; a dynamic run moves the probe
    // itself at each step, along `run`'s smooth ramp.
    let live = !sim.instruments().is_empty() || !st.is_static;
    if sim.instruments().is_empty() {
        let path_depth = if st.is_static { depth } else { from };
        sim.add_instrument(probe_instrument(
            point, radius, path_depth, ramp, st.contact,
        )?);
    }
    let st = Stepping { dt, ..*st };
    let (mut contacts, mut converged) = (0, true);
    let mut settled = run(
        &mut sim,
        &st,
        |sim, s| {
            if live {
                let at = top - Vec3::Y * (from + s * (depth - from));
                sim.set_instrument_position(0, Some(at))?;
            }
            Ok(())
        },
        |sim, dt| {
            let r = sim.step(dt)?;
            contacts = r.contacts.first().copied().unwrap_or(0);
            converged &= r.contact_converged;
            check_finite(sim.model())
        },
        |sim| sim.instrument_forces().first().map_or(0.0, |f| f.y),
    )?;
    settled.contacts = contacts;
    settled.contact_converged = converged;
    // The curve's load fraction is of this run's travel: make it of `depth`.
    for p in &mut settled.curve {
        p[0] = (from + p[0] * (depth - from)) / depth.max(1e-300);
    }
    Ok((settled, sim))
}

/// Quasi-static run with prescribed surface vertices: `targets(s)` gives each prescribed
/// vertex's position at load fraction s; `fixed` stay at rest. Watches `watch`.
pub fn prescribe(
    model: &mut dyn Deformable,
    fixed: &[u32],
    moved: &[u32],
    target: impl Fn(Vec3, Real) -> Vec3,
    st: &Stepping,
    watch: impl Fn(&dyn Deformable) -> Real,
) -> Result<Settled, Error> {
    prescribe_along(model, fixed, moved, target, None, st, watch).map(|(s, _)| s)
}

/// How `prescribe_along` held the moved vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlateHold {
    /// Along the direction both ways, free across it: the reference's frictionless plate
    /// (`Deformable::set_constraints_two_sided`).
    TwoSided,
    /// Along the direction as contacts that only push (free to leave the plate): a kind
    /// that holds a direction only so (`Deformable::contacts_push_only`) and cannot hold it
    /// both ways.
    PushOnly,
    /// In all three directions.
    Full,
}

impl PlateHold {
    /// As written in the record's note.
    pub fn note(self) -> &'static str {
        match self {
            Self::TwoSided => "plate frictionless, held along y both ways (the reference's)",
            Self::PushOnly => {
                "plate frictionless but pushing only (this kind cannot hold along y both \
                 ways): not the reference's two-sided plate"
            }
            Self::Full => "plate held in all three directions (the model cannot hold along y only)",
        }
    }
}

/// `prescribe` with the moved vertices held along `along` only where given (a frictionless
/// plate: free across it), both ways as the reference holds its plate, where the model can
/// (`Deformable::set_constraints_two_sided`); a kind whose directional holds only push and
/// that cannot hold both ways gets its push-only contacts, any other that cannot is held in
/// full. The second value says which. Every kind so gets the reference's boundary condition
/// where it can: with push-only holds the linear dynamic kinds' organ swelled by 8.8 %
/// under the plate, the static kinds' (two-sided) by 1.23 %: two problems scored as one.
pub fn prescribe_along(
    model: &mut dyn Deformable,
    fixed: &[u32],
    moved: &[u32],
    target: impl Fn(Vec3, Real) -> Vec3,
    along: Option<Vec3>,
    st: &Stepping,
    watch: impl Fn(&dyn Deformable) -> Real,
) -> Result<(Settled, PlateHold), Error> {
    let rest: Vec<Vec3> = model.rest_surface().to_vec();
    let normals = vec![along; moved.len()];
    let mut last = -1.0;
    let mut how = if along.is_some() {
        PlateHold::TwoSided
    } else {
        PlateHold::Full
    };
    let settled = run(
        model,
        st,
        |m, s| {
            if s == last {
                return Ok(());
            }
            last = s;
            let c = Constraints {
                fixed: fixed.to_vec(),
                prescribed: moved
                    .iter()
                    .map(|&v| Prescribed {
                        vertex: v,
                        position: target(rest[v as usize], s),
                    })
                    .collect(),
            };
            if along.is_none() {
                return Ok(m.set_constraints(&c)?);
            }
            let now = if m.set_constraints_two_sided(&c, &normals)? {
                PlateHold::TwoSided
            } else if m.contacts_push_only() && m.set_constraints_along(&c, &normals)? {
                PlateHold::PushOnly
            } else {
                PlateHold::Full
            };
            // The weakest hold of the run is the one to report.
            if how == PlateHold::TwoSided || now == PlateHold::Full {
                how = now;
            }
            Ok(())
        },
        |m, dt| {
            m.step(dt)?;
            check_finite(m)
        },
        |m| watch(m),
    )?;
    Ok((settled, how))
}

/// An error when the surface holds a non-finite position.
pub fn check_finite(m: &dyn Deformable) -> Result<(), Error> {
    match m
        .surface()
        .positions
        .iter()
        .position(|p| !is_finite_vec(*p))
    {
        None => Ok(()),
        Some(v) => Err(SimError::Diverged {
            step: 0,
            node: v,
            reason: "a surface position is not finite".into(),
        }
        .into()),
    }
}

/// Signed volume enclosed by the model's current surface, m³.
pub fn volume(m: &dyn Deformable) -> Real {
    let s = m.surface();
    crate::mesh::surface::signed_volume_of(s.positions, s.triangles)
}
