//! A uniform grid (spatial hash) of axis-aligned boxes, for "which elements might touch
//! this region" queries whose cost follows the region, not the mesh.
//!
//! Items are numbered `0..n` by the caller (tetrahedra, triangles, ...); each is filed in
//! every cell its box overlaps, and can be moved or taken out one at a time, so a caller
//! whose elements move re-files only the ones that left their boxes. Only occupied cells
//! are stored (a hash map), so the grid's extent is unbounded.
//!
//! Two guards keep bad geometry from making a query or an insertion cost the whole mesh:
//! an item whose box spans more than `MAX_ITEM_CELLS` cells goes to an "oversize" list that
//! every query returns, and a query whose box spans more cells than are occupied walks the
//! occupied cells instead.

use std::collections::HashMap;

use crate::math::{Real, Vec3};

/// Items larger than this many cells are not filed in cells (see the module doc).
const MAX_ITEM_CELLS: i64 = 512;
/// Cell coordinates are clamped to ±this, so that huge (finite) coordinates cannot
/// overflow; everything beyond shares the outermost cells.
const COORD_LIMIT: Real = 1.0e9;

type Cell = [i64; 3];

/// Where an item is filed.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Filed {
    Nowhere,
    Cells(Cell, Cell),
    Oversize,
}

/// The grid; see the module doc.
#[derive(Clone, Debug)]
pub struct SpatialGrid {
    cell: Real,
    cells: HashMap<Cell, Vec<u32>>,
    filed: Vec<Filed>,
    oversize: Vec<u32>,
    /// Query stamp per item (deduplicates items seen in several cells).
    stamp: Vec<u32>,
    epoch: u32,
}

impl SpatialGrid {
    /// An empty grid with cubic cells of side `cell` (a non-positive or non-finite size
    /// becomes 1).
    pub fn new(cell: Real) -> Self {
        let cell = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            1.0
        };
        Self {
            cell,
            cells: HashMap::new(),
            filed: Vec::new(),
            oversize: Vec::new(),
            stamp: Vec::new(),
            epoch: 0,
        }
    }

    pub fn cell_size(&self) -> Real {
        self.cell
    }

    /// Number of occupied cells.
    pub fn occupied_cells(&self) -> usize {
        self.cells.len()
    }

    fn coord(&self, x: Real) -> i64 {
        let c = (x / self.cell).floor();
        // NaN goes to 0 (callers pass finite boxes; this only keeps bad input harmless).
        if c.is_nan() {
            0
        } else {
            c.clamp(-COORD_LIMIT, COORD_LIMIT) as i64
        }
    }

    fn cell_range(&self, lo: Vec3, hi: Vec3) -> (Cell, Cell) {
        let a = [self.coord(lo.x), self.coord(lo.y), self.coord(lo.z)];
        let b = [self.coord(hi.x), self.coord(hi.y), self.coord(hi.z)];
        (a, [b[0].max(a[0]), b[1].max(a[1]), b[2].max(a[2])])
    }

    fn span(a: &Cell, b: &Cell) -> i64 {
        (0..3).fold(1i64, |n, k| n.saturating_mul(b[k] - a[k] + 1))
    }

    /// Files item `id` under the box [lo, hi], replacing where it was filed before.
    pub fn insert(&mut self, id: u32, lo: Vec3, hi: Vec3) {
        self.remove(id);
        let i = id as usize;
        if self.filed.len() <= i {
            self.filed.resize(i + 1, Filed::Nowhere);
            self.stamp.resize(i + 1, 0);
        }
        let (a, b) = self.cell_range(lo, hi);
        if Self::span(&a, &b) > MAX_ITEM_CELLS {
            self.oversize.push(id);
            self.filed[i] = Filed::Oversize;
            return;
        }
        for x in a[0]..=b[0] {
            for y in a[1]..=b[1] {
                for z in a[2]..=b[2] {
                    self.cells.entry([x, y, z]).or_default().push(id);
                }
            }
        }
        self.filed[i] = Filed::Cells(a, b);
    }

    /// Takes item `id` out of the grid (nothing if it is not in).
    pub fn remove(&mut self, id: u32) {
        let Some(f) = self.filed.get_mut(id as usize) else {
            return;
        };
        match std::mem::replace(f, Filed::Nowhere) {
            Filed::Nowhere => {}
            Filed::Oversize => self.oversize.retain(|&o| o != id),
            Filed::Cells(a, b) => {
                for x in a[0]..=b[0] {
                    for y in a[1]..=b[1] {
                        for z in a[2]..=b[2] {
                            let key = [x, y, z];
                            if let Some(list) = self.cells.get_mut(&key) {
                                if let Some(p) = list.iter().position(|&o| o == id) {
                                    list.swap_remove(p);
                                }
                                if list.is_empty() {
                                    self.cells.remove(&key);
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// The items filed in cells that overlap one of `boxes` and that `keep_cell(box index,
    /// cell min, cell max)` accepts (a finer test of the cell against the query shape),
    /// plus the oversize items; each once, appended to `out`.
    pub fn query(
        &mut self,
        boxes: &[(Vec3, Vec3)],
        mut keep_cell: impl FnMut(usize, Vec3, Vec3) -> bool,
        out: &mut Vec<u32>,
    ) {
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.epoch = 1;
        }
        let (epoch, cell) = (self.epoch, self.cell);
        let ranges: Vec<(Cell, Cell)> = boxes
            .iter()
            .map(|&(lo, hi)| self.cell_range(lo, hi))
            .collect();
        let stamp = &mut self.stamp;
        let mut take = |list: &[u32], out: &mut Vec<u32>| {
            for &id in list {
                if let Some(s) = stamp.get_mut(id as usize)
                    && *s != epoch
                {
                    *s = epoch;
                    out.push(id);
                }
            }
        };
        take(&self.oversize, out);
        let bounds = |c: &Cell| {
            let lo = Vec3::new(c[0] as Real, c[1] as Real, c[2] as Real) * cell;
            (lo, lo + Vec3::splat(cell))
        };
        for (k, (a, b)) in ranges.into_iter().enumerate() {
            if Self::span(&a, &b) > self.cells.len() as i64 {
                for (c, list) in &self.cells {
                    let inside = (0..3).all(|j| a[j] <= c[j] && c[j] <= b[j]);
                    let (cl, ch) = bounds(c);
                    if inside && keep_cell(k, cl, ch) {
                        take(list, out);
                    }
                }
                continue;
            }
            for x in a[0]..=b[0] {
                for y in a[1]..=b[1] {
                    for z in a[2]..=b[2] {
                        let c = [x, y, z];
                        if let Some(list) = self.cells.get(&c) {
                            let (cl, ch) = bounds(&c);
                            if keep_cell(k, cl, ch) {
                                take(list, out);
                            }
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ids(g: &mut SpatialGrid, lo: Vec3, hi: Vec3) -> Vec<u32> {
        let mut out = Vec::new();
        g.query(&[(lo, hi)], |_, _, _| true, &mut out);
        out.sort_unstable();
        out
    }

    #[test]
    fn finds_overlapping_boxes_once_and_follows_moves() {
        let mut g = SpatialGrid::new(1.0);
        // A unit box per item along x, spanning two cells each.
        for i in 0..10u32 {
            let lo = Vec3::new(i as Real + 0.5, 0.2, 0.2);
            g.insert(i, lo, lo + Vec3::splat(0.6));
        }
        assert_eq!(
            ids(&mut g, Vec3::new(3.1, 0.0, 0.0), Vec3::new(4.9, 0.9, 0.9)),
            [2, 3, 4]
        );
        // Two boxes over the same cells: each item once.
        let mut out = Vec::new();
        let b = (Vec3::new(3.1, 0.0, 0.0), Vec3::new(4.9, 0.9, 0.9));
        g.query(&[b, b], |_, _, _| true, &mut out);
        assert_eq!(out.len(), 3);
        g.insert(3, Vec3::splat(50.0), Vec3::splat(50.5));
        g.remove(4);
        g.remove(4);
        assert_eq!(ids(&mut g, b.0, b.1), [2]);
        assert_eq!(ids(&mut g, Vec3::splat(49.0), Vec3::splat(51.0)), [3]);
        // The cell filter sees each cell's bounds.
        let mut out = Vec::new();
        g.query(
            &[(Vec3::ZERO, Vec3::new(9.9, 0.9, 0.9))],
            |_, lo, _| lo.x >= 7.0,
            &mut out,
        );
        out.sort_unstable();
        assert_eq!(out, [6, 7, 8, 9]);
    }

    #[test]
    fn oversize_items_and_huge_queries_stay_cheap_and_correct() {
        let mut g = SpatialGrid::new(0.1);
        g.insert(0, Vec3::splat(-1e6), Vec3::splat(1e6));
        g.insert(1, Vec3::splat(0.01), Vec3::splat(0.02));
        g.insert(2, Vec3::splat(f64::MAX), Vec3::splat(f64::MAX));
        assert_eq!(ids(&mut g, Vec3::splat(5.0), Vec3::splat(5.0)), [0]);
        // A query box of 1e30 cells walks the two occupied cells instead.
        assert_eq!(
            ids(&mut g, Vec3::splat(-1e300), Vec3::splat(1e300)),
            [0, 1, 2]
        );
        assert_eq!(g.occupied_cells(), 2);
        g.remove(0);
        assert_eq!(ids(&mut g, Vec3::splat(-1.0), Vec3::splat(1.0)), [1]);
        assert_eq!(SpatialGrid::new(Real::NAN).cell_size(), 1.0);
    }
}
