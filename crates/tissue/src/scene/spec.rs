//! The tables of a scene file, as serde reads them: every one rejects unknown keys.

use std::path::PathBuf;

use serde::Deserialize;

use crate::interact::Keyframe;
use crate::math::Real;
use crate::sim::DEFAULT_CONTACT_ITERATIONS;

/// `[mesh]`: the file (relative to the scene) and a factor applied to its coordinates.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    pub file: PathBuf,
    #[serde(default = "one")]
    pub scale: Real,
    /// Lattice spacing (m, after `scale`) to mesh a surface-only file into tetrahedra by
    /// isosurface stuffing, for the kinds that need a volume.
    pub tet_size: Option<Real>,
    /// A finer surface (same units as `file`, scaled alike) that instruments touch, mapped
    /// onto the model's surface (`interact::fine_surface`); relative to the scene file.
    pub visual: Option<PathBuf>,
    /// Cut each `visual` triangle flat into 4^k similar ones before it is tied to the model
    /// (k ≤ `MAX_VISUAL_LEVELS`): contact points on its faces as well as its vertices, for
    /// an instrument smaller than a few of the visual surface's edges.
    pub visual_levels: Option<u32>,
}

/// The most `visual_levels` a scene may ask for (4⁴ = 256 triangles per visual triangle).
pub const MAX_VISUAL_LEVELS: u32 = 4;

fn one() -> Real {
    1.0
}

/// `[image]`: a volume image (NIfTI-1, MetaImage) turned into the voxel lattice of
/// `chainmail` or `linked-volumes`: a threshold window or label values select the voxels,
/// every `stride`-th voxel is sampled, and one face-connected part is kept (the one holding
/// `seed`, else the largest). The surface drawn is the marching surface of the voxels.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSpec {
    pub file: PathBuf,
    /// Occupied where `lo <= value <= hi` (the image's own intensity units).
    pub threshold: Option<[f32; 2]>,
    /// Occupied where the value is one of these (segmentation label images): values, or
    /// segment names of a `.seg.nrrd` (`labels = ["liver", "tumor"]`).
    pub labels: Option<Vec<crate::image::LabelRef>>,
    /// Sample every `stride`-th voxel along each axis (coarsens the lattice), default 1.
    #[serde(default = "one_step")]
    pub stride: usize,
    /// A point (m) inside the part to keep; default: the largest part.
    pub seed: Option<[Real; 3]>,
    /// Metres per header length unit, for MetaImage headers, which state no unit (default
    /// 0.001: millimetres, ITK's convention). NIfTI headers state theirs; `scale` is refused.
    pub scale: Option<Real>,
    /// Voxel spacing (m) replacing the header's (before `stride`).
    pub spacing: Option<[Real; 3]>,
    /// Centre of voxel (0, 0, 0) (m), replacing the header's origin.
    pub origin: Option<[Real; 3]>,
    /// Lattice spacing (m) to mesh the selected voxels into tetrahedra by isosurface
    /// stuffing, which makes the body fit for the tetrahedral kinds instead of the voxel ones.
    pub tet_size: Option<Real>,
    /// Gaussian σ (m) blurring the selected voxels before meshing, so that features much
    /// smaller than the tetrahedra do not count; default tet_size / 2, 0 for none.
    pub tet_smooth: Option<Real>,
    /// Cleaning of the selected voxels before meshing, as a segmentation editor would: the
    /// radius in voxels of a morphological opening then closing (default 1, 0 for none).
    pub tet_open_close: Option<usize>,
    /// Radius (m) of a closing by a ball before the other cleaning: cracks and channels of
    /// the background narrower than twice this are selected (default 0, none). It changes
    /// the input: every guarantee is then measured against the filtered voxels, and the
    /// model info says so (`cleaning.close`, `closed_voxels`).
    pub tet_close: Option<Real>,
    /// Radius (m) of an opening by a ball after `tet_close`: sheets and strands thinner than
    /// twice this are unselected (default 0, none); reported as `cleaning.open`,
    /// `opened_voxels`.
    pub tet_open: Option<Real>,
    /// Keep only the largest face-connected part of the voxels before meshing (default true).
    pub tet_largest_part: Option<bool>,
    /// Select the voxels enclosed by the selection (holes) before meshing (default true).
    pub tet_fill_holes: Option<bool>,
    /// Build the body even when its tetrahedral mesh breaks a guarantee (as `tissue mesh
    /// tetrahedralize --force`); `tissue run` prints which, and `summary.json` carries the
    /// report. Default false: such a mesh is refused.
    pub tet_force: Option<bool>,
}

impl ImageSpec {
    /// The voxel cleaning before meshing that the `tet_*` keys ask for.
    pub fn tet_cleaning(&self) -> crate::image::Cleaning {
        let d = crate::image::Cleaning::default();
        crate::image::Cleaning {
            open: self.tet_open.unwrap_or(d.open),
            close: self.tet_close.unwrap_or(d.close),
            open_close: self.tet_open_close.unwrap_or(d.open_close),
            largest_component: self.tet_largest_part.unwrap_or(d.largest_component),
            fill_holes: self.tet_fill_holes.unwrap_or(d.fill_holes),
        }
    }
}

fn one_step() -> usize {
    1
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
    /// probe | capsule | plane | box | grasper | scalpel
    pub kind: String,
    pub name: Option<String>,
    /// Tip radius (probe), shaft radius (capsule), grasp radius (grasper), in m.
    pub radius: Option<Real>,
    /// Contact of a probe, capsule, plane or box: "sliding" (the default: unilateral, Coulomb
    /// `friction`, frictionless without it) or "sticking" (a touched vertex is held at its
    /// point of the instrument).
    pub contact: Option<String>,
    /// Coulomb friction coefficient of a sliding contact (default 0: frictionless); implies
    /// `contact = "sliding"`.
    pub friction: Option<Real>,
    /// Capsule: the shaft's direction from the tip (the path point).
    pub axis: Option<[Real; 3]>,
    /// Plane: the normal pointing out of the instrument, toward the tissue.
    pub normal: Option<[Real; 3]>,
    /// Box: edge lengths along x, y, z, in m.
    pub size: Option<[Real; 3]>,
    pub path: Vec<Keyframe>,
    /// Grasper: when it closes and opens, in s.
    pub grasp_at: Option<Real>,
    pub release_at: Option<Real>,
    /// Scalpel: blade direction from the tip and blade length, in m; capsule: shaft length.
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

/// `[material]`: the body's material, and per region (`[material.regions.<name>]`) the
/// constants that differ from it. Damping stays whole-body (only `[material]` sets it).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    pub young_modulus: Real,
    pub poisson_ratio: Real,
    #[serde(default = "default_density")]
    pub density: Real,
    #[serde(default)]
    pub damping: Real,
    #[serde(default)]
    pub stiffness_damping: Real,
    /// Regions by name: a segment's name from the image's `labels`, or a tag's number (a
    /// label value of the image, a volume file's physical tag / cell tag / region
    /// attribute). Each takes the default material with the keys it gives replaced.
    #[serde(default)]
    pub regions: std::collections::BTreeMap<String, toml::Spanned<RegionMaterialSpec>>,
}

fn default_density() -> Real {
    1000.0
}

impl MaterialSpec {
    /// The default material (the regions' keys aside), unchecked.
    pub fn material(&self) -> crate::material::Material {
        crate::material::Material {
            young_modulus: self.young_modulus,
            poisson_ratio: self.poisson_ratio,
            density: self.density,
            damping: self.damping,
            stiffness_damping: self.stiffness_damping,
        }
    }
}

/// `[material.regions.<name>]`: the constants of one tagged region; those left out are the
/// default material's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionMaterialSpec {
    pub young_modulus: Option<Real>,
    pub poisson_ratio: Option<Real>,
    pub density: Option<Real>,
}

impl RegionMaterialSpec {
    /// `default` with this region's keys replaced, unchecked.
    pub fn over(&self, default: crate::material::Material) -> crate::material::Material {
        crate::material::Material {
            young_modulus: self.young_modulus.unwrap_or(default.young_modulus),
            poisson_ratio: self.poisson_ratio.unwrap_or(default.poisson_ratio),
            density: self.density.unwrap_or(default.density),
            ..default
        }
    }
}
