//! Which pieces a cut separated, found locally.
//!
//! Every tetrahedron carries the label of the piece it belongs to (0: the main body).
//! A piece that a cut splits must contain one of the surviving face-neighbours of the
//! removed tetrahedra (the seeds). From every seed a breadth-first search over face
//! neighbours starts; the searches take turns one tetrahedron at a time and merge when they
//! meet. A search that runs out has found a whole piece; once only one is still running,
//! it is the rest of the split piece and keeps going only until it is larger than every
//! finished one. So the work is about the size of the pieces that broke off (times the
//! number of seeds), plus what it takes the searches to meet around the end of the cut,
//! not the size of the mesh.
//!
//! Of the pieces of one split piece, the largest keeps the label (the main body stays the
//! main body); the others are fragments, reported once, with new labels. Two parts that
//! touch only along an edge or at a vertex are separate pieces (faces join, nothing else).

use std::collections::VecDeque;

/// Labels and search scratch, one entry per tetrahedron.
#[derive(Clone, Debug)]
pub struct Pieces {
    label: Vec<u32>,
    next_label: u32,
    /// Search group of each tetrahedron, valid when `mark_epoch` is the current epoch.
    mark: Vec<u32>,
    mark_epoch: Vec<u32>,
    epoch: u32,
}

#[derive(Default)]
struct Group {
    queue: VecDeque<u32>,
    members: Vec<u32>,
    done: bool,
}

/// The outcome of a split search.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Split {
    /// The fragments, each a list of tetrahedra, in the order found.
    pub fragments: Vec<Vec<usize>>,
    /// Tetrahedra the searches visited.
    pub visited: usize,
}

fn find(parent: &mut [usize], mut g: usize) -> usize {
    while parent[g] != g {
        parent[g] = parent[parent[g]];
        g = parent[g];
    }
    g
}

/// One search step's view of the marks.
struct Search<'a> {
    mark: &'a mut [u32],
    mark_epoch: &'a mut [u32],
    epoch: u32,
    alive: &'a [bool],
    neighbours: &'a [[Option<u32>; 4]],
}

impl Search<'_> {
    /// Expands group g by one tetrahedron; returns how many groups merged into it, or
    /// None when it has run out.
    fn expand(&mut self, g: usize, groups: &mut [Group], parent: &mut [usize]) -> Option<usize> {
        let t = groups[g].queue.pop_front()?;
        let mut root = g;
        let mut merged = 0;
        for m in self.neighbours[t as usize].iter().flatten() {
            let mi = *m as usize;
            if !self.alive.get(mi).copied().unwrap_or(false) {
                continue;
            }
            if self.mark_epoch[mi] != self.epoch {
                self.mark_epoch[mi] = self.epoch;
                self.mark[mi] = root as u32;
                groups[root].queue.push_back(*m);
                groups[root].members.push(*m);
                continue;
            }
            let other = find(parent, self.mark[mi] as usize);
            if other != root {
                // Small into large: each tetrahedron moves O(log seeds) times.
                let (big, small) = if groups[other].members.len() > groups[root].members.len() {
                    (other, root)
                } else {
                    (root, other)
                };
                let moved = std::mem::take(&mut groups[small]);
                groups[big].queue.extend(moved.queue);
                groups[big].members.extend(moved.members);
                parent[small] = big;
                root = big;
                merged += 1;
            }
        }
        Some(merged)
    }
}

impl Pieces {
    /// All `tets` tetrahedra in the main body.
    pub fn new(tets: usize) -> Self {
        Self {
            label: vec![0; tets],
            next_label: 1,
            mark: vec![0; tets],
            mark_epoch: vec![0; tets],
            epoch: 0,
        }
    }

    pub fn label(&self, t: usize) -> Option<u32> {
        self.label.get(t).copied()
    }

    /// Finds the pieces the removal of some tetrahedra separated, from the surviving
    /// face-neighbours `seeds` of the removed ones; labels the fragments.
    pub fn split(
        &mut self,
        seeds: &[usize],
        alive: &[bool],
        neighbours: &[[Option<u32>; 4]],
    ) -> Split {
        let mut seeds: Vec<(u32, usize)> = seeds
            .iter()
            .filter(|&&t| alive.get(t).copied().unwrap_or(false))
            .map(|&t| (self.label[t], t))
            .collect();
        seeds.sort_unstable();
        seeds.dedup();
        let mut out = Split::default();
        for same in seeds.chunk_by(|a, b| a.0 == b.0) {
            let group: Vec<usize> = same.iter().map(|s| s.1).collect();
            self.split_piece(&group, alive, neighbours, &mut out);
        }
        out
    }

    /// The search within one labelled piece.
    fn split_piece(
        &mut self,
        seeds: &[usize],
        alive: &[bool],
        neighbours: &[[Option<u32>; 4]],
        out: &mut Split,
    ) {
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.mark_epoch.iter_mut().for_each(|e| *e = 0);
            self.epoch = 1;
        }
        let epoch = self.epoch;
        let mut groups: Vec<Group> = Vec::with_capacity(seeds.len());
        for &s in seeds {
            self.mark[s] = groups.len() as u32;
            self.mark_epoch[s] = epoch;
            groups.push(Group {
                queue: VecDeque::from([s as u32]),
                members: vec![s as u32],
                done: false,
            });
        }
        let mut parent: Vec<usize> = (0..groups.len()).collect();
        let mut active = groups.len();
        while active > 1 {
            for g in 0..groups.len() {
                if active <= 1 {
                    break;
                }
                if parent[g] != g || groups[g].done {
                    continue;
                }
                let mut search = Search {
                    mark: &mut self.mark,
                    mark_epoch: &mut self.mark_epoch,
                    epoch,
                    alive,
                    neighbours,
                };
                match search.expand(g, &mut groups, &mut parent) {
                    Some(merged) => active -= merged,
                    None => {
                        groups[g].done = true;
                        active -= 1;
                    }
                }
            }
        }
        let largest_done = (0..groups.len())
            .filter(|&g| parent[g] == g && groups[g].done)
            .map(|g| groups[g].members.len())
            .max()
            .unwrap_or(0);
        let running = (0..groups.len()).find(|&g| parent[g] == g && !groups[g].done);
        if let Some(r) = running {
            let mut search = Search {
                mark: &mut self.mark,
                mark_epoch: &mut self.mark_epoch,
                epoch,
                alive,
                neighbours,
            };
            while groups[r].members.len() <= largest_done {
                if search.expand(r, &mut groups, &mut parent).is_none() {
                    groups[r].done = true;
                    break;
                }
            }
        }
        out.visited += groups.iter().map(|g| g.members.len()).sum::<usize>();
        let roots: Vec<usize> = (0..groups.len()).filter(|&g| parent[g] == g).collect();
        // The keeper: the one still running (larger than every finished one), else the
        // largest finished one (the first of equals).
        let keeper = roots
            .iter()
            .copied()
            .find(|&g| !groups[g].done)
            .or_else(|| {
                let best = roots.iter().map(|&g| groups[g].members.len()).max()?;
                roots
                    .iter()
                    .copied()
                    .find(|&g| groups[g].members.len() == best)
            });
        for g in roots {
            if Some(g) == keeper {
                continue;
            }
            let label = self.next_label;
            self.next_label = self.next_label.saturating_add(1);
            let mut piece: Vec<usize> = groups[g].members.iter().map(|&t| t as usize).collect();
            piece.sort_unstable();
            for &t in &piece {
                self.label[t] = label;
            }
            out.fragments.push(piece);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::topology::tet_neighbours;

    /// A chain of `n` tetrahedra, each sharing a face with the next.
    fn chain(n: usize) -> Vec<[u32; 4]> {
        (0..n as u32).map(|i| [i, i + 1, i + 2, i + 3]).collect()
    }

    #[test]
    fn a_chain_cut_twice_gives_each_fragment_once() {
        let tets = chain(30);
        let nb = tet_neighbours(&tets);
        let mut alive = vec![true; 30];
        let mut p = Pieces::new(30);
        // Cut at 20: the 9 tetrahedra beyond break off.
        alive[20] = false;
        let s = p.split(&[19, 21], &alive, &nb);
        assert_eq!(s.fragments, vec![(21..30).collect::<Vec<_>>()]);
        // Each search grows until the short side runs out: 9 + at most 11 on the long one
        // (counting the neighbours found but not yet expanded).
        assert!(s.visited <= 9 + 11, "{}", s.visited);
        // Cut at 5: only the main body splits; the kept fragment is not reported again.
        alive[5] = false;
        let s = p.split(&[4, 6], &alive, &nb);
        assert_eq!(s.fragments, vec![(0..5).collect::<Vec<_>>()]);
        // Cut the kept fragment at 25: its smaller part (26..30) is new, 21..25 keeps its label.
        alive[25] = false;
        let s = p.split(&[24, 26], &alive, &nb);
        assert_eq!(s.fragments, vec![(26..30).collect::<Vec<_>>()]);
        assert_eq!(p.label(21), p.label(24));
        assert_ne!(p.label(21), p.label(26));
        assert_eq!(p.label(10), Some(0));
        // Removing an end tetrahedron splits nothing and searches one.
        alive[29] = false;
        let s = p.split(&[28], &alive, &nb);
        assert!(s.fragments.is_empty());
        assert_eq!(s.visited, 1);
    }

    #[test]
    fn parts_touching_along_an_edge_are_separate_pieces() {
        // Two tetrahedra sharing the edge 0-1 only, joined through a third sharing a face
        // with each; removing the third leaves two pieces.
        let tets = vec![[0, 1, 2, 3], [0, 1, 3, 4], [0, 1, 4, 5]];
        let nb = tet_neighbours(&tets);
        let mut alive = vec![true; 3];
        alive[1] = false;
        let mut p = Pieces::new(3);
        let s = p.split(&[0, 2], &alive, &nb);
        assert_eq!(s.fragments.len(), 1);
        assert_eq!(s.visited, 2);
    }
}
