//! Quasi-viscous motion (eq. 13 of the survey): the static solution is a target that each
//! vertex approaches with the factor exp(−α d / Δt) per step, d being the geodesic distance
//! over the surface to the nearest vertex whose displacement is prescribed. Contact vertices
//! (d = 0) reach their targets at once; far regions lag, which reads as viscosity.
//!
//! Distances are shortest paths along mesh edges (Dijkstra from all sources at once),
//! recomputed when the contact set changes.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use crate::math::{Real, Vec3};

/// The surface's edge graph with edge lengths.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceGraph {
    neighbours: Vec<Vec<(u32, Real)>>,
}

#[derive(Clone, Copy, PartialEq)]
struct Item(Real, u32);

impl Eq for Item {}
impl Ord for Item {
    fn cmp(&self, other: &Self) -> Ordering {
        // Reversed: BinaryHeap pops the largest, Dijkstra wants the nearest.
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}
impl PartialOrd for Item {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl SurfaceGraph {
    /// The graph of triangle edges (indices must be valid, as checked when the model is built).
    pub fn new(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let mut neighbours: Vec<Vec<(u32, Real)>> = vec![Vec::new(); vertices.len()];
        for t in triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                let (Some(pa), Some(pb)) = (vertices.get(a as usize), vertices.get(b as usize))
                else {
                    continue;
                };
                let len = (*pa - *pb).length();
                for (x, y) in [(a, b), (b, a)] {
                    let list = &mut neighbours[x as usize];
                    if !list.iter().any(|&(v, _)| v == y) {
                        list.push((y, len));
                    }
                }
            }
        }
        Self { neighbours }
    }

    /// Geodesic (edge-path) distance of every vertex to the nearest of `sources`, in m;
    /// infinite where no source is reachable.
    pub fn distances(&self, sources: &[usize]) -> Vec<Real> {
        let mut d = vec![Real::INFINITY; self.neighbours.len()];
        let mut heap = BinaryHeap::new();
        for &s in sources {
            if let Some(slot) = d.get_mut(s) {
                *slot = 0.0;
                heap.push(Item(0.0, s as u32));
            }
        }
        while let Some(Item(dist, v)) = heap.pop() {
            if dist > d[v as usize] {
                continue;
            }
            for &(w, len) in &self.neighbours[v as usize] {
                let nd = dist + len;
                if nd < d[w as usize] {
                    d[w as usize] = nd;
                    heap.push(Item(nd, w));
                }
            }
        }
        d
    }
}

impl SurfaceGraph {
    /// The vertices at most `rings` edges from one of `sources` (sources included, invalid
    /// ones skipped), ascending: the neighbourhood of a contact patch.
    pub fn within_rings(&self, sources: &[usize], rings: usize) -> Vec<usize> {
        let mut seen = vec![false; self.neighbours.len()];
        let mut front: Vec<usize> = Vec::new();
        for &s in sources {
            if let Some(f) = seen.get_mut(s)
                && !*f
            {
                *f = true;
                front.push(s);
            }
        }
        for _ in 0..rings {
            let mut next = Vec::new();
            for &v in &front {
                for &(w, _) in &self.neighbours[v] {
                    if !std::mem::replace(&mut seen[w as usize], true) {
                        next.push(w as usize);
                    }
                }
            }
            front = next;
        }
        (0..seen.len()).filter(|&v| seen[v]).collect()
    }
}

/// Moves `positions` toward `targets` by eq. 13 with viscosity `alpha` (s/m) over `dt`.
/// Unreachable vertices (infinite distance) stay where they are.
pub fn relax(positions: &mut [Vec3], targets: &[Vec3], distance: &[Real], alpha: Real, dt: Real) {
    for ((p, t), d) in positions.iter_mut().zip(targets).zip(distance) {
        let f = (-alpha * d / dt).exp();
        *p += (*t - *p) * f;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_follow_edges() {
        // A unit square split along its diagonal (0,2): 0-1-2-3 around.
        let v = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let g = SurfaceGraph::new(&v, &[[0, 1, 2], [0, 2, 3]]);
        let d = g.distances(&[1]);
        assert_eq!(d[1], 0.0);
        assert!((d[0] - 1.0).abs() < 1e-15 && (d[2] - 1.0).abs() < 1e-15);
        // 1 → 0 → 3 or 1 → 2 → 3: 2; never through a missing edge (1,3).
        assert!((d[3] - 2.0).abs() < 1e-15);
        let two = g.distances(&[1, 3]);
        assert_eq!(two[3], 0.0);
        assert!((two[0] - 1.0).abs() < 1e-15);
        assert!(g.distances(&[]).iter().all(|x| x.is_infinite()));
        // Rings by edge count, not length: 1 reaches 0 and 2 (and itself), 2 reaches all.
        assert_eq!(g.within_rings(&[1], 0), vec![1]);
        assert_eq!(g.within_rings(&[1, 1, 9], 1), vec![0, 1, 2]);
        assert_eq!(g.within_rings(&[1], 2), vec![0, 1, 2, 3]);
    }

    #[test]
    fn relax_is_eq_13() {
        let mut p = vec![Vec3::ZERO; 3];
        let t = vec![Vec3::X; 3];
        relax(&mut p, &t, &[0.0, 0.01, Real::INFINITY], 10.0, 0.1);
        assert_eq!(p[0], Vec3::X);
        assert!((p[1].x - (-1.0f64).exp()).abs() < 1e-15);
        assert_eq!(p[2], Vec3::ZERO);
    }
}
