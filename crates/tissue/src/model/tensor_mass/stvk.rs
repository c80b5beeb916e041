//! St Venant–Kirchhoff in tensor form (Picinbono et al. 2000, 2003): the non-linear part
//! of the force from tensors stored on vertices, edges, triangles and tetrahedra.
//!
//! With u the corner displacements of a tetrahedron, H = Σ_a u_a g_aᵀ and the Green strain
//! E = ε + q, ε = sym H, q = ½ Σ_ab (u_a·u_b) sym(g_a g_bᵀ). Writing P_ab = u_a·u_b and
//! S_ab = sym(g_a g_bᵀ), the energy V·½E:ℂ:E splits by degree in u:
//! - W2 = ½ Σ_ab u_aᵀ K_ab u_b: the linear tensors (`tensors`);
//! - W3 = Σ_abc P_ab (u_c · C_abc) with the vectors C_abc = (V/2)(ℂ:S_ab) g_c;
//! - W4 = Σ_abcd D_abcd P_ab P_cd with the scalars D_abcd = (V/8) S_ab : ℂ : S_cd.
//!
//! Each term depends on the displacements of the distinct vertices among its indices:
//! one vertex, an edge, a triangle or (quartic only) the whole tetrahedron. Summing every
//! term over the tetrahedra that share that entity gives Picinbono's tensors on vertices,
//! edges, triangles and tetrahedra. Symmetry leaves few distinct coefficients per entity:
//! - vertex i: C(ii,i), D(ii,ii);
//! - edge i<j: C(ii,j), C(ij,i), C(jj,i), C(ij,j); D{ii,ij}, D{ii,jj}, D{ij,ij}, D{ij,jj};
//! - triangle i<j<k: C(jk,i), C(ik,j), C(ij,k) (slot = the lone index); D{mm, opposite edge}
//!   for each corner m, then D{two edges sharing m} for each m;
//! - tetrahedron i<j<k<l: D{ij,kl}, D{ik,jl}, D{il,jk}.
//!
//! The force −∂W/∂u is evaluated in three passes: P on vertices and edges; every entity adds
//! ∂W/∂P to its vertices' and edges' accumulators G (and the direct cubic force P·C to the
//! lone vertex); then f_i −= 2 G_ii u_i and f_i −= G_ij u_j over edges. Each tetrahedron's
//! tensors can be added or removed in O(1) (`update_tet`): cutting, and the hybrid switch
//! that keeps only strongly strained tetrahedra in the non-linear set.

use std::collections::HashMap;

use crate::math::{Mat3, Real, Vec3};

use super::elasticity::{Elasticity, TetRest, ddot, sym_outer};
use super::tensors::{Topology, update_count};

/// Index in `TET_EDGES` of the edge between corners a ≠ b.
fn local_edge(a: usize, b: usize) -> usize {
    match (a.min(b), a.max(b)) {
        (0, 1) => 0,
        (0, 2) => 1,
        (0, 3) => 2,
        (1, 2) => 3,
        (1, 3) => 4,
        _ => 5,
    }
}

/// A tetrahedron's cubic vectors C_abc and quartic scalars D_abcd.
struct TetTerms {
    c: [[[Vec3; 4]; 4]; 4],
    d: [[[[Real; 4]; 4]; 4]; 4],
}

fn tet_terms(rest: &TetRest, el: &Elasticity) -> TetTerms {
    let g = &rest.gradients;
    let v = rest.volume;
    let mut s = [[Mat3::ZERO; 4]; 4];
    let mut t = [[Mat3::ZERO; 4]; 4];
    for a in 0..4 {
        for b in 0..4 {
            s[a][b] = sym_outer(g[a], g[b]);
            t[a][b] = el.apply(s[a][b]);
        }
    }
    let mut terms = TetTerms {
        c: [[[Vec3::ZERO; 4]; 4]; 4],
        d: [[[[0.0; 4]; 4]; 4]; 4],
    };
    for a in 0..4 {
        for b in 0..4 {
            for c in 0..4 {
                terms.c[a][b][c] = t[a][b] * g[c] * (0.5 * v);
                for (d, tcd) in t[c].iter().enumerate() {
                    terms.d[a][b][c][d] = 0.125 * v * ddot(&s[a][b], tcd);
                }
            }
        }
    }
    terms
}

/// The non-linear tensors and the scratch of their force evaluation.
#[derive(Clone, Debug, Default)]
pub struct NonlinearTensors {
    vertex_c: Vec<Vec3>,
    vertex_d: Vec<Real>,
    vertex_n: Vec<u32>,
    edge_c: Vec<[Vec3; 4]>,
    edge_d: Vec<[Real; 4]>,
    edge_n: Vec<u32>,
    /// Sorted corners of each triangle and the edge opposite each corner.
    tri_vertices: Vec<[u32; 3]>,
    tri_edges: Vec<[u32; 3]>,
    tri_c: Vec<[Vec3; 3]>,
    tri_d: Vec<[Real; 6]>,
    tri_n: Vec<u32>,
    /// Per tetrahedron: its triangles (face opposite corner k), its edges in sorted-corner
    /// order (ij, ik, il, jk, jl, kl), its own quartic scalars and whether it is in the set.
    tet_faces: Vec<[u32; 4]>,
    tet_edges: Vec<[u32; 6]>,
    tet_d: Vec<[Real; 3]>,
    tet_in: Vec<bool>,
    // Entities with at least one non-linear tetrahedron, rebuilt after a change.
    dirty: bool,
    live_vertices: Vec<u32>,
    live_edges: Vec<u32>,
    live_tris: Vec<u32>,
    live_tets: Vec<u32>,
    pv: Vec<Real>,
    pe: Vec<Real>,
    gv: Vec<Real>,
    ge: Vec<Real>,
}

impl NonlinearTensors {
    /// The entities of the mesh with empty tensors (no tetrahedron in the set yet).
    pub fn empty(nodes: usize, tets: &[[u32; 4]], topo: &Topology) -> Self {
        let ne = topo.edges.len();
        let mut tri_index: HashMap<[u32; 3], u32> = HashMap::with_capacity(2 * tets.len());
        let mut tri_vertices = Vec::new();
        let mut tri_edges = Vec::new();
        let mut tet_faces = Vec::with_capacity(tets.len());
        let mut tet_edges = Vec::with_capacity(tets.len());
        for (t, tet) in tets.iter().enumerate() {
            let edge = |a: usize, b: usize| topo.tet_edges[t][local_edge(a, b)];
            let mut faces = [0u32; 4];
            for (m, face) in faces.iter_mut().enumerate() {
                // The three corners other than m, in increasing node order.
                let mut corners: Vec<usize> = (0..4).filter(|&c| c != m).collect();
                corners.sort_unstable_by_key(|&c| tet[c]);
                let key = [tet[corners[0]], tet[corners[1]], tet[corners[2]]];
                *face = *tri_index.entry(key).or_insert_with(|| {
                    tri_vertices.push(key);
                    tri_edges.push([
                        edge(corners[1], corners[2]),
                        edge(corners[0], corners[2]),
                        edge(corners[0], corners[1]),
                    ]);
                    (tri_vertices.len() - 1) as u32
                });
            }
            tet_faces.push(faces);
            let mut order = [0usize, 1, 2, 3];
            order.sort_unstable_by_key(|&c| tet[c]);
            let o = order;
            tet_edges.push([
                edge(o[0], o[1]),
                edge(o[0], o[2]),
                edge(o[0], o[3]),
                edge(o[1], o[2]),
                edge(o[1], o[3]),
                edge(o[2], o[3]),
            ]);
        }
        let nt = tri_vertices.len();
        Self {
            vertex_c: vec![Vec3::ZERO; nodes],
            vertex_d: vec![0.0; nodes],
            vertex_n: vec![0; nodes],
            edge_c: vec![[Vec3::ZERO; 4]; ne],
            edge_d: vec![[0.0; 4]; ne],
            edge_n: vec![0; ne],
            tri_vertices,
            tri_edges,
            tri_c: vec![[Vec3::ZERO; 3]; nt],
            tri_d: vec![[0.0; 6]; nt],
            tri_n: vec![0; nt],
            tet_faces,
            tet_edges,
            tet_d: vec![[0.0; 3]; tets.len()],
            tet_in: vec![false; tets.len()],
            dirty: true,
            live_vertices: Vec::new(),
            live_edges: Vec::new(),
            live_tris: Vec::new(),
            live_tets: Vec::new(),
            pv: vec![0.0; nodes],
            pe: vec![0.0; ne],
            gv: vec![0.0; nodes],
            ge: vec![0.0; ne],
        }
    }

    pub fn contains(&self, t: usize) -> bool {
        self.tet_in.get(t).copied().unwrap_or(false)
    }

    /// Tetrahedra in the non-linear set.
    pub fn count(&self) -> usize {
        self.tet_in.iter().filter(|&&b| b).count()
    }

    pub fn triangle_count(&self) -> usize {
        self.tri_vertices.len()
    }

    /// Puts tetrahedron `t` into the non-linear set (`add`) or takes it out: adds or
    /// subtracts its terms on its 4 vertices, 6 edges, 4 triangles and itself.
    pub fn update_tet(
        &mut self,
        topo: &Topology,
        t: usize,
        tet: &[u32; 4],
        rest: &TetRest,
        el: &Elasticity,
        add: bool,
    ) {
        if self.tet_in[t] == add {
            return;
        }
        self.tet_in[t] = add;
        self.dirty = true;
        let terms = tet_terms(rest, el);
        let sign = if add { 1.0 } else { -1.0 };
        // Counts first, so that an entity losing its last tetrahedron is zeroed exactly
        // and then left alone below.
        for &n in tet {
            let n = n as usize;
            update_count(
                &mut self.vertex_n[n],
                add,
                &mut self.vertex_c[n],
                Vec3::ZERO,
            );
            if self.vertex_n[n] == 0 {
                self.vertex_d[n] = 0.0;
            }
        }
        for &e in &topo.tet_edges[t] {
            let e = e as usize;
            update_count(
                &mut self.edge_n[e],
                add,
                &mut self.edge_c[e],
                [Vec3::ZERO; 4],
            );
            if self.edge_n[e] == 0 {
                self.edge_d[e] = [0.0; 4];
            }
        }
        for &f in &self.tet_faces[t] {
            let f = f as usize;
            update_count(&mut self.tri_n[f], add, &mut self.tri_c[f], [Vec3::ZERO; 3]);
            if self.tri_n[f] == 0 {
                self.tri_d[f] = [0.0; 6];
            }
        }
        if !add {
            self.tet_d[t] = [0.0; 3];
        }
        let live_v = |s: &Self, n: u32| s.vertex_n[n as usize] > 0;
        let mut rank = [0usize; 4];
        for a in 0..4 {
            rank[a] = (0..4).filter(|&b| tet[b] < tet[a]).count();
        }
        for a in 0..4 {
            for b in 0..4 {
                for c in 0..4 {
                    let cv = terms.c[a][b][c] * sign;
                    match distinct(&[a, b, c]) {
                        (1, _) => {
                            if live_v(self, tet[a]) {
                                self.vertex_c[tet[a] as usize] += cv;
                            }
                        }
                        (2, [p, q, _, _]) => {
                            let e = topo.tet_edges[t][local_edge(p, q)] as usize;
                            if self.edge_n[e] > 0 {
                                let lo = if tet[p] < tet[q] { p } else { q };
                                let slot = match (a == b, a == lo, c == lo) {
                                    (true, true, _) => 0,
                                    (true, false, _) => 2,
                                    (false, _, true) => 1,
                                    (false, _, false) => 3,
                                };
                                self.edge_c[e][slot] += cv;
                            }
                        }
                        _ => {
                            let m = 6 - a - b - c;
                            let f = self.tet_faces[t][m] as usize;
                            if self.tri_n[f] > 0 {
                                let slot = self.tri_position(f, tet[c]);
                                self.tri_c[f][slot] += cv;
                            }
                        }
                    }
                    for d in 0..4 {
                        let dv = terms.d[a][b][c][d] * sign;
                        self.add_quartic(topo, t, tet, &rank, [a, b, c, d], dv);
                    }
                }
            }
        }
    }

    fn tri_position(&self, f: usize, node: u32) -> usize {
        self.tri_vertices[f]
            .iter()
            .position(|&v| v == node)
            .unwrap_or(0)
    }

    fn add_quartic(
        &mut self,
        topo: &Topology,
        t: usize,
        tet: &[u32; 4],
        rank: &[usize; 4],
        [a, b, c, d]: [usize; 4],
        dv: Real,
    ) {
        match distinct(&[a, b, c, d]) {
            (1, _) => {
                let n = tet[a] as usize;
                if self.vertex_n[n] > 0 {
                    self.vertex_d[n] += dv;
                }
            }
            (2, [p, q, _, _]) => {
                let e = topo.tet_edges[t][local_edge(p, q)] as usize;
                if self.edge_n[e] > 0 {
                    let lo = if tet[p] < tet[q] { p } else { q };
                    // 0: both ends the low vertex, 1: one of each, 2: both the high one.
                    let code = |x: usize, y: usize| (x != lo) as usize + (y != lo) as usize;
                    let (c1, c2) = (code(a, b), code(c, d));
                    let slot = match (c1.min(c2), c1.max(c2)) {
                        (0, 1) => 0,
                        (0, 2) => 1,
                        (1, 1) => 2,
                        _ => 3,
                    };
                    self.edge_d[e][slot] += dv;
                }
            }
            (3, [p, q, r, _]) => {
                let m = 6 - p - q - r;
                let f = self.tet_faces[t][m] as usize;
                if self.tri_n[f] > 0 {
                    let slot = if a == b {
                        self.tri_position(f, tet[a])
                    } else if c == d {
                        self.tri_position(f, tet[c])
                    } else {
                        let shared = if a == c || a == d { a } else { b };
                        3 + self.tri_position(f, tet[shared])
                    };
                    self.tri_d[f][slot] += dv;
                }
            }
            _ => {
                if self.tet_in[t] {
                    // The partner of the lowest node names the pairing.
                    let low = (0..4).find(|&x| rank[x] == 0).unwrap_or(0);
                    let partner = if a == low {
                        b
                    } else if b == low {
                        a
                    } else if c == low {
                        d
                    } else {
                        c
                    };
                    self.tet_d[t][rank[partner].saturating_sub(1).min(2)] += dv;
                }
            }
        }
    }

    fn refresh(&mut self) {
        if !self.dirty {
            return;
        }
        let live = |n: &[u32]| {
            n.iter()
                .enumerate()
                .filter(|(_, c)| **c > 0)
                .map(|(i, _)| i as u32)
                .collect::<Vec<u32>>()
        };
        self.live_vertices = live(&self.vertex_n);
        self.live_edges = live(&self.edge_n);
        self.live_tris = live(&self.tri_n);
        self.live_tets = (0..self.tet_in.len() as u32)
            .filter(|&t| self.tet_in[t as usize])
            .collect();
        self.dirty = false;
    }

    /// f −= ∂(W3 + W4)/∂u, the non-linear part of the St Venant–Kirchhoff force; returns
    /// W3 + W4 (nearly free: every term's factors are at hand).
    pub fn add_forces(&mut self, topo: &Topology, u: &[Vec3], f: &mut [Vec3]) -> Real {
        let mut w = 0.0;
        self.refresh();
        let (pv, pe, gv, ge) = (&mut self.pv, &mut self.pe, &mut self.gv, &mut self.ge);
        for &i in &self.live_vertices {
            let i = i as usize;
            pv[i] = u[i].length_squared();
            gv[i] = 0.0;
        }
        for &e in &self.live_edges {
            let [i, j] = topo.edges[e as usize];
            pe[e as usize] = u[i as usize].dot(u[j as usize]);
            ge[e as usize] = 0.0;
        }
        for &i in &self.live_vertices {
            let i = i as usize;
            let c = self.vertex_c[i];
            let q = u[i].dot(c);
            w += pv[i] * (q + self.vertex_d[i] * pv[i]);
            gv[i] += q + 2.0 * self.vertex_d[i] * pv[i];
            f[i] -= c * pv[i];
        }
        for &e in &self.live_edges {
            let e = e as usize;
            let [i, j] = topo.edges[e];
            let (i, j) = (i as usize, j as usize);
            let (ui, uj) = (u[i], u[j]);
            let (c, d) = (&self.edge_c[e], &self.edge_d[e]);
            let (pi, pj, p) = (pv[i], pv[j], pe[e]);
            let q = [uj.dot(c[0]), ui.dot(c[1]), ui.dot(c[2]), uj.dot(c[3])];
            w += pi * q[0] + p * (q[1] + q[3]) + pj * q[2];
            w += p * (d[0] * pi + d[2] * p + d[3] * pj) + d[1] * pi * pj;
            gv[i] += q[0] + d[0] * p + d[1] * pj;
            gv[j] += q[2] + d[1] * pi + d[3] * p;
            ge[e] += q[1] + q[3] + d[0] * pi + 2.0 * d[2] * p + d[3] * pj;
            f[i] -= c[1] * p + c[2] * pj;
            f[j] -= c[0] * pi + c[3] * p;
        }
        for &k in &self.live_tris {
            let k = k as usize;
            let v = self.tri_vertices[k].map(|n| n as usize);
            let es = self.tri_edges[k].map(|e| e as usize);
            let (c, d) = (&self.tri_c[k], &self.tri_d[k]);
            let p = es.map(|e| pe[e]);
            for m in 0..3 {
                let (n, e) = (v[m], es[m]);
                let q = u[n].dot(c[m]);
                let (m1, m2) = ((m + 1) % 3, (m + 2) % 3);
                w += p[m] * (q + d[m] * pv[n]) + d[3 + m] * p[m1] * p[m2];
                ge[e] += q + d[m] * pv[n];
                gv[n] += d[m] * p[m];
                f[n] -= c[m] * p[m];
                // The two edges that share corner m.
                ge[es[m1]] += d[3 + m] * p[m2];
                ge[es[m2]] += d[3 + m] * p[m1];
            }
        }
        for &t in &self.live_tets {
            let t = t as usize;
            let es = self.tet_edges[t].map(|e| e as usize);
            let d = &self.tet_d[t];
            for (s, (x, y)) in [(0, 5), (1, 4), (2, 3)].into_iter().enumerate() {
                w += d[s] * pe[es[x]] * pe[es[y]];
                ge[es[x]] += d[s] * pe[es[y]];
                ge[es[y]] += d[s] * pe[es[x]];
            }
        }
        for &i in &self.live_vertices {
            let i = i as usize;
            f[i] -= u[i] * (2.0 * gv[i]);
        }
        for &e in &self.live_edges {
            let [i, j] = topo.edges[e as usize];
            let (i, j) = (i as usize, j as usize);
            let g = ge[e as usize];
            let (ui, uj) = (u[i], u[j]);
            f[i] -= uj * g;
            f[j] -= ui * g;
        }
        w
    }

    /// Bytes the force evaluation reads and writes: the live entities' tensors and ids, and
    /// the P and G scratch (written, then read).
    pub fn step_traffic_bytes(&self) -> usize {
        self.live_vertices.len() * (24 + 8 + 4 + 4 * 8)
            + self.live_edges.len() * (96 + 32 + 8 + 4 + 4 * 8)
            + self.live_tris.len() * (12 + 12 + 72 + 48 + 4)
            + self.live_tets.len() * (24 + 24 + 4)
    }

    pub fn memory_bytes(&self) -> usize {
        self.vertex_c.len() * (24 + 8 + 4 + 16)
            + self.edge_c.len() * (96 + 32 + 4 + 16)
            + self.tri_vertices.len() * (12 + 12 + 72 + 48 + 4)
            + self.tet_in.len() * (16 + 24 + 24 + 1)
    }
}

/// The distinct values of `idx` (at most 4), in order of first appearance, and their count.
fn distinct(idx: &[usize]) -> (usize, [usize; 4]) {
    let mut out = [0usize; 4];
    let mut n = 0;
    for &i in idx {
        if !out[..n].contains(&i) {
            out[n] = i;
            n += 1;
        }
    }
    (n, out)
}
