//! A finer surface carried by a model's coarse one (`visual = "…"` in a scene's `[mesh]`):
//! instruments touch it, and its points hand their contact forces to the coarse vertices.
//!
//! The pattern is SOFA's `BarycentricMapping`: each fine vertex is tied to the nearest
//! triangle of the model's rest surface by barycentric weights w (its projection there),
//! and moves with that triangle's vertices, x_fine = X_fine + Σ wᵢ (xᵢ − Xᵢ) (displacements
//! are mapped, so a fine vertex a little off the coarse surface keeps its offset). A force f
//! on a fine vertex reaches the coarse vertices as wᵢ f: the transpose of the same map, so
//! the work done is the same on both sides. The model's constraints live on its surface
//! vertices, which is why the fine surface is tied to surface triangles (the boundary faces
//! of the tetrahedra) rather than to the tetrahedra themselves.

use crate::interact::bvh::Bvh;
use crate::interact::contact::barycentric;
use crate::math::{Real, Vec3, closest_point_on_triangle};
use crate::mesh::SurfaceMapping;

/// The fine surface and its map onto the model's surface vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct MappedSurface {
    /// Fine vertices at rest, in m.
    pub rest: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Per fine vertex, the three coarse surface vertices of its triangle and their weights
    /// (`SurfaceMapping::Embedded`, fourth weight 0).
    pub mapping: SurfaceMapping,
}

impl MappedSurface {
    /// Ties every vertex of the fine surface (`rest`, `triangles`) to the nearest triangle
    /// of the coarse rest surface. `None` when the coarse surface has no triangle.
    pub fn new(
        rest: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        coarse_rest: &[Vec3],
        coarse_triangles: &[[u32; 3]],
    ) -> Option<Self> {
        if coarse_triangles.is_empty() {
            return None;
        }
        let bvh = Bvh::build(coarse_rest, coarse_triangles);
        let (lo, hi) = coarse_rest.iter().fold(
            (Vec3::splat(Real::INFINITY), Vec3::splat(Real::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let diagonal = (hi - lo).length().max(Real::MIN_POSITIVE);
        let mut nodes = Vec::with_capacity(rest.len());
        let mut weights = Vec::with_capacity(rest.len());
        for p in &rest {
            // Grow the query ball until it holds a triangle; the nearest of those within the
            // ball's radius is the nearest of all.
            let mut radius = 1e-3 * diagonal;
            let mut best: Option<(Real, [u32; 3], [Real; 3])> = None;
            loop {
                for t in bvh.query_sphere(*p, radius) {
                    let Some(tri) = coarse_triangles.get(t as usize) else {
                        continue;
                    };
                    let Some(x) = corners(coarse_rest, tri) else {
                        continue;
                    };
                    let q = closest_point_on_triangle(*p, x);
                    let d = q.distance(*p);
                    if best.is_none_or(|(b, _, _)| d < b) {
                        best = Some((d, *tri, clamped(barycentric(q, x))));
                    }
                }
                match best {
                    Some((d, _, _)) if d <= radius => break,
                    _ if radius > 4.0 * diagonal + p.distance(lo) => break,
                    _ => radius *= 2.0,
                }
            }
            let (_, tri, w) = best?;
            nodes.push([tri[0], tri[1], tri[2], tri[0]]);
            weights.push([w[0], w[1], w[2], 0.0]);
        }
        Some(Self {
            rest,
            triangles,
            mapping: SurfaceMapping::Embedded { nodes, weights },
        })
    }

    /// The coarse surface itself subdivided flat: each triangle into 4^`levels` similar
    /// triangles (its edges cut into 2^`levels` equal parts), every fine vertex tied to the
    /// coarse triangle it lies on by its exact barycentric weights. Vertices on a coarse
    /// edge are shared by its two triangles, so a closed surface stays closed, and each
    /// fine triangle keeps its coarse triangle's orientation. Triangles naming a vertex
    /// twice or one beyond `coarse_rest` are skipped. `None` when none is left.
    ///
    /// On a coarse surface of flat triangles (linear tetrahedra's boundary) the fine points
    /// lie on the very faces the model deforms, so an instrument touching them touches the
    /// model's own surface, only at more points than its vertices.
    pub fn subdivided(
        coarse_rest: &[Vec3],
        coarse_triangles: &[[u32; 3]],
        levels: u32,
    ) -> Option<Self> {
        let n = 1u32 << levels.min(10);
        let mut rest: Vec<Vec3> = coarse_rest.to_vec();
        let mut nodes: Vec<[u32; 4]> = (0..coarse_rest.len() as u32)
            .map(|v| [v, v, v, v])
            .collect();
        let mut weights: Vec<[Real; 4]> = vec![[1.0, 0.0, 0.0, 0.0]; coarse_rest.len()];
        // Points inside a coarse edge, by (lower vertex, upper vertex, steps from the lower).
        let mut on_edge: std::collections::HashMap<(u32, u32, u32), u32> = Default::default();
        let mut triangles = Vec::new();
        let mut lattice = Vec::with_capacity(((n + 1) * (n + 2) / 2) as usize);
        for tri in coarse_triangles {
            let [a, b, c] = *tri;
            if a == b || b == c || a == c || corners(coarse_rest, tri).is_none() {
                continue;
            }
            // Lattice point (i, j), i + j ≤ n, is a + i/n (b − a) + j/n (c − a).
            lattice.clear();
            for i in 0..=n {
                for j in 0..=n - i {
                    let w = [
                        (n - i - j) as Real / n as Real,
                        i as Real / n as Real,
                        j as Real / n as Real,
                    ];
                    let corner = match (i, j) {
                        (0, 0) => Some(a),
                        (i, 0) if i == n => Some(b),
                        (0, j) if j == n => Some(c),
                        _ => None,
                    };
                    // The edge the point lies inside, if any: (its ends, steps from the first).
                    let edge = match (i, j) {
                        _ if corner.is_some() => None,
                        (i, 0) => Some((a, b, i)),
                        (0, j) => Some((a, c, j)),
                        (i, j) if i + j == n => Some((b, c, j)),
                        _ => None,
                    };
                    let mut fresh = || {
                        rest.push(
                            w[0] * coarse_rest[a as usize]
                                + w[1] * coarse_rest[b as usize]
                                + w[2] * coarse_rest[c as usize],
                        );
                        nodes.push([a, b, c, a]);
                        weights.push([w[0], w[1], w[2], 0.0]);
                        (rest.len() - 1) as u32
                    };
                    let id = match (corner, edge) {
                        (Some(v), _) => v,
                        (None, Some((u, v, k))) => {
                            let key = if u < v { (u, v, k) } else { (v, u, n - k) };
                            *on_edge.entry(key).or_insert_with(fresh)
                        }
                        (None, None) => fresh(),
                    };
                    lattice.push(id);
                }
            }
            // Row i starts at Σ_{r<i} (n + 1 − r).
            let at = |i: u32, j: u32| lattice[(i * (n + 1) - i * (i.max(1) - 1) / 2 + j) as usize];
            for i in 0..n {
                for j in 0..n - i {
                    triangles.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
                    if i + j + 1 < n {
                        triangles.push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                    }
                }
            }
        }
        if triangles.is_empty() {
            return None;
        }
        Some(Self {
            rest,
            triangles,
            mapping: SurfaceMapping::Embedded { nodes, weights },
        })
    }

    /// Number of fine vertices.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// The coarse vertices and weights of fine vertex `j`.
    pub fn tie(&self, j: usize) -> Option<([u32; 3], [Real; 3])> {
        match &self.mapping {
            SurfaceMapping::Embedded { nodes, weights } => {
                let (n, w) = (nodes.get(j)?, weights.get(j)?);
                Some(([n[0], n[1], n[2]], [w[0], w[1], w[2]]))
            }
            SurfaceMapping::Nodes(n) => Some(([*n.get(j)?; 3], [1.0, 0.0, 0.0])),
        }
    }

    /// Where the fine vertices are for the coarse surface at `coarse` (rest `coarse_rest`).
    pub fn positions(&self, coarse_rest: &[Vec3], coarse: &[Vec3], out: &mut Vec<Vec3>) {
        let displacement: Vec<Vec3> = coarse
            .iter()
            .zip(coarse_rest)
            .map(|(x, r)| *x - *r)
            .collect();
        out.clear();
        out.resize(self.rest.len(), Vec3::ZERO);
        if self.mapping.len() == self.rest.len() && self.mapping_in_range(displacement.len()) {
            self.mapping.apply(&displacement, out);
        }
        for (o, r) in out.iter_mut().zip(&self.rest) {
            *o += *r;
        }
    }

    /// Every coarse index of the map is below `count` (a cut may have changed the surface).
    fn mapping_in_range(&self, count: usize) -> bool {
        match &self.mapping {
            SurfaceMapping::Embedded { nodes, .. } => nodes
                .iter()
                .all(|n| n.iter().all(|&i| (i as usize) < count)),
            SurfaceMapping::Nodes(n) => n.iter().all(|&i| (i as usize) < count),
        }
    }
}

fn corners(positions: &[Vec3], tri: &[u32; 3]) -> Option<[Vec3; 3]> {
    Some([
        *positions.get(tri[0] as usize)?,
        *positions.get(tri[1] as usize)?,
        *positions.get(tri[2] as usize)?,
    ])
}

/// Weights of a point of the triangle, rounding negatives removed.
fn clamped(w: [Real; 3]) -> [Real; 3] {
    let w = w.map(|x| x.max(0.0));
    let sum: Real = w.iter().sum();
    if sum > 0.0 {
        w.map(|x| x / sum)
    } else {
        [1.0, 0.0, 0.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fine_points_follow_their_triangle_and_forces_keep_their_work() {
        // One coarse triangle; fine points on it and one 1 mm above it.
        let coarse = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let tris = vec![[0, 1, 2]];
        let fine = vec![
            Vec3::new(0.25, 0.25, 0.0),
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(0.1, 0.2, 1e-3),
        ];
        let m = MappedSurface::new(fine.clone(), vec![[0, 1, 2]], &coarse, &tris).unwrap();
        // A rigid translation moves every fine point with it.
        let shift = Vec3::new(0.1, -0.2, 0.3);
        let moved: Vec<Vec3> = coarse.iter().map(|p| *p + shift).collect();
        let mut out = Vec::new();
        m.positions(&coarse, &moved, &mut out);
        for (o, f) in out.iter().zip(&fine) {
            assert!(o.distance(*f + shift) < 1e-15, "{o} {f}");
        }
        // Lifting vertex 1 by h lifts the point at its edge midpoint by h/2.
        let mut lifted = coarse.clone();
        lifted[1].z += 0.01;
        m.positions(&coarse, &lifted, &mut out);
        assert!((out[1].z - 0.005).abs() < 1e-15);
        // Forces back by the transpose: same total, same virtual work.
        let f = vec![Vec3::Z, Vec3::X, -Vec3::Y];
        let mut g = vec![Vec3::ZERO; 3];
        m.mapping.apply_transpose(&f, &mut g);
        let total: Vec3 = g.iter().copied().sum();
        assert!(total.distance(Vec3::Z + Vec3::X - Vec3::Y) < 1e-15);
    }

    /// A closed coarse surface (the unit tetrahedron's four faces) subdivided flat twice:
    /// 4² times the triangles, every coarse edge's inner points shared (V + E (2^k − 1) +
    /// F (2^k − 1)(2^k − 2)/2 vertices), closed and oriented as the coarse one (each fine
    /// triangle's normal is its coarse face's), the fine points on their faces, weights
    /// that sum to 1, and a motion of the coarse vertices carried to the fine ones by
    /// barycentric interpolation exactly (a fine point at a corner moves with its vertex).
    #[test]
    fn subdividing_flat_keeps_the_surface_closed_and_the_points_on_their_faces() {
        let coarse = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let tris = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        for k in 0..=3u32 {
            let m = MappedSurface::subdivided(&coarse, &tris, k).unwrap();
            let n = 1usize << k;
            assert_eq!(m.triangles.len(), 4 * n * n);
            assert_eq!(m.len(), 4 + 6 * (n - 1) + 4 * (n - 1) * (n.max(2) - 2) / 2);
            assert!(crate::compare::measure::closed_and_oriented(&m.triangles));
            let normal = |p: [Vec3; 3]| (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            for (f, t) in m.triangles.iter().enumerate() {
                let fine = normal(t.map(|v| m.rest[v as usize]));
                let c = tris[f / (n * n)];
                let coarse_n = normal(c.map(|v| coarse[v as usize]));
                assert!(fine.distance(coarse_n) < 1e-12, "k {k} triangle {f}");
            }
            let moved: Vec<Vec3> = coarse
                .iter()
                .enumerate()
                .map(|(i, p)| *p * (1.0 + i as Real) + Vec3::splat(0.1 * i as Real))
                .collect();
            let mut out = Vec::new();
            m.positions(&coarse, &moved, &mut out);
            for j in 0..m.len() {
                let (v, w) = m.tie(j).unwrap();
                assert!((w.iter().sum::<Real>() - 1.0).abs() < 1e-15);
                let at = |x: &[Vec3]| (0..3).map(|i| w[i] * x[v[i] as usize]).sum::<Vec3>();
                assert!(at(&coarse).distance(m.rest[j]) < 1e-15);
                assert!(at(&moved).distance(out[j]) < 1e-14);
            }
        }
        // Nothing to subdivide: no triangle, or only degenerate and out-of-range ones.
        assert!(MappedSurface::subdivided(&coarse, &[], 2).is_none());
        assert!(MappedSurface::subdivided(&coarse, &[[0, 0, 1], [0, 1, 9]], 2).is_none());
    }
}
