//! Fill-reducing orderings of a mesh's nodes for the sparse Cholesky factorisation.
//!
//! faer orders by approximate minimum degree (AMD). Nested dissection orders a separator (a
//! set of nodes whose removal splits the mesh in two) after the two halves, recursively, so
//! the elimination of one half never fills into the other and the dense work concentrates in
//! the separators. Which is better depends on the mesh: on regular 3-D grids nested
//! dissection wins (32³ nodes: a factor 1.6× smaller, 4× faster to compute), on the
//! benchmark's beams it depends on the size (20k: 4.0M values against AMD's 3.56M; 80k:
//! 28.0M against 31.8M), on the liver refined for the comparison's reference AMD wins (166k
//! unknowns: 334M values against 516M). `SparseCholesky::with_positions` analyses both and
//! keeps the smaller factor, so this never makes a factorisation worse. Its elimination tree
//! splits evenly (two subtrees of equal work under a top of 1-2%, where AMD's beam tree
//! keeps a third of the work in its top), but its many small supernodes are slower per
//! value in the solve: at 20k, in f32, 2.29 ms against AMD's 1.49 on one thread, and 1.42
//! against 1.27 on two (`tree_solve_study`).
//!
//! Separators are geometric: the part's nodes split at the median of their longest extent
//! (nodes level with the median all on one side, so a structured mesh's layer is never cut
//! through), and the nodes of one side coupled to the other side form the separator (a layer
//! about one element thick). Breadth-first level sets, which need no coordinates, were tried first: on
//! meshes with diagonal couplings their levels are shells around the start, nearly twice a
//! plane's size, and the factor came out larger than AMD's even on grids.

use crate::math::Vec3;

/// Parts at most this large are not split further: their own fill is small, and the
/// factorisation's dense kernels prefer blocks of some size.
const LEAF_NODES: usize = 48;

/// The nodes' elimination order (a permutation of `0..nodes`) by nested dissection of the
/// graph `ptr`/`adj` (`adj[ptr[a]..ptr[a + 1]]` the nodes coupled with `a`, itself allowed)
/// whose node `a` sits at `positions[a]`.
pub fn nested_dissection(ptr: &[usize], adj: &[u32], positions: &[Vec3]) -> Vec<u32> {
    let nodes = ptr.len().saturating_sub(1).min(positions.len());
    let mut order = Vec::with_capacity(nodes);
    // Which part each node is in while a part is split (0: elsewhere, 1 or 2: a half).
    let mut side = vec![0u8; nodes];
    // An explicit stack instead of recursion: a part, or a separator to emit once both of
    // its halves have been ordered.
    let mut stack = vec![Task::Split((0..nodes as u32).collect())];
    while let Some(task) = stack.pop() {
        match task {
            Task::Emit(sep) => order.extend(sep),
            Task::Split(part) if part.len() <= LEAF_NODES => order.extend(part),
            Task::Split(part) => {
                let (a, b, sep) = bisect(ptr, adj, positions, part, &mut side);
                // Ordered a, then b, then the separator: pushed in reverse.
                stack.push(Task::Emit(sep));
                stack.push(Task::Split(b));
                stack.push(Task::Split(a));
            }
        }
    }
    order
}

enum Task {
    Split(Vec<u32>),
    Emit(Vec<u32>),
}

/// Splits `part` at the median of its longest extent into two halves and the separator
/// between them (the nodes of the first half coupled to the second).
fn bisect(
    ptr: &[usize],
    adj: &[u32],
    positions: &[Vec3],
    mut part: Vec<u32>,
    side: &mut [u8],
) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let (mut lo, mut hi) = (Vec3::splat(f64::INFINITY), Vec3::splat(f64::NEG_INFINITY));
    for &v in &part {
        lo = lo.min(positions[v as usize]);
        hi = hi.max(positions[v as usize]);
    }
    let extent = hi - lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let coord = |v: u32| positions[v as usize][axis];
    let half = part.len() / 2;
    part.select_nth_unstable_by(half, |&a, &b| coord(a).total_cmp(&coord(b)));
    // Nodes level with the median go to the second half together: a structured mesh's layer
    // of nodes is then not cut through, and the separator is one layer, not parts of two.
    let median = coord(part[half]);
    // `select_nth` leaves only "not greater" before the median: its equals are moved to
    // just before it.
    let mut cut = half;
    let mut i = 0;
    while i < cut {
        if coord(part[i]) == median {
            cut -= 1;
            part.swap(i, cut);
        } else {
            i += 1;
        }
    }
    if cut == 0 {
        cut = half;
    }
    let b = part.split_off(cut);
    for &v in &part {
        side[v as usize] = 1;
    }
    for &v in &b {
        side[v as usize] = 2;
    }
    let (mut a, mut sep) = (Vec::with_capacity(part.len()), Vec::new());
    for &v in &part {
        let coupled = adj[ptr[v as usize]..ptr[v as usize + 1]]
            .iter()
            .any(|&w| side.get(w as usize) == Some(&2));
        if coupled { sep.push(v) } else { a.push(v) }
    }
    for &v in part.iter().chain(&b) {
        side[v as usize] = 0;
    }
    (a, b, sep)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 7-point graph of an n×n×n grid of nodes, and the nodes' positions.
    fn grid(n: usize) -> (Vec<usize>, Vec<u32>, Vec<Vec3>) {
        let id = |i: usize, j: usize, k: usize| (i + n * (j + n * k)) as u32;
        let (mut ptr, mut adj) = (vec![0], Vec::new());
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    adj.push(id(i, j, k));
                    for (di, dj, dk) in [(1, 0, 0), (0, 1, 0), (0, 0, 1)] {
                        if i + di < n && j + dj < n && k + dk < n {
                            adj.push(id(i + di, j + dj, k + dk));
                        }
                        if i >= di && j >= dj && k >= dk {
                            adj.push(id(i - di, j - dj, k - dk));
                        }
                    }
                    ptr.push(adj.len());
                }
            }
        }
        let positions = (0..n * n * n)
            .map(|v| Vec3::new((v % n) as f64, ((v / n) % n) as f64, (v / (n * n)) as f64))
            .collect();
        (ptr, adj, positions)
    }

    #[test]
    fn the_order_is_a_permutation() {
        let n = 12;
        let (ptr, adj, positions) = grid(n);
        let order = nested_dissection(&ptr, &adj, &positions);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..(n * n * n) as u32).collect::<Vec<_>>());
    }

    #[test]
    fn a_separator_disconnects_the_halves_and_is_a_thin_layer() {
        // Even: the median falls between two layers of nodes; odd: in the middle of one,
        // which goes whole to the second half (a layer cut through gave a separator of parts
        // of two layers, and the 20k beam's factor 28% more values).
        for n in [12, 11] {
            let (ptr, adj, positions) = grid(n);
            let part: Vec<u32> = (0..(n * n * n) as u32).collect();
            let mut side = vec![0u8; part.len()];
            let (a, b, sep) = bisect(&ptr, &adj, &positions, part.clone(), &mut side);
            assert_eq!(a.len() + b.len() + sep.len(), part.len());
            let mut half = vec![0u8; part.len()];
            a.iter().for_each(|&v| half[v as usize] = 1);
            b.iter().for_each(|&v| half[v as usize] = 2);
            for &v in &a {
                let nb = &adj[ptr[v as usize]..ptr[v as usize + 1]];
                assert!(nb.iter().all(|&w| half[w as usize] != 2), "edge {v} across");
            }
            // One layer of n² nodes, all at one x.
            assert_eq!(sep.len(), n * n, "n = {n}");
            let x = positions[sep[0] as usize].x;
            assert!(sep.iter().all(|&v| positions[v as usize].x == x));
            if n % 2 == 0 {
                assert_eq!(a.len() + sep.len(), b.len());
            }
            // The scratch is left clean for the next split.
            assert!(side.iter().all(|&s| s == 0));
        }
    }

    #[test]
    fn disconnected_graphs_are_split_between_their_components() {
        // Two separate chains of 100 nodes.
        let (mut ptr, mut adj) = (vec![0], Vec::new());
        for v in 0..200u32 {
            adj.push(v);
            if v % 100 != 0 {
                adj.push(v - 1);
            }
            if v % 100 != 99 {
                adj.push(v + 1);
            }
            ptr.push(adj.len());
        }
        let positions: Vec<Vec3> = (0..200).map(|v| Vec3::new(v as f64, 0.0, 0.0)).collect();
        let order = nested_dissection(&ptr, &adj, &positions);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..200).collect::<Vec<_>>());
        // The first split falls between the chains: nothing couples them, no separator.
        let mut side = vec![0u8; 200];
        let (a, b, sep) = bisect(&ptr, &adj, &positions, (0..200).collect(), &mut side);
        assert!(sep.is_empty() && a.len() == 100 && b.len() == 100);
    }
}
