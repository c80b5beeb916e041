//! Speed of the hybrid against whole-organ `tensor-mass-nonlinear` on the refined liver
//! (`split_tets` of the shipped one): cost per step, build time and memory at cut regions of
//! about 10, 25 and 50 % of the volume, the surface gap between the two after the same
//! loading, and the time of one automatic region growth. Ignored (long); run with
//! `cargo test --release --workspace --lib hybrid::tests_speed -- --ignored --nocapture`.

use std::time::Instant;

use super::*;
use crate::integrate::Scheme;
use crate::interact::{Constraints, Prescribed};
use crate::material::Material;
use crate::mesh::{MeshData, TetMesh};
use crate::model::tensor_mass::TensorMass;
use crate::model::{CutPath, Deformable};

/// The shipped liver split once (4,768 tetrahedra), or the tetrahedral mesh in centimetres
/// at `HYBRID_LIVER` (e.g. `tissue mesh tetrahedralize assets/meshes/liver-smooth.obj
/// liver-7k.msh --size 0.42 --force`: 7,191 tetrahedra), for the studies on a larger organ.
fn refined_liver() -> TetMesh {
    if let Ok(path) = std::env::var("HYBRID_LIVER") {
        let m = crate::io::read(&path).unwrap().tet_mesh(&path).unwrap();
        return TetMesh::new(m.vertices.iter().map(|v| *v * 0.01).collect(), m.tets);
    }
    let m = crate::io::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/meshes/liver.msh"
    ))
    .unwrap()
    .tet_mesh("liver.msh")
    .unwrap();
    let m = TetMesh::new(m.vertices.iter().map(|v| *v * 0.01).collect(), m.tets);
    crate::mesh::split_tets(&m).unwrap()
}

fn material() -> Material {
    let mut m = Material::new(3000.0, 0.3).unwrap();
    m.damping = 20.0;
    m
}

/// Ligament nodes 3, 39, 64 fixed, the surface vertices within 8 mm of the top of the
/// right lobe pressed 5 mm down: as surface vertices of a model whose surface vertex → node
/// map is `node_of`.
fn constraints(rest: &[Vec3], node_of: impl Fn(usize) -> u32) -> Constraints {
    let mut c = Constraints::default();
    let press = Vec3::new(0.0, 0.045, 0.005);
    for (v, p) in rest.iter().enumerate() {
        if [3, 39, 64].contains(&node_of(v)) {
            c.fixed.push(v as u32);
        } else if p.distance(press) < 0.008 {
            c.prescribed.push(Prescribed {
                vertex: v as u32,
                position: *p + Vec3::new(0.0, -0.005, 0.0),
            });
        }
    }
    c
}

fn sphere_for_fraction(mesh: &TetMesh, centre: Vec3, fraction: Real) -> Real {
    let cents = split::centroids(mesh);
    let total = mesh.volume();
    let (mut lo, mut hi) = (0.0, 0.2);
    for _ in 0..40 {
        let r = 0.5 * (lo + hi);
        let v: Real = (0..mesh.tets.len())
            .filter(|&t| cents[t].distance(centre) <= r)
            .map(|t| mesh.tet_volume(t))
            .sum();
        if v / total < fraction {
            lo = r;
        } else {
            hi = r;
        }
    }
    hi
}

/// Time this thread has spent on a CPU, in s (Linux schedstat), so that a rate is not
/// skewed by the other processes sharing the machine; wall clock elsewhere.
fn cpu_seconds(wall: Instant) -> Real {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<Real>().ok())
        .map_or_else(|| wall.elapsed().as_secs_f64(), |ns| ns * 1e-9)
}

/// What one model did under the press: CPU µs per outer step, the substeps it chose, the
/// press force after settling.
struct Run {
    us_per_step: Real,
    substeps: u32,
    force: Vec3,
}

/// `steps` outer steps of `dt` (the press ramped in over the first fifth), then the total
/// force on the pressed vertices. `read_surface`: the whole surface is read after every
/// step (as `Simulation` does for its contact search), else never (a haptic loop between
/// display frames reads only the reactions).
fn press(
    model: &mut dyn Deformable,
    dt: Real,
    steps: usize,
    full: &Constraints,
    read_surface: bool,
) -> Run {
    let rest = model.rest_surface().to_vec();
    let wall = Instant::now();
    let t0 = cpu_seconds(wall);
    let mut substeps = 0;
    let ramp = steps / 5;
    for k in 0..steps {
        if k <= ramp {
            let s = k as Real / ramp as Real;
            let mut c = full.clone();
            for p in &mut c.prescribed {
                let r = rest[p.vertex as usize];
                p.position = r + (p.position - r) * s;
            }
            model.set_constraints(&c).unwrap();
        }
        substeps = substeps.max(model.step(dt).unwrap().substeps);
        if read_surface {
            std::hint::black_box(model.surface().positions.last().copied());
        }
    }
    let t1 = cpu_seconds(wall);
    Run {
        us_per_step: (t1 - t0) / steps as Real * 1e6,
        substeps,
        force: model.reactions().prescribed.iter().copied().sum(),
    }
}

/// The speed table of `docs/hybrid.md`: whole-organ tensor-mass (linear and St
/// Venant–Kirchhoff) against the hybrid at region fractions 10–75 %, every model at its own
/// automatic substeps and the same outer dt (1 ms, a haptic loop's), pressed 5 mm on the
/// right lobe until settled; the press force against `fem-static`'s on the same mesh.
#[test]
#[ignore = "speed study: prints a table"]
fn hybrid_speed_against_whole_organ_tensor_mass() {
    let mesh = refined_liver();
    let data = MeshData::from_tets(&mesh);
    let (dt, steps) = (1e-3, 800);
    println!(
        "refined liver: {} tetrahedra, {} nodes; dt = {dt} s, {steps} steps",
        mesh.tets.len(),
        mesh.vertices.len()
    );
    let mut fem =
        crate::model::fem::FemStatic::new(&mesh, material(), crate::model::fem::Order::Linear)
            .unwrap();
    let fem_nodes = fem.surface_nodes().to_vec();
    fem.set_constraints(&constraints(fem.rest_surface(), |v| fem_nodes[v]))
        .unwrap();
    fem.step(dt).unwrap();
    let reference: Vec3 = fem.reactions().prescribed.iter().copied().sum();
    println!("fem-static press force: {reference:?} N");
    let error = |f: Vec3| (f - reference).length() / reference.length();
    println!(
        "| model | region fraction | region tets | interface nodes | CPU us/step | substeps | \
         us/substep | speed-up | force error vs fem-static | build s | MB |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut whole_us = 0.0;
    for nonlinear in [true, false] {
        let t0 = Instant::now();
        let mut whole = TensorMass::new(
            &mesh,
            material(),
            Default::default(),
            nonlinear,
            Scheme::SymplecticEuler,
        )
        .unwrap();
        let build = t0.elapsed().as_secs_f64();
        let nodes = whole.surface_nodes().to_vec();
        let c = constraints(whole.rest_surface(), |v| nodes[v]);
        let run = press(&mut whole, dt, steps, &c, true);
        if nonlinear {
            whole_us = run.us_per_step;
        }
        println!(
            "| whole {} | 1 | {} | 0 | {:.0} | {} | {:.0} | {:.2} | {:.1e} | {build:.3} | {:.1} |",
            whole.kind(),
            mesh.tets.len(),
            run.us_per_step,
            run.substeps,
            run.us_per_step / run.substeps.max(1) as Real,
            whole_us / run.us_per_step,
            error(run.force),
            whole.info().memory_bytes as Real / 1e6
        );
        println!(
            "  whole {}: stable dt {:.3e} s",
            whole.kind(),
            whole.integrator().stable_dt().unwrap_or(Real::NAN)
        );
    }
    let centre = Vec3::new(0.005, 0.04, 0.005);
    for (fraction, nonlinear) in [
        (0.1, true),
        (0.25, true),
        (0.25, false),
        (0.5, true),
        (0.75, true),
    ] {
        let r = sphere_for_fraction(&mesh, centre, fraction);
        let params: toml::Table = toml::from_str(&format!(
            "cut_region = {{ sphere = {{ center = [{}, {}, {}], radius = {r} }} }}\n\
             nonlinear = {nonlinear}\nintegrator = \"symplectic-euler\"",
            centre.x, centre.y, centre.z
        ))
        .unwrap();
        for read_surface in [false, true] {
            let mut h = Hybrid::from_input(&BuildInput {
                mesh: &data,
                source: "refined liver",
                material: material(),
                params: &params,
                regions: &[],
            })
            .unwrap();
            let surf = h.surf_nodes.clone();
            let c = constraints(h.rest_surface(), |v| surf[v]);
            let run = press(&mut h, dt, steps, &c, read_surface);
            let info = h.info();
            println!(
                "| hybrid ({}, surface read {}) | {:.2} | {} | {} | {:.0} | {} | {:.0} | {:.2} | \
                 {:.1e} | {:.3} | {:.1} |",
                if nonlinear { "StVK" } else { "linear" },
                if read_surface { "every step" } else { "never" },
                h.region_fraction(),
                h.region_tets(),
                h.interface_nodes(),
                run.us_per_step,
                run.substeps,
                run.us_per_step / run.substeps.max(1) as Real,
                whole_us / run.us_per_step,
                error(run.force),
                info.precompute_seconds,
                info.memory_bytes as Real / 1e6
            );
            if read_surface {
                continue;
            }
            // The rest's drawn surface against the exact condensed answer: every node of
            // the rest from one sparse solve with the interface displacements and the
            // contact forces (the volume view).
            let exact = h.volume().unwrap().positions.to_vec();
            let shown = h.surface().positions.to_vec();
            let (mut gap, mut size): (Real, Real) = (0.0, 0.0);
            for (v, &g) in h.surf_nodes.iter().enumerate() {
                if h.split.region.local[g as usize] == split::NONE {
                    gap = gap.max(shown[v].distance(exact[g as usize]));
                    size = size.max(exact[g as usize].distance(h.mesh.vertices[g as usize]));
                }
            }
            let coupled = h.tm.integrator().stable_dt().unwrap_or(Real::NAN);
            h.tm.measure_stability(None);
            let alone = h.tm.integrator().stable_dt().unwrap_or(Real::NAN);
            h.measure_stability();
            println!(
                "  rest surface vs exact condensed: {:.1e} (relative to its largest \
                 displacement {size:.2e} m); stable dt coupled {coupled:.3e} s, region \
                 alone {alone:.3e} s",
                gap / size.max(Real::MIN_POSITIVE)
            );
        }
    }
    // One automatic growth: a blade 2 cm from the starting region.
    let params: toml::Table = toml::from_str(
        "cut_region = \"auto\"\nauto_radius = 0.012\nauto_seeds = [[0.01, 0.04, 0.005]]",
    )
    .unwrap();
    let mut h = Hybrid::from_input(&BuildInput {
        mesh: &data,
        source: "refined liver",
        material: material(),
        params: &params,
        regions: &[],
    })
    .unwrap();
    // The ligaments held.
    let ligaments: Vec<u32> = (0..h.surf_nodes.len() as u32)
        .filter(|&v| [3, 39, 64].contains(&h.surf_nodes[v as usize]))
        .collect();
    h.set_constraints(&Constraints::fixed(ligaments)).unwrap();
    println!(
        "automatic region along a scalpel path (x from 0.03 to -0.05 m, 5 mm strokes, 5 steps \
         of 1 ms between strokes): start {} region tetrahedra ({:.2} of the volume)",
        h.region_tets(),
        h.region_fraction()
    );
    let mut removed = 0;
    for k in 0..16 {
        let x = 0.03 - 0.005 * k as Real;
        let grown = h.growths().len();
        removed += h
            .cut(&CutPath {
                start: [Vec3::new(x, 0.07, 0.005), Vec3::new(x, 0.035, 0.005)],
                end: [
                    Vec3::new(x - 0.005, 0.07, 0.005),
                    Vec3::new(x - 0.005, 0.035, 0.005),
                ],
            })
            .unwrap()
            .removed_elements;
        for _ in 0..5 {
            h.step(1e-3).unwrap();
        }
        if let Some(g) = h.growths().get(grown) {
            println!(
                "  stroke {k} at x = {x:.3}: growth to {} tetrahedra ({:.2} of the volume, {} \
                 interface nodes) in {:.3} s; {removed} cut so far",
                g.region_tets,
                h.region_fraction(),
                h.interface_nodes(),
                g.seconds
            );
        }
    }
    println!(
        "  end: {} region tetrahedra, {} growths, {removed} tetrahedra cut",
        h.region_tets(),
        h.growths().len()
    );
}

/// One model pressed by a probe through `Simulation` (as `tissue run` steps a scene):
/// CPU µs per outer step, the largest substep count, the probe's force at the end.
fn probe_run(model: Box<dyn Deformable>, path: &[(Real, Vec3)], radius: Real, read: bool) -> Run {
    probe_run_steps(model, path, radius, read, 800)
}

/// `probe_run` over `steps` outer steps of 1 ms.
fn probe_run_steps(
    model: Box<dyn Deformable>,
    path: &[(Real, Vec3)],
    radius: Real,
    read: bool,
    steps: usize,
) -> Run {
    use crate::interact::instrument::{Instrument, InstrumentKind};
    use crate::interact::trajectory::{Keyframe, Trajectory};
    let nodes: Vec<u32> = (0..model.rest_surface().len() as u32).collect();
    let fixed = ligaments(model.as_ref(), &nodes);
    let mut sim = crate::sim::Simulation::new(model, fixed, Default::default()).unwrap();
    let keys = path
        .iter()
        .map(|&(t, p)| Keyframe {
            t,
            position: p.into(),
        })
        .collect();
    sim.add_instrument(
        Instrument::new(
            "probe",
            InstrumentKind::Probe,
            radius,
            Trajectory::new(keys).unwrap(),
        )
        .unwrap()
        .sticking(),
    );
    let dt = 1e-3;
    let wall = Instant::now();
    let t0 = cpu_seconds(wall);
    let mut substeps = 0;
    let mut force = Vec3::ZERO;
    for _ in 0..steps {
        let r = sim.step(dt).unwrap();
        substeps = substeps.max(r.info.substeps);
        force = r.forces[0];
        if read {
            std::hint::black_box(sim.model().surface().positions.last().copied());
        }
    }
    let t1 = cpu_seconds(wall);
    Run {
        us_per_step: (t1 - t0) / steps as Real * 1e6,
        substeps,
        force,
    }
}

/// The surface vertices at the ligament nodes 3, 39, 64, found by rest position.
fn ligaments(model: &dyn Deformable, _nodes: &[u32]) -> Vec<u32> {
    let mesh = refined_liver();
    let at: Vec<Vec3> = [3, 39, 64].map(|n| mesh.vertices[n]).to_vec();
    (0..model.rest_surface().len() as u32)
        .filter(|&v| {
            at.iter()
                .any(|p| p.distance(model.rest_surface()[v as usize]) < 1e-12)
        })
        .collect()
}

/// The speed table through `Simulation`: a probe (8 mm) presses the right lobe's top 5 mm
/// (ramped over 0.16 s, held to 0.8 s), each model at its own automatic substeps and the
/// outer dt of 1 ms; the hybrids with the contact search reading only the reachable part of
/// the surface, and again with the whole surface read after every step (a display frame
/// every step: the cost before `contact_surface`). The probe's force against `fem-static`'s
/// with the probe where it ends.
#[test]
#[ignore = "speed study: prints a table"]
fn hybrid_speed_through_simulation() {
    let mesh = refined_liver();
    let data = MeshData::from_tets(&mesh);
    let radius = 0.008;
    // The topmost surface vertex within 1 cm of the right lobe's top (x, z of the press).
    let fem =
        crate::model::fem::FemStatic::new(&mesh, material(), crate::model::fem::Order::Linear)
            .unwrap();
    let (above, pressed) = probe_ends(fem.rest_surface(), radius);
    let path = [(0.0, above), (0.16, pressed)];
    let reference = {
        let static_path = [(0.0, pressed)];
        let mut run = probe_run(Box::new(fem), &static_path, radius, false);
        run.us_per_step = 0.0;
        run.force
    };
    println!(
        "refined liver: {} tetrahedra; probe {radius} m pressing 5 mm to {pressed:?}; fem-static \
         force {reference:?} N",
        mesh.tets.len()
    );
    let error = |f: Vec3| (f - reference).length() / reference.length();
    println!(
        "| model | region fraction | region tets | interface nodes | CPU us/step (contact \
         surface / whole surface every step) | substeps | speed-up vs whole StVK | force error \
         vs fem-static | build s | MB |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut whole_us = 0.0;
    for nonlinear in [true, false] {
        let build = || {
            Box::new(
                TensorMass::new(
                    &mesh,
                    material(),
                    Default::default(),
                    nonlinear,
                    Scheme::SymplecticEuler,
                )
                .unwrap(),
            )
        };
        let t0 = Instant::now();
        let model = build();
        let build_s = t0.elapsed().as_secs_f64();
        let (kind, mb) = (model.kind(), model.info().memory_bytes as Real / 1e6);
        let run = probe_run(model, &path, radius, false);
        if nonlinear {
            whole_us = run.us_per_step;
        }
        println!(
            "| whole {kind} | 1 | {} | — | {:.0} | {} | {:.2} | {:.1e} | {build_s:.2} | {mb:.1} |",
            mesh.tets.len(),
            run.us_per_step,
            run.substeps,
            whole_us / run.us_per_step,
            error(run.force)
        );
    }
    let centre = Vec3::new(0.005, 0.04, 0.005);
    for (fraction, nonlinear) in [
        (0.1, true),
        (0.15, true),
        (0.2, true),
        (0.25, true),
        (0.25, false),
        (0.5, true),
    ] {
        // `HYBRID_FRACTION=0.25` (for a profiler): that region size alone.
        if std::env::var("HYBRID_FRACTION")
            .ok()
            .and_then(|f| f.parse::<Real>().ok())
            .is_some_and(|f| f != fraction || !nonlinear)
        {
            continue;
        }
        let r = sphere_for_fraction(&mesh, centre, fraction);
        let params: toml::Table = toml::from_str(&format!(
            "cut_region = {{ sphere = {{ center = [{}, {}, {}], radius = {r} }} }}\n\
             nonlinear = {nonlinear}\nintegrator = \"symplectic-euler\"",
            centre.x, centre.y, centre.z
        ))
        .unwrap();
        let build = || {
            Hybrid::from_input(&BuildInput {
                mesh: &data,
                source: "refined liver",
                material: material(),
                params: &params,
                regions: &[],
            })
            .unwrap()
        };
        if std::env::var("HYBRID_FRACTION").is_ok() {
            // Where the time goes: the same model with a probe that never touches, and
            // pressed by prescribed vertices without `Simulation` (the study above).
            let away = [(0.0, above + Vec3::new(0.0, 0.05, 0.0))];
            let idle = probe_run(Box::new(build()), &away, radius, false);
            let mut h = build();
            let surf = h.surf_nodes.clone();
            let c = constraints(h.rest_surface(), |v| surf[v]);
            let direct = press(&mut h, 1e-3, 800, &c, false);
            println!(
                "  no contact through Simulation: {:.0} us/step; prescribed press without \
                 Simulation: {:.0} us/step",
                idle.us_per_step, direct.us_per_step
            );
        }
        let h = build();
        let (region, tets, iface) = (h.region_fraction(), h.region_tets(), h.interface_nodes());
        let info = h.info();
        let near = probe_run(Box::new(h), &path, radius, false);
        let whole = probe_run(Box::new(build()), &path, radius, true);
        println!(
            "| hybrid {} | {region:.2} | {tets} | {iface} | {:.0} / {:.0} | {} | **{:.2}** / \
             {:.2} | {:.1e} (whole surface: {:.1e}) | {:.2} | {:.1} |",
            if nonlinear { "StVK" } else { "linear" },
            near.us_per_step,
            whole.us_per_step,
            near.substeps,
            whole_us / near.us_per_step,
            whole_us / whole.us_per_step,
            error(near.force),
            error(whole.force),
            info.precompute_seconds,
            info.memory_bytes as Real / 1e6
        );
    }
}

/// One model through `Simulation` for a profiler (`valgrind --tool=callgrind`): the 25 %
/// StVK hybrid of the table above (`HYBRID_PROFILE=hybrid`, the default), the same with a
/// probe that never touches (`idle`), or whole-organ `tensor-mass-nonlinear` (`whole`);
/// `HYBRID_STEPS` outer steps (default 300).
#[test]
#[ignore = "profiling entry: one run, prints its CPU time"]
fn hybrid_probe_profile() {
    let which = std::env::var("HYBRID_PROFILE").unwrap_or_else(|_| "hybrid".into());
    let steps: usize = std::env::var("HYBRID_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300);
    let mesh = refined_liver();
    let data = MeshData::from_tets(&mesh);
    let radius = 0.008;
    let (above, pressed) = probe_ends(&mesh.vertices, radius);
    let ramp = 0.16 * (steps as Real / 800.0);
    let path = if which == "idle" {
        vec![(0.0, above + Vec3::new(0.0, 0.05, 0.0))]
    } else {
        vec![(0.0, above), (ramp, pressed)]
    };
    let model: Box<dyn Deformable> = if which == "whole" {
        Box::new(
            TensorMass::new(
                &mesh,
                material(),
                Default::default(),
                true,
                Scheme::SymplecticEuler,
            )
            .unwrap(),
        )
    } else {
        let centre = Vec3::new(0.005, 0.04, 0.005);
        let r = sphere_for_fraction(&mesh, centre, 0.25);
        let params: toml::Table = toml::from_str(&format!(
            "cut_region = {{ sphere = {{ center = [{}, {}, {}], radius = {r} }} }}\n\
             integrator = \"symplectic-euler\"",
            centre.x, centre.y, centre.z
        ))
        .unwrap();
        Box::new(
            Hybrid::from_input(&BuildInput {
                mesh: &data,
                source: "refined liver",
                material: material(),
                params: &params,
                regions: &[],
            })
            .unwrap(),
        )
    };
    let run = probe_run_steps(model, &path, radius, false, steps);
    println!(
        "{which}: {:.0} us/step, {} substeps, force {:?}",
        run.us_per_step, run.substeps, run.force
    );
}

/// The probe's path ends over the liver's top near (0, ·, 5 mm): 1 mm above the highest
/// point there, and pressed 5 mm in.
fn probe_ends(points: &[Vec3], radius: Real) -> (Vec3, Vec3) {
    let top = points
        .iter()
        .copied()
        .filter(|p| (p.x.powi(2) + (p.z - 0.005).powi(2)).sqrt() < 0.01)
        .fold(Vec3::new(0.0, Real::MIN, 0.0), |a, p| {
            if p.y > a.y { p } else { a }
        });
    (
        top + Vec3::new(0.0, radius + 0.001, 0.0),
        top + Vec3::new(0.0, radius - 0.005, 0.0),
    )
}
