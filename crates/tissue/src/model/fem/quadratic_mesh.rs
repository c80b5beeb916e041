//! The 10-node tetrahedral mesh built from a linear one: one mid-edge node per unique edge.
//!
//! Corner nodes keep their linear ids (0..n), so the boundary surface and every constraint on
//! a surface vertex refer to the same node in both orders; mid-edge nodes follow, numbered in
//! the order their edges are first met (tetrahedron order, VTK edge order), which makes the
//! numbering deterministic.

use std::collections::HashMap;

use crate::math::Vec3;
use crate::mesh::TetMesh;
use crate::model::fem::element_quadratic::EDGES;

/// A straight-sided quadratic tetrahedral mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct QuadraticMesh {
    /// Corner nodes (the linear mesh's vertices) followed by the mid-edge nodes.
    pub nodes: Vec<Vec3>,
    /// Tetrahedra in VTK order: corners, then mid-edge nodes of (0,1),(1,2),(0,2),(0,3),(1,3),(2,3).
    pub tets: Vec<[u32; 10]>,
    /// The mid-edge node of each edge, keyed by its corner ids in ascending order.
    pub edge_mid: HashMap<[u32; 2], u32>,
    /// Number of corner nodes.
    pub corners: usize,
}

impl QuadraticMesh {
    /// Adds a mid-edge node at the midpoint of every edge. The mesh's indices must be valid.
    pub fn from_linear(mesh: &TetMesh) -> Self {
        let mut nodes = mesh.vertices.clone();
        let mut edge_mid: HashMap<[u32; 2], u32> = HashMap::with_capacity(mesh.tets.len() * 2);
        let mut tets = Vec::with_capacity(mesh.tets.len());
        for tet in &mesh.tets {
            let mut t = [0u32; 10];
            t[..4].copy_from_slice(tet);
            for (e, [i, j]) in EDGES.iter().enumerate() {
                let (a, b) = (tet[*i], tet[*j]);
                let key = [a.min(b), a.max(b)];
                let id = *edge_mid.entry(key).or_insert_with(|| {
                    nodes.push((mesh.vertices[a as usize] + mesh.vertices[b as usize]) * 0.5);
                    (nodes.len() - 1) as u32
                });
                t[4 + e] = id;
            }
            tets.push(t);
        }
        Self {
            nodes,
            tets,
            edge_mid,
            corners: mesh.vertices.len(),
        }
    }

    /// The mid-edge node between corners `a` and `b`, if they share an edge.
    pub fn mid(&self, a: u32, b: u32) -> Option<u32> {
        self.edge_mid.get(&[a.min(b), a.max(b)]).copied()
    }
}
