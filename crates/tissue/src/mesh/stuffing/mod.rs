//! Isosurface stuffing (Labelle & Shewchuk, "Isosurface stuffing: fast tetrahedral meshes
//! with good dihedral angles", SIGGRAPH 2007), uniform sizing: a tetrahedral mesh of the
//! inside of a `Domain` (an implicit shape, a closed surface, a thresholded or labelled
//! image) whose dihedral angles the paper proves lie in [10.7°, 164.8°].
//!
//! 1. Fill the domain's box with the BCC lattice of spacing h (`lattice`), one cube of
//!    margin, and take the sign of the domain at every lattice vertex.
//! 2. On every lattice edge whose ends have opposite signs, find the cut point where the
//!    boundary crosses it.
//! 3. Warp: a lattice vertex closer to a cut point on one of its edges than α times that
//!    edge's length (α = `ALPHA_LONG` for the edges of length h, `ALPHA_SHORT` for the
//!    black–red edges of length h√3/2) moves onto that cut point and takes sign zero; the cut
//!    points of its edges are dropped.
//! 4. Fill every BCC tetrahedron by the stencil its signs select (`stencil`).
//!
//! Every output is measured (`report::measure`): angles, validity, volume, and the distance
//! between the boundaries; the caller refuses what breaks a guarantee.

pub mod domain;
pub mod image_domain;
mod lattice;
pub mod manifold;
pub mod pieces;
pub mod report;
mod split_rule;
mod stencil;
#[cfg(test)]
mod stencil_bounds;
pub mod surface_domain;
pub mod triangle_index;

use std::time::Instant;

use rustc_hash::FxHashMap;

use crate::error::MeshError;
use crate::math::{Real, Vec3, tet_signed_volume};
use crate::mesh::TetMesh;
use crate::model::Progress;

pub use domain::{Domain, Implicit};
pub use image_domain::ImageDomain;
use lattice::Lattice;
pub use report::{MeshingReport, dihedral_angles, measure, radius_ratio};
use split_rule::Site;
use stencil::{Fill, Key};
pub use surface_domain::SurfaceDomain;
pub use triangle_index::TriangleIndex;

/// Warping threshold on the long (length h) edges, from the paper's uniform-sizing proof.
pub const ALPHA_LONG: Real = 0.24999;
/// Warping threshold on the short (length h·√3/2) edges.
pub const ALPHA_SHORT: Real = 0.41189;
/// The paper's proven dihedral bounds for uniform sizing with these α, in degrees.
pub const PROVEN_DIHEDRAL_DEG: (Real, Real) = (10.7, 164.8);
/// Lattices beyond this many vertices are refused (memory: ~30 bytes each).
pub const MAX_LATTICE_VERTICES: usize = 16_000_000;

/// A tetrahedral mesh made by stuffing, its tags (one per tetrahedron, from
/// `Domain::tag_at`) and its report.
#[derive(Clone, Debug)]
pub struct Stuffed {
    pub mesh: TetMesh,
    pub tags: Vec<i32>,
    pub report: MeshingReport,
}

impl Stuffed {
    /// The mesh as file contents: vertices, tetrahedra and their tags.
    pub fn to_mesh_data(&self) -> crate::mesh::MeshData {
        crate::mesh::MeshData {
            vertices: self.mesh.vertices.clone(),
            tets: self.mesh.tets.clone(),
            tet_tags: self.tags.clone(),
            ..Default::default()
        }
    }
}

/// Gaussian σ of an image mask's blur, relative to the lattice spacing, by default.
pub const DEFAULT_IMAGE_SMOOTHING: Real = 0.5;

/// The tetrahedron count a size is chosen for when none is given.
pub const DEFAULT_TARGET_TETS: usize = 20_000;

/// The lattice spacing that fills `volume` (m³) with about `tets` tetrahedra: a BCC
/// tetrahedron has volume h³/12, so h = (12·V/N)^(1/3).
pub fn size_for(volume: Real, tets: usize) -> Real {
    (12.0 * volume.abs() / tets.max(1) as Real).cbrt()
}

/// A cut point: the lattice edge (a, b) it lies on and its position.
struct Cut {
    a: u32,
    b: u32,
    at: Vec3,
}

/// Meshes the inside of `domain` with lattice spacing `size` (m). The report is filled in;
/// whether to accept the mesh is the caller's call (`MeshingReport::violations`).
pub fn stuff(domain: &dyn Domain, size: Real, progress: &Progress) -> Result<Stuffed, MeshError> {
    let clock = Instant::now();
    let (lo, hi) = domain.bounds();
    if !(size.is_finite() && size > 0.0) {
        return Err(MeshError::Invalid(format!(
            "the tetrahedron size must be a positive length in m, not {size}"
        )));
    }
    if !(crate::math::is_finite_vec(lo) && crate::math::is_finite_vec(hi)) || hi.cmplt(lo).any() {
        return Err(MeshError::Invalid(format!(
            "the shape's bounds are not a box: {lo} .. {hi}"
        )));
    }
    // One cube of margin on every side, so that the outer red vertices are outside.
    let cubes = ((hi - lo) / size).ceil() + Vec3::splat(2.0);
    let count = (cubes.x + 1.0) * (cubes.y + 1.0) * (cubes.z + 1.0) * 2.0;
    if count > MAX_LATTICE_VERTICES as Real {
        return Err(MeshError::Invalid(format!(
            "size {size:e} m needs about {count:.3e} lattice vertices over the shape's box \
             ({:.3e} × {:.3e} × {:.3e} m), more than {MAX_LATTICE_VERTICES}; use a larger size",
            hi.x - lo.x,
            hi.y - lo.y,
            hi.z - lo.z
        )));
    }
    let lattice = Lattice {
        origin: lo - Vec3::splat(size),
        h: size,
        n: [cubes.x as usize, cubes.y as usize, cubes.z as usize],
    };
    let nl = lattice.vertex_count();

    // 1. Signs.
    progress.report("signs", 0.0);
    let mut pos: Vec<Vec3> = (0..nl as u32).map(|v| lattice.position(v)).collect();
    let mut sign: Vec<i8> = signs(domain, &pos, progress);

    // 2. Cut points.
    progress.report("cut points", 0.0);
    let mut cuts: Vec<Cut> = Vec::new();
    let mut cut_of: FxHashMap<(u32, u32), u32> = FxHashMap::default();
    lattice.for_each_edge(|a, b| {
        let (sa, sb) = (sign[a as usize], sign[b as usize]);
        if sa * sb < 0 {
            let (pa, pb) = (pos[a as usize], pos[b as usize]);
            let at = if sa < 0 {
                domain.cut(pa, pb)
            } else {
                domain.cut(pb, pa)
            };
            cut_of.insert((a.min(b), a.max(b)), cuts.len() as u32);
            cuts.push(Cut { a, b, at });
        }
    });

    // 3. Warping. A cut point violates at most one end (both α < 1/2).
    progress.report("warping", 0.0);
    let mut candidates: Vec<(u32, Real, u32)> = Vec::new();
    for (c, cut) in cuts.iter().enumerate() {
        let (pa, pb) = (pos[cut.a as usize], pos[cut.b as usize]);
        let len = (pb - pa).length();
        let alpha = if lattice.is_long(cut.a, cut.b) {
            ALPHA_LONG
        } else {
            ALPHA_SHORT
        };
        let (da, db) = ((cut.at - pa).length(), (cut.at - pb).length());
        if da < alpha * len {
            candidates.push((cut.a, da, c as u32));
        } else if db < alpha * len {
            candidates.push((cut.b, db, c as u32));
        }
    }
    candidates.sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
    let mut warped = 0;
    for &(v, _, c) in &candidates {
        let cut = &cuts[c as usize];
        let other = if cut.a == v { cut.b } else { cut.a };
        // The nearest cut point still alive: neither end already warped.
        if sign[v as usize] != 0 && sign[other as usize] != 0 {
            pos[v as usize] = cut.at;
            sign[v as usize] = 0;
            warped += 1;
        }
    }

    // 4. Stencils.
    progress.report("stencils", 0.0);
    let cut_base = nl as Key;
    let mut out_of_lattice = vec![u32::MAX; nl];
    let mut out_of_cut = vec![u32::MAX; cuts.len()];
    let mut vertices: Vec<Vec3> = Vec::new();
    let mut tets: Vec<[u32; 4]> = Vec::new();
    let mut tags: Vec<i32> = Vec::new();
    let mut pieces: Vec<[Key; 4]> = Vec::new();
    let missing_cut = std::cell::Cell::new(false);
    let cut_key = |a: u32, b: u32| -> Key {
        match cut_of.get(&(a.min(b), a.max(b))) {
            Some(&c) => cut_base + c as Key,
            None => {
                missing_cut.set(true);
                a as Key
            }
        }
    };
    // Reference geometry for orientation: unwarped lattice, cut points at edge midpoints.
    let reference = |k: Key| -> Vec3 {
        if k < cut_base {
            lattice.position(k as u32)
        } else {
            let c = &cuts[(k - cut_base) as usize];
            0.5 * (lattice.position(c.a) + lattice.position(c.b))
        }
    };
    let actual = |k: Key| -> Vec3 {
        if k < cut_base {
            pos[k as usize]
        } else {
            cuts[(k - cut_base) as usize].at
        }
    };
    // Quadrilaterals in lattice faces are split by the lattice rule (`split_rule`): both
    // BCC tetrahedra sharing one see the same face.
    let site = |k: Key| -> Site {
        if k < cut_base {
            Site::Vertex(lattice.coords(k as u32))
        } else {
            let c = &cuts[(k - cut_base) as usize];
            Site::Cut(lattice.coords(c.a), lattice.coords(c.b))
        }
    };
    let split = |q: [Key; 4]| split_rule::lattice_split(q, site, split_rule::PARITY);
    let quality = |t: &[[Key; 4]]| stencil_quality(t, &actual, &reference);
    let mut all_zero = Vec::new();
    let mut steiner: Vec<[Key; 6]> = Vec::new();
    let mut steiner_points = 0;
    lattice.for_each_tet(|t| {
        if t.iter().all(|&v| sign[v as usize] > 0) {
            return;
        }
        pieces.clear();
        steiner.clear();
        let fill = stencil::fill(
            t,
            |v| sign[v as usize],
            cut_key,
            &split,
            &quality,
            &mut pieces,
            &mut steiner,
        );
        if fill == Fill::AllZero {
            all_zero.push(t);
        }
        // Steiner points of this tetrahedron's prisms: new vertices at the prism centres.
        let extra: Vec<(u32, Vec3)> = steiner
            .iter()
            .map(|p| {
                let id = vertices.len() as u32;
                vertices.push(p.iter().map(|&k| actual(k)).sum::<Vec3>() / 6.0);
                (id, p.iter().map(|&k| reference(k)).sum::<Vec3>() / 6.0)
            })
            .collect();
        steiner_points += extra.len();
        for piece in &pieces {
            let centroid = piece
                .iter()
                .map(|&k| match k.checked_sub(stencil::STEINER_BASE) {
                    Some(s) => vertices[extra[s as usize].0 as usize],
                    None => actual(k),
                })
                .sum::<Vec3>()
                / 4.0;
            emit(
                *piece,
                &|k| match k.checked_sub(stencil::STEINER_BASE) {
                    Some(s) => extra[s as usize].1,
                    None => reference(k),
                },
                &actual,
                &extra,
                cut_base,
                (&mut out_of_lattice, &mut out_of_cut),
                &mut vertices,
                &mut tets,
            );
            tags.push(domain.tag_at(centroid));
        }
    });
    // A tetrahedron with all four corners on the boundary is inside when its centre is; it
    // is kept only when it keeps the angle bound (`stencil::keep_all_zero`).
    for t in all_zero {
        let keys = t.map(|v| v as Key);
        let centroid = keys.iter().map(|&k| actual(k)).sum::<Vec3>() / 4.0;
        if domain.value(centroid) < 0.0 && stencil::keep_all_zero(keys.map(actual)) {
            emit(
                keys,
                &reference,
                &actual,
                &[],
                cut_base,
                (&mut out_of_lattice, &mut out_of_cut),
                &mut vertices,
                &mut tets,
            );
            tags.push(domain.tag_at(centroid));
        }
    }
    if missing_cut.get() {
        return Err(MeshError::Invalid(
            "internal: a stencil asked for a cut point that was never made".into(),
        ));
    }
    let seconds = clock.elapsed().as_secs_f64();
    progress.report("report", 0.0);
    let mut mesh = TetMesh::new(vertices, tets);
    let manifold = manifold::make_boundary_manifold(&mut mesh, &mut tags);
    let pieces = pieces::pieces(&mut mesh, &mut tags, domain.one_piece());
    let mut report = measure(&mesh, domain, domain_index(domain), size);
    report.manifold = manifold;
    report.pieces = pieces;
    report.warped = warped;
    report.steiner_points = steiner_points;
    report.cut_points = cuts.len();
    report.seconds = seconds;
    progress.report("report", 1.0);
    Ok(Stuffed { mesh, tags, report })
}

/// The exact-distance index of a surface domain, if `domain` is one.
fn domain_index(domain: &dyn Domain) -> Option<&TriangleIndex> {
    domain.surface_index()
}

/// Signs of the domain at `points` (-1, 0, +1), in parallel when the feature is on.
fn signs(domain: &dyn Domain, points: &[Vec3], progress: &Progress) -> Vec<i8> {
    let s = |p: &Vec3| {
        let f = domain.value(*p);
        if f < 0.0 {
            -1
        } else if f > 0.0 {
            1
        } else {
            0
        }
    };
    let mut out = Vec::with_capacity(points.len());
    for (k, chunk) in points.chunks(65536).enumerate() {
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            out.par_extend(chunk.par_iter().map(s));
        }
        #[cfg(not(feature = "parallel"))]
        out.extend(chunk.iter().map(s));
        progress.report("signs", (k + 1) as Real * 65536.0 / points.len() as Real);
    }
    out
}

/// The smallest dihedral angle of `tets` (radians), -1 when one is turned inside out
/// relative to the reference geometry: how a stencil picks between free splits.
fn stencil_quality(
    tets: &[[Key; 4]],
    at: &dyn Fn(Key) -> Vec3,
    reference: &dyn Fn(Key) -> Vec3,
) -> Real {
    let mut worst = Real::INFINITY;
    for t in tets {
        let (p, r) = (t.map(at), t.map(reference));
        if tet_signed_volume(p[0], p[1], p[2], p[3]) * tet_signed_volume(r[0], r[1], r[2], r[3])
            <= 0.0
        {
            return -1.0;
        }
        worst = dihedral_angles(p).iter().copied().fold(worst, Real::min);
    }
    worst
}

/// Adds one output tetrahedron: maps its keys to output vertices (made on first use) and
/// orients it positively as measured on the reference geometry.
#[allow(clippy::too_many_arguments)]
fn emit(
    piece: [Key; 4],
    reference: &dyn Fn(Key) -> Vec3,
    actual: &dyn Fn(Key) -> Vec3,
    steiner: &[(u32, Vec3)],
    cut_base: Key,
    (of_lattice, of_cut): (&mut [u32], &mut [u32]),
    vertices: &mut Vec<Vec3>,
    tets: &mut Vec<[u32; 4]>,
) {
    let mut tet = piece.map(|k| {
        if let Some(s) = k.checked_sub(stencil::STEINER_BASE) {
            return steiner[s as usize].0;
        }
        let slot = if k < cut_base {
            &mut of_lattice[k as usize]
        } else {
            &mut of_cut[(k - cut_base) as usize]
        };
        if *slot == u32::MAX {
            *slot = vertices.len() as u32;
            vertices.push(actual(k));
        }
        *slot
    });
    let r = piece.map(reference);
    if tet_signed_volume(r[0], r[1], r[2], r[3]) < 0.0 {
        tet.swap(2, 3);
    }
    tets.push(tet);
}

#[cfg(test)]
mod tests;
