//! The rendered (and touched) surface of a spline model: a grid of surface points at a chosen
//! resolution, the linear map from control points to those points, and its transpose, which
//! brings forces on surface points back to the control points.
//!
//! `mesh::SurfaceMapping` holds at most four nodes per vertex; a cubic spline point depends on
//! sixteen, so this mirrors its `apply` / `apply_transpose` pair. The grid is a tensor product,
//! so `apply` evaluates in two passes (along u for each control row, then along v): about
//! 4·(nv + rows) instead of 16·rows multiply-adds per grid column.

use crate::math::{Real, Vec3};

use super::basis::{BasisValues, KnotKind};
use super::surface::SplineSurface;

/// Surface vertices on a (cols × rows) parameter grid; vertex a + cols·b.
#[derive(Clone, Debug, PartialEq)]
pub struct Tessellation {
    nu: usize,
    nv: usize,
    /// Basis at each grid column (u) and row (v).
    cols: Vec<BasisValues>,
    rows: Vec<BasisValues>,
    pub triangles: Vec<[u32; 3]>,
    /// Scratch of the first pass: one point per (column, control row).
    scratch: Vec<Vec3>,
}

impl Tessellation {
    /// `per_span` (≥ 1) segments per knot span in each direction; a periodic u wraps.
    pub fn new(surface: &SplineSurface, per_span: usize) -> Self {
        let k = per_span.max(1);
        let su = surface.u.spans() * k;
        let sv = surface.v.spans() * k;
        let periodic = surface.u.kind() == KnotKind::Periodic;
        let ncols = if periodic { su } else { su + 1 };
        let cols: Vec<BasisValues> = (0..ncols)
            .map(|a| surface.u.eval(a as Real / su as Real))
            .collect();
        let rows: Vec<BasisValues> = (0..=sv)
            .map(|b| surface.v.eval(b as Real / sv as Real))
            .collect();
        let mut triangles = Vec::with_capacity(2 * su * sv);
        let id = |a: usize, b: usize| ((a % ncols) + ncols * b) as u32;
        for b in 0..sv {
            for a in 0..su {
                let (p00, p10, p01, p11) = (id(a, b), id(a + 1, b), id(a, b + 1), id(a + 1, b + 1));
                // Counter-clockwise seen from S_u × S_v.
                triangles.push([p00, p10, p11]);
                triangles.push([p00, p11, p01]);
            }
        }
        Self {
            nu: surface.nu(),
            nv: surface.nv(),
            scratch: vec![Vec3::ZERO; ncols * surface.nv()],
            cols,
            rows,
            triangles,
        }
    }

    /// Number of surface vertices.
    pub fn len(&self) -> usize {
        self.cols.len() * self.rows.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Grid size (columns along u, rows along v).
    pub fn grid(&self) -> (usize, usize) {
        (self.cols.len(), self.rows.len())
    }

    /// The 16 control points and weights of surface vertex `vertex` (None if out of range).
    pub fn weights(&self, vertex: usize) -> Option<([u32; 16], [Real; 16])> {
        let nc = self.cols.len();
        let (c, r) = (self.cols.get(vertex % nc)?, self.rows.get(vertex / nc)?);
        let nodes = std::array::from_fn(|k| c.index[k % 4] + self.nu as u32 * r.index[k / 4]);
        let w = std::array::from_fn(|k| c.n[0][k % 4] * r.n[0][k / 4]);
        Some((nodes, w))
    }

    /// Surface positions (or displacements, velocities) from control values.
    pub fn apply(&mut self, control: &[Vec3], surface: &mut [Vec3]) {
        let nc = self.cols.len();
        for j in 0..self.nv {
            let row = &control[self.nu * j..self.nu * (j + 1)];
            for (a, c) in self.cols.iter().enumerate() {
                self.scratch[a + nc * j] =
                    (0..4).map(|k| c.n[0][k] * row[c.index[k] as usize]).sum();
            }
        }
        for (b, r) in self.rows.iter().enumerate() {
            let out = &mut surface[nc * b..nc * (b + 1)];
            for (a, o) in out.iter_mut().enumerate() {
                *o = (0..4)
                    .map(|k| r.n[0][k] * self.scratch[a + nc * r.index[k] as usize])
                    .sum();
            }
        }
    }

    /// Adds surface vertex forces to control point forces (the transpose of `apply`).
    pub fn apply_transpose(&self, surface_forces: &[Vec3], control_forces: &mut [Vec3]) {
        for (v, f) in surface_forces.iter().enumerate() {
            if *f == Vec3::ZERO {
                continue;
            }
            if let Some((nodes, w)) = self.weights(v) {
                for k in 0..16 {
                    control_forces[nodes[k] as usize] += w[k] * *f;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_direct_evaluation_and_transpose_preserves_work() {
        for (surf, periodic) in [
            (SplineSurface::tube(0.01, 0.05, 8, 6).unwrap(), true),
            (SplineSurface::flat_patch(0.1, 0.2, 5, 7).unwrap(), false),
        ] {
            let mut t = Tessellation::new(&surf, 3);
            let (c, r) = t.grid();
            let su = surf.u.spans() * 3;
            assert_eq!(c, if periodic { su } else { su + 1 });
            assert_eq!(r, surf.v.spans() * 3 + 1);
            assert_eq!(t.triangles.len(), 2 * su * (r - 1));
            let mut s = vec![Vec3::ZERO; t.len()];
            t.apply(&surf.control, &mut s);
            for (k, p) in s.iter().enumerate() {
                let (a, b) = (k % c, k / c);
                let q = surf.point(a as Real / su as Real, b as Real / (r - 1) as Real);
                assert!(p.distance(q) < 1e-15, "{k}");
            }
            // <apply(x), f> = <x, apply_transpose(f)>.
            let f: Vec<Vec3> = (0..t.len())
                .map(|i| Vec3::new((i as Real).sin(), (i as Real * 0.7).cos(), 0.3))
                .collect();
            let mut g = vec![Vec3::ZERO; surf.control.len()];
            t.apply_transpose(&f, &mut g);
            let lhs: Real = s.iter().zip(&f).map(|(a, b)| a.dot(*b)).sum();
            let rhs: Real = surf.control.iter().zip(&g).map(|(a, b)| a.dot(*b)).sum();
            assert!((lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0));
            // Every triangle is proper and the periodic grid is closed around.
            let mesh = crate::mesh::SurfaceMesh::new(s.clone(), t.triangles.clone());
            let borders = crate::mesh::topology::edge_faces(&mesh.triangles)
                .border_edges()
                .count();
            assert_eq!(
                borders,
                if periodic {
                    2 * su
                } else {
                    2 * su + 2 * (r - 1)
                }
            );
        }
    }
}
