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
    /// How many times the surface was cut in four before it was tied (`[mesh]
    /// visual_levels`; 0 for a surface as given), for the messages that suggest a level.
    pub levels: u32,
    /// What the local queries read (`near`, `position`, `outward_normal`), built from
    /// `rest`, `triangles` and `mapping` when the surface is made.
    local: Local,
}

/// Built once per surface, so that a step reads only the fine vertices near an instrument
/// rather than recomputing all of them: the fine vertices each coarse triangle carries, with
/// how far the farthest lies off it, and the fine triangles around each fine vertex.
#[derive(Clone, Debug, Default, PartialEq)]
struct Local {
    /// One per coarse triangle of the map (its three vertices as the map names them).
    groups: Vec<Group>,
    /// The fine triangles around fine vertex j: `around[start[j]..start[j + 1]]`, ascending.
    start: Vec<u32>,
    around: Vec<u32>,
    /// 1 or −1: the rest surface's orientation (its triangles' normals times this point
    /// out), as `contact::outward_normals` finds it from the enclosed volume's sign.
    sign: Real,
    /// The largest coarse index the map names (a cut may have removed it).
    top: u32,
}

#[derive(Clone, Debug, PartialEq)]
struct Group {
    corners: [u32; 3],
    /// The largest distance at rest of one of its fine vertices from its point of the
    /// triangle: a fine vertex is its point of the moved triangle plus this fixed offset
    /// (displacements are mapped), so it is never farther than this from the triangle.
    offset: Real,
    fine: Vec<u32>,
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
        Some(Self::embedded(rest, triangles, nodes, weights, coarse_rest))
    }

    /// The coarse surface itself with each triangle cut into n² similar ones (n ≥ 1), each
    /// fine vertex tied to the triangle it was made on by its exact barycentric weights: a
    /// fine contact surface lying on the coarse one, for contact on the faces as well as the
    /// vertices (a probe then cannot pass between the coarse vertices). Corners and edge
    /// points are shared between the triangles that meet there, so no two fine vertices
    /// coincide. `None` when the coarse surface has no triangle or names a missing vertex.
    pub fn subdivided(
        coarse_rest: &[Vec3],
        coarse_triangles: &[[u32; 3]],
        n: usize,
    ) -> Option<Self> {
        if coarse_triangles.is_empty() {
            return None;
        }
        let n = n.max(1);
        let mut rest = Vec::new();
        let (mut nodes, mut weights) = (Vec::new(), Vec::new());
        let mut shared: std::collections::HashMap<(u32, u32, usize), u32> =
            std::collections::HashMap::new();
        let mut triangles = Vec::with_capacity(coarse_triangles.len() * n * n);
        for tri in coarse_triangles {
            let x = corners(coarse_rest, tri)?;
            // Grid point (i, j): weights (n − i − j, i, j) / n on the corners.
            let mut id = |i: usize, j: usize| -> u32 {
                let w = [(n - i - j) as Real, i as Real, j as Real].map(|c| c / n as Real);
                // A point on an edge (or a corner) is keyed by the edge's two coarse vertices
                // in ascending order and its step from the lower one, so both triangles on
                // the edge find it.
                let on: Vec<usize> = (0..3).filter(|&k| w[k] > 0.0).collect();
                let key = match on.as_slice() {
                    [k] => Some((tri[*k], tri[*k], 0)),
                    [a, b] => {
                        let (a, b) = if tri[*a] < tri[*b] {
                            (*a, *b)
                        } else {
                            (*b, *a)
                        };
                        Some((tri[a], tri[b], (w[b] * n as Real).round() as usize))
                    }
                    _ => None,
                };
                if let Some(k) = key
                    && let Some(&v) = shared.get(&k)
                {
                    return v;
                }
                let v = rest.len() as u32;
                rest.push(x[0] * w[0] + x[1] * w[1] + x[2] * w[2]);
                nodes.push([tri[0], tri[1], tri[2], tri[0]]);
                weights.push([w[0], w[1], w[2], 0.0]);
                if let Some(k) = key {
                    shared.insert(k, v);
                }
                v
            };
            let mut grid = vec![vec![0u32; n + 1]; n + 1];
            for (i, row) in grid.iter_mut().enumerate() {
                for (j, g) in row.iter_mut().enumerate().take(n + 1 - i) {
                    *g = id(i, j);
                }
            }
            for i in 0..n {
                for j in 0..n - i {
                    triangles.push([grid[i][j], grid[i + 1][j], grid[i][j + 1]]);
                    if j + 1 < n - i {
                        triangles.push([grid[i + 1][j], grid[i + 1][j + 1], grid[i][j + 1]]);
                    }
                }
            }
        }
        Some(Self::embedded(rest, triangles, nodes, weights, coarse_rest))
    }

    /// Fine vertices `rest` and `triangles` tied to the coarse corners `nodes` by `weights`,
    /// indexed against the coarse rest surface.
    fn embedded(
        rest: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        nodes: Vec<[u32; 4]>,
        weights: Vec<[Real; 4]>,
        coarse_rest: &[Vec3],
    ) -> Self {
        Self {
            rest,
            triangles,
            mapping: SurfaceMapping::Embedded { nodes, weights },
            levels: 0,
            local: Local::default(),
        }
        .indexed(coarse_rest)
    }

    /// The surface with its local index built (`Local`), against the coarse rest surface.
    fn indexed(mut self, coarse_rest: &[Vec3]) -> Self {
        let mut local = Local {
            sign: 1.0,
            ..Local::default()
        };
        let mut group_of: std::collections::HashMap<[u32; 3], usize> =
            std::collections::HashMap::new();
        for (j, &p) in self.rest.iter().enumerate() {
            let Some((corners, w)) = self.tie(j) else {
                continue;
            };
            local.top = local.top.max(corners[0]).max(corners[1]).max(corners[2]);
            let on: Vec3 = (0..3)
                .map(|k| coarse_rest.get(corners[k] as usize).copied().unwrap_or(p) * w[k])
                .sum();
            let g = *group_of.entry(corners).or_insert_with(|| {
                local.groups.push(Group {
                    corners,
                    offset: 0.0,
                    fine: Vec::new(),
                });
                local.groups.len() - 1
            });
            local.groups[g].offset = local.groups[g].offset.max(p.distance(on));
            local.groups[g].fine.push(j as u32);
        }
        let mut count = vec![0u32; self.rest.len() + 1];
        let mut volume: Real = 0.0;
        for t in &self.triangles {
            if let Some(x) = corners(&self.rest, t) {
                volume += x[0].dot(x[1].cross(x[2]));
                for &v in t {
                    count[v as usize + 1] += 1;
                }
            }
        }
        for j in 0..self.rest.len() {
            count[j + 1] += count[j];
        }
        let mut fill = count.clone();
        local.around = vec![0; count[self.rest.len()] as usize];
        for (i, t) in self.triangles.iter().enumerate() {
            if corners(&self.rest, t).is_some() {
                for &v in t {
                    local.around[fill[v as usize] as usize] = i as u32;
                    fill[v as usize] += 1;
                }
            }
        }
        local.start = count;
        if volume < 0.0 {
            local.sign = -1.0;
        }
        self.local = local;
        self
    }

    /// Into `out` (cleared), ascending: the fine vertices that may lie within `reach` of
    /// `center` for the coarse surface at `coarse`: those of every coarse triangle that
    /// comes within `reach` plus its offset (`Group::offset`), so none nearer is left out.
    /// All of them when the map names a coarse vertex `coarse` does not have.
    pub fn near(&self, coarse: &[Vec3], center: Vec3, reach: Real, out: &mut Vec<u32>) {
        out.clear();
        if self.local.top as usize >= coarse.len() {
            out.extend(0..self.rest.len() as u32);
            return;
        }
        for g in &self.local.groups {
            let x = g.corners.map(|c| coarse[c as usize]);
            let q = closest_point_on_triangle(center, x);
            if q.distance(center) <= reach + g.offset {
                out.extend_from_slice(&g.fine);
            }
        }
        out.sort_unstable();
    }

    /// Where fine vertex `j` is for the coarse surface at `coarse` (rest `coarse_rest`):
    /// one entry of `positions`, the same sum in the same order.
    pub fn position(&self, j: usize, coarse_rest: &[Vec3], coarse: &[Vec3]) -> Vec3 {
        let Some(&rest) = self.rest.get(j) else {
            return Vec3::ZERO;
        };
        let top = self.local.top as usize;
        if top >= coarse.len() || top >= coarse_rest.len() {
            return rest;
        }
        match &self.mapping {
            SurfaceMapping::Embedded { nodes, weights } => {
                let (Some(n), Some(w)) = (nodes.get(j), weights.get(j)) else {
                    return rest;
                };
                let mut d = Vec3::ZERO;
                for k in 0..4 {
                    let v = n[k] as usize;
                    d += (coarse[v] - coarse_rest[v]) * w[k];
                }
                d + rest
            }
            SurfaceMapping::Nodes(n) => match n.get(j) {
                Some(&v) => coarse[v as usize] - coarse_rest[v as usize] + rest,
                None => rest,
            },
        }
    }

    /// The outward unit normal at fine vertex `j` (its triangles' area vectors summed), the
    /// fine vertices being where `at` puts them: `contact::outward_normals`' entry for `j`.
    pub fn outward_normal(&self, j: usize, at: &dyn Fn(u32) -> Vec3) -> Vec3 {
        let (Some(&a), Some(&b)) = (self.local.start.get(j), self.local.start.get(j + 1)) else {
            return Vec3::ZERO;
        };
        let mut n = Vec3::ZERO;
        for &t in self.local.around.get(a as usize..b as usize).unwrap_or(&[]) {
            let Some(t) = self.triangles.get(t as usize) else {
                continue;
            };
            n += crate::math::triangle_area_vector(at(t[0]), at(t[1]), at(t[2]));
        }
        self.local.sign * n.normalize_or_zero()
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

    #[test]
    fn a_subdivided_surface_lies_on_the_coarse_one_and_shares_its_edges() {
        // A tetrahedron's four faces (outward), each cut into 3² = 9.
        let coarse = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let tris = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let n = 3;
        let m = MappedSurface::subdivided(&coarse, &tris, n).unwrap();
        // V + E (n − 1) + F (n − 1)(n − 2)/2 distinct vertices: no two coincide.
        assert_eq!(m.len(), 4 + 6 * (n - 1) + 4 * (n - 1) * (n - 2) / 2);
        for (a, p) in m.rest.iter().enumerate() {
            for q in &m.rest[a + 1..] {
                assert!(p.distance(*q) > 1e-9);
            }
        }
        assert_eq!(m.triangles.len(), 4 * n * n);
        // The same enclosed volume and area vector per coarse face: the fine triangles tile
        // the coarse ones with their orientation.
        let volume = |x: &[Vec3], t: &[[u32; 3]]| -> Real {
            t.iter()
                .map(|t| x[t[0] as usize].dot(x[t[1] as usize].cross(x[t[2] as usize])) / 6.0)
                .sum()
        };
        assert!((volume(&m.rest, &m.triangles) - volume(&coarse, &tris)).abs() < 1e-15);
        // Each fine vertex is where its weights put it, and moves with the coarse surface.
        let moved: Vec<Vec3> = coarse
            .iter()
            .map(|p| *p * 1.5 + Vec3::new(0.1, 0.0, -0.2))
            .collect();
        let mut out = Vec::new();
        m.positions(&coarse, &moved, &mut out);
        for (j, (o, r)) in out.iter().zip(&m.rest).enumerate() {
            let (v, w) = m.tie(j).unwrap();
            let at: Vec3 = (0..3).map(|k| coarse[v[k] as usize] * w[k]).sum();
            assert!(at.distance(*r) < 1e-15);
            assert!(o.distance(*r * 1.5 + Vec3::new(0.1, 0.0, -0.2)) < 1e-14);
        }
        // n = 1 is the coarse surface itself.
        let same = MappedSurface::subdivided(&coarse, &tris, 1).unwrap();
        assert_eq!(same.rest, coarse);
        assert!(MappedSurface::subdivided(&coarse, &[], 2).is_none());
    }

    #[test]
    fn the_local_queries_give_the_whole_surfaces_numbers() {
        // A tetrahedron's faces cut into 4² each, the surface moved unevenly: each fine
        // vertex's `position` and `outward_normal` are the whole-surface passes' entries to
        // the bit, and `near` holds every vertex within reach (found by brute force).
        let coarse = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let tris = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let cut = MappedSurface::subdivided(&coarse, &tris, 4).unwrap();
        // The same points lifted off the coarse faces (by up to 5 %): ties with offsets.
        let centre = Vec3::splat(0.25);
        let lifted: Vec<Vec3> = cut
            .rest
            .iter()
            .map(|p| centre + (*p - centre) * 1.05)
            .collect();
        let off = MappedSurface::new(lifted, cut.triangles.clone(), &coarse, &tris).unwrap();
        let moved = vec![
            Vec3::new(0.01, -0.02, 0.0),
            Vec3::new(1.1, 0.05, -0.03),
            Vec3::new(-0.04, 0.9, 0.1),
            Vec3::new(0.02, 0.03, 1.2),
        ];
        for m in [&cut, &off] {
            let mut all = Vec::new();
            m.positions(&coarse, &moved, &mut all);
            let normals = crate::interact::contact::outward_normals(&all, &m.triangles);
            let at = |v: u32| m.position(v as usize, &coarse, &moved);
            for j in 0..m.len() {
                assert_eq!(at(j as u32), all[j]);
                assert_eq!(m.outward_normal(j, &at), normals[j]);
            }
            let mut near = Vec::new();
            for (c, reach) in [
                (Vec3::new(0.3, 0.3, 0.3), 0.1),
                (Vec3::new(0.5, 0.2, -0.1), 0.15),
                (Vec3::new(2.0, 2.0, 2.0), 0.5),
            ] {
                m.near(&moved, c, reach, &mut near);
                let within: Vec<u32> = (0..m.len() as u32)
                    .filter(|&j| all[j as usize].distance(c) <= reach)
                    .collect();
                assert!(within.iter().all(|j| near.binary_search(j).is_ok()));
                // Local: far fewer than all of them near a point of one face.
                assert!(near.len() < m.len());
            }
            // A map naming a vertex the coarse surface lacks (after a cut): every vertex.
            m.near(&moved[..3], Vec3::ZERO, 0.1, &mut near);
            assert_eq!(near.len(), m.len());
        }
    }
}
