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

use std::collections::HashMap;

use crate::math::{Real, Vec3};
use crate::mesh::topology::{UnionFind, triangle_edges, vertex_neighbours};

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
    let [nx, ny, _] = links.dims;
    let coords = |v: usize| [v % nx, (v / nx) % ny, v / (nx * ny)];
    let boundary = |v: usize, d: usize| links.is_occupied(v) && links.linked(v, d).is_none();

    // Faces as (voxel, direction), with their corners counter-clockwise seen from outside.
    let mut faces: Vec<(usize, usize)> = Vec::new();
    let mut face_of: HashMap<(usize, usize), usize> = HashMap::new();
    for v in 0..links.len() {
        for d in 0..6 {
            if boundary(v, d) {
                face_of.insert((v, d), faces.len());
                faces.push((v, d));
            }
        }
    }
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

    // Twin edges: join the face corners on each side of every face edge.
    let mut uf = UnionFind::new(4 * faces.len());
    // Per face and edge slot s (corners s → s + 1): the twin face.
    let mut twin_of = vec![[u32::MAX; 4]; faces.len()];
    for (f, &(v, d)) in faces.iter().enumerate() {
        let (p, sp) = (d / 2, d & 1 == 1);
        let corners = corners_of((v, d));
        for q in [(p + 1) % 3, (p + 2) % 3] {
            for sq in [false, true] {
                let Some(g) = twin(links, &face_of, v, p, sp, q, sq) else {
                    continue;
                };
                let other = corners_of(faces[g]);
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
    let mut vertex_of_root: HashMap<usize, u32> = HashMap::new();
    let mut rest = Vec::new();
    let mut members: Vec<Vec<u32>> = Vec::new();
    let mut slot_vertex = vec![0u32; 4 * faces.len()];
    for (f, &face) in faces.iter().enumerate() {
        let corners = corners_of(face);
        for s in 0..4 {
            let root = uf.find(4 * f + s);
            let id = *vertex_of_root.entry(root).or_insert_with(|| {
                let c = corners[s].map(|x| x as Real - 0.5);
                rest.push(links.origin + Vec3::from_array(c) * links.spacing);
                members.push(Vec::new());
                (rest.len() - 1) as u32
            });
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
    let mut on_edge: HashMap<(u32, u32), Vec<(usize, usize)>> = HashMap::new();
    for f in 0..faces.len() {
        for e in 0..4 {
            let (a, b) = (slot_vertex[4 * f + e], slot_vertex[4 * f + (e + 1) % 4]);
            on_edge
                .entry((a.min(b), a.max(b)))
                .or_default()
                .push((f, e));
        }
    }
    let mut midpoint: HashMap<(usize, usize), u32> = HashMap::new();
    let mut shared: Vec<_> = on_edge.into_values().filter(|u| u.len() > 2).collect();
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
        members.push(vec![v as u32]);
        let c = (rest.len() - 1) as u32;
        for k in 0..poly.len() {
            triangles.push([c, poly[k], poly[(k + 1) % poly.len()]]);
        }
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
        triangles = split_in_four(&mut rest, &mut follows, &triangles);
    }
    let (nodes, weights): (Vec<[u32; 8]>, Vec<[Real; 8]>) = follows
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
    taubin(&mut rest, &triangles, smoothing, &boxes);
    BoundarySurface {
        embedding: TrilinearEmbedding {
            rest,
            nodes,
            weights,
        },
        triangles,
    }
}

/// The face sharing the edge of face (v, direction (p, sp)) on its side (q, sq): walk
/// around the lattice edge through linked cells until a boundary face closes the wedge.
fn twin(
    links: &VoxelLinks,
    face_of: &HashMap<(usize, usize), usize>,
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
    triangles: &[[u32; 3]],
) -> Vec<[u32; 3]> {
    let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
    let mut out = Vec::with_capacity(4 * triangles.len());
    for tri in triangles {
        let m = [0, 1, 2].map(|e| {
            let (a, b) = (tri[e], tri[(e + 1) % 3]);
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                rest.push(0.5 * (rest[a as usize] + rest[b as usize]));
                let mut w: Vec<(u32, Real)> = Vec::with_capacity(8);
                for &(v, x) in follows[a as usize].iter().chain(&follows[b as usize]) {
                    match w.iter_mut().find(|(u, _)| *u == v) {
                        Some((_, y)) => *y += 0.5 * x,
                        None => w.push((v, 0.5 * x)),
                    }
                }
                if w.len() > 8 {
                    w.sort_by(|p, q| q.1.total_cmp(&p.1));
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
    let nb = vertex_neighbours(x.len(), &triangle_edges(triangles));
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

/// Switches a model's drawn surface to the voxel boundary: keeps the first `original`
/// vertices of `embedding` (no longer drawn, but constraints keep naming them and they
/// keep following their elements), replaces any vertices after them by the boundary's,
/// with voxel ids renamed through `element_of` (voxel → element id) when given, and
/// returns the triangles to draw (numbered after the original vertices).
pub fn redraw(
    embedding: &mut TrilinearEmbedding,
    original: usize,
    links: &VoxelLinks,
    element_of: Option<&[u32]>,
) -> Vec<[u32; 3]> {
    let b = boundary_surface_with(links, SUBDIVISIONS, SMOOTHING);
    let mut e = b.embedding;
    if let Some(map) = element_of {
        e.remap(map);
    }
    embedding.rest.truncate(original);
    embedding.nodes.truncate(original);
    embedding.weights.truncate(original);
    embedding.rest.extend(e.rest);
    embedding.nodes.extend(e.nodes);
    embedding.weights.extend(e.weights);
    let offset = original as u32;
    b.triangles
        .into_iter()
        .map(|t| t.map(|v| v + offset))
        .collect()
}

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
mod tests {
    use super::*;
    use crate::mesh::SurfaceMesh;
    use crate::model::CutPath;
    use crate::voxel::VoxelGrid;

    fn pieces(links: &VoxelLinks, smoothing: usize) -> (Vec<i64>, Real) {
        let b = boundary_surface(links, smoothing);
        let x = &b.embedding.rest;
        let chi = closed_pieces(&b.triangles, x, 1e-3).unwrap();
        let volume = SurfaceMesh::new(x.clone(), b.triangles.clone()).signed_volume();
        (chi, volume)
    }

    fn rest_cut(links: &mut VoxelLinks, blade: &CutPath) -> usize {
        let x: Vec<Vec3> = (0..links.len()).map(|v| links.centre_of(v)).collect();
        links.cut(|v| x[v], blade).len()
    }

    fn blade_x(x: Real, y_top: Real) -> CutPath {
        CutPath {
            start: [Vec3::new(x, -1.0, -1.0), Vec3::new(x, y_top, -1.0)],
            end: [Vec3::new(x, -1.0, 9.0), Vec3::new(x, y_top, 9.0)],
        }
    }

    #[test]
    fn a_block_is_one_closed_box_of_exact_volume() {
        let links = VoxelLinks::new(&VoxelGrid::filled([4, 3, 5], 1.0), 6);
        let (chi, v) = pieces(&links, 0);
        assert_eq!(chi, vec![2]);
        assert!((v - 60.0).abs() < 1e-12, "{v}");
        // 2·(4·3 + 3·5 + 4·5) faces, two triangles each.
        assert_eq!(boundary_surface(&links, 0).triangles.len(), 4 * 47);
        let (chi, v) = pieces(&links, SMOOTHING);
        assert_eq!(chi, vec![2]);
        // Rounded, inside the voxels, losing little volume.
        assert!(v > 0.85 * 60.0 && v < 60.0, "{v}");
    }

    #[test]
    fn a_full_cut_gives_two_closed_boxes_and_a_partial_cut_one() {
        let g = VoxelGrid::filled([6, 6, 6], 1.0);
        let mut links = VoxelLinks::new(&g, 6);
        assert_eq!(rest_cut(&mut links, &blade_x(2.5, 9.0)), 36);
        let (chi, v) = pieces(&links, 0);
        assert_eq!(chi, vec![2, 2]);
        assert!((v - 216.0).abs() < 1e-12);
        // The lips: 36 faces on each side of the cut, twice the 36 · 2 triangles.
        let b = boundary_surface(&links, 0);
        assert_eq!(b.triangles.len(), 2 * (6 * 36 + 2 * 36));
        assert_eq!(pieces(&links, SMOOTHING).0, vec![2, 2]);

        // A blade stopping at y = 2.5 cuts the links of rows y = 0..2: a slit, one piece.
        let mut links = VoxelLinks::new(&g, 6);
        assert_eq!(rest_cut(&mut links, &blade_x(2.5, 2.5)), 18);
        let (chi, v) = pieces(&links, 0);
        assert_eq!(chi, vec![2]);
        assert!((v - 216.0).abs() < 1e-12);
        assert_eq!(pieces(&links, SMOOTHING).0, vec![2]);
    }

    #[test]
    fn voxels_touching_along_an_edge_or_a_corner_stay_apart() {
        // Two voxels sharing an edge only, and a third sharing a corner only.
        let mut g = VoxelGrid::new([3, 3, 3], Vec3::ONE, Vec3::ZERO);
        for v in [g.index(0, 0, 0), g.index(1, 1, 0), g.index(2, 2, 1)] {
            g.labels[v.unwrap()] = 1;
        }
        let (chi, v) = pieces(&VoxelLinks::new(&g, 6), 0);
        assert_eq!(chi, vec![2, 2, 2]);
        assert!((v - 3.0).abs() < 1e-12);
        // A ring of eight voxels around an empty centre: a torus (χ = 0), and a 2x2x3
        // block whose middle layer keeps two voxels touching along an edge only.
        let mut g = VoxelGrid::new([3, 3, 1], Vec3::ONE, Vec3::ZERO);
        g.labels.fill(1);
        g.labels[4] = 0;
        assert_eq!(pieces(&VoxelLinks::new(&g, 6), 0).0, vec![0]);
        let mut g = VoxelGrid::new([2, 2, 3], Vec3::ONE, Vec3::ZERO);
        g.labels.fill(1);
        for (i, j) in [(1, 0), (0, 1)] {
            let v = g.index(i, j, 1).unwrap();
            g.labels[v] = 0;
        }
        // Two columns joining the end layers: a torus.
        let (chi, v) = pieces(&VoxelLinks::new(&g, 6), 0);
        assert_eq!(chi, vec![0]);
        assert!((v - 10.0).abs() < 1e-12);
    }

    #[test]
    fn a_carved_cavity_is_a_second_closed_sheet() {
        let mut links = VoxelLinks::new(&VoxelGrid::filled([5, 5, 5], 1.0), 6);
        let x: Vec<Vec3> = (0..links.len()).map(|v| links.centre_of(v)).collect();
        let (gone, _) = links.carve(|v| x[v], Vec3::splat(2.0), 0.5);
        assert_eq!(gone.len(), 1);
        // The outer box and the inner cube's inward sheet, both genus 0.
        let (chi, v) = pieces(&links, 0);
        assert_eq!(chi, vec![2, 2]);
        assert!((v - 124.0).abs() < 1e-12);
    }

    #[test]
    fn random_voxels_with_random_cut_links_are_always_closed() {
        // Random occupancy (about 60%) and a random third of the face links cut: every
        // configuration of edge and corner contacts, slits and crack tips shows up.
        let mut seed: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let mut midpoints = 0;
        let corners_used = |b: &BoundarySurface| {
            b.embedding
                .rest
                .iter()
                .filter(|p| p.to_array().iter().all(|c| c.fract().abs() == 0.5))
                .count()
        };
        for _ in 0..200 {
            let mut g = VoxelGrid::new([5, 5, 5], Vec3::ONE, Vec3::ZERO);
            for l in &mut g.labels {
                *l = (next() % 10 < 6) as u8;
            }
            let mut links = VoxelLinks::new(&g, 6);
            for v in 0..links.len() {
                for d in [1, 3, 5] {
                    if next() % 3 == 0 {
                        links.unlink(v, d);
                    }
                }
            }
            for (split, smoothing) in [(0, 0), (0, SMOOTHING), (SUBDIVISIONS, SMOOTHING)] {
                let b = boundary_surface_with(&links, split, smoothing);
                closed_pieces(&b.triangles, &b.embedding.rest, 1e-6).unwrap();
            }
            let b = boundary_surface(&links, 0);
            let v = SurfaceMesh::new(b.embedding.rest.clone(), b.triangles.clone()).signed_volume();
            assert!((v - g.occupied() as Real).abs() < 1e-9, "{v}");
            midpoints += b.embedding.len() - corners_used(&b);
        }
        // The fix for edge contacts was exercised.
        assert!(midpoints > 0);
    }
}
