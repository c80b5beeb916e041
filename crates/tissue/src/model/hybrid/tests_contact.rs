//! The contact search through `Simulation` reads only the part of the hybrid's surface an
//! instrument can reach (`Deformable::contact_surface`): the contacts and forces must be
//! those of a search over the whole surface.

use super::*;
use crate::interact::instrument::{Instrument, InstrumentKind};
use crate::interact::trajectory::{Keyframe, Trajectory};
use crate::interact::{Constraints, Loads};
use crate::material::Material;
use crate::math::Mat3;
use crate::mesh::MeshData;
use crate::mesh::generate::{BoxSplit, box_tets};
use crate::model::{
    CutInfo, CutPath, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView, VolumeView,
};
use crate::sim::Simulation;

/// The hybrid with the trait's default contact surface: every vertex computed, every read
/// (the search as it was before `contact_surface`).
struct WholeSurface(Hybrid);

impl Deformable for WholeSurface {
    fn kind(&self) -> &'static str {
        self.0.kind()
    }
    fn surface(&self) -> SurfaceView<'_> {
        self.0.surface()
    }
    fn rest_surface(&self) -> &[Vec3] {
        self.0.rest_surface()
    }
    fn volume(&self) -> Option<VolumeView<'_>> {
        self.0.volume()
    }
    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        self.0.set_constraints(c)
    }
    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        self.0.set_constraints_along(c, normals)
    }
    fn contacts_push_only(&self) -> bool {
        self.0.contacts_push_only()
    }
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        self.0.set_loads(loads)
    }
    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        self.0.step(dt)
    }
    fn reactions(&self) -> Reactions<'_> {
        self.0.reactions()
    }
    fn cut(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        self.0.cut(blade)
    }
    fn reset(&mut self) {
        self.0.reset()
    }
    fn prescribed_stiffness(&self, entries: std::ops::Range<usize>) -> Option<Mat3> {
        self.0.prescribed_stiffness(entries)
    }
    fn vertex_labels(&self) -> Option<Vec<u8>> {
        self.0.vertex_labels()
    }
    fn info(&self) -> ModelInfo {
        self.0.info()
    }
}

fn hybrid() -> Hybrid {
    beam_hybrid(
        10.0,
        "cut_region = { box = { min = [0.04, -1.0, -1.0], max = [0.08, 1.0, 1.0] } }",
    )
}

/// The 12 cm beam of 12 × 3 × 3 cells (E = 5 kPa, ν = 0.4) with damping `damping` as a
/// hybrid built with the `[model]` settings `params`.
fn beam_hybrid(damping: Real, params: &str) -> Hybrid {
    let mesh = box_tets(
        Vec3::ZERO,
        Vec3::new(0.12, 0.03, 0.03),
        [12, 3, 3],
        BoxSplit::Six,
    );
    let mut m = Material::new(5000.0, 0.4).unwrap();
    m.damping = damping;
    let params: toml::Table = toml::from_str(params).unwrap();
    Hybrid::from_input(&BuildInput {
        mesh: &MeshData::from_tets(&mesh),
        source: "test",
        material: m,
        params: &params,
        regions: &[],
    })
    .unwrap()
}

fn key(t: Real, p: [Real; 3]) -> Keyframe {
    Keyframe { t, position: p }
}

/// The beam clamped at x = 0; a sticking probe presses the top on the rest,
/// on the region (40–80 mm), on the rest again; a frictionless probe presses the front face on the rest (3 mm) and
/// slides along it.
fn simulation(model: Box<dyn Deformable>) -> Simulation {
    let rest = model.rest_surface().to_vec();
    let fixed = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    let mut sim = Simulation::new(model, fixed, Loads::default()).unwrap();
    let r = 0.006;
    // Three presses of 4 mm at a vertex: on the rest, on the region, on the rest again.
    let (up, down) = (0.03 + r + 0.001, 0.03 + r - 0.004);
    let top = Trajectory::new(vec![
        key(0.0, [0.02, 0.01, up]),
        key(0.03, [0.02, 0.01, down]),
        key(0.05, [0.02, 0.01, down]),
        key(0.07, [0.02, 0.01, up]),
        key(0.09, [0.06, 0.01, up]),
        key(0.12, [0.06, 0.01, down]),
        key(0.14, [0.06, 0.01, down]),
        key(0.16, [0.06, 0.01, up]),
        key(0.18, [0.1, 0.01, up]),
        key(0.21, [0.1, 0.01, down]),
    ])
    .unwrap();
    sim.add_instrument(
        Instrument::new("top", InstrumentKind::Probe, r, top)
            .unwrap()
            .sticking(),
    );
    let front = Trajectory::new(vec![
        key(0.0, [0.1, -r - 0.001, 0.02]),
        key(0.1, [0.1, -r + 0.003, 0.02]),
        key(0.25, [0.09, -r + 0.003, 0.02]),
    ])
    .unwrap();
    sim.add_instrument(
        Instrument::new("front", InstrumentKind::Probe, r, front)
            .unwrap()
            .with_friction(0.0)
            .unwrap(),
    );
    sim
}

#[test]
fn the_contact_search_on_part_of_the_surface_finds_what_the_whole_surface_gives() {
    let mut near = simulation(Box::new(hybrid()));
    let mut whole = simulation(Box::new(WholeSurface(hybrid())));
    let (mut partial, mut on_rest, mut on_region, mut fronts) = (0, 0, 0, 0);
    let mut worst: Real = 0.0;
    for step in 0..250 {
        let a = near.step(1e-3).unwrap();
        let b = whole.step(1e-3).unwrap();
        assert_eq!(a.contacts, b.contacts, "step {step}: contact counts");
        for (ia, ib) in near.instruments().iter().zip(whole.instruments()) {
            let va: Vec<u32> = ia.contacts().iter().map(|k| k.vertex).collect();
            let vb: Vec<u32> = ib.contacts().iter().map(|k| k.vertex).collect();
            assert_eq!(va, vb, "step {step}: contact vertices of {}", ia.name);
        }
        let scale = b.forces.iter().map(|f| f.length()).fold(1e-6, Real::max);
        for (fa, fb) in a.forces.iter().zip(&b.forces) {
            let gap = (*fa - *fb).length() / scale;
            worst = worst.max(gap);
            assert!(gap < 1e-12, "step {step}: force {fa} against {fb}");
        }
        // What this step's search read: only part of the rest's surface.
        let cs = near.model().contact_surface();
        if cs.slack.iter().any(|&s| s > 0.0) {
            partial += 1;
        }
        let labels = near.model().vertex_labels().unwrap();
        fronts += near.instruments()[1].contacts().len();
        for k in near.instruments()[0].contacts() {
            if labels[k.vertex as usize] == 0 {
                on_rest += 1;
            } else {
                on_region += 1;
            }
        }
    }
    println!(
        "{partial} of 250 steps searched part of the surface; top probe contacts: {on_rest} \
         on the rest, {on_region} on the region; front probe {fronts}; largest force gap {worst:.1e}"
    );
    // The other steps read the whole surface: too many of this small beam's rest vertices
    // were near the probes, or not yet bounded.
    assert!(partial > 50, "the search read the whole surface");
    assert!(on_rest > 0 && on_region > 0 && fronts > 0);
}

/// A change of the rest's contact set re-measures the stability limit from the last
/// dominant vector in a few iterations (not 30 cold ones): on a region one cell thick
/// (every region node on the interface, where the contacts' stiffness acts), with contact
/// sets on the rest beside the interface coming and going every 15 steps, the automatic
/// substep after every change is within the coupled operator's limit as a cold measure of
/// 200 iterations finds it, and 600 steps never trip the energy guard.
#[test]
fn a_contact_change_keeps_the_automatic_substep_within_the_coupled_limit() {
    let mut h = beam_hybrid(
        20.0,
        "cut_region = { box = { min = [0.04, -1.0, -1.0], max = [0.05, 1.0, 1.0] } }\n\
         integrator = \"symplectic-euler\"",
    );
    let rest = h.rest_surface().to_vec();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    // Top vertices of the rest beside the interface (x = 30 and 60 mm) and a little
    // farther (20, 70 mm), pressed in groups.
    let top = |x: Real| -> Vec<u32> {
        (0..rest.len() as u32)
            .filter(|&v| {
                let p = rest[v as usize];
                (p.x - x).abs() < 1e-9 && (p.z - 0.03).abs() < 1e-9
            })
            .collect()
    };
    let groups = [
        top(0.03),
        [top(0.03), top(0.06)].concat(),
        top(0.06),
        Vec::new(),
        [top(0.02), top(0.06), top(0.07)].concat(),
        [top(0.03), top(0.07)].concat(),
    ];
    h.set_loads(&Loads {
        gravity: Vec3::new(0.0, 0.0, -1.0),
        point_loads: Vec::new(),
    })
    .unwrap();
    let dt = 5e-3;
    let (mut changes, mut worst, mut max_substeps) = (0, 0.0 as Real, 0);
    let mut last_slots = Vec::new();
    for step in 0..600 {
        let phase = step / 15;
        let group = &groups[phase % groups.len()];
        // Each press ramps in over its 15 steps (a moving target: no re-measure).
        let depth = 0.002 * ((step % 15) as Real + 1.0) / 15.0;
        let c = Constraints {
            fixed: fixed.clone(),
            prescribed: group
                .iter()
                .map(|&v| crate::interact::Prescribed {
                    vertex: v,
                    position: rest[v as usize] - Vec3::new(0.0, 0.0, depth),
                })
                .collect(),
        };
        h.set_constraints(&c).unwrap();
        let slots = h.rest.contact_sites().to_vec();
        // (Before the first step the loads left the limit unmeasured: a full measure.)
        if let (true, Some(warm)) = (slots != last_slots, h.tm.integrator().stable_dt()) {
            changes += 1;
            let cold = h.cold_stable_dt(200);
            if std::env::var("HYBRID_RECHECK_TRACE").is_ok() {
                eprintln!(
                    "step {step}: {} contacts, warm {warm:.4e}, cold200 {cold:.4e}, cold30 {:.4e}",
                    slots.len(),
                    h.cold_stable_dt(30)
                );
            }
            // The substep taken is at most `warm`; the coupled operator is stable below
            // cold / SAFETY (the bound itself).
            let limit = cold / crate::integrate::stable_step::SAFETY;
            let substep =
                dt / crate::integrate::stable_step::substeps_for(dt, warm).unwrap() as Real;
            assert!(
                substep <= limit,
                "step {step}: substep {substep:e} above the coupled limit {limit:e}"
            );
            worst = worst.max(warm / cold);
            last_slots = slots;
        }
        let info = h.step(dt).unwrap();
        max_substeps = max_substeps.max(info.substeps);
    }
    let margin = h.tm.integrator().stiffness_margin();
    let speed = h
        .region_model()
        .velocities()
        .iter()
        .map(|v| v.length())
        .fold(0.0, Real::max);
    eprintln!(
        "{changes} contact-set changes; largest warm / cold stable step {worst:.4}; \
         {max_substeps} substeps at most; stiffness margin {margin}; region speed {speed:.2e} m/s"
    );
    assert!(changes >= 35, "{changes} changes");
    assert_eq!(margin, 1.0, "a step was refused by the energy guard");
    assert!(speed.is_finite() && speed < 1.0, "{speed}");
}
