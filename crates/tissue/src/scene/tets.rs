//! `tet_size`: a surface `[mesh]` or an `[image]` body stuffed into tetrahedra when the
//! scene is built (`mesh::stuffing`), for the kinds that need a volume. Results are cached in
//! the process by a hash of the input file's bytes and the settings, so building the same
//! scene again (a viewer reset, a comparison run) does not mesh again.

use std::hash::{Hash, Hasher};
use std::path::Path;
use std::sync::Mutex;

use rustc_hash::FxHasher;

use super::image::IMAGE_KINDS;
use super::spec::ImageSpec;
use crate::error::Error;
use crate::math::Real;
use crate::mesh::MeshData;
use crate::mesh::stuffing::{Domain, ImageDomain, MeshingReport, Stuffed, SurfaceDomain, stuff};
use crate::model::Progress;
use crate::voxel::VoxelGrid;

/// Bumped when the mesher's output changes, so stale entries are never reused.
const MESHER_VERSION: u64 = 8;
/// Meshes kept in the cache (oldest dropped first).
const CACHE_ENTRIES: usize = 8;

type Entry = (u64, MeshData, MeshingReport);
static CACHE: Mutex<Vec<Entry>> = Mutex::new(Vec::new());

pub(super) enum TetFailure {
    File(Error),
    /// What is wrong with the meshing, for a message naming the table and key.
    Mesh(String),
}

/// `tet_size` must be a positive length, and only for the kinds that take tetrahedra.
pub(super) fn check_tet_size(size: Option<Real>, kind: &str) -> Result<(), String> {
    let Some(h) = size else { return Ok(()) };
    if !(h.is_finite() && h > 0.0) {
        return Err(format!("tet_size = {h}: must be a length > 0 in m"));
    }
    if IMAGE_KINDS.contains(&kind) {
        return Err(format!(
            "tet_size meshes the body into tetrahedra, but `{kind}` builds on voxels; remove \
             tet_size"
        ));
    }
    Ok(())
}

fn file_hash(path: &Path, h: &mut FxHasher) -> Option<()> {
    let bytes = std::fs::read(path).ok()?;
    bytes.hash(h);
    Some(())
}

/// Cache key of a surface file meshed at `size` after `scale`.
pub(super) fn surface_key(path: &Path, scale: Real, size: Real) -> Option<u64> {
    let mut h = FxHasher::default();
    (MESHER_VERSION, "surface", scale.to_bits(), size.to_bits()).hash(&mut h);
    file_hash(path, &mut h)?;
    Some(h.finish())
}

/// Cache key of an image meshed at `size` with the voxel selection of `spec`.
pub(super) fn image_key(path: &Path, spec: &ImageSpec, size: Real) -> Option<u64> {
    let mut h = FxHasher::default();
    (MESHER_VERSION, "image", format!("{spec:?}"), size.to_bits()).hash(&mut h);
    file_hash(path, &mut h)?;
    // A MetaImage keeps its voxels in a second file.
    let raw = path.with_extension("raw");
    if raw != path {
        let _ = file_hash(&raw, &mut h);
    }
    Some(h.finish())
}

/// The cached mesh and report of `key`, if any.
pub(super) fn cached(key: u64) -> Option<(MeshData, MeshingReport)> {
    let cache = CACHE.lock().ok()?;
    cache
        .iter()
        .find(|e| e.0 == key)
        .map(|e| (e.1.clone(), e.2.clone()))
}

fn remember(key: u64, mesh: &MeshData, report: &MeshingReport) {
    if let Ok(mut cache) = CACHE.lock() {
        if cache.len() >= CACHE_ENTRIES {
            cache.remove(0);
        }
        cache.push((key, mesh.clone(), report.clone()));
    }
}

/// Stuffs a domain and refuses a mesh that breaks a guarantee, saying what to change,
/// unless `force` (the report then carries the violations to whoever prints it).
fn mesh_domain(
    domain: &dyn Domain,
    size: Real,
    force: bool,
) -> Result<(MeshData, MeshingReport), TetFailure> {
    let Stuffed { mesh, tags, report } =
        stuff(domain, size, &Progress::silent()).map_err(|e| TetFailure::Mesh(e.to_string()))?;
    let v = report.violations();
    if !v.is_empty() && !force {
        return Err(TetFailure::Mesh(format!(
            "the tetrahedral mesh ({} tetrahedra) breaks a guarantee: {}; a smaller tet_size \
             follows the shape more closely (tet_force = true builds it anyway)",
            report.tets,
            v.join("; ")
        )));
    }
    let data = MeshData {
        vertices: mesh.vertices,
        tets: mesh.tets,
        tet_tags: tags,
        ..MeshData::default()
    };
    Ok((data, report))
}

/// The tetrahedral mesh of the closed surface in `path` (coordinates times `scale`).
pub(super) fn surface_tets(path: &Path, scale: Real, size: Real) -> Result<MeshData, TetFailure> {
    let key = surface_key(path, scale, size);
    if let Some((mesh, _)) = key.and_then(cached) {
        return Ok(mesh);
    }
    let mut file = crate::io::read(path).map_err(|e| TetFailure::File(e.into()))?;
    if file.has_volume() {
        return Err(TetFailure::Mesh(format!(
            "{} already holds tetrahedra; remove tet_size to simulate on them",
            path.display()
        )));
    }
    for v in &mut file.vertices {
        *v *= scale;
    }
    let surface = file
        .surface_mesh()
        .map_err(|e| TetFailure::Mesh(format!("{}: {e}", path.display())))?;
    let domain = SurfaceDomain::new(&surface).map_err(|e| {
        TetFailure::Mesh(format!(
            "{}: {e}; only a closed surface has an inside",
            path.display()
        ))
    })?;
    let (mesh, report) = mesh_domain(&domain, size, false)?;
    if let Some(k) = key {
        remember(k, &mesh, &report);
    }
    Ok(mesh)
}

/// The tetrahedral mesh of the voxels `grid` kept from the image at `path`.
pub(super) fn image_tets(
    path: &Path,
    spec: &ImageSpec,
    grid: &VoxelGrid,
    size: Real,
) -> Result<MeshData, TetFailure> {
    let key = image_key(path, spec, size);
    if let Some((mesh, _)) = key.and_then(cached) {
        return Ok(mesh);
    }
    let sigma = spec
        .tet_smooth
        .unwrap_or(crate::mesh::stuffing::DEFAULT_IMAGE_SMOOTHING * size);
    let domain = ImageDomain::from_grid(grid)
        .and_then(|d| d.cleaned(spec.tet_cleaning()))
        .map_err(|e| TetFailure::Mesh(e.to_string()))?
        .smoothed(sigma);
    let (mesh, report) = mesh_domain(&domain, size, spec.tet_force.unwrap_or(false))?;
    if let Some(k) = key {
        remember(k, &mesh, &report);
    }
    Ok(mesh)
}
