//! The JSON messages the page receives: `init` (the mesh at rest, the kinds, the settings),
//! sent on connect and after every rebuild or cut, and `frame` (positions, instruments,
//! forces, rates), sent at ~30 Hz. Positions go as f32: the page draws in f32 anyway.

use serde_json::{Value, json};
use tissue::haptic::TimingSummary;
use tissue::model::KINDS;
use tissue::sim::Simulation;
use tissue::{Material, Real, Vec3};

use super::session::BuildStatus;
use super::setup::Setup;

fn flat_f32(points: &[Vec3]) -> Vec<f32> {
    points
        .iter()
        .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
        .collect()
}

pub fn init_message(
    sim: &Simulation,
    setup: &Setup,
    kind: &str,
    material: Material,
    dt: Real,
) -> String {
    let m = sim.model();
    let triangles: Vec<u32> = m.surface().triangles.iter().flatten().copied().collect();
    // Only what this body can be built as: an image scene lists its voxel kinds.
    let buildable = setup.buildable_kinds();
    let kinds: Vec<_> = KINDS
        .iter()
        .filter(|k| buildable.contains(&k.name))
        .map(|k| json!({ "name": k.name, "summary": k.summary }))
        .collect();
    let b = setup.bounds;
    json!({
        "type": "init",
        "kind": kind,
        "kinds": kinds,
        "is_static": m.info().is_static,
        "material": {
            "young_modulus": material.young_modulus,
            "poisson_ratio": material.poisson_ratio,
        },
        "rest": flat_f32(m.rest_surface()),
        "triangles": triangles,
        "fixed": sim.fixed(),
        "center": b.center.to_array(),
        "size": b.radius / 3.0,
        "probe_radius": setup.probe_radius,
        "grasp_radius": setup.grasp_radius,
        "dt": dt,
        "scene": setup.scene.path.display().to_string(),
        // A voxel body's surface is drawn smoothed by the page.
        "smooth": setup.body.grid.is_some(),
    })
    .to_string()
}

/// What the session knows beyond the simulation.
pub struct Figures<'a> {
    pub dt: Real,
    pub sim_rate: Real,
    pub haptic: TimingSummary,
    pub haptic_force: Vec3,
    pub probe_active: bool,
    /// The running model's kind and the internal steps its last step took.
    pub kind: &'a str,
    pub substeps: u32,
    /// The build in progress, if any.
    pub building: Option<BuildStatus>,
    /// A cut in progress: path points swept, of how many.
    pub cut: Option<(usize, usize)>,
}

/// `names`: the viewer's probe, grasper and scalpel.
pub fn frame_message(sim: &Simulation, f: &Figures<'_>, names: [&str; 3]) -> String {
    let tool = |name: &str| -> Option<Value> {
        sim.instruments().iter().find(|i| i.name == name).map(|i| {
            json!({
                "position": i.position().to_array(),
                "force": i.force().to_array(),
                "radius": i.radius(),
                "contacts": i.contacts().len(),
                "blade": i.blade_at(i.position()).map(|b| [b[0].to_array(), b[1].to_array()]),
            })
        })
    };
    let [probe, grasper, scalpel] = names;
    json!({
        "type": "frame",
        "time": sim.time(),
        "steps": sim.steps(),
        "dt": f.dt,
        "positions": flat_f32(sim.model().surface().positions),
        "probe": tool(probe),
        "probe_active": f.probe_active,
        "grasper": tool(grasper),
        "scalpel": tool(scalpel),
        "haptic_force": f.haptic_force.to_array(),
        "sim_rate": f.sim_rate,
        "haptic_rate": f.haptic.rate_hz,
        "haptic_p99_us": f.haptic.p99_us,
        "haptic_missed": f.haptic.missed_deadlines,
        "kind": f.kind,
        "substeps": f.substeps,
        "building": f.building.as_ref().map(|b| json!({
            "kind": b.kind,
            "stage": b.stage,
            "percent": (b.fraction >= 0.0).then(|| (100.0 * b.fraction).round()),
            "seconds": b.started.map_or(0.0, |t| t.elapsed().as_secs_f64()),
        })),
        "cut": f.cut.map(|(done, total)| json!({ "done": done, "total": total })),
        // Parts of a composed model (hybrid: 0 the pre-computed rest, 1 the region's border,
        // 2 the cuttable region), per surface vertex; every frame, as a region can grow.
        "labels": sim.model().vertex_labels(),
    })
    .to_string()
}
