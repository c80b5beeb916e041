//! Scene files (TOML, DESIGN §8): a mesh, a material, a model kind with its settings, fixed
//! regions, loads, instruments with scripted paths, and the run and output settings.
//!
//! Every table rejects unknown keys, so a typo is an error naming the key and its line.
//! Paths are relative to the scene file. `Scene::load` checks everything that can be checked
//! without the mesh; `Scene::build` loads the mesh and turns the scene into a `Simulation`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::error::{Error, IoError, SceneError};
use crate::interact::{Instrument, InstrumentKind, Keyframe, Loads, Region, Trajectory};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::MeshData;
use crate::model::{self, BuildInput, Deformable, KINDS};
use crate::sim::{DEFAULT_CONTACT_ITERATIONS, Simulation};

/// `[mesh]`: the file (relative to the scene) and a factor applied to its coordinates.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    pub file: PathBuf,
    #[serde(default = "one")]
    pub scale: Real,
}

fn one() -> Real {
    1.0
}

/// `[[fixed]]` or `[[load]]`: exactly one selector, plus `force` (N, total) for a load.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// A name for messages.
    pub name: Option<String>,
    #[serde(rename = "box")]
    pub aabb: Option<BoxSpec>,
    pub sphere: Option<SphereSpec>,
    pub plane: Option<PlaneSpec>,
    /// Surface vertex indices.
    pub indices: Option<Vec<u32>>,
    /// Vertex indices of the mesh file, found on the surface by position.
    pub file_vertices: Option<Vec<u32>>,
    /// `true`: the vertices the mesh file marks fixed.
    pub file: Option<bool>,
    /// Total force on the region, spread equally over its vertices (loads only), in N.
    pub force: Option<[Real; 3]>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    pub min: [Real; 3],
    pub max: [Real; 3],
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereSpec {
    pub center: [Real; 3],
    pub radius: Real,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    pub point: [Real; 3],
    pub normal: [Real; 3],
    #[serde(default)]
    pub tolerance: Real,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GravitySpec {
    pub g: [Real; 3],
}

/// `[[instrument]]`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstrumentSpec {
    /// probe | grasper | scalpel
    pub kind: String,
    pub name: Option<String>,
    /// Tip radius (probe), grasp radius (grasper), in m.
    pub radius: Option<Real>,
    pub path: Vec<Keyframe>,
    /// Grasper: when it closes and opens, in s.
    pub grasp_at: Option<Real>,
    pub release_at: Option<Real>,
    /// Scalpel: blade direction from the tip and blade length, in m.
    pub direction: Option<[Real; 3]>,
    pub length: Option<Real>,
}

#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    pub duration: Real,
    pub dt: Real,
}

impl RunSpec {
    /// Steps of length `dt` that cover `duration` (the last one may end a little after it).
    pub fn step_count(&self) -> u64 {
        ((self.duration / self.dt) * (1.0 - 1e-12)).ceil().max(1.0) as u64
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// A frame every this many steps (0: only the first and the last).
    #[serde(default = "ten")]
    pub every: u64,
}

impl Default for OutputSpec {
    fn default() -> Self {
        Self { every: ten() }
    }
}

fn ten() -> u64 {
    10
}

#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Cap of solves per step in the static contact loop.
    #[serde(default = "default_iterations")]
    pub max_iterations: usize,
}

impl Default for ContactSpec {
    fn default() -> Self {
        Self {
            max_iterations: default_iterations(),
        }
    }
}

fn default_iterations() -> usize {
    DEFAULT_CONTACT_ITERATIONS
}

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
        let resolved = self.mesh_path();
        if !resolved.is_file() {
            return Err(self.invalid(format!(
                "[mesh] file = \"{}\": no such file (looked for {})",
                self.mesh.file.display(),
                resolved.display()
            )));
        }
        let mesh = crate::io::read(&resolved)?;
        self.build_with_mesh(mesh, &resolved.display().to_string())
    }

    /// Builds the simulation from a mesh already loaded (unscaled); `source` names it.
    pub fn build_with_mesh(&self, mut mesh: MeshData, source: &str) -> Result<Simulation, Error> {
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
        let model = model::build(
            &self.model_kind,
            &BuildInput {
                mesh: &mesh,
                source,
                material,
                params: &self.model_params,
            },
        )?;
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

fn known_kinds() -> String {
    KINDS.iter().map(|k| k.name).collect::<Vec<_>>().join(", ")
}

fn check_run(run: &RunSpec) -> Result<(), String> {
    if !(run.duration.is_finite() && run.duration > 0.0) {
        return Err(format!(
            "duration = {}: must be finite and > 0 s",
            run.duration
        ));
    }
    if !(run.dt.is_finite() && run.dt > 0.0) {
        return Err(format!("dt = {}: must be finite and > 0 s", run.dt));
    }
    if run.dt > run.duration {
        return Err(format!(
            "dt = {} s is longer than duration = {} s",
            run.dt, run.duration
        ));
    }
    if run.duration / run.dt > 1e9 {
        return Err(format!(
            "dt = {}: more than 1e9 steps in duration = {}",
            run.dt, run.duration
        ));
    }
    Ok(())
}

fn region_label(table: &str, k: usize, r: &RegionSpec) -> String {
    match &r.name {
        Some(n) => format!("[[{table}]] {} (`{n}`)", k + 1),
        None => format!("[[{table}]] {}", k + 1),
    }
}

fn check_region(r: &RegionSpec, is_load: bool) -> Result<(), String> {
    let set = [
        ("box", r.aabb.is_some()),
        ("sphere", r.sphere.is_some()),
        ("plane", r.plane.is_some()),
        ("indices", r.indices.is_some()),
        ("file_vertices", r.file_vertices.is_some()),
        ("file", r.file == Some(true)),
    ];
    let given: Vec<&str> = set.iter().filter(|s| s.1).map(|s| s.0).collect();
    if given.len() != 1 {
        return Err(format!(
            "needs exactly one of box, sphere, plane, indices, file_vertices, file = true; found {}",
            if given.is_empty() {
                "none".to_string()
            } else {
                given.join(", ")
            }
        ));
    }
    let finite = |v: &[Real]| v.iter().all(|x| x.is_finite());
    if let Some(b) = &r.aabb
        && !(finite(&b.min) && finite(&b.max))
    {
        return Err("box bounds must be finite".into());
    }
    if let Some(s) = &r.sphere
        && !(finite(&s.center) && s.radius.is_finite() && s.radius >= 0.0)
    {
        return Err("sphere center and radius must be finite, radius >= 0".into());
    }
    if let Some(p) = &r.plane
        && !(finite(&p.point) && finite(&p.normal) && p.tolerance.is_finite())
    {
        return Err("plane point, normal and tolerance must be finite".into());
    }
    match (is_load, r.force) {
        (true, None) => Err("a load needs `force` (total, in N)".into()),
        (true, Some(f)) if !finite(&f) => Err("force must be finite".into()),
        (false, Some(_)) => Err("`force` belongs in a [[load]], not a [[fixed]] region".into()),
        _ => Ok(()),
    }
}

/// Surface vertices a region selects; errors name indices that do not exist or are interior.
fn select(model: &dyn Deformable, mesh: &MeshData, r: &RegionSpec) -> Result<Vec<u32>, String> {
    let rest = model.rest_surface();
    if let Some(b) = &r.aabb {
        return Ok(Region::Box {
            min: b.min,
            max: b.max,
        }
        .select(rest));
    }
    if let Some(s) = &r.sphere {
        return Ok(Region::Sphere {
            center: s.center,
            radius: s.radius,
        }
        .select(rest));
    }
    if let Some(p) = &r.plane {
        return Ok(Region::Plane {
            point: p.point,
            normal: p.normal,
            tolerance: p.tolerance,
        }
        .select(rest));
    }
    if let Some(ids) = &r.indices {
        let region = Region::Indices(ids.clone());
        if let Some(bad) = region.out_of_range(rest.len()).first() {
            return Err(format!(
                "surface vertex {bad} does not exist: the surface has {} vertices",
                rest.len()
            ));
        }
        return Ok(region.select(rest));
    }
    let (ids, what) = match (&r.file_vertices, r.file) {
        (Some(ids), _) => (ids.clone(), "file vertex"),
        (None, Some(true)) => (
            mesh.fixed_vertices.clone(),
            "vertex marked fixed in the file,",
        ),
        _ => return Ok(Vec::new()),
    };
    // The surface is built from the file's vertices without moving them, so an exact
    // position match finds a file vertex on the surface.
    let key = |p: Vec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    let on_surface: HashMap<[u64; 3], u32> = rest
        .iter()
        .enumerate()
        .map(|(i, &p)| (key(p), i as u32))
        .collect();
    let mut out = Vec::with_capacity(ids.len());
    for i in ids {
        let p = mesh.vertices.get(i as usize).ok_or_else(|| {
            format!(
                "{what} {i} does not exist: the file has {} vertices",
                mesh.vertices.len()
            )
        })?;
        let s = on_surface
            .get(&key(*p))
            .ok_or_else(|| format!("{what} {i} is not on the surface (it is interior)"))?;
        out.push(*s);
    }
    out.sort_unstable();
    out.dedup();
    Ok(out)
}

/// The instrument an `[[instrument]]` entry describes, or why it is not one.
fn make_instrument(i: &InstrumentSpec, k: usize) -> Result<Instrument, String> {
    let trajectory = Trajectory::new(i.path.clone()).map_err(|e| format!("path: {e}"))?;
    let forbid = |key: &str, present: bool, kind: &str| {
        if present {
            Err(format!("`{key}` does not apply to a {kind}"))
        } else {
            Ok(())
        }
    };
    let need_radius = || {
        i.radius
            .ok_or_else(|| format!("a {} needs `radius` (m)", i.kind))
    };
    let (kind, radius) = match i.kind.as_str() {
        "probe" => {
            forbid("grasp_at", i.grasp_at.is_some(), "probe")?;
            forbid("release_at", i.release_at.is_some(), "probe")?;
            forbid("direction", i.direction.is_some(), "probe")?;
            forbid("length", i.length.is_some(), "probe")?;
            (InstrumentKind::Probe, need_radius()?)
        }
        "grasper" => {
            forbid("direction", i.direction.is_some(), "grasper")?;
            forbid("length", i.length.is_some(), "grasper")?;
            let grasp_at = i.grasp_at.ok_or("a grasper needs `grasp_at` (s)")?;
            (
                InstrumentKind::Grasper {
                    grasp_at,
                    release_at: i.release_at,
                },
                need_radius()?,
            )
        }
        "scalpel" => {
            forbid("grasp_at", i.grasp_at.is_some(), "scalpel")?;
            forbid("release_at", i.release_at.is_some(), "scalpel")?;
            let direction = i.direction.ok_or("a scalpel needs `direction`")?;
            let length = i.length.ok_or("a scalpel needs `length` (m)")?;
            (
                InstrumentKind::Scalpel {
                    direction: Vec3::from(direction),
                    length,
                },
                i.radius.unwrap_or(length),
            )
        }
        other => {
            return Err(format!(
                "unknown instrument kind `{other}`; known: probe, grasper, scalpel"
            ));
        }
    };
    let name = i
        .name
        .clone()
        .unwrap_or_else(|| format!("{}{}", i.kind, k + 1));
    Instrument::new(name, kind, radius, trajectory).map_err(|e| e.to_string())
}
