//! The influence matrices H and G of the collocation BEM (eq. 11: H U = G P) on linear
//! triangles: displacement and traction vary linearly over each triangle, with their values
//! at the vertices as unknowns, and each vertex is a collocation (source) point.
//!
//! Row block i (3 rows) holds the integrals of T* (for H) and U* (for G) from source i,
//! weighted by each vertex's shape function, over every triangle. H's diagonal blocks, which
//! would need the free term and a Cauchy principal value, come instead from rigid-body
//! motion: a translation produces no traction, so every row of H must sum to zero. Rows are
//! independent, so they are computed in parallel (rayon, `parallel` feature).

use std::sync::atomic::{AtomicUsize, Ordering};

use crate::math::{Real, Vec3};

use super::kelvin::Kelvin;
use super::quadrature::{Rules, side_for};

/// H and G as dense row-major 3n × 3n arrays (n vertices; dof 3j + k is component k of
/// vertex j).
#[derive(Clone, Debug, PartialEq)]
pub struct Influence {
    pub vertices: usize,
    pub h: Vec<Real>,
    pub g: Vec<Real>,
}

impl Influence {
    /// Unknowns: three per vertex.
    pub fn dofs(&self) -> usize {
        3 * self.vertices
    }
    pub fn h_at(&self, row: usize, col: usize) -> Real {
        self.h[row * self.dofs() + col]
    }
    pub fn g_at(&self, row: usize, col: usize) -> Real {
        self.g[row * self.dofs() + col]
    }
}

/// What assembly needs of each triangle, computed once.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Element {
    pub nodes: [usize; 3],
    pub corners: [Vec3; 3],
    pub normal: Vec3,
    /// Twice the area: the Jacobian of the reference triangle.
    pub jac: Real,
    pub centroid: Vec3,
    /// Longest edge.
    pub size: Real,
}

impl Element {
    /// `None` for a triangle without area (its normal is undefined).
    pub fn new(vertices: &[Vec3], tri: [u32; 3]) -> Option<Self> {
        let nodes = tri.map(|v| v as usize);
        let corners = [
            *vertices.get(nodes[0])?,
            *vertices.get(nodes[1])?,
            *vertices.get(nodes[2])?,
        ];
        let [a, b, c] = corners;
        let cross = (b - a).cross(c - a);
        let jac = cross.length();
        if jac <= 0.0 || !jac.is_finite() {
            return None;
        }
        Some(Self {
            nodes,
            corners,
            normal: cross / jac,
            jac,
            centroid: (a + b + c) / 3.0,
            size: (b - a).length().max((c - b).length()).max((a - c).length()),
        })
    }
}

/// Assembles H and G. `elements` must be valid (see `Element::new`); `progress` receives the
/// fraction of rows done, about a hundred times.
pub(crate) fn assemble(
    vertices: &[Vec3],
    elements: &[Element],
    kelvin: &Kelvin,
    progress: &(dyn Fn(f64) + Sync),
) -> Influence {
    let n = vertices.len();
    let dofs = 3 * n;
    let mut h = vec![0.0; dofs * dofs];
    let mut g = vec![0.0; dofs * dofs];
    let rules = Rules::new();
    let done = AtomicUsize::new(0);
    let every = (n / 100).max(1);
    let row = |(i, (hr, gr)): (usize, (&mut [Real], &mut [Real]))| {
        assemble_rows(i, vertices[i], elements, kelvin, &rules, hr, gr);
        let d = done.fetch_add(1, Ordering::Relaxed) + 1;
        if d.is_multiple_of(every) || d == n {
            progress(d as f64 / n as f64);
        }
    };
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        h.par_chunks_mut(3 * dofs)
            .zip(g.par_chunks_mut(3 * dofs))
            .enumerate()
            .for_each(row);
    }
    #[cfg(not(feature = "parallel"))]
    h.chunks_mut(3 * dofs)
        .zip(g.chunks_mut(3 * dofs))
        .enumerate()
        .for_each(row);
    Influence { vertices: n, h, g }
}

/// The three rows of source `i` (row-major, 3n columns each).
pub(crate) fn assemble_rows(
    i: usize,
    x: Vec3,
    elements: &[Element],
    kelvin: &Kelvin,
    rules: &Rules,
    h: &mut [Real],
    g: &mut [Real],
) {
    let dofs = h.len() / 3;
    h.fill(0.0);
    g.fill(0.0);
    for e in elements {
        let rule = match e.nodes.iter().position(|&v| v == i) {
            Some(corner) => &rules.singular[corner],
            None => &rules.regular[side_for((e.centroid - x).length(), e.size)],
        };
        let mut he = [[[0.0; 3]; 3]; 3];
        let mut ge = [[[0.0; 3]; 3]; 3];
        for q in rule {
            let y = e.corners[0] * q.n[0] + e.corners[1] * q.n[1] + e.corners[2] * q.n[2];
            let r = y - x;
            let u = kelvin.u(r);
            let t = kelvin.t(r, e.normal);
            let w = q.w * e.jac;
            for a in 0..3 {
                let wa = w * q.n[a];
                for l in 0..3 {
                    for k in 0..3 {
                        ge[a][l][k] += wa * u[l][k];
                        he[a][l][k] += wa * t[l][k];
                    }
                }
            }
        }
        for (a, &j) in e.nodes.iter().enumerate() {
            for l in 0..3 {
                let row = l * dofs + 3 * j;
                for k in 0..3 {
                    g[row + k] += ge[a][l][k];
                    // The source's own block comes from the rigid-body condition below.
                    if j != i {
                        h[row + k] += he[a][l][k];
                    }
                }
            }
        }
    }
    for l in 0..3 {
        let r = &mut h[l * dofs..(l + 1) * dofs];
        let mut sum = [0.0; 3];
        for (c, v) in r.iter().enumerate() {
            sum[c % 3] += v;
        }
        for k in 0..3 {
            r[3 * i + k] = -sum[k];
        }
    }
}
