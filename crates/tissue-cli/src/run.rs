//! `tissue run SCENE --out DIR`: steps a scene and writes a VTU time series with a ParaView
//! `.pvd` index, the instrument forces as CSV and a JSON summary. A failing step still leaves
//! what was produced so far (the summary then carries `"error"`).

use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::{Value, json};
use tissue::Real;
use tissue::io::{WriteOptions, write_with};
use tissue::mesh::{Field, MeshData};
use tissue::model::{Deformable, Progress};
use tissue::scene::Scene;
use tissue::sim::Simulation;

use crate::RunArgs;

pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    let scene = Scene::load(&args.scene)?;
    let sim = scene.build_with_progress(precompute_progress(args.quiet))?;
    if !args.quiet {
        let info = sim.model().info();
        eprintln!(
            "{}: {} nodes, {} elements, built in {:.3} s, {:.1} MB",
            info.kind,
            info.nodes,
            info.elements,
            info.precompute_seconds,
            info.memory_bytes as Real / 1e6
        );
        if let Some(r) = scene.meshing_report() {
            eprintln!(
                "body meshed by isosurface stuffing (tet_size {:.4e} m): {} tetrahedra in {:.2} s, \
                 dihedral {:.1}°..{:.1}°, volume {:+.2} %, Hausdorff {:.3} h",
                r.size,
                r.tets,
                r.seconds,
                r.min_dihedral_deg,
                r.max_dihedral_deg,
                100.0 * r.volume_error.unwrap_or(0.0),
                r.hausdorff / r.size
            );
            let broken = r.violations();
            if !broken.is_empty() {
                eprintln!(
                    "the tetrahedral mesh breaks a guarantee (built because tet_force = true): {}",
                    broken.join("; ")
                );
            }
            if r.input_beyond_half_size > 0.0 {
                eprintln!(
                    "{:.2} % of the input boundary lies farther than h/2 from the mesh (up to {:.2} h): \
                     features thinner than tet_size",
                    100.0 * r.input_beyond_half_size,
                    r.input_to_mesh / r.size
                );
            }
        }
    }
    if !args.quiet {
        for w in sim.contact_warnings() {
            eprintln!("warning: {w}");
        }
    }
    let outcome = execute(&scene, sim, Some(&args.out), args.quiet)?;
    if !args.quiet {
        eprintln!(
            "{} steps in {:.2} s ({:.1} steps/s); output in {}",
            outcome.steps,
            outcome.wall_seconds,
            outcome.steps as Real / outcome.wall_seconds.max(1e-12),
            args.out.display()
        );
        if outcome.capped_steps > 0 {
            eprintln!(
                "{} steps stopped at their iteration cap before their tolerance \
                 (worst residual {:.2e}; an iterative solver's, or the fine points' projection \
                 sweeps, which leave a point more than a nanometre past its plane): raise the \
                 model's iteration cap or loosen its tolerance, or use a kind that solves its \
                 points exactly (fem-semi-implicit, fem-static)",
                outcome.capped_steps, outcome.worst_residual
            );
        }
        if outcome.contact_capped_steps > 0 {
            eprintln!(
                "{} steps stopped their contact loop at its cap ([contact] max_iterations) with \
                 the contact set still moving: raise max_iterations",
                outcome.contact_capped_steps
            );
        }
        if outcome.substeps.1 > 1 {
            eprintln!(
                "substeps per step: {} to {} (the model's stability limit)",
                outcome.substeps.0, outcome.substeps.1
            );
        }
    }
    match outcome.error {
        Some(e) => anyhow::bail!(e),
        None => Ok(()),
    }
}

/// A progress display for models that pre-compute: a bar on a terminal, a line per quarter
/// otherwise (logs), nothing when quiet.
fn precompute_progress(quiet: bool) -> Progress {
    if quiet {
        return Progress::silent();
    }
    if std::io::stderr().is_terminal() {
        let bar = ProgressBar::new(1000);
        if let Ok(style) = ProgressStyle::with_template("{msg} {bar:40} {percent}% {elapsed}") {
            bar.set_style(style);
        }
        return Progress::new(move |stage, fraction| {
            // A stage reported after the build (a model's notice, e.g. `hybrid`'s region
            // covering the organ) is a line of its own: the bar is gone.
            if bar.is_finished() {
                eprintln!("{stage}");
                return;
            }
            bar.set_message(stage.to_string());
            bar.set_position((fraction * 1000.0) as u64);
            if fraction >= 1.0 {
                bar.finish_and_clear();
            }
        });
    }
    // The last stage and quarter printed: a new stage (a later build stage, or a model's
    // notice during the run) starts its quarters again.
    let quarter = Mutex::new((String::new(), -1));
    Progress::new(move |stage, fraction| {
        let q = (fraction * 4.0).floor() as i32;
        if let Ok(mut last) = quarter.lock() {
            if last.0 != stage {
                *last = (stage.to_string(), -1);
            }
            if q > last.1 {
                last.1 = q;
                eprintln!("{stage}: {:.0}%", fraction * 100.0);
            }
        }
    })
}

/// What a run measured; `error` is set when a step failed.
pub struct Outcome {
    pub model: String,
    pub steps: u64,
    pub wall_seconds: Real,
    pub initial_volume: Real,
    pub final_volume: Real,
    pub max_displacement: Real,
    pub max_instrument_force: Real,
    pub surface_vertices: usize,
    pub nodes: usize,
    pub elements: usize,
    /// Steps whose iterative solver stopped at its cap before its tolerance
    /// (`StepInfo::capped`), and the largest residual any step reported.
    pub capped_steps: u64,
    pub worst_residual: Real,
    /// Steps whose static contact loop stopped at its cap with the contact set still
    /// changing (`StepReport::contact_converged` false).
    pub contact_capped_steps: u64,
    pub error: Option<String>,
    /// Internal steps per step the model took (fewest, most; 0 when it does not say).
    pub substeps: (u32, u32),
}

/// Steps the scene to its end, writing outputs into `out` when given.
pub fn execute(
    scene: &Scene,
    mut sim: Simulation,
    out: Option<&Path>,
    quiet: bool,
) -> anyhow::Result<Outcome> {
    let writer = match out {
        Some(dir) => Some(Writer::new(dir, sim.instruments().len())?),
        None => None,
    };
    let mut writer = writer;
    let info = sim.model().info();
    let total = scene.run.step_count();
    let every = scene.output.every;
    let initial_volume = tissue::metrics::volume(sim.model());
    if let Some(w) = &mut writer {
        w.frame(&sim)?;
        w.forces(&sim);
    }
    let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
        let b = ProgressBar::new(total);
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40} {pos}/{len} steps, {per_sec}, eta {eta}")
        {
            b.set_style(style);
        }
        b
    });
    let start = Instant::now();
    let mut max_displacement: Real = 0.0;
    let mut max_force: Real = 0.0;
    let mut error = None;
    let (mut capped_steps, mut worst_residual) = (0u64, 0.0 as Real);
    let mut contact_capped_steps = 0u64;
    let mut substeps = (u32::MAX, 0);
    for k in 1..=total {
        let t = sim.time();
        match sim.step(scene.run.dt) {
            Ok(report) => {
                capped_steps += u64::from(report.info.capped);
                contact_capped_steps += u64::from(!report.contact_converged);
                worst_residual = worst_residual.max(report.info.residual);
                let s = report.info.substeps;
                substeps = (substeps.0.min(s), substeps.1.max(s));
            }
            Err(e) => {
                error = Some(format!("step {k} (from t = {t} s) failed: {e}"));
                break;
            }
        }
        max_displacement = max_displacement.max(tissue::metrics::max_displacement(sim.model()));
        for f in sim.instrument_forces() {
            max_force = max_force.max(f.length());
        }
        if let Some(w) = &mut writer {
            w.forces(&sim);
            if k == total || (every > 0 && k % every == 0) {
                w.frame(&sim)?;
            }
        }
        if let Some(b) = &bar {
            b.inc(1);
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let wall_seconds = start.elapsed().as_secs_f64();
    let outcome = Outcome {
        model: info.kind.to_string(),
        steps: sim.steps(),
        wall_seconds,
        initial_volume,
        final_volume: tissue::metrics::volume(sim.model()),
        max_displacement,
        max_instrument_force: max_force,
        surface_vertices: sim.model().surface().positions.len(),
        nodes: info.nodes,
        elements: info.elements,
        capped_steps,
        worst_residual,
        contact_capped_steps,
        error,
        substeps: (substeps.0.min(substeps.1), substeps.1),
    };
    if let Some(w) = &writer {
        w.finish(scene, &sim, &outcome)?;
    }
    Ok(outcome)
}

/// The mesh written for a frame: tetrahedra if any, else the surface, with displacements.
fn frame_mesh(model: &dyn Deformable) -> MeshData {
    let mut mesh = MeshData::default();
    let (now, rest) = match model.volume() {
        Some(v) => {
            mesh.tets = v.tets.to_vec();
            (v.positions, v.rest_positions)
        }
        None => {
            let s = model.surface();
            mesh.triangles = s.triangles.to_vec();
            (s.positions, model.rest_surface())
        }
    };
    mesh.vertices = now.to_vec();
    let values = now
        .iter()
        .zip(rest)
        .flat_map(|(p, q)| (*p - *q).to_array())
        .collect();
    mesh.point_data.push(Field {
        name: "displacement".into(),
        components: 3,
        values,
    });
    mesh
}

/// Files of one run, written as it goes.
struct Writer {
    dir: PathBuf,
    frames: Vec<(Real, String)>,
    csv: String,
}

impl Writer {
    fn new(dir: &Path, instruments: usize) -> anyhow::Result<Self> {
        let frames = dir.join("frames");
        std::fs::create_dir_all(&frames)
            .with_context(|| format!("cannot create {}", frames.display()))?;
        let mut csv = String::from("t");
        for i in 0..instruments {
            if i == 0 {
                csv.push_str(",fx,fy,fz");
            } else {
                let _ = write!(csv, ",fx_{i},fy_{i},fz_{i}");
            }
        }
        csv.push('\n');
        Ok(Self {
            dir: dir.to_path_buf(),
            frames: Vec::new(),
            csv,
        })
    }

    fn frame(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        let rel = format!("frames/frame_{:05}.vtu", self.frames.len());
        write_with(
            self.dir.join(&rel),
            &frame_mesh(sim.model()),
            &WriteOptions::default(),
        )?;
        self.frames.push((sim.time(), rel));
        Ok(())
    }

    fn forces(&mut self, sim: &Simulation) {
        let _ = write!(self.csv, "{:e}", sim.time());
        for f in sim.instrument_forces() {
            let _ = write!(self.csv, ",{:e},{:e},{:e}", f.x, f.y, f.z);
        }
        self.csv.push('\n');
    }

    fn finish(&self, scene: &Scene, sim: &Simulation, o: &Outcome) -> anyhow::Result<()> {
        tissue::io::series::write_pvd(&self.dir.join("scene.pvd"), &self.frames)?;
        let csv = self.dir.join("forces.csv");
        std::fs::write(&csv, &self.csv)
            .with_context(|| format!("cannot write {}", csv.display()))?;
        let info = sim.model().info();
        let details: serde_json::Map<String, Value> = info
            .details
            .iter()
            .map(|(k, v)| (k.clone(), Value::String(v.clone())))
            .collect();
        let mut summary = json!({
            "scene": scene.path.display().to_string(),
            "model": o.model,
            "steps": o.steps,
            "dt": scene.run.dt,
            "duration": scene.run.duration,
            "time": sim.time(),
            "wall_seconds": o.wall_seconds,
            "steps_per_second": o.steps as Real / o.wall_seconds.max(1e-12),
            "surface_vertices": o.surface_vertices,
            "initial_volume": o.initial_volume,
            "final_volume": o.final_volume,
            "max_displacement": o.max_displacement,
            "max_instrument_force": o.max_instrument_force,
            "final_instrument_forces": sim.instrument_forces().iter().map(|f| f.to_array()).collect::<Vec<_>>(),
            "fixed_vertices": sim.fixed().len(),
            "capped_steps": o.capped_steps,
            "worst_residual": o.worst_residual,
            "contact_capped_steps": o.contact_capped_steps,
            "frames": self.frames.len(),
            "substeps_min": o.substeps.0,
            "substeps_max": o.substeps.1,
            "model_info": {
                "kind": info.kind,
                "nodes": info.nodes,
                "dofs": info.dofs,
                "elements": info.elements,
                "memory_bytes": info.memory_bytes,
                "precompute_seconds": info.precompute_seconds,
            "meshing": scene.meshing_report(),
                "is_static": info.is_static,
                "details": details,
            },
        });
        // What the model said during the run that changes how to read it (`hybrid`: its
        // region came to cover the organ, so it is whole-organ tensor-mass).
        let notices: Vec<Value> = info
            .notices()
            .map(String::from)
            .chain(sim.contact_warnings())
            .map(Value::String)
            .collect();
        if let Some(map) = summary.as_object_mut() {
            map.insert("notices".into(), Value::Array(notices));
        }
        if let (Some(e), Some(map)) = (&o.error, summary.as_object_mut()) {
            map.insert("error".into(), Value::String(e.clone()));
        }
        let path = self.dir.join("summary.json");
        std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(())
    }
}
