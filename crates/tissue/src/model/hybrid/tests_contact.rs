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
    let mesh = box_tets(
        Vec3::ZERO,
        Vec3::new(0.12, 0.03, 0.03),
        [12, 3, 3],
        BoxSplit::Six,
    );
    let mut m = Material::new(5000.0, 0.4).unwrap();
    m.damping = 10.0;
    let params: toml::Table = toml::from_str(
        "cut_region = { box = { min = [0.04, -1.0, -1.0], max = [0.08, 1.0, 1.0] } }",
    )
    .unwrap();
    Hybrid::from_input(&BuildInput {
        mesh: &MeshData::from_tets(&mesh),
        source: "test",
        material: m,
        params: &params,
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
    sim.add_instrument(Instrument::new("top", InstrumentKind::Probe, r, top).unwrap());
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
