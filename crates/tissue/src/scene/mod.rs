//! Scene files (TOML, DESIGN §8): a mesh, a material, a model kind with its settings, fixed
//! regions, loads, instruments with scripted paths, and the run and output settings.
//!
//! Every table rejects unknown keys, so a typo is an error naming the key and its line.
//! Paths are relative to the scene file. `Scene::load` checks everything that can be checked
//! without the mesh; `Scene::build` loads the mesh and turns the scene into a `Simulation`.

mod checks;
mod spec;

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::error::{Error, IoError, SceneError};
use crate::interact::Loads;
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::MeshData;
use crate::model::{self, BuildInput, Deformable, KINDS, Progress};
use crate::sim::Simulation;

use checks::{check_region, check_run, known_kinds, make_instrument, region_label, select};
pub use spec::{
    BoxSpec, ContactSpec, GravitySpec, InstrumentSpec, MeshSpec, OutputSpec, PlaneSpec, RegionSpec,
    RunSpec, SphereSpec,
};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    mesh: MeshSpec,
    material: Option<Material>,
    model: Spanned<toml::Table>,
    #[serde(default)]
    fixed: Vec<Spanned<RegionSpec>>,
    gravity: Option<GravitySpec>,
    #[serde(default)]
    load: Vec<Spanned<RegionSpec>>,
    #[serde(default)]
    instrument: Vec<Spanned<InstrumentSpec>>,
    run: Spanned<RunSpec>,
    #[serde(default)]
    output: OutputSpec,
    #[serde(default)]
    contact: ContactSpec,
}

/// A value and the 1-based line of the scene file where it starts.
#[derive(Clone, Debug, PartialEq)]
pub struct Located<T> {
    pub line: usize,
    pub value: T,
}

/// A checked scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The scene file, as given (names it in messages).
    pub path: PathBuf,
    /// The directory relative paths start from.
    pub base_dir: PathBuf,
    pub mesh: MeshSpec,
    /// `None`: take the material the mesh file carries (PLY `material`).
    pub material: Option<Material>,
    pub model_kind: String,
    /// `[model]` without `kind`, for the model's own settings.
    pub model_params: toml::Table,
    pub fixed: Vec<Located<RegionSpec>>,
    pub gravity: Vec3,
    pub loads: Vec<Located<RegionSpec>>,
    pub instruments: Vec<Located<InstrumentSpec>>,
    pub run: RunSpec,
    pub output: OutputSpec,
    pub contact: ContactSpec,
}

impl Scene {
    /// Reads and checks a scene file.
    pub fn load(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|e| IoError::os(path, "read the scene file", e))?;
        let base = path.parent().unwrap_or(Path::new("")).to_path_buf();
        Scene::from_toml(&text, &base, path)
    }

    /// Parses and checks scene text; `name` names it in messages, `base_dir` resolves paths.
    pub fn from_toml(text: &str, base_dir: &Path, name: &Path) -> Result<Scene, SceneError> {
        let invalid = |message: String| SceneError::Invalid {
            path: name.to_path_buf(),
            message,
        };
        let line = |span: std::ops::Range<usize>| {
            text.get(..span.start)
                .map_or(1, |s| s.matches('\n').count() + 1)
        };
        let raw: RawScene =
            toml::from_str(text).map_err(|e| invalid(e.to_string().trim_end().to_string()))?;

        let model_line = line(raw.model.span());
        let mut params = raw.model.into_inner();
        let model_kind = match params.remove("kind") {
            Some(toml::Value::String(k)) => k,
            Some(other) => {
                return Err(invalid(format!(
                    "line {model_line}: [model] kind must be a string, found {other}"
                )));
            }
            None => {
                return Err(invalid(format!(
                    "line {model_line}: [model] needs `kind`; built in: {}",
                    known_kinds()
                )));
            }
        };
        if !KINDS.iter().any(|k| k.name == model_kind) {
            return Err(invalid(format!(
                "line {model_line}: unknown model kind `{model_kind}`; built in: {}",
                known_kinds()
            )));
        }

        let s = raw.mesh.scale;
        if !(s.is_finite() && s > 0.0) {
            return Err(invalid(format!(
                "[mesh] scale = {s}: must be finite and > 0"
            )));
        }
        let run_line = line(raw.run.span());
        let run = raw.run.into_inner();
        check_run(&run).map_err(|m| invalid(format!("line {run_line}: [run] {m}")))?;
        if let Some(m) = raw.material {
            m.validated()
                .map_err(|e| invalid(format!("[material] {e}")))?;
        }
        let gravity = raw.gravity.map_or(Vec3::ZERO, |g| Vec3::from(g.g));
        if !crate::math::is_finite_vec(gravity) {
            return Err(invalid("[gravity] g must be finite".into()));
        }

        let mut fixed = Vec::new();
        for (k, r) in raw.fixed.into_iter().enumerate() {
            let l = line(r.span());
            let r = r.into_inner();
            check_region(&r, false)
                .map_err(|m| invalid(format!("line {l}: {}: {m}", region_label("fixed", k, &r))))?;
            fixed.push(Located { line: l, value: r });
        }
        let mut loads = Vec::new();
        for (k, r) in raw.load.into_iter().enumerate() {
            let l = line(r.span());
            let r = r.into_inner();
            check_region(&r, true)
                .map_err(|m| invalid(format!("line {l}: {}: {m}", region_label("load", k, &r))))?;
            loads.push(Located { line: l, value: r });
        }
        let mut instruments = Vec::new();
        for (k, i) in raw.instrument.into_iter().enumerate() {
            let l = line(i.span());
            let i = i.into_inner();
            make_instrument(&i, k)
                .map_err(|m| invalid(format!("line {l}: [[instrument]] {}: {m}", k + 1)))?;
            instruments.push(Located { line: l, value: i });
        }

        Ok(Scene {
            path: name.to_path_buf(),
            base_dir: base_dir.to_path_buf(),
            mesh: raw.mesh,
            material: raw.material,
            model_kind,
            model_params: params,
            fixed,
            gravity,
            loads,
            instruments,
            run,
            output: raw.output,
            contact: raw.contact,
        })
    }

    /// The mesh file as the scene names it, resolved against the scene's directory.
    pub fn mesh_path(&self) -> PathBuf {
        self.base_dir.join(&self.mesh.file)
    }

    fn invalid(&self, message: String) -> Error {
        SceneError::Invalid {
            path: self.path.clone(),
            message,
        }
        .into()
    }

    /// Loads the mesh and builds the simulation.
    pub fn build(&self) -> Result<Simulation, Error> {
        self.build_with_progress(Progress::silent())
    }

    /// Like `build`; models that pre-compute report how far they have gone to `progress`.
    pub fn build_with_progress(&self, progress: Progress) -> Result<Simulation, Error> {
        let resolved = self.mesh_path();
        if !resolved.is_file() {
            return Err(self.invalid(format!(
                "[mesh] file = \"{}\": no such file (looked for {})",
                self.mesh.file.display(),
                resolved.display()
            )));
        }
        let mesh = crate::io::read(&resolved)?;
        self.build_from(mesh, &resolved.display().to_string(), progress)
    }

    /// Builds the simulation from a mesh already loaded (unscaled); `source` names it.
    pub fn build_with_mesh(&self, mesh: MeshData, source: &str) -> Result<Simulation, Error> {
        self.build_from(mesh, source, Progress::silent())
    }

    fn build_from(
        &self,
        mut mesh: MeshData,
        source: &str,
        progress: Progress,
    ) -> Result<Simulation, Error> {
        for v in &mut mesh.vertices {
            *v *= self.mesh.scale;
        }
        let material = match (self.material, mesh.material) {
            (Some(m), _) => m,
            (None, Some(r)) => Material {
                young_modulus: r.young_modulus,
                poisson_ratio: r.poisson_ratio,
                density: r.density,
                damping: 0.0,
                stiffness_damping: 0.0,
            }
            .validated()?,
            (None, None) => {
                return Err(self.invalid(format!(
                    "no [material] table, and {source} carries no material"
                )));
            }
        };
        let mut model = model::build(
            &self.model_kind,
            &BuildInput {
                mesh: &mesh,
                source,
                material,
                params: &self.model_params,
            },
        )?;
        model.set_progress(progress);
        self.build_with_model(model, &mesh)
    }

    /// Builds the simulation around a model already built from `mesh` (scaled): regions,
    /// loads and instruments come from the scene. `mesh` resolves `file_vertices` and `file`.
    pub fn build_with_model(
        &self,
        model: Box<dyn Deformable>,
        mesh: &MeshData,
    ) -> Result<Simulation, Error> {
        let mut fixed = Vec::new();
        for (k, r) in self.fixed.iter().enumerate() {
            let label = region_label("fixed", k, &r.value);
            let ids = select(model.as_ref(), mesh, &r.value)
                .map_err(|m| self.invalid(format!("line {}: {label}: {m}", r.line)))?;
            if ids.is_empty() {
                return Err(self.invalid(format!(
                    "line {}: {label} selects no surface vertex",
                    r.line
                )));
            }
            fixed.extend(ids);
        }
        fixed.sort_unstable();
        fixed.dedup();
        let mut point_loads = Vec::new();
        for (k, r) in self.loads.iter().enumerate() {
            let label = region_label("load", k, &r.value);
            let ids = select(model.as_ref(), mesh, &r.value)
                .map_err(|m| self.invalid(format!("line {}: {label}: {m}", r.line)))?;
            if ids.is_empty() {
                return Err(self.invalid(format!(
                    "line {}: {label} selects no surface vertex",
                    r.line
                )));
            }
            let total = Vec3::from(r.value.force.unwrap_or_default());
            let each = total / ids.len() as Real;
            point_loads.extend(ids.into_iter().map(|v| (v, each)));
        }
        let loads = Loads {
            gravity: self.gravity,
            point_loads,
        };
        let mut sim = Simulation::new(model, fixed, loads)?;
        sim.set_max_contact_iterations(self.contact.max_iterations);
        for (k, i) in self.instruments.iter().enumerate() {
            let inst = make_instrument(&i.value, k).map_err(|m| {
                self.invalid(format!("line {}: [[instrument]] {}: {m}", i.line, k + 1))
            })?;
            sim.add_instrument(inst);
        }
        Ok(sim)
    }
}
