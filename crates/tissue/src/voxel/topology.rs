//! Which voxels exist and which lattice links between them hold: the topology both voxel
//! models share (`chainmail` uses the 6 face links, `linked-volumes` 6, 18 or 26), and
//! its three edits: `cut` removes the links whose segment (current positions) crosses a
//! scalpel's swept quad, `carve` removes the voxels under a ball, `join` restores links
//! between lattice neighbours that the caller finds touching.
//!
//! Directions come in opposite pairs (d, d ^ 1): the 6 faces first (−x, +x, −y, +y, −z,
//! +z, so direction d is along axis d / 2), then the 12 face diagonals, then the 8 body
//! diagonals; a model with n neighbours uses directions 0..n. A link is stored on both of
//! its voxels (bit d on a, bit d ^ 1 on b) and reported once, as (a, d) with d odd.

use crate::math::{Real, Vec3};
use crate::model::CutPath;

use super::VoxelGrid;

/// The 26 lattice offsets, opposite directions paired as (d, d ^ 1).
pub const OFFSETS: [[i8; 3]; 26] = [
    [-1, 0, 0],
    [1, 0, 0],
    [0, -1, 0],
    [0, 1, 0],
    [0, 0, -1],
    [0, 0, 1],
    [-1, -1, 0],
    [1, 1, 0],
    [-1, 1, 0],
    [1, -1, 0],
    [-1, 0, -1],
    [1, 0, 1],
    [-1, 0, 1],
    [1, 0, -1],
    [0, -1, -1],
    [0, 1, 1],
    [0, -1, 1],
    [0, 1, -1],
    [-1, -1, -1],
    [1, 1, 1],
    [-1, -1, 1],
    [1, 1, -1],
    [-1, 1, -1],
    [1, -1, 1],
    [1, -1, -1],
    [-1, 1, 1],
];

/// A link, named once: voxel `a` and direction `d` (odd) toward its neighbour.
pub type Link = (u32, u8);

/// Occupied voxels (a label each) and the links between them.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelLinks {
    pub dims: [usize; 3],
    pub spacing: Vec3,
    pub origin: Vec3,
    /// Per voxel: 0 empty, otherwise its material class.
    pub labels: Vec<u8>,
    /// Per voxel: bit d set when linked to its neighbour in direction d.
    pub bits: Vec<u32>,
    directions: usize,
    strides: [isize; 26],
}

impl VoxelLinks {
    /// Links every occupied voxel of `grid` to its occupied neighbours in the first
    /// `directions` directions (6, 18 or 26; larger values are capped at 26).
    pub fn new(grid: &VoxelGrid, directions: usize) -> Self {
        let [nx, ny, _] = grid.dims;
        let strides = OFFSETS
            .map(|o| o[0] as isize + nx as isize * (o[1] as isize + ny as isize * o[2] as isize));
        let mut links = Self {
            dims: grid.dims,
            spacing: grid.spacing,
            origin: grid.origin,
            labels: grid.labels.clone(),
            bits: vec![0; grid.len()],
            directions: directions.min(26),
            strides,
        };
        for v in 0..links.len() {
            if links.is_occupied(v) {
                for d in 0..links.directions {
                    if links
                        .lattice_neighbour(v, d)
                        .is_some_and(|b| links.is_occupied(b))
                    {
                        links.bits[v] |= 1 << d;
                    }
                }
            }
        }
        links
    }

    /// Number of voxels in the grid (occupied or not).
    pub fn len(&self) -> usize {
        self.labels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.labels.is_empty()
    }

    /// Directions in use (6, 18 or 26).
    pub fn directions(&self) -> usize {
        self.directions
    }

    /// Linear index offset of direction d.
    pub fn strides(&self) -> &[isize; 26] {
        &self.strides
    }

    pub fn is_occupied(&self, v: usize) -> bool {
        self.labels.get(v).is_some_and(|&l| l != 0)
    }

    /// The grid as it is now (labels of removed voxels are 0).
    pub fn grid(&self) -> VoxelGrid {
        VoxelGrid {
            dims: self.dims,
            spacing: self.spacing,
            origin: self.origin,
            labels: self.labels.clone(),
        }
    }

    /// Rest centre of voxel v.
    pub fn centre_of(&self, v: usize) -> Vec3 {
        let [nx, ny, _] = self.dims;
        let (i, j, k) = (v % nx, (v / nx) % ny, v / (nx * ny));
        self.origin + Vec3::new(i as Real, j as Real, k as Real) * self.spacing
    }

    /// The lattice neighbour of v in direction d (occupied or not), if inside the grid.
    pub fn lattice_neighbour(&self, v: usize, d: usize) -> Option<usize> {
        let [nx, ny, nz] = self.dims;
        let o = OFFSETS.get(d)?;
        let c = [v % nx, (v / nx) % ny, v / (nx * ny)];
        let mut q = [0usize; 3];
        for a in 0..3 {
            let x = c[a] as isize + o[a] as isize;
            if x < 0 || x >= [nx, ny, nz][a] as isize {
                return None;
            }
            q[a] = x as usize;
        }
        Some(q[0] + nx * (q[1] + ny * q[2]))
    }

    /// The neighbour of v in direction d, if linked.
    #[inline]
    pub fn linked(&self, v: usize, d: usize) -> Option<usize> {
        (self.bits.get(v).is_some_and(|b| b & (1 << d) != 0))
            .then(|| (v as isize + self.strides[d]) as usize)
    }

    /// Number of links (each counted once).
    pub fn link_count(&self) -> usize {
        self.bits
            .iter()
            .map(|b| (b & 0xAAAA_AAAA).count_ones() as usize)
            .sum()
    }

    /// Every link, each once, as (a, b, d) with d odd.
    pub fn each_link(&self) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
        (0..self.len()).flat_map(move |a| {
            (1..self.directions)
                .step_by(2)
                .filter_map(move |d| self.linked(a, d).map(|b| (a, b, d)))
        })
    }

    /// Removes the link from a in direction d (and its twin); true if there was one.
    pub fn unlink(&mut self, a: usize, d: usize) -> bool {
        let Some(b) = self.linked(a, d) else {
            return false;
        };
        self.bits[a] &= !(1 << d);
        self.bits[b] &= !(1 << (d ^ 1));
        true
    }

    /// Links a to its lattice neighbour in direction d if both are occupied; true if added.
    pub fn link(&mut self, a: usize, d: usize) -> bool {
        if d >= self.directions || !self.is_occupied(a) || self.linked(a, d).is_some() {
            return false;
        }
        let Some(b) = self
            .lattice_neighbour(a, d)
            .filter(|&b| self.is_occupied(b))
        else {
            return false;
        };
        self.bits[a] |= 1 << d;
        self.bits[b] |= 1 << (d ^ 1);
        true
    }

    /// Removes voxel v and its links; returns the links removed.
    pub fn remove(&mut self, v: usize) -> Vec<Link> {
        let mut gone = Vec::new();
        for d in 0..self.directions {
            if let Some(b) = self.linked(v, d) {
                self.unlink(v, d);
                gone.push(canonical(v, b, d));
            }
        }
        if let Some(l) = self.labels.get_mut(v) {
            *l = 0;
        }
        gone
    }

    /// Removes every link whose segment between the current positions `x(voxel)` crosses
    /// the blade's swept quad; returns the links removed.
    pub fn cut(&mut self, x: impl Fn(usize) -> Vec3, blade: &CutPath) -> Vec<Link> {
        let reach = self.spacing.max_element() * 2.0;
        let (mut lo, mut hi) = (Vec3::splat(Real::INFINITY), Vec3::splat(Real::NEG_INFINITY));
        for p in blade.start.iter().chain(&blade.end) {
            lo = lo.min(*p - Vec3::splat(reach));
            hi = hi.max(*p + Vec3::splat(reach));
        }
        let mut removed = Vec::new();
        for a in 0..self.len() {
            if self.bits[a] == 0 {
                continue;
            }
            let xa = x(a);
            if xa.cmplt(lo).any() || xa.cmpgt(hi).any() {
                continue;
            }
            for d in (1..self.directions).step_by(2) {
                if let Some(b) = self.linked(a, d)
                    && blade.crossing(xa, x(b)).is_some()
                {
                    self.unlink(a, d);
                    removed.push((a as u32, d as u8));
                }
            }
        }
        removed
    }

    /// Removes the occupied voxels whose current position lies within `radius` of
    /// `centre`; returns them and the links removed with them.
    pub fn carve(
        &mut self,
        x: impl Fn(usize) -> Vec3,
        centre: Vec3,
        radius: Real,
    ) -> (Vec<usize>, Vec<Link>) {
        let gone: Vec<usize> = (0..self.len())
            .filter(|&v| self.is_occupied(v) && x(v).distance(centre) <= radius)
            .collect();
        let mut links = Vec::new();
        for &v in &gone {
            links.extend(self.remove(v));
        }
        (gone, links)
    }

    /// Links the unlinked occupied lattice neighbours (a, b, direction d) for which
    /// `touching(a, b, d)` holds; returns the links added.
    pub fn join(&mut self, mut touching: impl FnMut(usize, usize, usize) -> bool) -> Vec<Link> {
        let mut added = Vec::new();
        for a in 0..self.len() {
            if !self.is_occupied(a) {
                continue;
            }
            for d in (1..self.directions).step_by(2) {
                if self.linked(a, d).is_some() {
                    continue;
                }
                let Some(b) = self
                    .lattice_neighbour(a, d)
                    .filter(|&b| self.is_occupied(b))
                else {
                    continue;
                };
                if touching(a, b, d) && self.link(a, d) {
                    added.push((a as u32, d as u8));
                }
            }
        }
        added
    }
}

/// The link between a and b (b = a's neighbour in direction d), named from its odd end.
fn canonical(a: usize, b: usize, d: usize) -> Link {
    if d & 1 == 1 {
        (a as u32, d as u8)
    } else {
        (b as u32, (d ^ 1) as u8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane_blade(x: Real, lo: Real, hi: Real) -> CutPath {
        CutPath {
            start: [Vec3::new(x, lo, lo), Vec3::new(x, hi, lo)],
            end: [Vec3::new(x, lo, hi), Vec3::new(x, hi, hi)],
        }
    }

    #[test]
    fn directions_pair_up_and_counts_are_exact() {
        for d in 0..26 {
            let (a, b) = (OFFSETS[d], OFFSETS[d ^ 1]);
            assert_eq!([a[0] + b[0], a[1] + b[1], a[2] + b[2]], [0, 0, 0]);
        }
        let g = VoxelGrid::filled([4, 4, 4], 1.0);
        // Axis links 3·3·16, face diagonals 3 planes' worth, body diagonals 27·4.
        assert_eq!(VoxelLinks::new(&g, 6).link_count(), 144);
        assert_eq!(VoxelLinks::new(&g, 18).link_count(), 144 + 6 * 9 * 4);
        assert_eq!(VoxelLinks::new(&g, 26).link_count(), 144 + 216 + 27 * 4);
    }

    #[test]
    fn a_plane_cut_removes_the_links_across_it_and_join_restores_them() {
        let g = VoxelGrid::filled([6, 6, 6], 1.0);
        // Column 2 to 3: 36 axis links, 4·30 face diagonals, 4·25 body diagonals.
        for (dirs, across) in [(6, 36), (18, 156), (26, 256)] {
            let mut l = VoxelLinks::new(&g, dirs);
            let before = l.link_count();
            let c = |v: usize| l.centre_of(v);
            let x: Vec<Vec3> = (0..l.len()).map(c).collect();
            let cut = l.cut(|v| x[v], &plane_blade(2.5, -1.0, 7.0));
            // Counted directly: every link from column 2 to column 3.
            let expect = g
                .labels
                .iter()
                .enumerate()
                .flat_map(|(a, _)| (1..dirs).step_by(2).map(move |d| (a, d)))
                .filter(|&(a, d)| {
                    let i = (a % 6) as i32;
                    let j = i + OFFSETS[d][0] as i32;
                    VoxelLinks::new(&g, dirs).linked(a, d).is_some() && i.min(j) == 2 && i != j
                })
                .count();
            assert_eq!(cut.len(), expect, "{dirs}");
            assert_eq!(cut.len(), across, "{dirs}");
            assert_eq!(l.link_count(), before - cut.len());
            assert_eq!(l.join(|_, _, _| true).len(), cut.len());
            assert_eq!(l.link_count(), before);
        }
    }

    #[test]
    fn carving_a_corner_removes_its_voxels_and_their_links() {
        let g = VoxelGrid::filled([6, 6, 6], 1.0);
        let mut l = VoxelLinks::new(&g, 6);
        let x: Vec<Vec3> = (0..l.len()).map(|v| l.centre_of(v)).collect();
        let (gone, links) = l.carve(|v| x[v], Vec3::ZERO, 1.1);
        assert_eq!(gone.len(), 4);
        assert_eq!(links.len(), 12);
        assert_eq!(l.link_count(), 540 - 12);
    }
}
