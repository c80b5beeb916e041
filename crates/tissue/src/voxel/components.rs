//! Face-connected parts of the occupied voxels: a segmentation often holds specks and
//! neighbouring organs, and a model wants one connected body.

use super::VoxelGrid;

/// The parts: `part[v]` is the part of voxel v (`u32::MAX` for empty voxels), `sizes[p]` its
/// voxel count.
#[derive(Clone, Debug, PartialEq)]
pub struct Components {
    pub part: Vec<u32>,
    pub sizes: Vec<usize>,
}

/// Labels the 6-connected parts by breadth-first search.
pub fn components(grid: &VoxelGrid) -> Components {
    let n = grid.len();
    let mut part = vec![u32::MAX; n];
    let mut sizes = Vec::new();
    let mut queue = Vec::new();
    for seed in 0..n {
        if !grid.is_occupied(seed) || part[seed] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        part[seed] = id;
        queue.clear();
        queue.push(seed);
        let mut head = 0;
        while let Some(&v) = queue.get(head) {
            head += 1;
            for w in face_neighbours(grid, v).into_iter().flatten() {
                if grid.is_occupied(w) && part[w] == u32::MAX {
                    part[w] = id;
                    queue.push(w);
                }
            }
        }
        sizes.push(queue.len());
    }
    Components { part, sizes }
}

/// The six face neighbours of voxel v that exist in the grid.
pub(crate) fn face_neighbours(grid: &VoxelGrid, v: usize) -> [Option<usize>; 6] {
    let [i, j, k] = grid.coords(v);
    [
        i.checked_sub(1).and_then(|i| grid.index(i, j, k)),
        grid.index(i + 1, j, k),
        j.checked_sub(1).and_then(|j| grid.index(i, j, k)),
        grid.index(i, j + 1, k),
        k.checked_sub(1).and_then(|k| grid.index(i, j, k)),
        grid.index(i, j, k + 1),
    ]
}

/// Empties every voxel outside the largest part; returns the voxels kept.
pub fn keep_largest(grid: &mut VoxelGrid) -> usize {
    let c = components(grid);
    let Some((best, &size)) = c.sizes.iter().enumerate().max_by_key(|&(_, s)| *s) else {
        return 0;
    };
    retain(grid, &c, best as u32);
    size
}

/// Empties every voxel outside the part holding voxel `seed`; `None` (grid unchanged) if
/// `seed` is empty or outside the grid.
pub fn keep_component_at(grid: &mut VoxelGrid, seed: usize) -> Option<usize> {
    let c = components(grid);
    let p = *c.part.get(seed)?;
    let size = *c.sizes.get(p as usize)?;
    retain(grid, &c, p);
    Some(size)
}

fn retain(grid: &mut VoxelGrid, c: &Components, keep: u32) {
    for (l, &p) in grid.labels.iter_mut().zip(&c.part) {
        if p != keep {
            *l = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    #[test]
    fn parts_are_counted_and_selected() {
        let mut g = VoxelGrid::new([5, 3, 3], Vec3::ONE, Vec3::ZERO);
        // A 2x1x1 bar, a diagonal-only neighbour (a separate part under 6-connectivity),
        // and a 3-voxel L.
        for (i, j, k) in [
            (0, 0, 0),
            (1, 0, 0),
            (2, 1, 1),
            (4, 0, 0),
            (4, 1, 0),
            (4, 2, 0),
        ] {
            let idx = g.index(i, j, k).unwrap();
            g.labels[idx] = 1;
        }
        let c = components(&g);
        assert_eq!(c.sizes, vec![2, 3, 1]);
        let mut a = g.clone();
        assert_eq!(keep_largest(&mut a), 3);
        assert_eq!(a.occupied(), 3);
        let mut b = g.clone();
        assert_eq!(
            keep_component_at(&mut b, g.index(2, 1, 1).unwrap()),
            Some(1)
        );
        assert_eq!(b.occupied(), 1);
        assert_eq!(keep_component_at(&mut b, 1000), None);
    }
}
