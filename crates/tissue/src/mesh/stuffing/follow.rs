//! Boundary vertices moved towards the input where the lattice skipped a feature it could
//! follow (issue 25).
//!
//! An image's input at resolution h (`Domain::at_resolution`: the voxels opened and closed
//! by a ball of radius h/2) still holds features 3–4 voxels wide, about h: a bump, or a
//! channel between two folds. Whether the stuffing follows one depends on where the
//! lattice's vertices fall (its covering radius is 0.56 h), and where none falls on it the
//! mesh passes over it: the brain at 7 mm left input 0.595 h from the mesh where h/2 is
//! promised. The cut points are already on the input; what is missing is a vertex where the
//! feature is. So, for a few rounds, every sample of the input at resolution h farther than
//! `FAR`·h from the mesh boundary pulls its nearest boundary vertex onto it (the sample is
//! on the input's boundary, so the vertex stays on the isosurface), or the largest part of
//! the way that keeps the vertex's tetrahedra oriented and within the angle bounds
//! (`move_within_bounds`) and leaves each of its boundary faces' vertices, centroids and
//! edge midpoints within `NEAR`·h of the whole input (or no farther than they were): the
//! same points the report's mesh→input distance measures, so one direction is not bought
//! with the other. The other direction likewise: a boundary face whose centroid or edge
//! midpoint is farther than `FAR`·h from the whole input (a face passing over a hollow that
//! the filter keeps; the brain at 7 mm, 0.52 h) pulls its corner nearest to the input point
//! nearest it onto that point, and a boundary vertex that far pulls itself, when that brings
//! the faces' farthest point nearer. A vertex
//! between two tags stays (it would move an interface), and a vertex moves at most once per
//! round. Where nothing is far the mesh is left as it was.

use rustc_hash::FxHashMap;

use super::domain::Domain;
use super::interface_volume::{FaceGap, face_gap};
use super::report::refined_distance;
use super::triangle_index::TriangleIndex;
use super::vertex_move::move_within_bounds;
use crate::math::{Real, Vec3};
use crate::mesh::TetMesh;
use crate::mesh::boundary::boundary_surface;

/// A resolved input sample, or a boundary face point, farther than this (per h) from the
/// other side pulls a vertex.
const FAR: Real = 0.45;
/// The mesh→input distance (per h) a move may leave at its faces' points.
const NEAR: Real = 0.45;
/// Rounds of pulls (each on the boundary as the round before left it).
const ROUNDS: usize = 4;
/// Parts of the way to the target tried, largest first.
const FRACTIONS: [Real; 4] = [1.0, 0.75, 0.5, 0.25];
/// The mean gap between a chord and a quadratic surface through its corners, per gap at
/// its centroid (`interface_volume`).
const MEAN_PER_CENTROID_GAP: Real = 0.75;
/// How far (per h) from a face's centroid the input is looked for.
const CHORD_SEARCH: Real = 0.25;
/// A face whose centroid is nearer the input than this (per h) lies on a plane of it.
const FLAT: Real = 1e-3;

/// What `follow_input` did: vertices moved all the way onto the input, part of the way, and
/// pulls refused (angles, or the mesh→input distance).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Followed {
    pub onto: usize,
    pub partly: usize,
    pub refused: usize,
    /// Boundary vertices then moved off their faces' chords (`off_chords`).
    pub off_chords: usize,
}

/// Points binned by cells of size h, for the nearest point within about h.
struct Bins {
    size: Real,
    cells: FxHashMap<[i32; 3], Vec<(u32, Vec3)>>,
}

impl Bins {
    fn new(points: impl Iterator<Item = (u32, Vec3)>, size: Real) -> Self {
        let mut cells: FxHashMap<[i32; 3], Vec<(u32, Vec3)>> = FxHashMap::default();
        for (i, p) in points {
            cells.entry(cell(p, size)).or_default().push((i, p));
        }
        Bins { size, cells }
    }

    /// The nearest point to `p` in the 27 cells around it, with its id.
    fn nearest(&self, p: Vec3) -> Option<(u32, Vec3)> {
        let c = cell(p, self.size);
        let mut best: Option<(Real, u32, Vec3)> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let key = [c[0] + dx, c[1] + dy, c[2] + dz];
                    for &(i, q) in self.cells.get(&key).map(Vec::as_slice).unwrap_or(&[]) {
                        let d = (q - p).length();
                        if best.is_none_or(|b| d < b.0) {
                            best = Some((d, i, q));
                        }
                    }
                }
            }
        }
        best.map(|(_, i, q)| (i, q))
    }
}

fn cell(p: Vec3, size: Real) -> [i32; 3] {
    (p / size).floor().as_ivec3().to_array()
}

/// The vertices, centroids and edge midpoints of `faces`, where `mesh` has them now.
fn face_points(mesh: &TetMesh, faces: &[[u32; 3]]) -> Vec<Vec3> {
    let mut q = Vec::with_capacity(5 * faces.len());
    for f in faces {
        let [a, b, c] = f.map(|u| mesh.vertices[u as usize]);
        q.extend([
            a,
            (a + b + c) / 3.0,
            0.5 * (a + b),
            0.5 * (b + c),
            0.5 * (c + a),
        ]);
    }
    q
}

/// `d` without its parts along the unit `normals` (of flat faces): a move within their
/// planes, or none when they leave no direction (three planes, or normals that do not
/// agree after two passes).
fn within_planes(mut d: Vec3, normals: &[Vec3]) -> Vec3 {
    for _ in 0..2 {
        for n in normals {
            d -= d.dot(*n) * *n;
        }
    }
    let tolerance = 1e-6 * d.length();
    if normals.iter().all(|n| d.dot(*n).abs() <= tolerance) {
        d
    } else {
        Vec3::ZERO
    }
}

/// How a boundary vertex may move: its tetrahedra, its boundary faces, the distance to the
/// input, and what the move must keep.
struct Pull<'a> {
    around: &'a [usize],
    faces: &'a [[u32; 3]],
    to_input: &'a dyn Fn(Vec3) -> Real,
    size: Real,
    /// The faces' farthest point must come nearer the input.
    must_improve: bool,
    /// Parts of the way tried, largest first.
    fractions: &'a [Real],
}

impl Pull<'_> {
    /// Moves `v` towards `target` by the largest of `fractions` that keeps the angles
    /// (`move_within_bounds`) and every point of its faces within `NEAR`·h of the input or
    /// no farther than it was (and, with `must_improve`, brings the farthest nearer).
    /// Returns the fraction's index; `None` leaves the vertex where it was.
    fn pull(&self, mesh: &mut TetMesh, v: u32, target: Vec3) -> Option<usize> {
        let to_input = self.to_input;
        let before: Vec<Real> = face_points(mesh, self.faces)
            .into_iter()
            .map(to_input)
            .collect();
        let worst = before.iter().copied().fold(0.0, Real::max);
        let x = mesh.vertices[v as usize];
        for (i, &f) in self.fractions.iter().enumerate() {
            if move_within_bounds(mesh, v, self.around, target - x, &[f]).is_none() {
                continue;
            }
            let after: Vec<Real> = face_points(mesh, self.faces)
                .into_iter()
                .map(to_input)
                .collect();
            let kept = after
                .iter()
                .zip(&before)
                .all(|(&a, &b)| a <= (NEAR * self.size).max(b));
            let better = !self.must_improve || after.iter().copied().fold(0.0, Real::max) < worst;
            if kept && better {
                return Some(i);
            }
            mesh.vertices[v as usize] = x;
        }
        None
    }
}

/// Moves boundary vertices of `mesh` towards the input where the mesh passes farther than
/// `FAR`·h from it, either way; `resolved` is `domain` at resolution `size`
/// (`Domain::at_resolution`; `None`, a surface, leaves the mesh as it is). See the module doc.
pub fn follow_input(
    mesh: &mut TetMesh,
    tags: &[i32],
    domain: &dyn Domain,
    resolved: Option<&dyn Domain>,
    size: Real,
) -> Followed {
    let mut done = Followed::default();
    let Some(resolved) = resolved else {
        return done;
    };
    let samples = resolved.boundary_samples(0.25 * size);
    // The whole input's samples bound the first-order mesh→input estimate, as in `measure`.
    let whole = domain.boundary_samples(0.25 * size);
    if samples.is_empty() || whole.is_empty() {
        return done;
    }
    let points: Vec<[u32; 3]> = (0..whole.len() as u32).map(|i| [i, i, i]).collect();
    let near_whole = TriangleIndex::new(&whole, &points);
    let whole_bins = Bins::new(whole.iter().enumerate().map(|(i, &p)| (i as u32, p)), size);
    let step = 1e-3 * size;
    let to_input = |p: Vec3| {
        let estimate = domain
            .boundary_distance(p, step)
            .min(near_whole.distance(p));
        refined_distance(domain, p, estimate, size)
    };
    let mut around: FxHashMap<u32, Vec<usize>> = FxHashMap::default();
    for (t, tet) in mesh.tets.iter().enumerate() {
        for &v in tet {
            around.entry(v).or_default().push(t);
        }
    }
    let one_tag =
        |ts: &[usize]| !ts.is_empty() && ts.windows(2).all(|w| tags.get(w[0]) == tags.get(w[1]));
    let count = |done: &mut Followed, taken: Option<usize>| match taken {
        Some(0) => done.onto += 1,
        Some(_) => done.partly += 1,
        None => done.refused += 1,
    };
    for _ in 0..ROUNDS {
        let boundary = boundary_surface(mesh);
        let surface = &boundary.surface;
        // Boundary faces per mesh vertex (as mesh vertex triples).
        let mut faces: FxHashMap<u32, Vec<[u32; 3]>> = FxHashMap::default();
        for tri in &surface.triangles {
            let f = tri.map(|s| boundary.nodes[s as usize]);
            for v in f {
                faces.entry(v).or_default().push(f);
            }
        }
        let mut moved_now: Vec<u32> = Vec::new();
        // One vertex pulled toward `target` (once a round, a vertex of one tag only); with
        // `must_improve`, only a move that brings its faces' farthest point nearer the input.
        let pull_to = |mesh: &mut TetMesh,
                       v: u32,
                       target: Vec3,
                       must_improve: bool,
                       moved_now: &mut Vec<u32>,
                       done: &mut Followed| {
            let ts = around.get(&v).map(Vec::as_slice).unwrap_or(&[]);
            if moved_now.contains(&v) || !one_tag(ts) {
                return;
            }
            let own = faces.get(&v).map(Vec::as_slice).unwrap_or(&[]);
            let at = Pull {
                around: ts,
                faces: own,
                to_input: &to_input,
                size,
                must_improve,
                fractions: &FRACTIONS,
            };
            let taken = at.pull(mesh, v, target);
            count(done, taken);
            if taken.is_some() {
                moved_now.push(v);
            }
        };
        // Direction (b): resolved samples far from the mesh, farthest first, each pulling
        // its nearest boundary vertex.
        let index = TriangleIndex::new(&surface.vertices, &surface.triangles);
        let mut far: Vec<(Real, Vec3)> = samples
            .iter()
            .map(|&p| (index.distance(p), p))
            .filter(|&(d, _)| d > FAR * size)
            .collect();
        far.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
        let vertex_bins = Bins::new(faces.keys().map(|&v| (v, mesh.vertices[v as usize])), size);
        for (_, p) in far {
            let Some((v, _)) = vertex_bins.nearest(p) else {
                continue;
            };
            pull_to(mesh, v, p, false, &mut moved_now, &mut done);
        }
        // Direction (a): face points far from the whole input, farthest first.
        let mut pulls: Vec<(Real, u32, Vec3)> = Vec::new();
        // A vertex off the input (moved there by a pull, or a split copy) pulls itself.
        for &v in faces.keys() {
            let x = mesh.vertices[v as usize];
            let d = to_input(x);
            if d > FAR * size
                && let Some((_, s)) = whole_bins.nearest(x)
            {
                pulls.push((d, v, s));
            }
        }
        for tri in &surface.triangles {
            let f = tri.map(|s| boundary.nodes[s as usize]);
            let [a, b, c] = f.map(|u| mesh.vertices[u as usize]);
            for q in [
                (a + b + c) / 3.0,
                0.5 * (a + b),
                0.5 * (b + c),
                0.5 * (c + a),
            ] {
                let d = to_input(q);
                if d <= FAR * size {
                    continue;
                }
                let Some((_, s)) = whole_bins.nearest(q) else {
                    continue;
                };
                let dist = |u: u32| (mesh.vertices[u as usize] - s).length();
                let v = f
                    .into_iter()
                    .min_by(|&u, &w| dist(u).total_cmp(&dist(w)))
                    .unwrap_or(f[0]);
                pulls.push((d, v, s));
            }
        }
        pulls.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
        for (_, v, s) in pulls {
            pull_to(mesh, v, s, true, &mut moved_now, &mut done);
        }
        if moved_now.is_empty() {
            break;
        }
    }
    done.off_chords = off_chords(mesh, &around, &one_tag, domain, &to_input, size);
    done
}

/// The outer boundary moved off its chords, as `interface_volume` moves interfaces: each
/// boundary vertex by 3/4 of the area-weighted mean gap from its faces' centroids to the
/// input along their normals (found within h/4), so each face moves by its mean gap and the
/// volume between mesh and input vanishes to first order. Stuffing puts every boundary
/// vertex on the input, so each face is a chord that shaves a convex part (the brain at 7 mm
/// lost 0.93 % so, more after the pulls above carved hollows). A vertex on a flat face of
/// the input moves only along that face's plane (`within_planes`). A move is kept only as
/// `pull` keeps one (angles, and its faces' points within `NEAR`·h of the input or no
/// farther than they were), else halved, else dropped. Returns the vertices moved.
fn off_chords(
    mesh: &mut TetMesh,
    around: &FxHashMap<u32, Vec<usize>>,
    one_tag: &dyn Fn(&[usize]) -> bool,
    domain: &dyn Domain,
    to_input: &dyn Fn(Vec3) -> Real,
    size: Real,
) -> usize {
    let boundary = boundary_surface(mesh);
    let surface = &boundary.surface;
    let reach = CHORD_SEARCH * size;
    let mut gaps: FxHashMap<u32, (Vec3, Real)> = FxHashMap::default();
    let mut faces: FxHashMap<u32, Vec<[u32; 3]>> = FxHashMap::default();
    // A face on a plane of the input (no sag) holds its vertices to that plane: the mean
    // of its zero gap and a curved neighbour's outward one would lift them off it (a block's
    // face, an image's border), so the part of their move along its normal is taken out.
    let mut planes: FxHashMap<u32, Vec<Vec3>> = FxHashMap::default();
    for tri in &surface.triangles {
        let f = tri.map(|s| boundary.nodes[s as usize]);
        for v in f {
            faces.entry(v).or_default().push(f);
        }
        let [p, q, r] = f.map(|u| mesh.vertices[u as usize]);
        let value = |x: Vec3| domain.value(x);
        let Some(FaceGap {
            area,
            normal: n,
            gap,
        }) = face_gap([p, q, r], reach, value)
        else {
            continue;
        };
        if gap.length() <= FLAT * size {
            for v in f {
                planes.entry(v).or_default().push(n);
            }
        }
        for v in f {
            let e = gaps.entry(v).or_insert((Vec3::ZERO, 0.0));
            e.0 += area * gap;
            e.1 += area;
        }
    }
    let mut moves: Vec<(u32, Vec3)> = gaps
        .into_iter()
        .filter(|(_, (_, area))| *area > 0.0)
        .map(|(v, (sum, area))| {
            let d = MEAN_PER_CENTROID_GAP * sum / area;
            (
                v,
                within_planes(d, planes.get(&v).map(Vec::as_slice).unwrap_or(&[])),
            )
        })
        .collect();
    moves.sort_unstable_by_key(|m| m.0);
    let mut moved = 0;
    for (v, d) in moves {
        let ts = around.get(&v).map(Vec::as_slice).unwrap_or(&[]);
        if !one_tag(ts) {
            continue;
        }
        let own = faces.get(&v).map(Vec::as_slice).unwrap_or(&[]);
        let x = mesh.vertices[v as usize];
        let at = Pull {
            around: ts,
            faces: own,
            to_input,
            size,
            must_improve: false,
            fractions: &[1.0, 0.5],
        };
        if at.pull(mesh, v, x + d).is_some() {
            moved += 1;
        }
    }
    moved
}

#[cfg(test)]
mod tests {
    use super::super::report::measure;
    use super::super::{ImageDomain, stuff};
    use super::*;
    use crate::image::{ByteOrder, SourceType, VoxelImage};
    use crate::model::Progress;

    /// A ball of voxels meshed, one boundary vertex then pushed 0.6 h off the input (as far
    /// as the angles allow): the report sees the mesh farther than h/2, and the pulls bring
    /// it back within 0.45 h, every tetrahedron oriented and within the proven angles.
    #[test]
    fn a_boundary_vertex_off_the_input_is_pulled_back_within_the_angles() {
        let (n, sp, h) = ([28, 28, 28], 0.001, 0.003);
        let c = Vec3::splat(13.5);
        let mut values = vec![0f32; n[0] * n[1] * n[2]];
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let p = Vec3::new(i as Real, j as Real, k as Real);
                    let inside = (p - c).length() < 10.0;
                    values[i + n[0] * (j + n[1] * k)] = if inside { 1.0 } else { 0.0 };
                }
            }
        }
        let image = VoxelImage {
            dims: n,
            spacing: Vec3::splat(sp),
            origin: Vec3::ZERO,
            values,
            source_type: SourceType::U8,
            byte_order: ByteOrder::Little,
            segments: Vec::new(),
        };
        let d = ImageDomain::from_threshold(&image, 0.5, 1.5).unwrap_or_else(|e| panic!("{e}"));
        let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        assert!(s.report.violations().is_empty(), "{}", s.report);
        let mut mesh = s.mesh.clone();
        let boundary = boundary_surface(&mesh);
        let z = |v: u32| mesh.vertices[v as usize].z;
        let top = boundary
            .nodes
            .iter()
            .copied()
            .max_by(|&a, &b| z(a).total_cmp(&z(b)))
            .unwrap_or_else(|| panic!("no boundary"));
        let around: Vec<usize> = (0..mesh.tets.len())
            .filter(|&t| mesh.tets[t].contains(&top))
            .collect();
        let push = 0.6 * h * Vec3::Z;
        let pushed = move_within_bounds(&mut mesh, top, &around, push, &[1.0, 0.9, 0.85]);
        assert!(pushed.is_some(), "the push kept no angle");
        let before = measure(&mesh, &d, None, h);
        assert!(before.mesh_to_input > 0.5 * h, "{before}");
        let resolved = Domain::at_resolution(&d, h);
        let done = follow_input(&mut mesh, &s.tags, &d, resolved.as_deref(), h);
        assert!(done.onto + done.partly >= 1, "{done:?}");
        let after = measure(&mesh, &d, None, h);
        assert!(after.hausdorff <= 0.45 * h, "{after}");
        assert_eq!((after.inverted, after.degenerate), (0, 0), "{after}");
        assert!(after.min_dihedral_deg >= 10.7 - 1e-9, "{after}");
        assert!(after.volume_error.unwrap_or(1.0).abs() < 0.01, "{after}");
    }
}
