//! A dense uniform grid over a triangle surface for the two questions meshing asks of it:
//! the point of the surface nearest to a point, and where a short segment first crosses it.

use crate::math::{Real, Vec3, closest_point_on_triangle, segment_triangle};

/// Cells are about the surface's mean edge length, and never more than this many.
const MAX_CELLS: usize = 1 << 21;

#[derive(Clone, Debug)]
pub struct TriangleIndex {
    pub(crate) vertices: Vec<Vec3>,
    pub(crate) triangles: Vec<[u32; 3]>,
    lo: Vec3,
    cell: Real,
    n: [usize; 3],
    /// Triangles of cell c: `items[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    items: Vec<u32>,
}

impl TriangleIndex {
    /// Indexes the triangles (their indices must be in range; `io::read` checks that).
    pub fn new(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let (mut lo, mut hi) = (Vec3::splat(Real::INFINITY), Vec3::splat(-Real::INFINITY));
        let mut edge_sum = 0.0;
        for t in triangles {
            let p = t.map(|v| vertices[v as usize]);
            for q in p {
                lo = lo.min(q);
                hi = hi.max(q);
            }
            edge_sum += (p[1] - p[0]).length() + (p[2] - p[1]).length() + (p[0] - p[2]).length();
        }
        if triangles.is_empty() {
            (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        }
        let ext = (hi - lo).max(Vec3::splat(1e-12));
        let mean_edge = edge_sum / (3 * triangles.len()).max(1) as Real;
        let volume_cells = |c: Real| {
            let n = (ext / c).ceil();
            n.x * n.y * n.z
        };
        let mut cell = mean_edge.max(ext.max_element() / 256.0);
        while volume_cells(cell) > MAX_CELLS as Real {
            cell *= 1.25;
        }
        let n = (ext / cell).ceil().max(Vec3::ONE);
        let n = [n.x as usize, n.y as usize, n.z as usize];
        let mut index = Self {
            vertices: vertices.to_vec(),
            triangles: triangles.to_vec(),
            lo,
            cell,
            n,
            start: Vec::new(),
            items: Vec::new(),
        };
        let cells = n[0] * n[1] * n[2];
        let mut count = vec![0u32; cells + 1];
        for t in 0..triangles.len() {
            index.for_cells_of(t, |c| count[c] += 1);
        }
        let mut acc = 0u32;
        for c in count.iter_mut() {
            let k = *c;
            *c = acc;
            acc += k;
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; acc as usize];
        for t in 0..triangles.len() {
            index.for_cells_of(t, |c| {
                items[fill[c] as usize] = t as u32;
                fill[c] += 1;
            });
        }
        index.start = count;
        index.items = items;
        index
    }

    fn cell_of(&self, p: Vec3) -> [usize; 3] {
        let r = (p - self.lo) / self.cell;
        [r.x, r.y, r.z]
            .iter()
            .zip(self.n)
            .map(|(&v, n)| (v.max(0.0) as usize).min(n - 1))
            .collect::<Vec<_>>()
            .try_into()
            .unwrap_or([0; 3])
    }

    fn cell_id(&self, c: [usize; 3]) -> usize {
        c[0] + self.n[0] * (c[1] + self.n[1] * c[2])
    }

    fn for_cells_of(&self, t: usize, f: impl FnMut(usize)) {
        let p = self.triangles[t].map(|v| self.vertices[v as usize]);
        let a = self.cell_of(p[0].min(p[1]).min(p[2]));
        let b = self.cell_of(p[0].max(p[1]).max(p[2]));
        self.for_box(a, b, f);
    }

    fn for_box(&self, a: [usize; 3], b: [usize; 3], mut f: impl FnMut(usize)) {
        for k in a[2]..=b[2] {
            for j in a[1]..=b[1] {
                for i in a[0]..=b[0] {
                    f(self.cell_id([i, j, k]));
                }
            }
        }
    }

    fn cell_items(&self, c: usize) -> &[u32] {
        &self.items[self.start[c] as usize..self.start[c + 1] as usize]
    }

    pub(crate) fn corners(&self, t: u32) -> [Vec3; 3] {
        self.triangles[t as usize].map(|v| self.vertices[v as usize])
    }

    /// Distance from `p` to the nearest point of the surface (infinite for no triangles).
    pub fn distance(&self, p: Vec3) -> Real {
        if self.triangles.is_empty() {
            return Real::INFINITY;
        }
        let c = self.cell_of(p);
        let mut best = Real::INFINITY;
        let rmax = self.n.iter().copied().max().unwrap_or(1);
        for r in 0..=rmax {
            let lo = c.map(|v| v.saturating_sub(r));
            let hi = [0, 1, 2].map(|a| (c[a] + r).min(self.n[a] - 1));
            for k in lo[2]..=hi[2] {
                for j in lo[1]..=hi[1] {
                    for i in lo[0]..=hi[0] {
                        let ring = [i, j, k]
                            .iter()
                            .zip(c)
                            .map(|(&x, y)| x.abs_diff(y))
                            .max()
                            .unwrap_or(0);
                        if ring != r {
                            continue;
                        }
                        for &t in self.cell_items(self.cell_id([i, j, k])) {
                            let q = closest_point_on_triangle(p, self.corners(t));
                            best = best.min((q - p).length());
                        }
                    }
                }
            }
            // Cells beyond ring r are at least r cells from p's (clamped) cell.
            if best <= r as Real * self.cell {
                break;
            }
        }
        best
    }

    /// Where the segment p→q first crosses the surface, as a fraction of p→q.
    pub fn first_hit(&self, p: Vec3, q: Vec3) -> Option<Real> {
        let a = self.cell_of(p.min(q));
        let b = self.cell_of(p.max(q));
        let mut best: Option<Real> = None;
        self.for_box(a, b, |c| {
            for &t in self.cell_items(c) {
                if let Some(s) = segment_triangle(p, q, self.corners(t))
                    && best.is_none_or(|b| s < b)
                {
                    best = Some(s);
                }
            }
        });
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::icosphere;

    #[test]
    fn distance_and_hits_on_a_sphere() {
        let s = icosphere(Vec3::ZERO, 1.0, 3);
        let index = TriangleIndex::new(&s.vertices, &s.triangles);
        // The icosphere is inscribed: its faces are at most ~1% inside the unit sphere.
        for p in [
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, -1.5, 0.3),
            Vec3::ZERO,
        ] {
            let d = index.distance(p);
            assert!((d - (p.length() - 1.0).abs()).abs() < 0.02, "{p}: {d}");
        }
        let brute = |p: Vec3| {
            (0..s.triangles.len())
                .map(|t| (closest_point_on_triangle(p, s.corners(t)) - p).length())
                .fold(Real::INFINITY, Real::min)
        };
        for p in [Vec3::new(0.3, 0.2, -0.1), Vec3::new(5.0, 1.0, 2.0)] {
            assert!((index.distance(p) - brute(p)).abs() < 1e-12);
        }
        let t = index.first_hit(Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0));
        assert!(t.is_some_and(|t| (t - 0.5).abs() < 0.01));
        assert!(
            index
                .first_hit(Vec3::ZERO, Vec3::new(0.5, 0.0, 0.0))
                .is_none()
        );
    }
}
