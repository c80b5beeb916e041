//! Finding the tetrahedra a blade may touch without looking at all of them: each
//! tetrahedron is filed in a `SpatialGrid` under its bounding box, inflated by a margin,
//! at the node positions it was filed with (the reference positions). While no node is
//! farther than the margin from its reference, every filed box still contains its
//! tetrahedron, so a query is exact (conservative). Before a query, `refresh` re-files the
//! tetrahedra of the nodes that moved farther: a scan of the node positions (a few flops
//! per node) plus work proportional to what moved.
//!
//! The cell size is twice the median tetrahedron extent, the margin a quarter cell: a
//! tetrahedron overlaps about 8 cells, and a node re-files its tetrahedra only after
//! moving half a typical element.

use crate::math::{Real, Vec3};
use crate::mesh::spatial_grid::SpatialGrid;

/// The grid of tetrahedra and the node → tetrahedra table.
#[derive(Clone, Debug)]
pub struct TetLocator {
    grid: SpatialGrid,
    margin: Real,
    /// Tetrahedra of node n: `node_tets[node_start[n]..node_start[n + 1]]` (alive or not).
    node_start: Vec<u32>,
    node_tets: Vec<u32>,
    reference: Vec<Vec3>,
    /// Stamps so that a tetrahedron of several moved nodes is re-filed once per refresh.
    refiled: Vec<u32>,
    epoch: u32,
    candidates: Vec<u32>,
}

fn bounds(p: &[Vec3; 4]) -> (Vec3, Vec3) {
    (
        p[0].min(p[1]).min(p[2]).min(p[3]),
        p[0].max(p[1]).max(p[2]).max(p[3]),
    )
}

impl TetLocator {
    /// Files every tetrahedron of `tets` at positions `x`.
    pub fn new(tets: &[[u32; 4]], x: &[Vec3]) -> Self {
        let n = x.len();
        let mut node_start = vec![0u32; n + 1];
        for &v in tets.iter().flatten() {
            node_start[v as usize + 1] += 1;
        }
        for i in 0..n {
            node_start[i + 1] += node_start[i];
        }
        let mut fill = node_start.clone();
        let mut node_tets = vec![0u32; 4 * tets.len()];
        for (t, tet) in tets.iter().enumerate() {
            for &v in tet {
                node_tets[fill[v as usize] as usize] = t as u32;
                fill[v as usize] += 1;
            }
        }
        let mut extents: Vec<Real> = tets
            .iter()
            .map(|tet| {
                let (lo, hi) = bounds(&tet.map(|v| x[v as usize]));
                (hi - lo).max_element()
            })
            .collect();
        let median = if extents.is_empty() {
            1.0
        } else {
            let mid = extents.len() / 2;
            *extents.select_nth_unstable_by(mid, Real::total_cmp).1
        };
        let cell = 2.0 * median;
        let mut locator = Self {
            grid: SpatialGrid::new(cell),
            margin: 0.0,
            node_start,
            node_tets,
            reference: x.to_vec(),
            refiled: vec![0; tets.len()],
            epoch: 0,
            candidates: Vec::new(),
        };
        locator.margin = 0.25 * locator.grid.cell_size();
        for (t, tet) in tets.iter().enumerate() {
            locator.file(t, tet);
        }
        locator
    }

    /// The tetrahedra (alive or not) that have node `n` as a corner.
    pub fn tets_of(&self, n: usize) -> &[u32] {
        match (self.node_start.get(n), self.node_start.get(n + 1)) {
            (Some(&a), Some(&b)) => &self.node_tets[a as usize..b as usize],
            _ => &[],
        }
    }

    fn file(&mut self, t: usize, tet: &[u32; 4]) {
        let (lo, hi) = bounds(&tet.map(|v| self.reference[v as usize]));
        let m = Vec3::splat(self.margin);
        self.grid.insert(t as u32, lo - m, hi + m);
    }

    /// Takes a removed tetrahedron out of the grid.
    pub fn remove(&mut self, t: usize) {
        self.grid.remove(t as u32);
    }

    /// Re-files the alive tetrahedra of every node that moved farther than the margin from
    /// its reference position; returns how many nodes moved that far.
    pub fn refresh(&mut self, tets: &[[u32; 4]], alive: &[bool], x: &[Vec3]) -> usize {
        let m2 = self.margin * self.margin;
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.refiled.iter_mut().for_each(|s| *s = 0);
            self.epoch = 1;
        }
        let mut moved = 0;
        for (n, &xn) in x.iter().enumerate().take(self.reference.len()) {
            if (xn - self.reference[n]).length_squared() <= m2 {
                continue;
            }
            moved += 1;
            self.reference[n] = xn;
            let (a, b) = (self.node_start[n] as usize, self.node_start[n + 1] as usize);
            for k in a..b {
                let t = self.node_tets[k] as usize;
                if alive[t] && self.refiled[t] != self.epoch {
                    self.refiled[t] = self.epoch;
                    self.file(t, &tets[t]);
                }
            }
        }
        moved
    }

    /// Tetrahedra filed in the cells that the triangles' boxes overlap and whose planes
    /// pass through (a cell the triangle's plane misses cannot hold a touching one).
    pub fn candidates(&mut self, triangles: &[[Vec3; 3]]) -> &[u32] {
        let boxes: Vec<(Vec3, Vec3)> = triangles
            .iter()
            .map(|t| (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])))
            .collect();
        let normals: Vec<Vec3> = triangles
            .iter()
            .map(|t| (t[1] - t[0]).cross(t[2] - t[0]))
            .collect();
        let margin = self.margin;
        self.candidates.clear();
        self.grid.query(
            &boxes,
            |k, lo, hi| {
                // Separating-axis test of the cell against the triangle's plane, with a
                // small slack for rounding.
                let (c, h) = (
                    0.5 * (lo + hi),
                    0.5 * (hi - lo) + Vec3::splat(1e-3 * margin),
                );
                let nrm = normals[k];
                nrm.dot(c - triangles[k][0]).abs() <= h.dot(nrm.abs())
            },
            &mut self.candidates,
        );
        &self.candidates
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_table_and_refresh_follow_the_nodes() {
        let x = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(11.0, 0.0, 0.0),
            Vec3::new(10.0, 1.0, 0.0),
            Vec3::new(10.0, 0.0, 1.0),
        ];
        let tets = [[0, 1, 2, 3], [4, 5, 6, 7]];
        let mut loc = TetLocator::new(&tets, &x);
        assert_eq!(loc.tets_of(1), [0]);
        assert!(loc.tets_of(99).is_empty());
        let tri = |o: Vec3| [o, o + Vec3::Y * 0.5, o + Vec3::Z * 0.5];
        assert_eq!(loc.candidates(&[tri(Vec3::new(0.3, 0.1, 0.1))]), [0]);
        // Move the second tetrahedron onto the first: found there after a refresh only.
        let mut y = x.clone();
        for p in &mut y[4..] {
            *p -= Vec3::new(10.0, 0.0, 0.0);
        }
        let alive = [true, true];
        assert_eq!(loc.refresh(&tets, &alive, &y), 4);
        let mut found = loc.candidates(&[tri(Vec3::new(0.3, 0.1, 0.1))]).to_vec();
        found.sort_unstable();
        assert_eq!(found, [0, 1]);
        assert_eq!(loc.refresh(&tets, &alive, &y), 0);
        loc.remove(0);
        assert_eq!(loc.candidates(&[tri(Vec3::new(0.3, 0.1, 0.1))]), [1]);
    }
}
