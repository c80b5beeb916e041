//! The blocks, probe paths, slides and the `Relaxed` wrapper the sliding-contact tests share
//! (`sliding_contact.rs`, `normal_holds.rs`; each uses a part of them).
#![allow(dead_code)]

use tissue::error::SimError;
use tissue::interact::{
    Constraints, Instrument, InstrumentKind, Keyframe, Loads, MappedSurface, Trajectory,
};
use tissue::material::Material;
use tissue::math::{Mat3, Real, Vec3};
use tissue::mesh::MeshData;
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::model::registry::{BuildInput, build};
use tissue::model::{
    ContactSurface, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView, VolumeView,
};
use tissue::sim::Simulation;

pub const E: Real = 3000.0;

/// A block [−l, l]² × [0, h] on a fixed floor, `cells` cells across (half as many deep),
/// graded toward the top centre: x = l (α s + (1 − α) s³), s ∈ [−1, 1], and the same
/// toward the top in z. `lift(x)` raises the top surface (a curved block), fading to the
/// floor.
pub fn block(l: Real, h: Real, cells: usize, lift: &dyn Fn(Real) -> Real) -> MeshData {
    let mut mesh = box_tets(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 1.0),
        [cells, cells, cells / 2],
        BoxSplit::Six,
    );
    let alpha = 0.25;
    let grade = |s: Real| alpha * s + (1.0 - alpha) * s * s * s;
    for p in &mut mesh.vertices {
        let (x, y) = (l * grade(p.x), l * grade(p.y));
        // 1 − grade(1 − z): fine at the top.
        let t = 1.0 - grade(1.0 - p.z);
        *p = Vec3::new(x, y, h * t + t * lift(x));
    }
    MeshData::from_tets(&mesh)
}

pub fn model(kind: &str, mesh: &MeshData, nu: Real) -> Box<dyn tissue::model::Deformable> {
    model_with(kind, mesh, nu, toml::Table::new())
}

pub fn model_with(
    kind: &str,
    mesh: &MeshData,
    nu: Real,
    params: toml::Table,
) -> Box<dyn tissue::model::Deformable> {
    let mut material = Material::new(E, nu).unwrap();
    material.damping = 20.0;
    let input = BuildInput {
        mesh,
        source: "graded block",
        material,
        params: &params,
        regions: &[],
    };
    build(kind, &input).unwrap()
}

/// The simulation with the floor (z = 0) fixed.
pub fn sim_on_floor(model: Box<dyn tissue::model::Deformable>) -> Simulation {
    let fixed: Vec<u32> = (0..model.rest_surface().len() as u32)
        .filter(|&v| model.rest_surface()[v as usize].z < 1e-9)
        .collect();
    Simulation::new(model, fixed, Loads::default()).unwrap()
}

pub fn path(keys: &[(Real, Vec3)]) -> Trajectory {
    Trajectory::new(
        keys.iter()
            .map(|&(t, p)| Keyframe {
                t,
                position: p.to_array(),
            })
            .collect(),
    )
    .unwrap()
}

/// Hertz: F = 4/3 · E/(1 − ν²) · √R · δ^{3/2}.
pub fn hertz(nu: Real, r: Real, depth: Real) -> Real {
    4.0 / 3.0 * E / (1.0 - nu * nu) * r.sqrt() * depth.powf(1.5)
}

pub const L: Real = 0.02;
pub const H: Real = 0.02;

/// The sliding probe: large against its indentation (contact radius √(R δ) = 2.4 mm, a/R =
/// 0.12), so that its surface is nearly flat over the contact and μN along the surface is
/// μN sideways within 1%.
pub const SLIDE_R: Real = 0.02;
pub const SLIDE_DEPTH: Real = 3e-4;

/// Presses the probe into the flat block, then moves it 3 mm along +x; the force at each
/// step of the move.
pub fn slide(kind: &str, friction: Real, dt: Real) -> Vec<Vec3> {
    slide_on(kind, friction, dt, 16)
}

/// `slide` on a block of `cells` cells across.
pub fn slide_on(kind: &str, friction: Real, dt: Real, cells: usize) -> Vec<Vec3> {
    slide_of(kind, friction, dt, cells, false).0
}

/// `slide_on`, the model wrapped in `Relaxed` when `relaxed`; also the most solves a step
/// took.
pub fn slide_of(
    kind: &str,
    friction: Real,
    dt: Real,
    cells: usize,
    relaxed: bool,
) -> (Vec<Vec3>, usize) {
    let mesh = block(L, H, cells, &|_| 0.0);
    let built = model(kind, &mesh, 0.3);
    let mut sim = sim_on_floor(if relaxed {
        Box::new(Relaxed(built))
    } else {
        built
    });
    sim.set_max_contact_iterations(60);
    let top = Vec3::new(-0.0015, 0.0, H + SLIDE_R);
    let down = top - Vec3::Z * SLIDE_DEPTH;
    let probe = Instrument::new(
        "probe",
        InstrumentKind::Probe,
        SLIDE_R,
        path(&[(0.0, top), (0.5, down), (1.5, down + Vec3::X * 3e-3)]),
    )
    .unwrap()
    .with_friction(friction)
    .unwrap();
    sim.add_instrument(probe);
    let mut forces = Vec::new();
    let mut most_solves = 0;
    let mut t = 0.0;
    while t < 1.5 - 1e-9 {
        let r = sim.step(dt).unwrap();
        t = r.time;
        most_solves = most_solves.max(r.contact_iterations);
        if t > 0.5 + 1e-9 {
            forces.push(r.forces[0]);
            eprintln!(
                "t {t:.2}: {} solves, slide residual {:.1e}, {} contacts",
                r.contact_iterations, r.slide_residual, r.contacts[0]
            );
        }
    }
    (forces, most_solves)
}

/// A model with the default `Deformable::set_constraints_along` (every contact held in all
/// three directions, false returned): `Simulation` slides its frictionless contacts by the
/// relaxation of their targets, as the compliance kinds did before they held them along
/// their normals. What the exact holds are measured against.
pub struct Relaxed(pub Box<dyn Deformable>);

impl Deformable for Relaxed {
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
    fn reset(&mut self) {
        self.0.reset()
    }
    fn prescribed_stiffness(&self, entries: std::ops::Range<usize>) -> Option<Mat3> {
        self.0.prescribed_stiffness(entries)
    }
    fn set_contact_reach(&mut self, reach: Option<&[(Vec3, Real)]>) {
        self.0.set_contact_reach(reach)
    }
    fn contact_surface(&self) -> ContactSurface<'_> {
        self.0.contact_surface()
    }
    fn info(&self) -> ModelInfo {
        self.0.info()
    }
}

pub fn tangential(f: Vec3) -> Real {
    Vec3::new(f.x, f.y, 0.0).length()
}

/// The model's own surface with each triangle cut into n² (`MappedSurface::subdivided`): a
/// fine surface lying on the coarse one.
pub fn subdivided(sim: &Simulation, n: usize) -> MappedSurface {
    let m = sim.model();
    MappedSurface::subdivided(m.rest_surface(), m.surface().triangles, n).unwrap()
}
