//! The linear tensor-mass data (Cotin et al. 1999): a 3×3 stiffness tensor on every vertex
//! and every edge, each the sum over the tetrahedra that share it of that tetrahedron's
//! stiffness block.
//!
//! With u the displacements, the elastic force on vertex i is
//! f_i = −K_ii u_i − Σ_{j ~ i} K_ij u_j, the linear FEM force −K u organised by mesh
//! entity instead of by matrix row: one pass over the vertices and one over the edges. The
//! block of a tetrahedron coupling its corners a and b is the 4-node element's
//! K_ab = V (λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a·g_b) I) (`element_linear::add_block`) plus the
//! fibre part of ℂ, K_ab e_j = V (ℂ_f : sym(e_j g_bᵀ)) g_a.
//!
//! Because every tensor is a sum over tetrahedra, removing a tetrahedron (cutting) or
//! moving it between the linear and the non-linear set (the hybrid switch) subtracts its 10
//! blocks from its 4 vertices and 6 edges: O(1) per tetrahedron. Counts of contributing
//! tetrahedra let a tensor that has lost all of them be set to exactly zero.

use crate::math::{Mat3, Vec3};
use crate::model::fem::element_linear::add_block;

use super::elasticity::{Elasticity, TetRest, sym_outer};

/// Corner pairs of a tetrahedron's six edges; `Topology::tet_edges` follows this order.
pub const TET_EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

/// The unique edges of a tetrahedral mesh and the edges of each tetrahedron.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Topology {
    /// Sorted (i < j), in increasing order.
    pub edges: Vec<[u32; 2]>,
    /// Edge ids of each tetrahedron, in `TET_EDGES` order.
    pub tet_edges: Vec<[u32; 6]>,
}

impl Topology {
    /// Node ids must be valid (the model validates the mesh first).
    pub fn new(tets: &[[u32; 4]]) -> Self {
        let mut all: Vec<([u32; 2], u32)> = Vec::with_capacity(6 * tets.len());
        for (t, tet) in tets.iter().enumerate() {
            for (k, [a, b]) in TET_EDGES.iter().enumerate() {
                let (i, j) = (tet[*a], tet[*b]);
                all.push(([i.min(j), i.max(j)], (6 * t + k) as u32));
            }
        }
        all.sort_unstable();
        let mut edges: Vec<[u32; 2]> = Vec::new();
        let mut tet_edges = vec![[0u32; 6]; tets.len()];
        for (key, slot) in all {
            if edges.last() != Some(&key) {
                edges.push(key);
            }
            let s = slot as usize;
            tet_edges[s / 6][s % 6] = (edges.len() - 1) as u32;
        }
        Self { edges, tet_edges }
    }
}

/// The 4×4 stiffness blocks K_ab of one tetrahedron (block (a, b) couples the force on
/// corner a to the displacement of corner b; K_ba = K_abᵀ).
pub fn tet_blocks(rest: &TetRest, el: &Elasticity) -> [[Mat3; 4]; 4] {
    let g = &rest.gradients;
    let v = rest.volume;
    let mut k = [[Mat3::ZERO; 4]; 4];
    for a in 0..4 {
        for b in 0..4 {
            let mut blk = [[0.0; 3]; 3];
            add_block(&mut blk, g[a], g[b], el.lambda, el.mu, v);
            // add_block fills rows; glam stores columns.
            let mut m = Mat3::from_cols_array_2d(&blk).transpose();
            if el.has_fibre() {
                let cols = [Vec3::X, Vec3::Y, Vec3::Z]
                    .map(|e| el.apply_fibre(sym_outer(e, g[b])) * g[a] * v);
                m += Mat3::from_cols(cols[0], cols[1], cols[2]);
            }
            k[a][b] = m;
        }
    }
    k
}

/// Kᵀ u without forming the transpose.
#[inline]
pub fn transpose_mul(k: &Mat3, u: Vec3) -> Vec3 {
    Vec3::new(k.x_axis.dot(u), k.y_axis.dot(u), k.z_axis.dot(u))
}

/// Vertex and edge stiffness tensors with their contributing-tetrahedron counts.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinearTensors {
    pub vertex: Vec<Mat3>,
    /// K_ij of edge (i < j): force on i per displacement of j.
    pub edge: Vec<Mat3>,
    vertex_tets: Vec<u32>,
    edge_tets: Vec<u32>,
    /// Tetrahedra whose blocks are in (0: every tensor is exactly zero).
    tets_in: usize,
}

impl LinearTensors {
    /// Empty tensors over `nodes` vertices and the edges of `topo`.
    pub fn empty(nodes: usize, topo: &Topology) -> Self {
        Self {
            vertex: vec![Mat3::ZERO; nodes],
            edge: vec![Mat3::ZERO; topo.edges.len()],
            vertex_tets: vec![0; nodes],
            edge_tets: vec![0; topo.edges.len()],
            tets_in: 0,
        }
    }

    /// Adds (`add`) or removes tetrahedron `t`'s blocks: the local update.
    pub fn update_tet(
        &mut self,
        topo: &Topology,
        t: usize,
        tet: &[u32; 4],
        blocks: &[[Mat3; 4]; 4],
        add: bool,
    ) {
        let sign = if add { 1.0 } else { -1.0 };
        self.tets_in = if add {
            self.tets_in + 1
        } else {
            self.tets_in.saturating_sub(1)
        };
        for (a, &n) in tet.iter().enumerate() {
            let n = n as usize;
            update_count(
                &mut self.vertex_tets[n],
                add,
                &mut self.vertex[n],
                Mat3::ZERO,
            );
            if self.vertex_tets[n] > 0 {
                self.vertex[n] += blocks[a][a] * sign;
            }
        }
        for (k, [a, b]) in TET_EDGES.iter().enumerate() {
            let e = topo.tet_edges[t][k] as usize;
            // Edge (i < j) stores K_ij: the block from the corner that holds i.
            let blk = if tet[*a] < tet[*b] {
                blocks[*a][*b]
            } else {
                blocks[*b][*a]
            };
            update_count(&mut self.edge_tets[e], add, &mut self.edge[e], Mat3::ZERO);
            if self.edge_tets[e] > 0 {
                self.edge[e] += blk * sign;
            }
        }
    }

    /// f −= K u.
    pub fn add_forces(&self, topo: &Topology, u: &[Vec3], f: &mut [Vec3]) {
        for ((fi, k), ui) in f.iter_mut().zip(&self.vertex).zip(u) {
            *fi -= *k * *ui;
        }
        for (&[i, j], k) in topo.edges.iter().zip(&self.edge) {
            let (i, j) = (i as usize, j as usize);
            let (ui, uj) = (u[i], u[j]);
            f[i] -= *k * uj;
            f[j] -= transpose_mul(k, ui);
        }
    }

    /// The diagonal of K, per vertex.
    pub fn diagonal(&self) -> impl Iterator<Item = Vec3> + '_ {
        self.vertex
            .iter()
            .map(|k| Vec3::new(k.x_axis.x, k.y_axis.y, k.z_axis.z))
    }

    /// Tetrahedra whose blocks the tensors hold.
    pub fn tet_count(&self) -> usize {
        self.tets_in
    }

    /// Tetrahedra that contribute to vertex `n`.
    pub fn vertex_tets(&self, n: usize) -> u32 {
        self.vertex_tets.get(n).copied().unwrap_or(0)
    }

    pub fn memory_bytes(&self) -> usize {
        (self.vertex.len() + self.edge.len()) * (std::mem::size_of::<Mat3>() + 4)
    }
}

/// Counts a tetrahedron in or out; a tensor whose last tetrahedron leaves is reset to an
/// exact zero rather than left with rounding residue.
#[inline]
pub(crate) fn update_count<T>(count: &mut u32, add: bool, value: &mut T, zero: T) {
    if add {
        *count += 1;
    } else {
        *count = count.saturating_sub(1);
        if *count == 0 {
            *value = zero;
        }
    }
}
