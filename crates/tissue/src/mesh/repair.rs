//! Mesh repairs: merge coincident vertices, drop unused vertices, collapsed and duplicate
//! elements, and orient elements consistently and outward.
//!
//! Repairs never panic, whatever the input: elements with out-of-range indices are dropped
//! first, non-manifold edges simply do not propagate orientation, and every vertex array
//! (positions, point data, fixed vertices) is remapped together so they stay in step.

use std::collections::VecDeque;
use std::fmt;

use serde::Serialize;

use crate::math::{Real, Vec3, tet_signed_volume, triangle_area_vector};
use crate::mesh::MeshData;
use crate::mesh::check::{COINCIDENT_TOLERANCE, finite_diagonal, traverses};
use crate::mesh::topology::{coincident_map, edge_faces};

/// Which repairs `repair` runs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RepairOptions {
    /// Merge vertices closer than this fraction of the bounding-box diagonal; `None` skips.
    pub merge_tolerance: Option<Real>,
    pub remove_degenerate: bool,
    pub remove_duplicates: bool,
    pub remove_unused: bool,
    pub orient: bool,
}

impl Default for RepairOptions {
    fn default() -> Self {
        Self {
            merge_tolerance: Some(COINCIDENT_TOLERANCE),
            remove_degenerate: true,
            remove_duplicates: true,
            remove_unused: true,
            orient: true,
        }
    }
}

/// What `repair` changed.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct RepairReport {
    /// Elements (and fixed-vertex entries) naming a vertex that does not exist.
    pub invalid_elements_removed: usize,
    pub vertices_merged: usize,
    pub degenerate_elements_removed: usize,
    pub duplicate_elements_removed: usize,
    pub unused_vertices_removed: usize,
    pub elements_reoriented: usize,
}

impl RepairReport {
    /// Number of changes of any kind.
    pub fn total(&self) -> usize {
        self.invalid_elements_removed
            + self.vertices_merged
            + self.degenerate_elements_removed
            + self.duplicate_elements_removed
            + self.unused_vertices_removed
            + self.elements_reoriented
    }
}

impl fmt::Display for RepairReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rows = [
            ("invalid elements removed", self.invalid_elements_removed),
            ("vertices merged", self.vertices_merged),
            (
                "degenerate elements removed",
                self.degenerate_elements_removed,
            ),
            (
                "duplicate elements removed",
                self.duplicate_elements_removed,
            ),
            ("unused vertices removed", self.unused_vertices_removed),
            ("elements reoriented", self.elements_reoriented),
        ];
        for (name, n) in rows {
            writeln!(f, "{name:<28} {n}")?;
        }
        Ok(())
    }
}

/// Runs the repairs in an order where each one's output suits the next: drop invalid
/// elements, merge vertices (which may collapse elements), drop collapsed then duplicate
/// elements, drop the vertices left unused, and orient last, on the final topology.
pub fn repair(mesh: &mut MeshData, options: &RepairOptions) -> RepairReport {
    let mut r = RepairReport {
        invalid_elements_removed: remove_invalid_elements(mesh),
        ..RepairReport::default()
    };
    if let Some(rel) = options.merge_tolerance {
        let tol = rel * finite_diagonal(&mesh.vertices);
        r.vertices_merged = merge_duplicate_vertices(mesh, tol);
    }
    if options.remove_degenerate {
        r.degenerate_elements_removed =
            remove_degenerate_triangles(mesh) + remove_collapsed_tets(mesh);
    }
    if options.remove_duplicates {
        r.duplicate_elements_removed = remove_duplicate_elements(mesh);
    }
    if options.remove_unused {
        r.unused_vertices_removed = remove_unused_vertices(mesh);
    }
    if options.orient {
        r.elements_reoriented = orient_outward(mesh);
    }
    r
}

fn in_range<const N: usize>(e: &[u32; N], n: usize) -> bool {
    e.iter().all(|&i| (i as usize) < n)
}

fn has_repeat(e: &[u32]) -> bool {
    (1..e.len()).any(|k| e[..k].contains(&e[k]))
}

/// Keeps the elements `keep` accepts, and their tags when there is one tag per element.
/// Returns the number removed.
fn retain_tagged<T>(
    elements: &mut Vec<T>,
    tags: &mut Vec<i32>,
    mut keep: impl FnMut(&T) -> bool,
) -> usize {
    let flags: Vec<bool> = elements.iter().map(&mut keep).collect();
    let removed = flags.iter().filter(|k| !**k).count();
    if removed == 0 {
        return 0;
    }
    if tags.len() == elements.len() {
        let mut it = flags.iter();
        tags.retain(|_| it.next().copied().unwrap_or(true));
    }
    let mut it = flags.iter();
    elements.retain(|_| it.next().copied().unwrap_or(true));
    removed
}

/// Drops elements naming a vertex that does not exist, and such fixed-vertex entries.
pub fn remove_invalid_elements(mesh: &mut MeshData) -> usize {
    let n = mesh.vertices.len();
    let mut none = Vec::new();
    let fixed_before = mesh.fixed_vertices.len();
    mesh.fixed_vertices.retain(|&v| (v as usize) < n);
    retain_tagged(&mut mesh.triangles, &mut mesh.triangle_tags, |e| {
        in_range(e, n)
    }) + retain_tagged(&mut mesh.tets, &mut mesh.tet_tags, |e| in_range(e, n))
        + retain_tagged(&mut mesh.tets10, &mut none, |e| in_range(e, n))
        + (fixed_before - mesh.fixed_vertices.len())
}

/// Renumbers vertices: `new_of[old]` is the new index (`u32::MAX` to drop) and `sources`
/// lists, for each new vertex, the old one whose position and point data it takes.
fn renumber(mesh: &mut MeshData, new_of: &[u32], sources: &[usize]) {
    let old_n = mesh.vertices.len();
    let map = |i: &mut u32| *i = new_of.get(*i as usize).copied().unwrap_or(u32::MAX);
    mesh.triangles.iter_mut().flatten().for_each(map);
    mesh.tets.iter_mut().flatten().for_each(map);
    mesh.tets10.iter_mut().flatten().for_each(map);
    let mut fixed: Vec<u32> = Vec::with_capacity(mesh.fixed_vertices.len());
    for &v in &mesh.fixed_vertices {
        let w = new_of.get(v as usize).copied().unwrap_or(u32::MAX);
        if w != u32::MAX && !fixed.contains(&w) {
            fixed.push(w);
        }
    }
    mesh.fixed_vertices = fixed;
    mesh.vertices = sources.iter().map(|&s| mesh.vertices[s]).collect();
    for field in &mut mesh.point_data {
        let c = field.components;
        // A field of the wrong length was broken before; it is left as it was.
        if c == 0 || c.checked_mul(old_n) != Some(field.values.len()) {
            continue;
        }
        field.values = sources
            .iter()
            .flat_map(|&s| field.values[s * c..(s + 1) * c].iter().copied())
            .collect();
    }
}

/// Merges vertices within `tolerance` (absolute distance) of an earlier vertex into it,
/// removing the later ones. Elements, fixed vertices and point data (the first vertex's
/// values win) follow. Returns the number of vertices removed. Elements may collapse: run
/// `remove_degenerate_triangles` and `remove_collapsed_tets` after.
pub fn merge_duplicate_vertices(mesh: &mut MeshData, tolerance: Real) -> usize {
    let rep = coincident_map(&mesh.vertices, tolerance);
    let mut new_of = vec![u32::MAX; rep.len()];
    let mut sources = Vec::with_capacity(rep.len());
    for (v, &r) in rep.iter().enumerate() {
        if r as usize == v {
            new_of[v] = sources.len() as u32;
            sources.push(v);
        }
    }
    let merged = rep.len() - sources.len();
    if merged == 0 {
        return 0;
    }
    for (v, &r) in rep.iter().enumerate() {
        new_of[v] = new_of[r as usize];
    }
    renumber(mesh, &new_of, &sources);
    merged
}

/// Removes vertices no triangle or tetrahedron uses (fixed vertices among them are dropped
/// from the fixed list). Returns the number removed.
pub fn remove_unused_vertices(mesh: &mut MeshData) -> usize {
    let n = mesh.vertices.len();
    let mut used = vec![false; n];
    let elements = mesh.triangles.iter().flatten();
    let elements = elements.chain(mesh.tets.iter().flatten());
    for &i in elements.chain(mesh.tets10.iter().flatten()) {
        if let Some(u) = used.get_mut(i as usize) {
            *u = true;
        }
    }
    let sources: Vec<usize> = (0..n).filter(|&v| used[v]).collect();
    if sources.len() == n {
        return 0;
    }
    let mut new_of = vec![u32::MAX; n];
    for (k, &s) in sources.iter().enumerate() {
        new_of[s] = k as u32;
    }
    renumber(mesh, &new_of, &sources);
    n - sources.len()
}

/// Removes triangles that repeat a vertex or have exactly zero area. Nearly flat triangles
/// with three distinct vertices are kept: removing them would open a crack in the surface.
pub fn remove_degenerate_triangles(mesh: &mut MeshData) -> usize {
    let v = &mesh.vertices;
    retain_tagged(&mut mesh.triangles, &mut mesh.triangle_tags, |t| {
        let p = |i: u32| v.get(i as usize).copied();
        match (p(t[0]), p(t[1]), p(t[2])) {
            _ if has_repeat(t) => false,
            (Some(a), Some(b), Some(c)) => triangle_area_vector(a, b, c) != Vec3::ZERO,
            _ => true,
        }
    })
}

/// Removes tetrahedra (linear and 10-node) whose corners repeat a vertex.
pub fn remove_collapsed_tets(mesh: &mut MeshData) -> usize {
    let mut none = Vec::new();
    retain_tagged(&mut mesh.tets, &mut mesh.tet_tags, |t| !has_repeat(t))
        + retain_tagged(&mut mesh.tets10, &mut none, |t| !has_repeat(&t[..4]))
}

/// Removes elements with the same vertex set as an earlier one of their kind, whatever the
/// order (two opposite triangles on the same corners are duplicates).
pub fn remove_duplicate_elements(mesh: &mut MeshData) -> usize {
    let mut none = Vec::new();
    dedup_elements(&mut mesh.triangles, &mut mesh.triangle_tags)
        + dedup_elements(&mut mesh.tets, &mut mesh.tet_tags)
        + dedup_elements(&mut mesh.tets10, &mut none)
}

fn dedup_elements<const N: usize>(elements: &mut Vec<[u32; N]>, tags: &mut Vec<i32>) -> usize {
    let mut keys: Vec<([u32; N], usize)> = elements
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let mut k = *e;
            k.sort_unstable();
            (k, i)
        })
        .collect();
    keys.sort_unstable();
    let mut keep = vec![true; elements.len()];
    for group in keys.chunk_by(|x, y| x.0 == y.0) {
        for &(_, i) in &group[1..] {
            keep[i] = false;
        }
    }
    let mut idx = 0;
    retain_tagged(elements, tags, |_| {
        idx += 1;
        keep[idx - 1]
    })
}

/// Orients elements: inverted tetrahedra get two corners swapped; triangles are made
/// consistent over each edge-connected component (agreeing with the majority of the
/// component), then closed components enclosing negative volume are flipped whole.
/// Returns the number of elements flipped.
pub fn orient_outward(mesh: &mut MeshData) -> usize {
    let v = &mesh.vertices;
    let p = |i: u32| v.get(i as usize).copied();
    let mut flipped = 0;
    let inverted = |t: &[u32]| match (p(t[0]), p(t[1]), p(t[2]), p(t[3])) {
        (Some(a), Some(b), Some(c), Some(d)) => tet_signed_volume(a, b, c, d) < 0.0,
        _ => false,
    };
    for t in &mut mesh.tets {
        if inverted(t) {
            t.swap(2, 3);
            flipped += 1;
        }
    }
    for t in &mut mesh.tets10 {
        if inverted(t) {
            // Swapping corners 2 and 3 exchanges edges (1,2) ↔ (1,3) and (0,2) ↔ (0,3).
            t.swap(2, 3);
            t.swap(5, 8);
            t.swap(6, 7);
            flipped += 1;
        }
    }
    let flips = surface_flips(v, &mesh.triangles);
    for (t, &f) in mesh.triangles.iter_mut().zip(&flips) {
        if f {
            t.swap(1, 2);
            flipped += 1;
        }
    }
    flipped
}

/// Which triangles to flip for a consistent, outward surface.
fn surface_flips(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Vec<bool> {
    let n = vertices.len();
    let usable = |t: &[u32; 3]| in_range(t, n) && !has_repeat(t);
    let ef = edge_faces(triangles);
    // Links across manifold edges: (face, neighbour, whether they traverse the edge alike).
    let mut links: Vec<(u32, u32, bool)> = Vec::new();
    // Faces on a border or non-manifold edge: their component cannot be judged closed.
    let mut open = vec![false; triangles.len()];
    for (e, faces) in ef.with_face_count(|_| true) {
        match faces {
            [f, g] if usable(&triangles[*f as usize]) && usable(&triangles[*g as usize]) => {
                let same =
                    traverses(triangles[*f as usize], e) == traverses(triangles[*g as usize], e);
                links.push((*f, *g, same));
                links.push((*g, *f, same));
            }
            _ => faces.iter().for_each(|&f| open[f as usize] = true),
        }
    }
    links.sort_unstable();
    let start = |f: u32| links.partition_point(|l| l.0 < f);

    let mut flip: Vec<Option<bool>> = vec![None; triangles.len()];
    let mut queue = VecDeque::new();
    for seed in 0..triangles.len() {
        if flip[seed].is_some() || !usable(&triangles[seed]) {
            continue;
        }
        flip[seed] = Some(false);
        queue.push_back(seed as u32);
        let mut members = Vec::new();
        let mut closed = true;
        while let Some(f) = queue.pop_front() {
            members.push(f);
            closed &= !open[f as usize];
            let here = flip[f as usize].unwrap_or(false);
            for &(_, g, same) in links[start(f)..].iter().take_while(|l| l.0 == f) {
                // Traversing the shared edge alike means one of the two must turn.
                let want = here ^ same;
                match flip[g as usize] {
                    None => {
                        flip[g as usize] = Some(want);
                        queue.push_back(g);
                    }
                    // A Möbius-like loop: no consistent orientation exists.
                    Some(have) if have != want => closed = false,
                    Some(_) => {}
                }
            }
        }
        let turned = members
            .iter()
            .filter(|&&f| flip[f as usize] == Some(true))
            .count();
        let mut invert = 2 * turned > members.len();
        if closed {
            let volume: Real = members
                .iter()
                .map(|&f| {
                    let [a, b, c] = triangles[f as usize].map(|i| vertices[i as usize]);
                    let s = a.dot(b.cross(c));
                    if flip[f as usize] == Some(true) {
                        -s
                    } else {
                        s
                    }
                })
                .sum();
            invert = volume < 0.0;
        }
        if invert {
            for &f in &members {
                flip[f as usize] = flip[f as usize].map(|x| !x);
            }
        }
    }
    flip.into_iter().map(|f| f == Some(true)).collect()
}

#[cfg(test)]
mod tests;
