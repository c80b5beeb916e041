//! Scene files (TOML, DESIGN §8): a body (a `[mesh]` file, or an `[image]` for the voxel
//! models), a material, a model kind with its settings, fixed regions, loads, instruments
//! with scripted paths, and the run and output settings.
//!
//! Every table rejects unknown keys, so a typo is an error naming the key and its line.
//! Paths are relative to the scene file. `Scene::load` checks everything that can be checked
//! without the mesh or image; `Scene::build` loads the body and turns the scene into a
//! `Simulation`.

mod checks;
mod image;
mod spec;
mod tets;

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::error::{Error, IoError, SceneError};
use crate::interact::plausibility::check_instrument_size;
use crate::interact::{Loads, MappedSurface};
use crate::material::{Material, RegionMaterial};
use crate::math::{Real, Vec3};
use crate::mesh::MeshData;
use crate::model::{self, BuildInput, Deformable, KINDS, Progress};
use crate::sim::Simulation;
use crate::voxel::{VoxelGrid, marching_surface};

use checks::{check_region, check_run, known_kinds, make_instrument, region_label, select};
pub use image::IMAGE_KINDS;
use image::{Failure, check_image, check_model, image_grid, voxel_model};
pub use spec::{
    BoxSpec, ContactSpec, GravitySpec, ImageSpec, InstrumentSpec, MAX_VISUAL_LEVELS, MaterialSpec,
    MeshSpec, OutputSpec, PlaneSpec, RegionMaterialSpec, RegionSpec, RunSpec, SphereSpec,
};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    mesh: Option<MeshSpec>,
    image: Option<Spanned<ImageSpec>>,
    material: Option<MaterialSpec>,
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

/// What the body is made from: exactly one of `[mesh]` and `[image]`.
#[derive(Clone, Debug, PartialEq)]
pub enum BodySpec {
    Mesh(MeshSpec),
    /// A volume image, for the voxel kinds (`IMAGE_KINDS`).
    Image(Located<ImageSpec>),
}

/// A scene's body, loaded: the scaled mesh, or for an `[image]` the voxel grid of the part
/// kept and its marching surface (as a surface-only mesh, for sizes and drawing). With
/// `tet_size`, the mesh is the tetrahedral mesh stuffed into the surface or the voxels.
#[derive(Clone, Debug)]
pub struct Body {
    pub mesh: MeshData,
    pub grid: Option<VoxelGrid>,
    /// The file it came from, for messages.
    pub source: String,
    /// Names of the mesh's tetrahedron tags (`mesh.tet_tags`): an image's segments by their
    /// label's tag, for `[material.regions.<name>]`. Empty for a mesh file (its tags are
    /// named by number).
    pub tag_names: Vec<(String, i32)>,
}

/// `[material.regions.<name>]`: a tagged region's constants, resolved to a tag when the
/// body is built.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialRegion {
    /// The key as written: a segment's name or a tag's number.
    pub name: String,
    pub spec: RegionMaterialSpec,
}

/// A checked scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The scene file, as given (names it in messages).
    pub path: PathBuf,
    /// The directory relative paths start from.
    pub base_dir: PathBuf,
    pub body: BodySpec,
    /// `None`: take the material the mesh file carries (PLY `material`).
    pub material: Option<Material>,
    /// Per-region materials (`[material.regions.<name>]`), in name order; empty for one
    /// material.
    pub material_regions: Vec<Located<MaterialRegion>>,
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

        let body = match (raw.mesh, raw.image) {
            (Some(mesh), None) => {
                let s = mesh.scale;
                if !(s.is_finite() && s > 0.0) {
                    return Err(invalid(format!(
                        "[mesh] scale = {s}: must be finite and > 0"
                    )));
                }
                tets::check_tet_size(mesh.tet_size, &model_kind)
                    .map_err(|m| invalid(format!("[mesh] {m}")))?;
                match (mesh.visual_levels, &mesh.visual) {
                    (Some(_), None) => {
                        return Err(invalid(
                            "[mesh] visual_levels cuts the `visual` surface, but there is no \
                             `visual`: name one or remove visual_levels"
                                .into(),
                        ));
                    }
                    (Some(k), Some(_)) if k > spec::MAX_VISUAL_LEVELS => {
                        return Err(invalid(format!(
                            "[mesh] visual_levels = {k}: at most {} (each level makes four \
                             times the contact points)",
                            spec::MAX_VISUAL_LEVELS
                        )));
                    }
                    _ => {}
                }
                BodySpec::Mesh(mesh)
            }
            (None, Some(image)) => {
                let l = line(image.span());
                let image = image.into_inner();
                check_image(&image).map_err(|m| invalid(format!("line {l}: [image] {m}")))?;
                if image.tet_size.is_some() {
                    tets::check_tet_size(image.tet_size, &model_kind)
                        .map_err(|m| invalid(format!("line {l}: [image] {m}")))?;
                } else {
                    check_model(&model_kind, &params)
                        .map_err(|m| invalid(format!("line {model_line}: [model] {m}")))?;
                }
                if raw.material.is_none() {
                    return Err(invalid(format!(
                        "line {l}: an [image] body needs a [material] table (an image carries none)"
                    )));
                }
                BodySpec::Image(Located {
                    line: l,
                    value: image,
                })
            }
            (Some(_), Some(_)) => {
                return Err(invalid(
                    "has both [mesh] and [image]; the body comes from exactly one".into(),
                ));
            }
            (None, None) => {
                return Err(invalid(format!(
                    "needs [mesh] (a mesh file) or [image] (a volume image, for {})",
                    IMAGE_KINDS.join(" and ")
                )));
            }
        };
        let is_image = matches!(body, BodySpec::Image(_));
        let run_line = line(raw.run.span());
        let run = raw.run.into_inner();
        check_run(&run).map_err(|m| invalid(format!("line {run_line}: [run] {m}")))?;
        let mut material = None;
        let mut material_regions = Vec::new();
        if let Some(spec) = raw.material {
            let m = spec
                .material()
                .validated()
                .map_err(|e| invalid(format!("[material] {e}")))?;
            for (name, r) in spec.regions {
                let l = line(r.span());
                let r = r.into_inner();
                let key = format!("line {l}: [material.regions.{name}]");
                r.over(m)
                    .validated()
                    .map_err(|e| invalid(format!("{key} {e}")))?;
                if let Some(why) = model::regions_refusal(&model_kind) {
                    return Err(invalid(format!("{key}: {why}")));
                }
                if let BodySpec::Image(i) = &body
                    && i.value.labels.is_none()
                {
                    return Err(invalid(format!(
                        "{key}: the [image] is selected by `threshold`, which makes one region; \
                         select it by `labels = [...]` to mesh each label as a region of its own"
                    )));
                }
                material_regions.push(Located {
                    line: l,
                    value: MaterialRegion { name, spec: r },
                });
            }
            material = Some(m);
        }
        let gravity = raw.gravity.map_or(Vec3::ZERO, |g| Vec3::from(g.g));
        if !crate::math::is_finite_vec(gravity) {
            return Err(invalid("[gravity] g must be finite".into()));
        }

        let mut fixed = Vec::new();
        for (k, r) in raw.fixed.into_iter().enumerate() {
            let l = line(r.span());
            let r = r.into_inner();
            check_region(&r, false, is_image)
                .map_err(|m| invalid(format!("line {l}: {}: {m}", region_label("fixed", k, &r))))?;
            fixed.push(Located { line: l, value: r });
        }
        let mut loads = Vec::new();
        for (k, r) in raw.load.into_iter().enumerate() {
            let l = line(r.span());
            let r = r.into_inner();
            check_region(&r, true, is_image)
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
            body,
            material,
            material_regions,
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

    /// The body's file (`[mesh]` or `[image]` `file`), resolved against the scene's directory.
    pub fn mesh_path(&self) -> PathBuf {
        self.base_dir.join(self.body_file())
    }

    /// The body's file as the scene names it.
    fn body_file(&self) -> &Path {
        match &self.body {
            BodySpec::Mesh(m) => &m.file,
            BodySpec::Image(i) => &i.value.file,
        }
    }

    /// The `[mesh]` table, if the body is a mesh.
    pub fn mesh_spec(&self) -> Option<&MeshSpec> {
        match &self.body {
            BodySpec::Mesh(m) => Some(m),
            BodySpec::Image(_) => None,
        }
    }

    /// The report of the tetrahedral mesh this scene's body was stuffed into (`tet_size`),
    /// if it has been built in this process.
    pub fn meshing_report(&self) -> Option<crate::mesh::stuffing::MeshingReport> {
        let size = match &self.body {
            BodySpec::Mesh(m) => m.tet_size?,
            BodySpec::Image(i) => i.value.tet_size?,
        };
        let key = match &self.body {
            BodySpec::Mesh(m) => tets::surface_key(&self.mesh_path(), m.scale, size),
            BodySpec::Image(i) => tets::image_key(&self.mesh_path(), &i.value, size),
        };
        tets::cached(key?).map(|(_, r)| r)
    }

    fn tet_failure(&self, f: tets::TetFailure, table: &str, size: Real) -> Error {
        match f {
            tets::TetFailure::File(e) => e,
            tets::TetFailure::Mesh(m) => self.invalid(format!("{table} tet_size = {size}: {m}")),
        }
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
        let body = self.load_body()?;
        let material = self.material_for(&body)?;
        let mut model = self.build_model(&self.model_kind, &body, material, &self.model_params)?;
        model.set_progress(progress);
        self.build_with_model(model, &body.mesh)
    }

    /// Reads the body: the mesh file (scaled), or the image made into a voxel grid.
    pub fn load_body(&self) -> Result<Body, Error> {
        let resolved = self.mesh_path();
        let table = match self.body {
            BodySpec::Mesh(_) => "[mesh]".to_string(),
            BodySpec::Image(ref i) => format!("line {}: [image]", i.line),
        };
        if !resolved.is_file() {
            return Err(self.invalid(format!(
                "{table} file = \"{}\": no such file (looked for {})",
                self.body_file().display(),
                resolved.display()
            )));
        }
        let source = resolved.display().to_string();
        match &self.body {
            BodySpec::Mesh(m) => {
                if let Some(size) = m.tet_size {
                    let mesh = tets::surface_tets(&resolved, m.scale, size)
                        .map_err(|f| self.tet_failure(f, "[mesh]", size))?;
                    return Ok(Body {
                        mesh,
                        grid: None,
                        source,
                        tag_names: Vec::new(),
                    });
                }
                let mut mesh = crate::io::read(&resolved)?;
                for v in &mut mesh.vertices {
                    *v *= m.scale;
                }
                Ok(Body {
                    mesh,
                    grid: None,
                    source,
                    tag_names: Vec::new(),
                })
            }
            BodySpec::Image(i) => {
                let meshed = i.value.tet_size.is_some();
                let (grid, regions) =
                    image_grid(&i.value, &resolved, meshed).map_err(|f| match f {
                        Failure::Key(m) => self.invalid(format!("{table} {m} (image {source})")),
                        Failure::File(e) => e,
                    })?;
                if let Some(size) = i.value.tet_size {
                    let mut mesh = tets::image_tets(&resolved, &i.value, &grid, size)
                        .map_err(|f| self.tet_failure(f, &table, size))?;
                    // The mesher tags each tetrahedron by its voxel class; the scene names
                    // regions by label value or segment name.
                    if !regions.tags.is_empty() {
                        for t in &mut mesh.tet_tags {
                            let class = t.checked_sub(1).and_then(|c| usize::try_from(c).ok());
                            if let Some(tag) = class.and_then(|c| regions.tags.get(c)) {
                                *t = *tag;
                            }
                        }
                    }
                    return Ok(Body {
                        mesh,
                        grid: None,
                        source,
                        tag_names: regions.names,
                    });
                }
                Ok(Body {
                    mesh: MeshData::from_surface(&marching_surface(&grid)),
                    grid: Some(grid),
                    source,
                    tag_names: Vec::new(),
                })
            }
        }
    }

    /// The scene's `[material]`, else the one the mesh file carries.
    pub fn material_for(&self, body: &Body) -> Result<Material, Error> {
        match (self.material, body.mesh.material) {
            (Some(m), _) => Ok(m),
            (None, Some(r)) => Ok(Material {
                young_modulus: r.young_modulus,
                poisson_ratio: r.poisson_ratio,
                density: r.density,
                damping: 0.0,
                stiffness_damping: 0.0,
            }
            .validated()?),
            (None, None) => Err(self.invalid(format!(
                "no [material] table, and {} carries no material",
                body.source
            ))),
        }
    }

    /// A model of `kind` on the loaded body (any kind on a mesh; the voxel kinds on an
    /// image, whose grid becomes the lattice).
    pub fn build_model(
        &self,
        kind: &str,
        body: &Body,
        material: Material,
        params: &toml::Table,
    ) -> Result<Box<dyn Deformable>, Error> {
        let regions = self.region_materials(body, material, kind)?;
        match &body.grid {
            Some(grid) => {
                check_model(kind, params).map_err(|m| self.invalid(format!("[model] {m}")))?;
                voxel_model(kind, grid.clone(), material, params)
            }
            None => {
                let params = if kind == "hybrid" {
                    self.hybrid_params(params)
                } else {
                    params.clone()
                };
                model::build(
                    kind,
                    &BuildInput {
                        mesh: &body.mesh,
                        source: &body.source,
                        material,
                        params: &params,
                        regions: &regions,
                    },
                )
            }
        }
    }

    /// The scene's `[material.regions.*]` on the loaded body: each name resolved to a tag
    /// of its tetrahedra (a segment's name, else a number), the constants over `default`.
    /// Refused, naming the table's line: a name the body does not have, a tag no
    /// tetrahedron carries, a kind that takes one material.
    pub fn region_materials(
        &self,
        body: &Body,
        default: Material,
        kind: &str,
    ) -> Result<Vec<RegionMaterial>, Error> {
        let mut out = Vec::new();
        for r in &self.material_regions {
            let key = format!("line {}: [material.regions.{}]", r.line, r.value.name);
            if let Some(why) = model::regions_refusal(kind) {
                return Err(self.invalid(format!("{key}: {why}")));
            }
            let mut tags = body.mesh.tet_tags.clone();
            tags.sort_unstable();
            tags.dedup();
            let known = || {
                let mut list: Vec<String> = tags.iter().map(i32::to_string).collect();
                list.extend(body.tag_names.iter().map(|(n, t)| format!("{n} (= {t})")));
                if list.is_empty() {
                    "none: its tetrahedra carry no tags".to_string()
                } else {
                    list.join(", ")
                }
            };
            let name = r.value.name.trim();
            let tag = match body.tag_names.iter().find(|(n, _)| n == name) {
                Some((_, t)) => *t,
                None => name.parse::<i32>().map_err(|_| {
                    self.invalid(format!(
                        "{key}: {} has no region named `{name}`; its regions are {}",
                        body.source,
                        known()
                    ))
                })?,
            };
            if tags.binary_search(&tag).is_err() {
                return Err(self.invalid(format!(
                    "{key}: no tetrahedron of {} is tagged {tag}; its regions are {}",
                    body.source,
                    known()
                )));
            }
            out.push(RegionMaterial {
                name: r.value.name.clone(),
                tag,
                material: r.value.spec.over(default),
            });
        }
        Ok(out)
    }

    /// `hybrid`'s automatic region starts around the scalpels: their blades at the first
    /// keyframe (tip, middle, heel) become `auto_seeds`; with scalpels and no `cut_region`,
    /// the region is automatic.
    fn hybrid_params(&self, params: &toml::Table) -> toml::Table {
        let mut params = params.clone();
        let mut seeds = toml::value::Array::new();
        for i in &self.instruments {
            let i = &i.value;
            let (Some(first), "scalpel") = (i.path.first(), i.kind.as_str()) else {
                continue;
            };
            let tip = Vec3::from(first.position);
            let dir = Vec3::from(i.direction.unwrap_or([0.0, -1.0, 0.0])).normalize_or_zero();
            let heel = tip + dir * i.length.unwrap_or(0.0);
            for p in [tip, (tip + heel) * 0.5, heel] {
                seeds.push(toml::Value::Array(
                    p.to_array()
                        .iter()
                        .map(|&c| toml::Value::Float(c))
                        .collect(),
                ));
            }
        }
        if seeds.is_empty() {
            return params;
        }
        params
            .entry("cut_region")
            .or_insert_with(|| toml::Value::String("auto".into()));
        params
            .entry("auto_seeds")
            .or_insert(toml::Value::Array(seeds));
        params
    }

    /// Builds the simulation from a mesh already loaded (unscaled, scaled here by `[mesh]`
    /// `scale`); `source` names it. The scene's kind is built on it as on a `[mesh]` body.
    /// A `[mesh] visual` the scene names is read from its file.
    pub fn build_with_mesh(&self, mesh: MeshData, source: &str) -> Result<Simulation, Error> {
        self.build_with_meshes(mesh, source, None)
    }

    /// `build_with_mesh` with the `[mesh] visual` surface loaded too (unscaled, as read; used
    /// when the scene names one), for a scene whose files are built into the program (the
    /// demo) rather than beside it.
    pub fn build_with_meshes(
        &self,
        mut mesh: MeshData,
        source: &str,
        visual: Option<MeshData>,
    ) -> Result<Simulation, Error> {
        let scale = self.mesh_spec().map_or(1.0, |m| m.scale);
        for v in &mut mesh.vertices {
            *v *= scale;
        }
        let body = Body {
            mesh,
            grid: None,
            source: source.to_string(),
            tag_names: Vec::new(),
        };
        let material = self.material_for(&body)?;
        let model = self.build_model(&self.model_kind, &body, material, &self.model_params)?;
        self.build_around(model, &body.mesh, visual)
    }

    /// Builds the simulation around a model already built from `mesh` (scaled): regions,
    /// loads and instruments come from the scene. `mesh` resolves `file_vertices` and `file`.
    pub fn build_with_model(
        &self,
        model: Box<dyn Deformable>,
        mesh: &MeshData,
    ) -> Result<Simulation, Error> {
        self.build_around(model, mesh, None)
    }

    /// `build_with_model`, with the `[mesh] visual` surface given (unscaled) or read.
    fn build_around(
        &self,
        model: Box<dyn Deformable>,
        mesh: &MeshData,
        visual_mesh: Option<MeshData>,
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
        // The stiffest region bounds the plausible forces.
        let stiffest = self
            .material_regions
            .iter()
            .filter_map(|r| r.value.spec.young_modulus)
            .fold(None, |a: Option<Real>, e| Some(a.map_or(e, |a| a.max(e))));
        let young = (self.material.map(|m| m.young_modulus))
            .or(mesh.material.map(|m| m.young_modulus))
            .map(|e| stiffest.map_or(e, |s| s.max(e)));
        if let Some(e) = young {
            let bounds = sim.plausibility().clone().with_young_modulus(e);
            sim.set_plausibility(bounds);
        }
        let size = sim.plausibility().size;
        for (k, i) in self.instruments.iter().enumerate() {
            let inst = make_instrument(&i.value, k)
                .and_then(|inst| check_instrument_size(&inst, size).map(|()| inst))
                .map_err(|m| {
                    self.invalid(format!("line {}: [[instrument]] {}: {m}", i.line, k + 1))
                })?;
            sim.add_instrument(inst);
        }
        if let Some(visual) = self.mesh_spec().and_then(|m| m.visual.as_ref()) {
            let surface = self.fine_surface(visual, visual_mesh, sim.model())?;
            sim.set_fine_surface(surface)?;
        }
        Ok(sim)
    }

    /// `[mesh] visual`: the fine surface (`given`, or read from its file), scaled like the
    /// body, and tied to the model's rest surface.
    fn fine_surface(
        &self,
        visual: &Path,
        given: Option<MeshData>,
        model: &dyn Deformable,
    ) -> Result<MappedSurface, Error> {
        let named =
            |m: String| self.invalid(format!("[mesh] visual = \"{}\": {m}", visual.display()));
        let mut mesh = match given {
            Some(mesh) => mesh,
            None => {
                let path = self.base_dir.join(visual);
                if !path.is_file() {
                    return Err(named(format!(
                        "no such file (looked for {})",
                        path.display()
                    )));
                }
                crate::io::read(&path)?
            }
        };
        if mesh.triangles.is_empty() {
            return Err(named("the file has no triangles".into()));
        }
        let scale = self.mesh_spec().map_or(1.0, |m| m.scale);
        for v in &mut mesh.vertices {
            *v *= scale;
        }
        let levels = self.mesh_spec().and_then(|m| m.visual_levels).unwrap_or(0);
        if levels > 0 {
            // The visual surface cut flat: the same shape, with points on its faces.
            let cut = MappedSurface::subdivided(&mesh.vertices, &mesh.triangles, 1 << levels)
                .ok_or_else(|| named("a triangle names a vertex the file does not have".into()))?;
            (mesh.vertices, mesh.triangles) = (cut.rest, cut.triangles);
        }
        let mut tied = MappedSurface::new(
            mesh.vertices,
            mesh.triangles,
            model.rest_surface(),
            model.surface().triangles,
        )
        .ok_or_else(|| named("the model has no surface triangles to tie it to".into()))?;
        tied.levels = levels;
        Ok(tied)
    }
}
