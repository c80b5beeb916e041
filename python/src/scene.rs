//! Scenes and simulations: a TOML scene loaded and built, stepped or run to its end with a
//! Python callback, and the built-in demo (the liver the `tissue demo` command presses).

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};
use std::time::Instant;

use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use tissue::io::{Format, parse};
use tissue::math::Real;
use tissue::metrics;
use tissue::scene::Scene as SceneFile;
use tissue::sim::{Simulation as Sim, StepReport};

use crate::convert::{Points, Rows, err, point, points_array, rows_u32};
use crate::model::info_dict;

/// The demo's scene and mesh, as `tissue demo` has them.
const DEMO_SCENE: &str = include_str!("../../scenes/liver-probe.toml");
const DEMO_LIVER: &[u8] = include_bytes!("../../assets/meshes/liver.msh");
const DEMO_LIVER_NAME: &str = "liver.msh (built in)";
/// The demo scene's `[mesh] visual`: the smooth surface its probe touches.
const DEMO_LIVER_SMOOTH: &[u8] = include_bytes!("../../assets/meshes/liver-smooth.obj");
const DEMO_LIVER_SMOOTH_NAME: &str = "liver-smooth.obj (built in)";

/// A scene file, loaded and checked (nothing built yet).
#[pyclass(module = "tissue._native")]
pub struct Scene {
    scene: SceneFile,
    /// The demo's mesh comes from the module, not from a file.
    built_in_mesh: bool,
}

#[pymethods]
impl Scene {
    /// Reads and checks a scene file (errors name the key and line).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        Ok(Self {
            scene: SceneFile::load(&path).map_err(err)?,
            built_in_mesh: false,
        })
    }

    /// Parses scene text; relative paths start from `base_dir`.
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = PathBuf::from(".")))]
    fn from_toml(text: &str, base_dir: PathBuf) -> PyResult<Self> {
        let name = base_dir.join("scene.toml (from text)");
        Ok(Self {
            scene: SceneFile::from_toml(text, &base_dir, &name).map_err(err)?,
            built_in_mesh: false,
        })
    }

    /// The built-in demo: a probe pressing 1 cm into a liver held at three ligament nodes.
    #[staticmethod]
    fn demo() -> PyResult<Self> {
        let scene = SceneFile::from_toml(
            DEMO_SCENE,
            Path::new("scenes"),
            Path::new("liver-probe.toml (built in)"),
        )
        .map_err(err)?;
        Ok(Self {
            scene,
            built_in_mesh: true,
        })
    }

    /// The demo's scene text.
    #[staticmethod]
    fn demo_text() -> &'static str {
        DEMO_SCENE
    }

    #[getter]
    fn dt(&self) -> Real {
        self.scene.run.dt
    }

    #[getter]
    fn duration(&self) -> Real {
        self.scene.run.duration
    }

    #[getter]
    fn steps(&self) -> u64 {
        self.scene.run.step_count()
    }

    #[getter]
    fn model_kind(&self) -> &str {
        &self.scene.model_kind
    }

    #[getter]
    fn path(&self) -> PathBuf {
        self.scene.path.clone()
    }

    /// Loads the body and builds the model, supports, loads and instruments (without the
    /// GIL: a bem or condensed build takes seconds).
    fn build(&self, py: Python<'_>) -> PyResult<Simulation> {
        let sim = py
            .detach(|| {
                if self.built_in_mesh {
                    let mesh = parse(Format::Msh, DEMO_LIVER, Path::new(DEMO_LIVER_NAME))?;
                    let smooth = parse(
                        Format::Obj,
                        DEMO_LIVER_SMOOTH,
                        Path::new(DEMO_LIVER_SMOOTH_NAME),
                    )?;
                    self.scene
                        .build_with_meshes(mesh, DEMO_LIVER_NAME, Some(smooth))
                } else {
                    self.scene.build()
                }
            })
            .map_err(err)?;
        Ok(Simulation {
            inner: Mutex::new(sim),
            dt: self.scene.run.dt,
            duration: self.scene.run.duration,
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene({}, {}, dt = {} s, {} steps)",
            self.scene.path.display(),
            self.scene.model_kind,
            self.scene.run.dt,
            self.scene.run.step_count()
        )
    }
}

/// A model with its supports, loads, instruments and clock.
#[pyclass(module = "tissue._native")]
pub struct Simulation {
    inner: Mutex<Sim>,
    /// The scene's step and duration: the defaults of `step` and `run`.
    dt: Real,
    duration: Real,
}

impl Simulation {
    fn lock(&self) -> PyResult<MutexGuard<'_, Sim>> {
        self.inner
            .lock()
            .map_err(|_| err("the simulation was poisoned by a panic in another thread"))
    }
}

fn report_dict<'py>(py: Python<'py>, r: &StepReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("time", r.time)?;
    d.set_item("step", r.step)?;
    d.set_item("contacts", r.contacts.clone())?;
    d.set_item("forces", points_array(py, &r.forces)?)?;
    d.set_item("contact_iterations", r.contact_iterations)?;
    d.set_item("contact_converged", r.contact_converged)?;
    d.set_item("iterations", r.info.iterations)?;
    d.set_item("residual", r.info.residual)?;
    d.set_item("capped", r.info.capped)?;
    d.set_item("substeps", r.info.substeps)?;
    Ok(d)
}

/// What a run keeps track of while it goes.
#[derive(Default)]
struct Tally {
    max_displacement: Real,
    max_force: Real,
    capped_steps: u64,
    worst_capped_residual: Real,
    max_substeps: u32,
}

impl Tally {
    fn add(&mut self, sim: &Sim, r: &StepReport) {
        self.max_displacement = self
            .max_displacement
            .max(metrics::max_displacement(sim.model()));
        for f in &r.forces {
            self.max_force = self.max_force.max(f.length());
        }
        if r.info.capped {
            self.capped_steps += 1;
            self.worst_capped_residual = self.worst_capped_residual.max(r.info.residual);
        }
        self.max_substeps = self.max_substeps.max(r.info.substeps);
    }
}

#[pymethods]
impl Simulation {
    /// One step of `dt` s (the scene's by default), without the GIL. Returns the report:
    /// time, step, contacts and force (N) per instrument, solver figures.
    #[pyo3(signature = (dt = None))]
    fn step<'py>(&self, py: Python<'py>, dt: Option<Real>) -> PyResult<Bound<'py, PyDict>> {
        let dt = dt.unwrap_or(self.dt);
        // The lock is taken without the GIL, so a thread holding it can finish.
        let report = py.detach(|| self.lock()?.step(dt).map_err(err))?;
        report_dict(py, &report)
    }

    /// Steps to `duration` s (the scene's by default) at `dt`, calling `callback(report)`
    /// every `every` steps (and after the last). A failed step ends the run; the summary
    /// then has an `error` entry and the simulation keeps its last good state. The callback
    /// may read the simulation; an exception it raises stops the run and propagates.
    #[pyo3(signature = (callback = None, every = 1, duration = None, dt = None))]
    fn run<'py>(
        &self,
        py: Python<'py>,
        callback: Option<Bound<'py, PyAny>>,
        every: u64,
        duration: Option<Real>,
        dt: Option<Real>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let dt = dt.unwrap_or(self.dt);
        let duration = duration.unwrap_or(self.duration);
        if !(dt.is_finite() && dt > 0.0 && duration.is_finite() && duration > 0.0) {
            return Err(err(format!(
                "run: dt = {dt} s and duration = {duration} s must be positive"
            )));
        }
        let total = tissue::scene::RunSpec { duration, dt }.step_count();
        let (initial_volume, model_info) = {
            let sim = self.lock()?;
            (
                metrics::volume(sim.model()),
                info_dict(py, sim.model())?.unbind(),
            )
        };
        let mut tally = Tally::default();
        let mut error = None;
        let start = Instant::now();
        let mut done = 0;
        for k in 1..=total {
            let outcome = py.detach(|| -> PyResult<_> {
                let mut sim = self.lock()?;
                let t = sim.time();
                Ok(match sim.step(dt) {
                    Ok(r) => {
                        tally.add(&sim, &r);
                        Ok(r)
                    }
                    Err(e) => Err(format!("step {k} (from t = {t} s) failed: {e}")),
                })
            })?;
            let report = match outcome {
                Ok(r) => r,
                Err(e) => {
                    error = Some(e);
                    break;
                }
            };
            done = k;
            if let Some(cb) = &callback
                && (k == total || (every > 0 && k % every == 0))
            {
                cb.call1((report_dict(py, &report)?,))?;
            }
        }
        let wall = start.elapsed().as_secs_f64();
        let sim = self.lock()?;
        let d = PyDict::new(py);
        d.set_item("model", sim.model().kind())?;
        d.set_item("steps", done)?;
        d.set_item("dt", dt)?;
        d.set_item("time", sim.time())?;
        d.set_item("wall_seconds", wall)?;
        d.set_item("steps_per_second", done as Real / wall.max(1e-12))?;
        d.set_item("initial_volume", initial_volume)?;
        d.set_item("final_volume", metrics::volume(sim.model()))?;
        d.set_item("max_displacement", tally.max_displacement)?;
        d.set_item("max_instrument_force", tally.max_force)?;
        d.set_item(
            "final_instrument_forces",
            points_array(py, &sim.instrument_forces())?,
        )?;
        d.set_item("capped_steps", tally.capped_steps)?;
        d.set_item("worst_capped_residual", tally.worst_capped_residual)?;
        d.set_item("max_substeps", tally.max_substeps)?;
        d.set_item("model_info", model_info)?;
        d.set_item("error", error)?;
        Ok(d)
    }

    #[getter]
    fn time(&self) -> PyResult<Real> {
        Ok(self.lock()?.time())
    }

    #[getter]
    fn steps(&self) -> PyResult<u64> {
        Ok(self.lock()?.steps())
    }

    /// The scene's time step, s.
    #[getter]
    fn dt(&self) -> Real {
        self.dt
    }

    /// Force on each instrument after the last step, (k, 3) in N.
    fn instrument_forces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        points_array(py, &self.lock()?.instrument_forces())
    }

    /// Moves instrument `index` to a live position (a device, a script) from the next step
    /// on; None returns it to its scripted path.
    #[pyo3(signature = (index, position = None))]
    fn set_instrument_position(&self, index: usize, position: Option<[f64; 3]>) -> PyResult<()> {
        let p = position.map(|p| point(p, "position")).transpose()?;
        self.lock()?.set_instrument_position(index, p).map_err(err)
    }

    /// The surface now: (positions (n, 3), triangles (m, 3)).
    fn surface<'py>(&self, py: Python<'py>) -> PyResult<(Points<'py>, Rows<'py>)> {
        let sim = self.lock()?;
        let s = sim.model().surface();
        Ok((points_array(py, s.positions)?, rows_u32(py, s.triangles)?))
    }

    /// Largest displacement from rest now, m.
    fn max_displacement(&self) -> PyResult<Real> {
        Ok(metrics::max_displacement(self.lock()?.model()))
    }

    /// Enclosed volume now, m³.
    fn volume(&self) -> PyResult<Real> {
        Ok(metrics::volume(self.lock()?.model()))
    }

    /// The model's description (kind, nodes, dofs, elements, memory, build time, details).
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        info_dict(py, self.lock()?.model())
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Scene>()?;
    m.add_class::<Simulation>()
}
