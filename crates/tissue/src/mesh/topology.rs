//! Mesh topology: unique edges, vertex adjacency, edge → face and tet → tet adjacency,
//! connected components, the Euler characteristic, and coincident-vertex detection.
//!
//! Everything here is deterministic (sorted, never hash-order dependent) and tolerant of
//! bad input: element indices at or beyond the vertex count are skipped rather than
//! trusted, so a broken file never panics a topology query.

use std::collections::HashMap;

use crate::math::{Real, Vec3, is_finite_vec};

/// Compressed sparse rows: row `i` is `indices[offsets[i]..offsets[i + 1]]`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Csr {
    pub offsets: Vec<usize>,
    pub indices: Vec<u32>,
}

impl Csr {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `i`; empty for a row that does not exist.
    pub fn row(&self, i: usize) -> &[u32] {
        match (self.offsets.get(i), self.offsets.get(i + 1)) {
            (Some(&s), Some(&e)) => self.indices.get(s..e).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Builds rows from (row, value) pairs; pairs with `row >= rows` are dropped. Values keep
    /// their input order within a row (counting sort), which keeps results deterministic.
    fn from_pairs(rows: usize, pairs: impl Iterator<Item = (u32, u32)> + Clone) -> Self {
        let mut offsets = vec![0usize; rows + 1];
        for (r, _) in pairs.clone() {
            if let Some(o) = offsets.get_mut(r as usize + 1) {
                *o += 1;
            }
        }
        for i in 0..rows {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut indices = vec![0u32; offsets[rows]];
        for (r, v) in pairs {
            if let Some(f) = fill.get_mut(r as usize).filter(|_| (r as usize) < rows) {
                indices[*f] = v;
                *f += 1;
            }
        }
        Self { offsets, indices }
    }
}

#[inline]
fn edge_key(a: u32, b: u32) -> [u32; 2] {
    if a < b { [a, b] } else { [b, a] }
}

/// Unique edges of a triangle mesh as sorted pairs `[lo, hi]`, in increasing order.
/// Collapsed edges (a triangle repeating a vertex) are left out.
pub fn triangle_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    unique_edges(
        triangles
            .iter()
            .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)]),
    )
}

/// Unique edges of a tetrahedral mesh as sorted pairs `[lo, hi]`, in increasing order.
pub fn tet_edges(tets: &[[u32; 4]]) -> Vec<[u32; 2]> {
    unique_edges(
        tets.iter()
            .flat_map(|&[a, b, c, d]| [(a, b), (a, c), (a, d), (b, c), (b, d), (c, d)]),
    )
}

fn unique_edges(pairs: impl Iterator<Item = (u32, u32)>) -> Vec<[u32; 2]> {
    let mut e: Vec<[u32; 2]> = pairs
        .filter(|(a, b)| a != b)
        .map(|(a, b)| edge_key(a, b))
        .collect();
    e.sort_unstable();
    e.dedup();
    e
}

/// Vertex → neighbouring vertices (sorted), from a list of unique edges.
pub fn vertex_neighbours(vertex_count: usize, edges: &[[u32; 2]]) -> Csr {
    Csr::from_pairs(
        vertex_count,
        edges.iter().flat_map(|&[a, b]| [(a, b), (b, a)]),
    )
    .sorted_rows()
}

/// Vertex → neighbouring vertices of a closed, consistently oriented triangle surface, in
/// triangle order. There every edge runs a→b in exactly one triangle, so a's neighbours are
/// the heads of its outgoing edges, each once: no edge list to sort and deduplicate, which
/// is most of `vertex_neighbours`' cost on a large surface.
pub fn oriented_surface_neighbours(vertex_count: usize, triangles: &[[u32; 3]]) -> Csr {
    Csr::from_pairs(
        vertex_count,
        triangles
            .iter()
            .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)]),
    )
}

impl Csr {
    fn sorted_rows(mut self) -> Self {
        for i in 0..self.len() {
            let (s, e) = (self.offsets[i], self.offsets[i + 1]);
            self.indices[s..e].sort_unstable();
        }
        self
    }
}

/// Vertex → incident elements (triangles, tetrahedra or any fixed-size element), each row in
/// increasing element order. An element repeating a vertex is listed once for it.
pub fn vertex_elements<const N: usize>(vertex_count: usize, elements: &[[u32; N]]) -> Csr {
    let pairs = elements.iter().enumerate().flat_map(|(e, el)| {
        el.iter()
            .enumerate()
            .filter(move |(k, v)| !el[..*k].contains(v))
            .map(move |(_, &v)| (v, e as u32))
    });
    Csr::from_pairs(vertex_count, pairs)
}

/// Each unique edge of a surface with the triangles using it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct EdgeFaces {
    /// Unique edges `[lo, hi]`, increasing.
    pub edges: Vec<[u32; 2]>,
    /// Row `i`: the triangles using edge `i`, increasing.
    pub faces: Csr,
}

impl EdgeFaces {
    /// Edges used by exactly one triangle: the rims of holes.
    pub fn border_edges(&self) -> impl Iterator<Item = [u32; 2]> + '_ {
        self.with_face_count(|n| n == 1).map(|(e, _)| e)
    }

    /// Edges used by three or more triangles, with their triangles.
    pub fn non_manifold_edges(&self) -> impl Iterator<Item = ([u32; 2], &[u32])> + '_ {
        self.with_face_count(|n| n > 2)
    }

    /// Edges whose face count satisfies `keep`, with their faces.
    pub fn with_face_count<'a>(
        &'a self,
        keep: impl Fn(usize) -> bool + 'a,
    ) -> impl Iterator<Item = ([u32; 2], &'a [u32])> + 'a {
        self.edges
            .iter()
            .enumerate()
            .map(|(i, &e)| (e, self.faces.row(i)))
            .filter(move |(_, f)| keep(f.len()))
    }
}

/// The edge → faces map of a surface. Collapsed edges are left out; a triangle repeating a
/// vertex still contributes its proper edges.
pub fn edge_faces(triangles: &[[u32; 3]]) -> EdgeFaces {
    let mut pairs: Vec<([u32; 2], u32)> = triangles
        .iter()
        .enumerate()
        .flat_map(|(t, &[a, b, c])| [(a, b), (b, c), (c, a)].map(|(p, q)| (p, q, t as u32)))
        .filter(|(p, q, _)| p != q)
        .map(|(p, q, t)| (edge_key(p, q), t))
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let mut edges = Vec::new();
    let mut offsets = vec![0usize];
    let mut faces = Vec::with_capacity(pairs.len());
    for (i, &(e, t)) in pairs.iter().enumerate() {
        if i == 0 || pairs[i - 1].0 != e {
            if i > 0 {
                offsets.push(faces.len());
            }
            edges.push(e);
        }
        faces.push(t);
    }
    if !edges.is_empty() {
        offsets.push(faces.len());
    }
    EdgeFaces {
        edges,
        faces: Csr {
            offsets,
            indices: faces,
        },
    }
}

/// For each tetrahedron, the neighbour across face k (the face opposite corner k, see
/// `TET_FACES`), or `None` on the boundary. A face shared by three or more tetrahedra is
/// non-manifold and gets no neighbour on any side.
pub fn tet_neighbours(tets: &[[u32; 4]]) -> Vec<[Option<u32>; 4]> {
    let mut faces: Vec<([u32; 3], u32, u8)> = Vec::with_capacity(tets.len() * 4);
    for (t, tet) in tets.iter().enumerate() {
        for (k, f) in crate::mesh::TET_FACES.iter().enumerate() {
            let key = crate::mesh::boundary::sorted([tet[f[0]], tet[f[1]], tet[f[2]]]);
            faces.push((key, t as u32, k as u8));
        }
    }
    faces.sort_unstable();
    let mut out = vec![[None; 4]; tets.len()];
    for group in faces.chunk_by(|x, y| x.0 == y.0) {
        if let [(_, t0, k0), (_, t1, k1)] = group {
            out[*t0 as usize][*k0 as usize] = Some(*t1);
            out[*t1 as usize][*k1 as usize] = Some(*t0);
        }
    }
    out
}

/// Connected components of a set of elements, joined through shared vertices.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Components {
    pub count: usize,
    /// Component of each element; components are numbered in order of their first element.
    pub of_element: Vec<u32>,
}

/// Components of any elements (triangles, tetrahedra) joined through shared vertices.
pub fn components<const N: usize>(elements: &[[u32; N]]) -> Components {
    // Union-find over the vertices the elements use, numbered compactly so that a stray huge
    // index costs nothing.
    let mut used: Vec<u32> = elements.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    let slot = |v: u32| used.binary_search(&v).unwrap_or(0);
    let n = used.len();
    let mut uf = UnionFind::new(n);
    for e in elements {
        for w in e.windows(2) {
            uf.union(slot(w[0]), slot(w[1]));
        }
    }
    let mut label = vec![u32::MAX; n];
    let mut count = 0usize;
    let of_element = elements
        .iter()
        .map(|e| {
            let Some(&v) = e.first() else { return 0 };
            let root = uf.find(slot(v));
            if label[root] == u32::MAX {
                label[root] = count as u32;
                count += 1;
            }
            label[root]
        })
        .collect();
    Components { count, of_element }
}

/// Euler characteristic V − E + F of a surface, counting only vertices the triangles use.
/// 2 for a closed genus-0 surface, 1 for a disc.
pub fn euler_characteristic(triangles: &[[u32; 3]]) -> i64 {
    let mut used: Vec<u32> = triangles.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    used.len() as i64 - triangle_edges(triangles).len() as i64 + triangles.len() as i64
}

pub(crate) struct UnionFind {
    parent: Vec<usize>,
}

impl UnionFind {
    pub(crate) fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
        }
    }

    pub(crate) fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }

    pub(crate) fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        // The smaller root wins so that results do not depend on union order.
        if ra < rb {
            self.parent[rb] = ra;
        } else {
            self.parent[ra] = rb;
        }
    }
}

/// For each vertex, the first vertex (lowest index) within `tolerance` of it: itself when it
/// is unique. Non-finite vertices map to themselves.
///
/// A spatial hash with cells of size `tolerance` holds only the representatives, which are
/// more than `tolerance` apart, so every cell holds few of them and the search is O(n) even
/// when all vertices coincide.
pub fn coincident_map(vertices: &[Vec3], tolerance: Real) -> Vec<u32> {
    let tol = if tolerance.is_finite() {
        tolerance.max(0.0)
    } else {
        0.0
    };
    let h = if tol > 0.0 { tol } else { 1.0 };
    let cell = |p: Vec3| {
        let c = (p / h).floor();
        // `as` saturates: far-away points share an extreme cell but never overflow.
        [c.x as i64, c.y as i64, c.z as i64]
    };
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    let mut map = Vec::with_capacity(vertices.len());
    for (i, &p) in vertices.iter().enumerate() {
        if !is_finite_vec(p) {
            map.push(i as u32);
            continue;
        }
        let c = cell(p);
        let mut found = None;
        'search: for dx in -1i64..=1 {
            for dy in -1i64..=1 {
                for dz in -1i64..=1 {
                    let key = [
                        c[0].saturating_add(dx),
                        c[1].saturating_add(dy),
                        c[2].saturating_add(dz),
                    ];
                    let Some(reps) = grid.get(&key) else { continue };
                    for &r in reps {
                        if vertices[r as usize].distance_squared(p) <= tol * tol {
                            found = Some(found.map_or(r, |f: u32| f.min(r)));
                        }
                    }
                    if found.is_some() && tol == 0.0 {
                        break 'search;
                    }
                }
            }
        }
        match found {
            Some(r) => map.push(r),
            None => {
                grid.entry(c).or_default().push(i as u32);
                map.push(i as u32);
            }
        }
    }
    map
}

#[cfg(test)]
mod tests;
