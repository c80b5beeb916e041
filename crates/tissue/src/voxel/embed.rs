//! A triangle surface embedded in the voxel lattice: each surface vertex follows the
//! displacements of the (up to) eight voxel centres around it, weighted trilinearly.
//!
//! Near the object's boundary some of the eight corners are empty voxels (no element to
//! follow); their weights are dropped and the rest renormalised, so the vertex moves with
//! the elements it has. Writing the map on displacements, p = p₀ + Σ wₖ (xₖ − rₖ), keeps
//! this exact for a rigid translation and reduces to plain trilinear interpolation of
//! positions when all eight corners exist. A vertex with no occupied corner (a thin part
//! the voxels missed) follows its nearest occupied voxel.
//!
//! `apply` moves the surface out (drawing, contact); `apply_transpose` brings surface forces
//! back to the elements (instrument forces): the two are adjoint.

use crate::error::MeshError;
use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;

use super::{VoxelGrid, keep_largest, marching_surface};

/// How far (in voxels) a vertex with no occupied corner may be from an occupied voxel.
const MAX_SNAP: usize = 6;

#[derive(Clone, Debug, PartialEq)]
pub struct TrilinearEmbedding {
    /// Surface vertices at rest.
    pub rest: Vec<Vec3>,
    /// Per vertex: eight element ids (voxel indices, or any ids after `remap`).
    pub nodes: Vec<[u32; 8]>,
    /// Per vertex: the weights of `nodes`; zero for unused slots; each row sums to 1.
    pub weights: Vec<[Real; 8]>,
}

impl TrilinearEmbedding {
    /// Embeds `points` (rest positions, m) in the occupied voxels of `grid`.
    pub fn build(grid: &VoxelGrid, points: &[Vec3]) -> Result<Self, MeshError> {
        let [nx, ny, nz] = grid.dims;
        if grid.occupied() == 0 {
            return Err(MeshError::Empty {
                what: "occupied voxels to embed the surface in",
            });
        }
        let mut nodes = Vec::with_capacity(points.len());
        let mut weights = Vec::with_capacity(points.len());
        for (vertex, &p) in points.iter().enumerate() {
            let q = (p - grid.origin) / grid.spacing;
            if !crate::math::is_finite_vec(q) {
                return Err(MeshError::NonFiniteVertex {
                    vertex,
                    x: p.x,
                    y: p.y,
                    z: p.z,
                });
            }
            let base = |x: Real, n: usize| x.floor().clamp(0.0, n.saturating_sub(2) as Real);
            let b = Vec3::new(base(q.x, nx), base(q.y, ny), base(q.z, nz));
            let f = (q - b).clamp(Vec3::ZERO, Vec3::ONE);
            let mut ids = [0u32; 8];
            let mut w = [0.0; 8];
            let mut sum = 0.0;
            for c in 0..8 {
                let o = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
                let Some(idx) = grid.index(
                    b.x as usize + o[0],
                    b.y as usize + o[1],
                    b.z as usize + o[2],
                ) else {
                    continue;
                };
                if !grid.is_occupied(idx) {
                    continue;
                }
                let wc = (if o[0] == 1 { f.x } else { 1.0 - f.x })
                    * (if o[1] == 1 { f.y } else { 1.0 - f.y })
                    * (if o[2] == 1 { f.z } else { 1.0 - f.z });
                ids[c] = idx as u32;
                w[c] = wc;
                sum += wc;
            }
            if sum > 1e-9 {
                w.iter_mut().for_each(|x| *x /= sum);
            } else {
                let near = nearest_occupied(grid, p).ok_or_else(|| {
                    MeshError::Invalid(format!(
                        "surface vertex {vertex} at {p} is more than {MAX_SNAP} voxels from \
                         any occupied voxel; use a finer voxel spacing"
                    ))
                })?;
                ids = [near as u32; 8];
                w = [0.0; 8];
                w[0] = 1.0;
            }
            nodes.push(ids);
            weights.push(w);
        }
        Ok(Self {
            rest: points.to_vec(),
            nodes,
            weights,
        })
    }

    pub fn len(&self) -> usize {
        self.rest.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Surface positions from element positions `x` and element rest positions `rest`.
    pub fn apply(&self, x: &[Vec3], rest: &[Vec3], out: &mut [Vec3]) {
        for (((o, p0), ids), w) in out
            .iter_mut()
            .zip(&self.rest)
            .zip(&self.nodes)
            .zip(&self.weights)
        {
            let mut u = Vec3::ZERO;
            for k in 0..8 {
                if w[k] != 0.0 {
                    let n = ids[k] as usize;
                    if let (Some(a), Some(b)) = (x.get(n), rest.get(n)) {
                        u += w[k] * (*a - *b);
                    }
                }
            }
            *o = *p0 + u;
        }
    }

    /// Adds surface vertex forces to element forces (the transpose of `apply`).
    pub fn apply_transpose(&self, surface_forces: &[Vec3], forces: &mut [Vec3]) {
        for ((f, ids), w) in surface_forces.iter().zip(&self.nodes).zip(&self.weights) {
            for k in 0..8 {
                if let Some(g) = forces.get_mut(ids[k] as usize).filter(|_| w[k] != 0.0) {
                    *g += w[k] * *f;
                }
            }
        }
    }

    /// Renames element ids through `map` (e.g. voxel index → compact element index);
    /// corners mapped to `u32::MAX` are dropped and the rest renormalised.
    pub fn remap(&mut self, map: &[u32]) {
        self.rebind(|_, n| map.get(n as usize).is_some_and(|&m| m != u32::MAX));
        for ids in &mut self.nodes {
            for id in ids.iter_mut() {
                *id = map
                    .get(*id as usize)
                    .copied()
                    .filter(|&m| m != u32::MAX)
                    .unwrap_or(0);
            }
        }
    }

    /// Drops the corners for which `keep(vertex, node)` is false and renormalises; returns
    /// the vertices left with no corner (they keep their last binding).
    pub fn rebind(&mut self, keep: impl Fn(usize, u32) -> bool) -> Vec<usize> {
        self.rebind_first(self.len(), keep)
    }

    /// `rebind` for the first `count` vertices only (the others are left as they are).
    pub fn rebind_first(&mut self, count: usize, keep: impl Fn(usize, u32) -> bool) -> Vec<usize> {
        let mut orphans = Vec::new();
        let corners = self.nodes.iter().zip(self.weights.iter_mut()).take(count);
        for (v, (ids, w)) in corners.enumerate() {
            let mut kept = *w;
            for k in 0..8 {
                if kept[k] != 0.0 && !keep(v, ids[k]) {
                    kept[k] = 0.0;
                }
            }
            let sum: Real = kept.iter().sum();
            if sum > 1e-12 {
                *w = kept.map(|x| x / sum);
            } else if w.iter().any(|&x| x != 0.0) {
                orphans.push(v);
            }
        }
        orphans
    }
}

/// The occupied voxel nearest to `p` within `MAX_SNAP` voxels (shell by shell).
fn nearest_occupied(grid: &VoxelGrid, p: Vec3) -> Option<usize> {
    let q = ((p - grid.origin) / grid.spacing).round();
    let [nx, ny, nz] = grid.dims.map(|d| d as i64);
    let c = [q.x as i64, q.y as i64, q.z as i64];
    let mut best: Option<(Real, usize)> = None;
    for r in 0..=MAX_SNAP as i64 {
        for k in (c[2] - r).max(0)..=(c[2] + r).min(nz - 1) {
            for j in (c[1] - r).max(0)..=(c[1] + r).min(ny - 1) {
                for i in (c[0] - r).max(0)..=(c[0] + r).min(nx - 1) {
                    let idx = (i + nx * (j + ny * k)) as usize;
                    if grid.is_occupied(idx) {
                        let d = grid.centre_of(idx).distance_squared(p);
                        if best.is_none_or(|(b, _)| d < b) {
                            best = Some((d, idx));
                        }
                    }
                }
            }
        }
        if best.is_some() {
            return best.map(|(_, i)| i);
        }
    }
    None
}

/// What a voxel model is built on: the grid cut down to its largest connected part, and
/// the surface to draw (the given one, or marching tetrahedra over the voxels) embedded in
/// it.
pub fn embedded_body(
    grid: &mut VoxelGrid,
    surface: Option<SurfaceMesh>,
) -> Result<(SurfaceMesh, TrilinearEmbedding), MeshError> {
    if keep_largest(grid) == 0 {
        return Err(MeshError::Empty {
            what: "occupied voxels",
        });
    }
    let surface = surface.unwrap_or_else(|| marching_surface(grid));
    let embedding = TrilinearEmbedding::build(grid, &surface.vertices)?;
    Ok((surface, embedding))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_translates_and_is_adjoint() {
        let g = VoxelGrid::filled([3, 3, 3], 0.5);
        let rest: Vec<Vec3> = (0..g.len()).map(|i| g.centre_of(i)).collect();
        let pts = vec![
            Vec3::new(0.2, 0.7, 0.9),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(-0.3, 0.1, 0.4),
        ];
        let e = TrilinearEmbedding::build(&g, &pts).unwrap();
        for w in &e.weights {
            assert!((w.iter().sum::<Real>() - 1.0).abs() < 1e-12);
        }
        // An affine deformation of the elements is reproduced exactly inside the lattice.
        let a = |p: Vec3| Vec3::new(2.0 * p.x + 0.1 * p.y, p.y - 0.3 * p.z, 0.5 * p.z + 1.0);
        let x: Vec<Vec3> = rest.iter().map(|&p| a(p)).collect();
        let mut out = vec![Vec3::ZERO; 3];
        e.apply(&x, &rest, &mut out);
        for k in 0..2 {
            assert!(out[k].distance(a(pts[k])) < 1e-12, "{k}");
        }
        // A translation moves every vertex, even the one outside the lattice, rigidly.
        let t = Vec3::new(0.3, -0.2, 0.1);
        let xt: Vec<Vec3> = rest.iter().map(|&p| p + t).collect();
        e.apply(&xt, &rest, &mut out);
        for k in 0..3 {
            assert!(out[k].distance(pts[k] + t) < 1e-12);
        }
        // <apply(u), f> = <u, apply_transpose(f)>.
        let u: Vec<Vec3> = (0..g.len())
            .map(|i| Vec3::new(i as Real, 1.0, -(i as Real) * 0.5))
            .collect();
        let xu: Vec<Vec3> = rest.iter().zip(&u).map(|(r, d)| *r + *d).collect();
        e.apply(&xu, &rest, &mut out);
        let f = vec![
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(-1.0, 0.5, 0.0),
            Vec3::new(0.2, 0.2, -0.7),
        ];
        let mut g2 = vec![Vec3::ZERO; g.len()];
        e.apply_transpose(&f, &mut g2);
        let lhs: Real = out
            .iter()
            .zip(&pts)
            .zip(&f)
            .map(|((o, p), f)| (*o - *p).dot(*f))
            .sum();
        let rhs: Real = u.iter().zip(&g2).map(|(a, b)| a.dot(*b)).sum();
        assert!((lhs - rhs).abs() < 1e-9);
    }

    #[test]
    fn empty_corners_are_dropped_and_far_vertices_refused() {
        let mut g = VoxelGrid::filled([2, 2, 2], 1.0);
        g.labels[7] = 0;
        let e = TrilinearEmbedding::build(&g, &[Vec3::splat(0.9)]).unwrap();
        assert_eq!(e.weights[0][7], 0.0);
        assert!((e.weights[0].iter().sum::<Real>() - 1.0).abs() < 1e-12);
        assert!(TrilinearEmbedding::build(&g, &[Vec3::splat(100.0)]).is_err());
    }
}
