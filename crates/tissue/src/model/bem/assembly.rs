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

use crate::error::MeshError;
use crate::material::Material;
use crate::math::{Real, Vec3, closest_point_on_triangle};
use crate::mesh::SurfaceMesh;

use super::kelvin::Kelvin;
use super::quadrature::{MAX_SIDE, QuadPoint, Rules, side_for};

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

    /// The point with shape-function values `n`.
    fn point(&self, n: [Real; 3]) -> Vec3 {
        self.corners[0] * n[0] + self.corners[1] * n[1] + self.corners[2] * n[2]
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
        let (he, ge) = element_integrals(i, x, e, kelvin, rules, true);
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

/// Indexed [corner][load direction][component].
type Block = [[[Real; 3]; 3]; 3];

/// The integrals of T* (`he`) and U* (`ge`) times each corner's shape function over element
/// `e`, from source `i` at `x`. The rule depends only on the source's position and the
/// element, so re-integrating one element later reproduces its share of H and G exactly.
/// `with_h = false` skips T*.
pub(super) fn element_integrals(
    i: usize,
    x: Vec3,
    e: &Element,
    kelvin: &Kelvin,
    rules: &Rules,
    with_h: bool,
) -> (Block, Block) {
    let mut sum = Integrals {
        x,
        e,
        kelvin,
        with_h,
        he: [[[0.0; 3]; 3]; 3],
        ge: [[[0.0; 3]; 3]; 3],
    };
    match e.nodes.iter().position(|&v| v == i) {
        Some(corner) => sum.add_rule(&WHOLE, 1.0, &rules.singular[corner]),
        None => sum.add_regular(&WHOLE, 0, rules),
    }
    (sum.he, sum.ge)
}

/// A piece of an element: its corners in the element's shape functions.
type Piece = [[Real; 3]; 3];

const WHOLE: Piece = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Halvings of an element near a source before the largest rule is used regardless: a
/// source 1e-4 element sizes away needs about 13. Only the pieces next to the source are
/// split, so this costs a few hundred points per level, for the few pairs that need it.
const MAX_SPLITS: u32 = 16;

/// The running integrals of one element from one source.
struct Integrals<'a> {
    x: Vec3,
    e: &'a Element,
    kelvin: &'a Kelvin,
    with_h: bool,
    he: Block,
    ge: Block,
}

impl Integrals<'_> {
    /// Adds `piece` (split `level` times from the element) with the rule its distance from
    /// the source asks for, or its four halves when no rule is accurate enough.
    fn add_regular(&mut self, piece: &Piece, level: u32, rules: &Rules) {
        let e = self.e;
        let h = e.size * 0.5f64.powi(level as i32);
        // Far elements (most of them) take the smallest rule on a cheap lower bound of the
        // distance: the centroid is within one longest edge of every point.
        if level == 0 && side_for(((e.centroid - self.x).length() - h) / h) == Some(2) {
            return self.add_rule(piece, 1.0, &rules.regular[2]);
        }
        let corners = piece.map(|b| e.point(b));
        let d = (closest_point_on_triangle(self.x, corners) - self.x).length();
        let scale = 0.25f64.powi(level as i32);
        match side_for(d / h) {
            Some(m) => self.add_rule(piece, scale, &rules.regular[m]),
            None if level < MAX_SPLITS => {
                let mid = |a: usize, b: usize| -> [Real; 3] {
                    std::array::from_fn(|k| 0.5 * (piece[a][k] + piece[b][k]))
                };
                let (m01, m12, m20) = (mid(0, 1), mid(1, 2), mid(2, 0));
                for child in [
                    [piece[0], m01, m20],
                    [m01, piece[1], m12],
                    [m20, m12, piece[2]],
                    [m01, m12, m20],
                ] {
                    self.add_regular(&child, level + 1, rules);
                }
            }
            None => self.add_rule(piece, scale, &rules.regular[MAX_SIDE]),
        }
    }

    /// Adds `rule` mapped onto `piece`, whose area is `scale` times the element's.
    fn add_rule(&mut self, piece: &Piece, scale: Real, rule: &[QuadPoint]) {
        let e = self.e;
        for q in rule {
            let n: [Real; 3] = std::array::from_fn(|k| {
                q.n[0] * piece[0][k] + q.n[1] * piece[1][k] + q.n[2] * piece[2][k]
            });
            let r = e.point(n) - self.x;
            let u = self.kelvin.u(r);
            let t = if self.with_h {
                self.kelvin.t(r, e.normal)
            } else {
                [[0.0; 3]; 3]
            };
            let w = q.w * e.jac * scale;
            for (a, &na) in n.iter().enumerate() {
                let wa = w * na;
                for l in 0..3 {
                    for k in 0..3 {
                        self.ge[a][l][k] += wa * u[l][k];
                        self.he[a][l][k] += wa * t[l][k];
                    }
                }
            }
        }
    }
}

/// What re-integrating single elements needs: the surface, its elements and the kernels.
/// Kept by the system so that the fixed-set columns of A₀ can drop individual triangles.
#[derive(Clone, Debug)]
pub(crate) struct Geometry {
    pub vertices: Vec<Vec3>,
    pub elements: Vec<Element>,
    pub kelvin: Kelvin,
    /// Per vertex, its (element, corner) pairs.
    pub corners: Vec<Vec<(usize, usize)>>,
    /// Per vertex, the other vertices of its elements (each once).
    pub neighbours: Vec<Vec<usize>>,
}

impl Geometry {
    /// The elements of `surface` (checked: a degenerate triangle is an error naming it) and
    /// the Kelvin kernels of `material`.
    pub fn new(surface: &SurfaceMesh, material: &Material) -> Result<Self, MeshError> {
        let elements = surface
            .triangles
            .iter()
            .enumerate()
            .map(|(t, &tri)| {
                Element::new(&surface.vertices, tri).ok_or(MeshError::DegenerateTriangle {
                    triangle: t,
                    area: 0.0,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let n = surface.vertices.len();
        let mut corners = vec![Vec::new(); n];
        let mut neighbours = vec![Vec::new(); n];
        for (e, tri) in surface.triangles.iter().enumerate() {
            for (corner, &v) in tri.iter().enumerate() {
                corners[v as usize].push((e, corner));
                neighbours[v as usize]
                    .extend(tri.iter().map(|&w| w as usize).filter(|&w| w != v as usize));
            }
        }
        for list in &mut neighbours {
            list.sort_unstable();
            list.dedup();
        }
        Ok(Self {
            vertices: surface.vertices.clone(),
            elements,
            kelvin: Kelvin::new(material.mu(), material.poisson_ratio),
            corners,
            neighbours,
        })
    }

    /// Corner `corner` of element `e`'s share of G's three columns of that vertex, for every
    /// source: `out[3 * (3 i + l) + k]` (source i, load direction l, component k).
    pub fn element_g_columns(&self, e: usize, corner: usize, rules: &Rules) -> Vec<Real> {
        let n = self.vertices.len();
        let mut out = vec![0.0; 9 * n];
        let Some(el) = self.elements.get(e) else {
            return out;
        };
        for (i, &x) in self.vertices.iter().enumerate() {
            let (_, ge) = element_integrals(i, x, el, &self.kelvin, rules, false);
            for l in 0..3 {
                for k in 0..3 {
                    out[3 * (3 * i + l) + k] = ge[corner][l][k];
                }
            }
        }
        out
    }

    /// Per vertex, a third of each adjacent triangle's area: what a traction continuous
    /// across its triangles acts on.
    pub fn tributary_areas(&self) -> Vec<Real> {
        let mut area = vec![0.0; self.vertices.len()];
        for el in &self.elements {
            for &v in &el.nodes {
                area[v] += el.jac / 6.0;
            }
        }
        area
    }

    /// Where the unknown traction of each constrained vertex acts. The traction jumps where
    /// a constrained region meets a free one (the support pushes on the constrained side, the
    /// free side carries the known zero), which one value per vertex cannot represent if it
    /// is spread over both sides. So a constrained vertex's traction acts only on its
    /// triangles whose three vertices are all constrained; the others (the rim triangles,
    /// listed per vertex as (element, corner)) see the free side's known traction. A
    /// constrained vertex without any such triangle (a point or line support) keeps all its
    /// triangles: it has no constrained side to carry its traction.
    /// Returns the rim triangles per vertex and the area each constrained vertex's traction
    /// acts on (a third of each remaining triangle; 0 for unconstrained vertices).
    pub fn traction_supports(&self, constrained: &[bool]) -> (Vec<Vec<(usize, usize)>>, Vec<Real>) {
        let n = self.vertices.len();
        let is = |v: usize| constrained.get(v).copied().unwrap_or(false);
        let mut rim = vec![Vec::new(); n];
        let mut inner_area = vec![0.0; n];
        let mut all_area = vec![0.0; n];
        for (e, el) in self.elements.iter().enumerate() {
            let inner = el.nodes.iter().all(|&v| is(v));
            let third = el.jac / 6.0;
            for (corner, &v) in el.nodes.iter().enumerate() {
                if !is(v) {
                    continue;
                }
                all_area[v] += third;
                if inner {
                    inner_area[v] += third;
                } else {
                    rim[v].push((e, corner));
                }
            }
        }
        let mut area = vec![0.0; n];
        for v in 0..n {
            if inner_area[v] > 0.0 {
                area[v] = inner_area[v];
            } else {
                area[v] = all_area[v];
                rim[v].clear();
            }
        }
        (rim, area)
    }
}

impl Geometry {
    /// G times a traction given per triangle corner (`t[e][a]` at corner a of element e, so
    /// it may jump across edges and at rims): Σ_e Σ_a ∫ U* φ_a t[e][a] dΓ for every source,
    /// as 3n values (source i, load direction l at 3i + l). The same rules as `assemble`,
    /// so a traction that is continuous gives exactly G times its vertex values.
    pub fn g_times_corner_tractions(&self, t: &[[Vec3; 3]]) -> Vec<Real> {
        let n = self.vertices.len();
        let rules = Rules::new();
        let mut out = vec![0.0; 3 * n];
        let row = |(i, r): (usize, &mut [Real])| {
            for (e, el) in self.elements.iter().enumerate() {
                let Some(te) = t.get(e) else { continue };
                let (_, ge) =
                    element_integrals(i, self.vertices[i], el, &self.kelvin, &rules, false);
                for (a, ta) in te.iter().enumerate() {
                    for (l, rl) in r.iter_mut().enumerate() {
                        *rl += ge[a][l][0] * ta.x + ge[a][l][1] * ta.y + ge[a][l][2] * ta.z;
                    }
                }
            }
        };
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            out.par_chunks_mut(3).enumerate().for_each(row);
        }
        #[cfg(not(feature = "parallel"))]
        out.chunks_mut(3).enumerate().for_each(row);
        out
    }
}
