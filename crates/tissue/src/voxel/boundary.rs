//! The rendered surface after a topology edit: the boundary of the voxel cubes, where a
//! cube face is boundary when the voxel across it is missing or the face link across it
//! is cut, closed and oriented by construction, and smoothed without changing its
//! connectivity.
//!
//! Why not the given surface: a cut or a carve opens it, and closing it with caps that
//! follow arbitrary blade paths is fragile. The cube boundary is closed whatever was cut.
//!
//! Connectivity: every boundary face edge lies on a lattice edge shared by four cells.
//! Walking around that edge from a face, through the cells linked across their faces, we
//! meet the one other boundary face bounding the same linked wedge of cells: that is the
//! edge's twin (for a cut that ends at the edge, the face on the other lip of the same
//! wall). Pairing edges this way never gives an edge more than two faces, even where two
//! voxels touch along an edge only. Surface vertices are then the classes of face corners
//! joined across twin edges (union-find): the umbrella of faces around a lattice corner
//! that belong together. Two lips of a cut meet at the same lattice corner but form two
//! umbrellas, hence two vertices that move apart.
//!
//! Motion: a vertex follows the mean displacement of the voxels whose faces it joins
//! (they are all on its side of any cut), written as a `TrilinearEmbedding` with equal
//! weights, so `apply` and `apply_transpose` work as for the given surface.

use rustc_hash::FxHashMap;

use crate::math::{Real, Vec3};
use crate::mesh::topology::{UnionFind, oriented_surface_neighbours};

use super::TrilinearEmbedding;
use super::topology::VoxelLinks;

/// A closed triangle surface bounding the linked voxels.
#[derive(Clone, Debug, PartialEq)]
pub struct BoundarySurface {
    /// Rest positions and the voxels (grid indices) each vertex follows.
    pub embedding: TrilinearEmbedding,
    pub triangles: Vec<[u32; 3]>,
}

/// Direction index of axis `axis` with sign `positive`.
fn dir(axis: usize, positive: bool) -> usize {
    2 * axis + positive as usize
}

/// The boundary surface of the occupied voxels of `links` (face links decide what is
/// joined), with `smoothing` Taubin passes on the rest positions (0: the cube corners).
pub fn boundary_surface(links: &VoxelLinks, smoothing: usize) -> BoundarySurface {
    boundary_surface_with(links, 0, smoothing)
}

/// As `boundary_surface`, with every triangle split in four `subdivisions` times before
/// smoothing: finer vertices for the probe (contacts hold vertices) and a rounder shape.
pub fn boundary_surface_with(
    links: &VoxelLinks,
    subdivisions: usize,
    smoothing: usize,
) -> BoundarySurface {
    build(links, &Region::all(links.dims), subdivisions, smoothing).into_surface()
}

/// A box of voxels, by grid coordinates, bounds included.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Region {
    pub lo: [usize; 3],
    pub hi: [usize; 3],
}

impl Region {
    pub fn all(dims: [usize; 3]) -> Self {
        Region {
            lo: [0; 3],
            hi: dims.map(|d| d.saturating_sub(1)),
        }
    }

    /// This box grown by `margin` voxels each way, within a grid of `dims`.
    pub fn grown(&self, margin: usize, dims: [usize; 3]) -> Self {
        Region {
            lo: self.lo.map(|l| l.saturating_sub(margin)),
            hi: [0, 1, 2].map(|a| (self.hi[a] + margin).min(dims[a].saturating_sub(1))),
        }
    }

    pub fn contains(&self, c: [usize; 3]) -> bool {
        (0..3).all(|a| self.lo[a] <= c[a] && c[a] <= self.hi[a])
    }

    pub fn voxels(&self) -> usize {
        (0..3).map(|a| self.hi[a] + 1 - self.lo[a]).product()
    }

    /// Whether the point `c`, in voxel units (voxel centres at integers), lies within the
    /// box grown by `margin`.
    pub fn reaches(&self, c: Vec3, margin: Real) -> bool {
        let c = c.to_array();
        (0..3).all(|a| c[a] >= self.lo[a] as Real - margin && c[a] <= self.hi[a] as Real + margin)
    }
}

/// What identifies a boundary vertex whatever part of the lattice it was built from, so an
/// edit can rebuild a window and splice it in (`DrawnBoundary`). Faces are keyed
/// 6·voxel + direction and face corners 4·face + slot. A corner vertex is its class's
/// smallest corner key, a midpoint added where two twin pairs share an edge the smaller of
/// its two (face, edge) keys, a face centre its face key (each tagged in the top bits).
/// A vertex of a triangle split is the pair of its edge's ends; an unsplit one pairs with
/// `u64::MAX`.
pub(crate) type VertexKey = u128;

const TAG_SHIFT: u32 = 62;
const CORNER: u64 = 0;
const TWIN_MIDPOINT: u64 = 1 << TAG_SHIFT;
const FACE_CENTRE: u64 = 2 << TAG_SHIFT;

fn unsplit(key: u64) -> VertexKey {
    ((u64::MAX as u128) << 64) | key as u128
}

fn split_key(a: VertexKey, b: VertexKey) -> VertexKey {
    let (a, b) = (a as u64, b as u64);
    ((a.max(b) as u128) << 64) | a.min(b) as u128
}

/// The boundary faces of a region, triangulated, split and smoothed, with keys.
pub(crate) struct Built {
    /// Smoothed rest positions.
    pub rest: Vec<Vec3>,
    /// Rest positions before smoothing, in voxel units (voxel centres at integers).
    pub lattice: Vec<Vec3>,
    /// Per vertex, the voxels it follows and their weights (at most eight).
    pub follows: Vec<Vec<(u32, Real)>>,
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle, the key of the voxel face it tiles.
    pub face_of_triangle: Vec<u64>,
    pub keys: Vec<VertexKey>,
}

impl Built {
    fn into_surface(self) -> BoundarySurface {
        BoundarySurface {
            embedding: embedding_of(self.rest, &self.follows),
            triangles: self.triangles,
        }
    }
}

/// Rest positions and followed voxels as a `TrilinearEmbedding` (at most eight voxels per
/// vertex: a lattice corner has eight cells around it).
pub(crate) fn embedding_of(rest: Vec<Vec3>, follows: &[Vec<(u32, Real)>]) -> TrilinearEmbedding {
    let (nodes, weights) = follows
        .iter()
        .map(|m| {
            let mut ids = [0u32; 8];
            let mut w = [0.0; 8];
            for (k, &(v, x)) in m.iter().take(8).enumerate() {
                ids[k] = v;
                w[k] = x;
            }
            (ids, w)
        })
        .unzip();
    TrilinearEmbedding {
        rest,
        nodes,
        weights,
    }
}

/// The boundary of the occupied voxels of `region` (their faces; twins and classes are
/// found among those, so near the region's sides the result is only a window's).
pub(crate) fn build(
    links: &VoxelLinks,
    region: &Region,
    subdivisions: usize,
    smoothing: usize,
) -> Built {
    let [nx, ny, _] = links.dims;
    let coords = |v: usize| [v % nx, (v / nx) % ny, v / (nx * ny)];
    let boundary = |v: usize, d: usize| links.is_occupied(v) && links.linked(v, d).is_none();

    // Faces as (voxel, direction), with their corners counter-clockwise seen from outside,
    // in increasing key order (which makes a class's first corner its smallest).
    let mut faces: Vec<(usize, usize)> = Vec::new();
    let mut face_of: FxHashMap<(usize, usize), usize> = FxHashMap::default();
    if !links.is_empty() {
        for k in region.lo[2]..=region.hi[2] {
            for j in region.lo[1]..=region.hi[1] {
                for i in region.lo[0]..=region.hi[0] {
                    let v = i + nx * (j + ny * k);
                    for d in 0..6 {
                        if boundary(v, d) {
                            face_of.insert((v, d), faces.len());
                            faces.push((v, d));
                        }
                    }
                }
            }
        }
    }
    let face_key = |f: usize| (6 * faces[f].0 + faces[f].1) as u64;
    let slot_key = |f: usize, s: usize| 4 * face_key(f) + s as u64;
    let corners_of = |(v, d): (usize, usize)| -> [[usize; 3]; 4] {
        let (p, positive) = (d / 2, d & 1 == 1);
        let (u, w) = ((p + 1) % 3, (p + 2) % 3);
        let order: [(usize, usize); 4] = if positive {
            [(0, 0), (1, 0), (1, 1), (0, 1)]
        } else {
            [(0, 0), (0, 1), (1, 1), (1, 0)]
        };
        let base = coords(v);
        order.map(|(ou, ow)| {
            let mut c = base;
            c[p] += positive as usize;
            c[u] += ou;
            c[w] += ow;
            c
        })
    };
    let face_corners: Vec<[[usize; 3]; 4]> = faces.iter().map(|&f| corners_of(f)).collect();

    // Twin edges: join the face corners on each side of every face edge.
    let mut uf = UnionFind::new(4 * faces.len());
    // Per face and edge slot s (corners s → s + 1): the twin face.
    let mut twin_of = vec![[u32::MAX; 4]; faces.len()];
    for (f, &(v, d)) in faces.iter().enumerate() {
        let (p, sp) = (d / 2, d & 1 == 1);
        let corners = &face_corners[f];
        for q in [(p + 1) % 3, (p + 2) % 3] {
            for sq in [false, true] {
                let Some(g) = twin(links, &face_of, v, p, sp, q, sq) else {
                    continue;
                };
                let other = &face_corners[g];
                let base = coords(v)[q] + sq as usize;
                if let Some(s) =
                    (0..4).find(|&s| corners[s][q] == base && corners[(s + 1) % 4][q] == base)
                {
                    twin_of[f][s] = g as u32;
                }
                for (s, c) in corners.iter().enumerate() {
                    if c[q] != base {
                        continue;
                    }
                    if let Some(t) = other.iter().position(|o| o == c) {
                        uf.union(4 * f + s, 4 * g + t);
                    }
                }
            }
        }
    }

    // Vertices: one per class; rest at its lattice corner, following its voxels.
    let mut vertex_of_root = vec![u32::MAX; 4 * faces.len()];
    let mut rest = Vec::new();
    let mut keys: Vec<VertexKey> = Vec::new();
    let mut members: Vec<Vec<u32>> = Vec::new();
    let mut slot_vertex = vec![0u32; 4 * faces.len()];
    for (f, &face) in faces.iter().enumerate() {
        let corners = &face_corners[f];
        for s in 0..4 {
            let root = uf.find(4 * f + s);
            if vertex_of_root[root] == u32::MAX {
                let c = corners[s].map(|x| x as Real - 0.5);
                rest.push(links.origin + Vec3::from_array(c) * links.spacing);
                keys.push(unsplit(CORNER | slot_key(f, s)));
                members.push(Vec::new());
                vertex_of_root[root] = (rest.len() - 1) as u32;
            }
            let id = vertex_of_root[root];
            slot_vertex[4 * f + s] = id;
            let m = &mut members[id as usize];
            if !m.contains(&(face.0 as u32)) {
                m.push(face.0 as u32);
            }
        }
    }
    // Where two voxels touch along a lattice edge only and both its end vertices are
    // shared (the voxels are joined around both ends), two twin pairs run between the same
    // two vertices. Every pair after the first gets a midpoint vertex of its own, so that
    // no two triangles' edges coincide.
    let edge = |f: usize, e: usize| {
        let (a, b) = (slot_vertex[4 * f + e], slot_vertex[4 * f + (e + 1) % 4]);
        (a.min(b), a.max(b))
    };
    let mut uses_of_edge: FxHashMap<(u32, u32), u32> = FxHashMap::default();
    uses_of_edge.reserve(2 * faces.len());
    for f in 0..faces.len() {
        for e in 0..4 {
            *uses_of_edge.entry(edge(f, e)).or_insert(0) += 1;
        }
    }
    // Shared edges are rare: list their uses only.
    let mut on_edge: FxHashMap<(u32, u32), Vec<(usize, usize)>> = FxHashMap::default();
    for f in 0..faces.len() {
        for e in 0..4 {
            if uses_of_edge[&edge(f, e)] > 2 {
                on_edge.entry(edge(f, e)).or_default().push((f, e));
            }
        }
    }
    let mut midpoint: FxHashMap<(usize, usize), u32> = FxHashMap::default();
    let mut shared: Vec<_> = on_edge.into_values().collect();
    shared.sort_unstable();
    for uses in shared {
        let mut done: Vec<usize> = Vec::new();
        for &(f, e) in &uses {
            if done.contains(&f) {
                continue;
            }
            let g = twin_of[f][e] as usize;
            let Some(&(_, e2)) = uses.iter().find(|&&(h, _)| h == g) else {
                continue;
            };
            done.extend([f, g]);
            if done.len() == 2 {
                continue;
            }
            let (a, b) = (slot_vertex[4 * f + e], slot_vertex[4 * f + (e + 1) % 4]);
            rest.push(0.5 * (rest[a as usize] + rest[b as usize]));
            keys.push(unsplit(TWIN_MIDPOINT | slot_key(f, e).min(slot_key(g, e2))));
            let mut m = vec![faces[f].0 as u32];
            if faces[g].0 != faces[f].0 {
                m.push(faces[g].0 as u32);
            }
            members.push(m);
            let id = (rest.len() - 1) as u32;
            midpoint.insert((f, e), id);
            midpoint.insert((g, e2), id);
        }
    }
    let mut triangles = Vec::with_capacity(2 * faces.len());
    let mut face_of_triangle = Vec::with_capacity(2 * faces.len());
    for (f, &(v, d)) in faces.iter().enumerate() {
        let q = &slot_vertex[4 * f..4 * f + 4];
        if (0..4).all(|e| !midpoint.contains_key(&(f, e))) {
            // The two lips of a cut wall list the same lattice corners; opposite
            // diagonals keep their triangles' edges apart when their vertices coincide
            // (a link cut alone inside the body).
            if d & 1 == 1 {
                triangles.push([q[0], q[1], q[2]]);
                triangles.push([q[0], q[2], q[3]]);
            } else {
                triangles.push([q[1], q[2], q[3]]);
                triangles.push([q[1], q[3], q[0]]);
            }
            face_of_triangle.resize(triangles.len(), face_key(f));
            continue;
        }
        // The face as a polygon with its midpoints, fanned from a vertex at its centre
        // (its own, so no fan edge can coincide with another face's).
        let mut poly = Vec::with_capacity(8);
        for (e, &corner) in q.iter().enumerate() {
            poly.push(corner);
            if let Some(&m) = midpoint.get(&(f, e)) {
                poly.push(m);
            }
        }
        let centre = q.iter().map(|&c| rest[c as usize]).sum::<Vec3>() / 4.0;
        rest.push(centre);
        keys.push(unsplit(FACE_CENTRE | face_key(f)));
        members.push(vec![v as u32]);
        let c = (rest.len() - 1) as u32;
        for k in 0..poly.len() {
            triangles.push([c, poly[k], poly[(k + 1) % poly.len()]]);
        }
        face_of_triangle.resize(triangles.len(), face_key(f));
    }
    // A lattice corner has eight cells around it, so a class has at most eight voxels.
    let mut follows: Vec<Vec<(u32, Real)>> = members
        .iter()
        .map(|m| {
            let share = 1.0 / m.len().clamp(1, 8) as Real;
            m.iter().take(8).map(|&v| (v, share)).collect()
        })
        .collect();
    for _ in 0..subdivisions {
        triangles = split_in_four(&mut rest, &mut follows, &mut keys, &triangles);
        face_of_triangle = face_of_triangle.iter().flat_map(|&f| [f; 4]).collect();
    }
    let boxes: Vec<(Vec3, Vec3)> = follows
        .iter()
        .map(|m| {
            let half = 0.5 * links.spacing;
            m.iter().fold(
                (Vec3::splat(Real::INFINITY), Vec3::splat(Real::NEG_INFINITY)),
                |(lo, hi), &(v, _)| {
                    let c = links.centre_of(v as usize);
                    (lo.min(c - half), hi.max(c + half))
                },
            )
        })
        .collect();
    let lattice = rest
        .iter()
        .map(|&p| (p - links.origin) / links.spacing)
        .collect();
    taubin(&mut rest, &triangles, smoothing, &boxes);
    Built {
        rest,
        lattice,
        follows,
        triangles,
        face_of_triangle,
        keys,
    }
}

/// The face sharing the edge of face (v, direction (p, sp)) on its side (q, sq): walk
/// around the lattice edge through linked cells until a boundary face closes the wedge.
fn twin(
    links: &VoxelLinks,
    face_of: &FxHashMap<(usize, usize), usize>,
    v: usize,
    p: usize,
    sp: bool,
    q: usize,
    sq: bool,
) -> Option<usize> {
    let steps = [(q, sq), (p, sp), (q, !sq), (p, !sp)];
    let mut cell = v;
    for (k, &(axis, sign)) in steps.iter().enumerate() {
        let d = dir(axis, sign);
        match links.linked(cell, d) {
            Some(next) if k < 3 => cell = next,
            _ => return face_of.get(&(cell, d)).copied(),
        }
    }
    None
}

/// Splits every triangle in four at its edge midpoints. A midpoint follows its edge's
/// two ends half each (the coarse surface moves exactly as before; if the two ends follow
/// more than eight voxels between them, the eight largest weights are kept). The surface
/// stays closed and oriented: each edge gets one midpoint, shared by both its triangles.
fn split_in_four(
    rest: &mut Vec<Vec3>,
    follows: &mut Vec<Vec<(u32, Real)>>,
    keys: &mut Vec<VertexKey>,
    triangles: &[[u32; 3]],
) -> Vec<[u32; 3]> {
    let mut mid: FxHashMap<(u32, u32), u32> = FxHashMap::default();
    let mut out = Vec::with_capacity(4 * triangles.len());
    for tri in triangles {
        let m = [0, 1, 2].map(|e| {
            let (a, b) = (tri[e], tri[(e + 1) % 3]);
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                rest.push(0.5 * (rest[a as usize] + rest[b as usize]));
                keys.push(split_key(keys[a as usize], keys[b as usize]));
                let mut w: Vec<(u32, Real)> = Vec::with_capacity(8);
                for &(v, x) in follows[a as usize].iter().chain(&follows[b as usize]) {
                    match w.iter_mut().find(|(u, _)| *u == v) {
                        Some((_, y)) => *y += 0.5 * x,
                        None => w.push((v, 0.5 * x)),
                    }
                }
                if w.len() > 8 {
                    // Ties by voxel: the same vertex whichever triangle reaches it first.
                    w.sort_by(|p, q| q.1.total_cmp(&p.1).then(p.0.cmp(&q.0)));
                    w.truncate(8);
                    let sum: Real = w.iter().map(|p| p.1).sum();
                    w.iter_mut().for_each(|p| p.1 /= sum);
                }
                follows.push(w);
                (rest.len() - 1) as u32
            })
        });
        out.extend([
            [tri[0], m[0], m[2]],
            [tri[1], m[1], m[0]],
            [tri[2], m[2], m[1]],
            [m[0], m[1], m[2]],
        ]);
    }
    out
}

/// Taubin λ|μ smoothing (λ = 0.5, μ = −0.53): rounds the cube corners with little
/// shrinkage; the connectivity is untouched, so the surface stays closed. Each vertex is
/// kept inside `boxes` (the box of the cubes of the voxels it follows), so the two lips of
/// a cut, which follow voxels on either side, never cross each other at rest.
fn taubin(x: &mut [Vec3], triangles: &[[u32; 3]], passes: usize, boxes: &[(Vec3, Vec3)]) {
    if passes == 0 {
        return;
    }
    // The boundary is closed and oriented by construction.
    let nb = oriented_surface_neighbours(x.len(), triangles);
    let mut next = x.to_vec();
    for _ in 0..passes {
        for factor in [0.5, -0.53] {
            for (i, out) in next.iter_mut().enumerate() {
                let row = nb.row(i);
                if row.is_empty() {
                    continue;
                }
                let mean = row.iter().map(|&j| x[j as usize]).sum::<Vec3>() / row.len() as Real;
                let p = x[i] + factor * (mean - x[i]);
                *out = boxes.get(i).map_or(p, |&(lo, hi)| p.clamp(lo, hi));
            }
            x.copy_from_slice(&next);
        }
    }
}

/// Triangle splits the models give the boundary surface (each one quarters the triangles).
pub const SUBDIVISIONS: usize = 1;

/// Taubin passes the models give the boundary surface.
pub const SMOOTHING: usize = 8;

/// Test helper: checks that a surface is closed and oriented (every directed edge has
/// exactly one opposite twin) with no degenerate triangle (repeated vertex or area below
/// `min_area`), and returns the Euler characteristic of each connected piece.
#[cfg(test)]
pub(crate) fn closed_pieces(
    triangles: &[[u32; 3]],
    positions: &[Vec3],
    min_area: Real,
) -> Result<Vec<i64>, String> {
    use crate::mesh::topology::{components, euler_characteristic};
    use std::collections::HashMap;
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for (t, &[a, b, c]) in triangles.iter().enumerate() {
        if a == b || b == c || a == c {
            return Err(format!("triangle {t} repeats a vertex"));
        }
        let [pa, pb, pc] = [a, b, c].map(|v| positions[v as usize]);
        let area = 0.5 * (pb - pa).cross(pc - pa).length();
        if area < min_area {
            return Err(format!("triangle {t} has area {area}"));
        }
        for e in [(a, b), (b, c), (c, a)] {
            *directed.entry(e).or_insert(0) += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        let back = directed.get(&(b, a)).copied().unwrap_or(0);
        if n != 1 || back != 1 {
            return Err(format!("edge {a}-{b} used {n} times, {b}-{a} {back} times"));
        }
    }
    let comp = components(triangles);
    Ok((0..comp.count as u32)
        .map(|c| {
            let piece: Vec<[u32; 3]> = triangles
                .iter()
                .zip(&comp.of_element)
                .filter(|(_, k)| **k == c)
                .map(|(t, _)| *t)
                .collect();
            euler_characteristic(&piece)
        })
        .collect())
}

#[cfg(test)]
#[path = "boundary_tests.rs"]
mod tests;
