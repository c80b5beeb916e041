//! The boundary surface of the surviving tetrahedra, patched locally as they are removed:
//! a removed tetrahedron's boundary faces go, its faces shared with surviving neighbours
//! appear, oriented outward from those neighbours.
//!
//! Surface vertex numbers are stable: a node that becomes exposed is appended, a node that
//! stops being on the surface (or is detached from every tetrahedron) keeps its number and
//! no triangle uses it. Constraints that name surface vertices therefore stay valid across
//! cuts, and across a reset, which restores the uncut triangles but keeps the vertices.

use std::collections::HashMap;

use crate::math::Vec3;
use crate::mesh::TET_FACES;
use crate::mesh::topology::tet_neighbours;

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
    /// Face neighbours of every tetrahedron of the uncut mesh.
    pub(super) neighbours: Vec<[Option<u32>; 4]>,
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

    /// Back to the boundary of all tetrahedra, keeping the vertex numbers handed out so far
    /// (the uncut boundary's vertices come first and keep theirs; vertices appended by cuts
    /// stay, unused).
    pub fn restore(&mut self, tets: &[[u32; 4]], rest: &[Vec3], x: &[Vec3]) {
        self.triangles.clear();
        self.keys.clear();
        self.index.clear();
        for (t, tet) in tets.iter().enumerate() {
            for k in 0..4 {
                if self.neighbours[t][k].is_none() {
                    self.add_face(tet, k, rest, x);
                }
            }
        }
        self.update_positions(x);
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
    pub(super) fn on_removed(&mut self, t: usize, system: &TensorSystem, x: &[Vec3]) {
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
