//! Cutting by removing tetrahedra (electrocautery style, survey §2.4): the tetrahedra the
//! blade's swept surface touches leave the mesh, their tensors leave the vertices, edges
//! and triangles they shared (`TensorSystem::remove_tet`, O(1) each), and the boundary
//! surface is patched locally: a removed tetrahedron's boundary faces go, its faces shared
//! with surviving neighbours appear, oriented outward from those neighbours.
//!
//! Surface vertex numbers are stable: a node that becomes exposed is appended, a node that
//! stops being on the surface keeps its number (no triangle uses it). Constraints that name
//! surface vertices therefore stay valid across cuts.
//!
//! After a cut the surviving tetrahedra are grouped into pieces joined through shared
//! faces; every piece but the largest is a fragment, reported and then removed or kept as
//! the model's `fragments` setting says. Finding the touched tetrahedra and the pieces looks
//! at every tetrahedron (a bounding-box test first); only the updates are local.

use std::collections::HashMap;

use crate::math::{Real, Vec3};
use crate::mesh::TET_FACES;
use crate::mesh::topology::tet_neighbours;
use crate::model::CutPath;

use super::system::TensorSystem;

fn face_key(tet: &[u32; 4], k: usize) -> [u32; 3] {
    let f = TET_FACES[k];
    let mut key = [tet[f[0]], tet[f[1]], tet[f[2]]];
    key.sort_unstable();
    key
}

/// The boundary surface of the surviving tetrahedra, kept up to date as they are removed.
#[derive(Clone, Debug, Default)]
pub struct CutSurface {
    /// Mechanical node of each surface vertex.
    pub nodes: Vec<u32>,
    node_to_surface: Vec<u32>,
    pub rest_positions: Vec<Vec3>,
    pub positions: Vec<Vec3>,
    /// Triangles over surface vertices, outward.
    pub triangles: Vec<[u32; 3]>,
    /// Sorted node ids of each triangle → its index in `triangles`.
    index: HashMap<[u32; 3], usize>,
    keys: Vec<[u32; 3]>,
    neighbours: Vec<[Option<u32>; 4]>,
}

impl CutSurface {
    /// The boundary of all tetrahedra (outward for positive ones).
    pub fn new(tets: &[[u32; 4]], rest: &[Vec3]) -> Self {
        let neighbours = tet_neighbours(tets);
        let mut s = Self {
            node_to_surface: vec![u32::MAX; rest.len()],
            neighbours,
            ..Self::default()
        };
        for (t, tet) in tets.iter().enumerate() {
            for k in 0..4 {
                if s.neighbours[t][k].is_none() {
                    s.add_face(tet, k, rest, rest);
                }
            }
        }
        s
    }

    /// Surface vertex of node `n`, appended (at `x`) if it is new.
    fn vertex(&mut self, n: u32, rest: &[Vec3], x: &[Vec3]) -> u32 {
        let slot = &mut self.node_to_surface[n as usize];
        if *slot == u32::MAX {
            *slot = self.nodes.len() as u32;
            self.nodes.push(n);
            self.rest_positions.push(rest[n as usize]);
            self.positions.push(x[n as usize]);
        }
        *slot
    }

    fn add_face(&mut self, tet: &[u32; 4], k: usize, rest: &[Vec3], x: &[Vec3]) {
        let key = face_key(tet, k);
        if self.index.contains_key(&key) {
            return;
        }
        let f = TET_FACES[k];
        let tri = [tet[f[0]], tet[f[1]], tet[f[2]]].map(|n| self.vertex(n, rest, x));
        self.index.insert(key, self.triangles.len());
        self.triangles.push(tri);
        self.keys.push(key);
    }

    fn remove_face(&mut self, key: &[u32; 3]) {
        let Some(i) = self.index.remove(key) else {
            return;
        };
        self.triangles.swap_remove(i);
        self.keys.swap_remove(i);
        if let Some(moved) = self.keys.get(i) {
            self.index.insert(*moved, i);
        }
    }

    /// Patches the surface for tetrahedron `t`, just removed from `system`.
    fn on_removed(&mut self, t: usize, system: &TensorSystem, x: &[Vec3]) {
        let tet = system.tets[t];
        for k in 0..4 {
            let key = face_key(&tet, k);
            match self.neighbours[t][k] {
                Some(n) if system.is_alive(n as usize) => {
                    let other = system.tets[n as usize];
                    if let Some(j) = (0..4).find(|&j| face_key(&other, j) == key) {
                        self.add_face(&other, j, &system.rest, x);
                    }
                }
                _ => self.remove_face(&key),
            }
        }
    }

    /// Copies the current node positions onto the surface vertices.
    pub fn update_positions(&mut self, x: &[Vec3]) {
        for (p, &n) in self.positions.iter_mut().zip(&self.nodes) {
            *p = x[n as usize];
        }
    }

    pub fn surface_vertex(&self, node: usize) -> Option<u32> {
        self.node_to_surface
            .get(node)
            .copied()
            .filter(|&s| s != u32::MAX)
    }
}

/// What one cut removed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CutReport {
    /// Tetrahedra the blade touched.
    pub cut_tets: usize,
    /// Pieces separated from the largest one, with their tetrahedron counts.
    pub fragments: Vec<usize>,
    /// Tetrahedra removed as fragments (0 when fragments are kept).
    pub fragment_tets: usize,
    pub added_vertices: usize,
    /// Every tetrahedron removed, in order.
    pub removed: Vec<usize>,
}

/// Removes the tetrahedra touched by the blade's sweep and patches the surface; fragments
/// are removed when `remove_fragments`.
pub fn cut(
    system: &mut TensorSystem,
    surface: &mut CutSurface,
    x: &[Vec3],
    blade: &CutPath,
    remove_fragments: bool,
) -> CutReport {
    let vertices_before = surface.nodes.len();
    let [a, b] = blade.start;
    let [c, d] = blade.end;
    let quads = [[a, b, d], [a, d, c]];
    let lo = a.min(b).min(c).min(d);
    let hi = a.max(b).max(c).max(d);
    let touched: Vec<usize> = (0..system.tets.len())
        .filter(|&t| system.is_alive(t))
        .filter(|&t| {
            let p = system.tets[t].map(|v| x[v as usize]);
            let (pl, ph) = (
                p[0].min(p[1]).min(p[2]).min(p[3]),
                p[0].max(p[1]).max(p[2]).max(p[3]),
            );
            pl.cmple(hi).all()
                && ph.cmpge(lo).all()
                && quads.iter().any(|q| tet_meets_triangle(&p, q))
        })
        .collect();
    let mut report = CutReport::default();
    for &t in &touched {
        if system.remove_tet(t) {
            surface.on_removed(t, system, x);
            report.removed.push(t);
        }
    }
    report.cut_tets = report.removed.len();
    if !touched.is_empty() {
        let pieces = pieces(system, &surface.neighbours);
        let largest = pieces.iter().map(Vec::len).max().unwrap_or(0);
        let main = pieces.iter().position(|p| p.len() == largest);
        for (i, piece) in pieces.iter().enumerate() {
            if Some(i) == main {
                continue;
            }
            report.fragments.push(piece.len());
            if remove_fragments {
                for &t in piece {
                    if system.remove_tet(t) {
                        surface.on_removed(t, system, x);
                        report.removed.push(t);
                    }
                }
                report.fragment_tets += piece.len();
            }
        }
    }
    report.added_vertices = surface.nodes.len() - vertices_before;
    report
}

/// The surviving tetrahedra grouped into pieces joined through faces.
fn pieces(system: &TensorSystem, neighbours: &[[Option<u32>; 4]]) -> Vec<Vec<usize>> {
    let n = system.tets.len();
    let mut seen = vec![false; n];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for start in 0..n {
        if seen[start] || !system.is_alive(start) {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut piece = Vec::new();
        while let Some(t) = stack.pop() {
            piece.push(t);
            for m in neighbours[t].iter().flatten() {
                let m = *m as usize;
                if !seen[m] && system.is_alive(m) {
                    seen[m] = true;
                    stack.push(m);
                }
            }
        }
        out.push(piece);
    }
    out
}

/// Where segment p→q crosses triangle (a, b, c), if it does (Möller–Trumbore).
fn segment_hits_triangle(p: Vec3, q: Vec3, tri: &[Vec3; 3]) -> bool {
    let dir = q - p;
    let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
    let h = dir.cross(e2);
    let det = e1.dot(h);
    if det.abs() <= 1e-300 {
        return false;
    }
    let inv = 1.0 / det;
    let s = p - tri[0];
    let u = s.dot(h) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let qv = s.cross(e1);
    let v = dir.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = e2.dot(qv) * inv;
    (0.0..=1.0).contains(&t)
}

fn inside_tet(p: Vec3, x: &[Vec3; 4]) -> bool {
    let vol = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| (b - a).dot((c - a).cross(d - a));
    let total = vol(x[0], x[1], x[2], x[3]);
    let parts = [
        vol(p, x[1], x[2], x[3]),
        vol(x[0], p, x[2], x[3]),
        vol(x[0], x[1], p, x[3]),
        vol(x[0], x[1], x[2], p),
    ];
    parts.iter().all(|&v| v * total >= 0.0)
}

/// Does the (solid) tetrahedron meet the triangle? An edge of one crosses a face of the
/// other, or the triangle lies inside.
pub fn tet_meets_triangle(x: &[Vec3; 4], tri: &[Vec3; 3]) -> bool {
    const EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];
    if EDGES
        .iter()
        .any(|[i, j]| segment_hits_triangle(x[*i], x[*j], tri))
    {
        return true;
    }
    for f in TET_FACES {
        let face = [x[f[0]], x[f[1]], x[f[2]]];
        if (0..3).any(|k| segment_hits_triangle(tri[k], tri[(k + 1) % 3], &face)) {
            return true;
        }
    }
    inside_tet(tri[0], x)
}

/// Volume enclosed by the surface (outward triangles give the solid's volume).
pub fn enclosed_volume(positions: &[Vec3], triangles: &[[u32; 3]]) -> Real {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}
