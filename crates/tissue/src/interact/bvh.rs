//! A bounding-volume hierarchy of axis-aligned boxes over the surface triangles.
//!
//! Built once from the topology (median split on triangle centroids) and refitted every step:
//! the surface moves but keeps its triangles, so only the boxes change. A refit is one pass
//! over the nodes in reverse order, because children are always stored after their parent.
//! A model that moves only part of its surface between two refits (`hybrid`: the region
//! and the rest's vertices near an instrument) names the vertices that moved, and
//! `refit_moved` recomputes only their triangles' boxes, their leaves and those leaves'
//! ancestors: the same boxes, bit for bit, as a whole refit.

use crate::math::Vec3;

/// Triangles per leaf: small leaves keep queries tight; the tree stays shallow anyway.
const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug, PartialEq)]
struct Aabb {
    min: Vec3,
    max: Vec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f64::INFINITY),
        max: Vec3::splat(f64::NEG_INFINITY),
    };

    fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    fn overlaps(&self, o: &Aabb) -> bool {
        self.min.cmple(o.max).all() && o.min.cmple(self.max).all()
    }
}

#[derive(Clone, Copy, Debug)]
enum Node {
    /// Triangles `order[start..end]`.
    Leaf { start: u32, end: u32 },
    /// Children node indices, both greater than this node's index.
    Inner { left: u32, right: u32 },
}

/// The tree; triangle ids refer to the triangle list it was built from.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    boxes: Vec<Aabb>,
    order: Vec<u32>,
    /// The box of each triangle, by triangle id.
    tri_boxes: Vec<Aabb>,
    triangle_count: usize,
    /// Parent of each node (`NO_NODE` for the root).
    parent: Vec<u32>,
    /// Leaf holding each triangle (`NO_NODE` for a triangle left out).
    leaf_of: Vec<u32>,
    /// The triangles at each vertex (compressed rows: `vertex_start[v]..vertex_start[v + 1]`
    /// in `vertex_tris`), for `refit_moved`.
    vertex_start: Vec<u32>,
    vertex_tris: Vec<u32>,
    /// `refit_moved`'s marks: a triangle or node whose mark equals `stamp` is done.
    tri_mark: Vec<u32>,
    node_mark: Vec<u32>,
    stamp: u32,
    /// `refit_moved`'s nodes to recompute (reused).
    dirty: Vec<u32>,
}

const NO_NODE: u32 = u32::MAX;

impl Bvh {
    /// Builds the tree over `triangles` at `positions`. Triangles naming a missing vertex
    /// are left out (the model validated its surface; this keeps bad input from panicking).
    pub fn build(positions: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let n = positions.len();
        let mut order: Vec<u32> = (0..triangles.len() as u32)
            .filter(|&t| triangles[t as usize].iter().all(|&v| (v as usize) < n))
            .collect();
        let centroid = |t: u32| -> Vec3 {
            let [a, b, c] = triangles[t as usize];
            (positions[a as usize] + positions[b as usize] + positions[c as usize]) / 3.0
        };
        let mut bvh = Bvh {
            nodes: Vec::new(),
            boxes: Vec::new(),
            order: Vec::new(),
            tri_boxes: Vec::new(),
            triangle_count: triangles.len(),
            ..Default::default()
        };
        if !order.is_empty() {
            let len = order.len();
            bvh.split(&mut order, 0, len, &centroid);
        }
        bvh.order = order;
        bvh.link(n, triangles);
        bvh.refit(positions, triangles);
        bvh
    }

    /// The parents, each triangle's leaf and each vertex's triangles, for `refit_moved`.
    fn link(&mut self, vertices: usize, triangles: &[[u32; 3]]) {
        self.parent = vec![NO_NODE; self.nodes.len()];
        self.leaf_of = vec![NO_NODE; triangles.len()];
        for (id, node) in self.nodes.iter().enumerate() {
            match *node {
                Node::Inner { left, right } => {
                    self.parent[left as usize] = id as u32;
                    self.parent[right as usize] = id as u32;
                }
                Node::Leaf { start, end } => {
                    for &t in &self.order[start as usize..end as usize] {
                        self.leaf_of[t as usize] = id as u32;
                    }
                }
            }
        }
        // Only the triangles in the tree (every vertex of theirs exists).
        self.vertex_start = vec![0; vertices + 1];
        for &t in &self.order {
            for &v in &triangles[t as usize] {
                self.vertex_start[v as usize + 1] += 1;
            }
        }
        for v in 0..vertices {
            self.vertex_start[v + 1] += self.vertex_start[v];
        }
        let mut fill = self.vertex_start.clone();
        self.vertex_tris = vec![0; self.vertex_start[vertices] as usize];
        for &t in &self.order {
            for &v in &triangles[t as usize] {
                self.vertex_tris[fill[v as usize] as usize] = t;
                fill[v as usize] += 1;
            }
        }
        self.tri_mark = vec![0; triangles.len()];
        self.node_mark = vec![0; self.nodes.len()];
        self.stamp = 0;
    }

    fn split(&mut self, order: &mut [u32], start: usize, end: usize, c: &dyn Fn(u32) -> Vec3) {
        let id = self.nodes.len();
        self.nodes.push(Node::Leaf {
            start: start as u32,
            end: end as u32,
        });
        self.boxes.push(Aabb::EMPTY);
        if end - start <= LEAF_SIZE {
            return;
        }
        let (lo, hi) = order[start..end].iter().map(|&t| c(t)).fold(
            (Vec3::splat(f64::INFINITY), Vec3::splat(f64::NEG_INFINITY)),
            |(l, h), p| (l.min(p), h.max(p)),
        );
        let extent = hi - lo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        let mid = (start + end) / 2;
        order[start..end]
            .select_nth_unstable_by(mid - start, |&a, &b| c(a)[axis].total_cmp(&c(b)[axis]));
        let left = self.nodes.len();
        self.split(order, start, mid, c);
        let right = self.nodes.len();
        self.split(order, mid, end, c);
        self.nodes[id] = Node::Inner {
            left: left as u32,
            right: right as u32,
        };
    }

    /// Number of triangles the tree was built for (rebuild when the surface's count differs).
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// Recomputes every box from the current positions; the topology must be the one built.
    pub fn refit(&mut self, positions: &[Vec3], triangles: &[[u32; 3]]) {
        self.tri_boxes.clear();
        self.tri_boxes
            .extend(triangles.iter().map(|tri| triangle_box(positions, tri)));
        for id in (0..self.nodes.len()).rev() {
            self.boxes[id] = self.node_box(id);
        }
    }

    /// Recomputes the boxes of the triangles at the `moved` vertices, of their leaves and
    /// of those leaves' ancestors: when every other vertex is where the last refit (or
    /// build) had it, the boxes equal a whole `refit`'s bit for bit (the same folds in
    /// the same order). The topology must be the one built; vertices out of range and
    /// repeats are ignored. Worth it when few vertices moved; it falls back to `refit`
    /// when as many are named (repeats counted) as there are vertices.
    pub fn refit_moved(
        &mut self,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        moved: impl IntoIterator<Item = u32> + Clone,
    ) {
        let vertices = self.vertex_start.len().saturating_sub(1);
        let named = moved.clone().into_iter().count();
        if named >= vertices
            || self.tri_boxes.len() != triangles.len()
            || self.leaf_of.len() != triangles.len()
        {
            self.refit(positions, triangles);
            return;
        }
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            // The marks wrapped: clear them, so that no old mark equals a new stamp.
            self.tri_mark.iter_mut().for_each(|m| *m = 0);
            self.node_mark.iter_mut().for_each(|m| *m = 0);
            self.stamp = 1;
        }
        let stamp = self.stamp;
        let mut dirty = std::mem::take(&mut self.dirty);
        dirty.clear();
        for v in moved {
            let v = v as usize;
            if v >= vertices {
                continue;
            }
            let (a, b) = (
                self.vertex_start[v] as usize,
                self.vertex_start[v + 1] as usize,
            );
            for &t in &self.vertex_tris[a..b] {
                let t = t as usize;
                if self.tri_mark[t] == stamp {
                    continue;
                }
                self.tri_mark[t] = stamp;
                self.tri_boxes[t] = triangle_box(positions, &triangles[t]);
                // The leaf and its ancestors, up to the first one already marked.
                let mut id = self.leaf_of[t];
                while id != NO_NODE && self.node_mark[id as usize] != stamp {
                    self.node_mark[id as usize] = stamp;
                    dirty.push(id);
                    id = self.parent[id as usize];
                }
            }
        }
        // Children are stored after their parent: descending ids recompute them first.
        dirty.sort_unstable_by(|a, b| b.cmp(a));
        for &id in &dirty {
            self.boxes[id as usize] = self.node_box(id as usize);
        }
        self.dirty = dirty;
    }

    /// A node's box from its triangles' (a leaf) or its children's boxes.
    fn node_box(&self, id: usize) -> Aabb {
        match self.nodes[id] {
            Node::Leaf { start, end } => {
                self.order[start as usize..end as usize]
                    .iter()
                    .fold(Aabb::EMPTY, |b, &t| {
                        b.union(
                            self.tri_boxes
                                .get(t as usize)
                                .copied()
                                .unwrap_or(Aabb::EMPTY),
                        )
                    })
            }
            Node::Inner { left, right } => {
                self.boxes[left as usize].union(self.boxes[right as usize])
            }
        }
    }

    /// Triangles whose box overlaps the box of the ball (center, radius), ascending.
    pub fn query_sphere(&self, center: Vec3, radius: f64) -> Vec<u32> {
        let r = Vec3::splat(radius.max(0.0));
        let q = Aabb {
            min: center - r,
            max: center + r,
        };
        let mut out = Vec::new();
        let mut stack = Vec::new();
        if !self.nodes.is_empty() {
            stack.push(0usize);
        }
        while let Some(id) = stack.pop() {
            if !self.boxes[id].overlaps(&q) {
                continue;
            }
            match self.nodes[id] {
                Node::Leaf { start, end } => out.extend(
                    self.order[start as usize..end as usize]
                        .iter()
                        .copied()
                        .filter(|&t| {
                            self.tri_boxes
                                .get(t as usize)
                                .is_some_and(|b| b.overlaps(&q))
                        }),
                ),
                Node::Inner { left, right } => {
                    stack.push(left as usize);
                    stack.push(right as usize);
                }
            }
        }
        out.sort_unstable();
        out
    }
}

/// The box of a triangle's existing vertices.
fn triangle_box(positions: &[Vec3], tri: &[u32; 3]) -> Aabb {
    tri.iter()
        .filter_map(|&v| positions.get(v as usize))
        .fold(Aabb::EMPTY, |b, &p| b.union(Aabb { min: p, max: p }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift), so the test needs no dependency.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        fn vec(&mut self) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next())
        }
    }

    fn brute(p: &[Vec3], tris: &[[u32; 3]], c: Vec3, r: f64) -> Vec<u32> {
        (0..tris.len() as u32)
            .filter(|&t| {
                let v = tris[t as usize].map(|i| p[i as usize]);
                let lo = v[0].min(v[1]).min(v[2]);
                let hi = v[0].max(v[1]).max(v[2]);
                (0..3).all(|k| lo[k] <= c[k] + r && c[k] - r <= hi[k])
            })
            .collect()
    }

    #[test]
    fn query_equals_brute_force_before_and_after_refit() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        let mut p: Vec<Vec3> = (0..300).map(|_| rng.vec()).collect();
        let tris: Vec<[u32; 3]> = (0..200)
            .map(|_| [0, 0, 0].map(|_: u32| (rng.next() * 300.0) as u32 % 300))
            .collect();
        let mut bvh = Bvh::build(&p, &tris);
        assert_eq!(bvh.triangle_count(), 200);
        let mut hits = 0;
        for round in 0..2 {
            for _ in 0..200 {
                let (c, r) = (rng.vec() * 1.2 - 0.1, 0.2 * rng.next());
                let got = bvh.query_sphere(c, r);
                assert_eq!(got, brute(&p, &tris, c, r), "round {round}");
                hits += got.len();
            }
            // Move every vertex and refit: the answers must follow.
            for v in &mut p {
                *v += 0.3 * (rng.vec() - 0.5);
            }
            bvh.refit(&p, &tris);
        }
        assert!(hits > 100, "the spheres should hit something: {hits}");
    }

    /// A refit of the moved vertices only gives the boxes of a whole refit, bit for bit,
    /// whichever part moved (a few vertices, many, with repeats and bad numbers), and the
    /// queries follow.
    #[test]
    fn refit_of_the_moved_vertices_equals_a_whole_refit() {
        let mut rng = Rng(0x2545_F491_4F6C_DD1D);
        let n = 400;
        let mut p: Vec<Vec3> = (0..n).map(|_| rng.vec()).collect();
        let tris: Vec<[u32; 3]> = (0..600)
            .map(|_| [0, 0, 0].map(|_: u32| (rng.next() * n as f64) as u32 % n as u32))
            .collect();
        let mut partial = Bvh::build(&p, &tris);
        // The same tree, refitted whole every round.
        let mut whole = partial.clone();
        for round in 0..40 {
            // From one vertex to most of them (the last rounds fall back to a whole refit).
            let count = 1 + (round * round) % (n / 2 + 60);
            let mut moved: Vec<u32> = (0..count)
                .map(|_| (rng.next() * n as f64) as u32 % n as u32)
                .collect();
            for &v in &moved {
                p[v as usize] += 0.2 * (rng.vec() - 0.5);
            }
            moved.extend_from_slice(&moved.clone()[..count / 3]);
            moved.push(u32::MAX);
            partial.refit_moved(&p, &tris, moved.iter().copied());
            whole.refit(&p, &tris);
            assert_eq!(partial.tri_boxes, whole.tri_boxes, "round {round}");
            assert_eq!(partial.boxes, whole.boxes, "round {round}");
            for _ in 0..20 {
                let (c, r) = (rng.vec() * 1.2 - 0.1, 0.2 * rng.next());
                assert_eq!(partial.query_sphere(c, r), brute(&p, &tris, c, r));
            }
        }
        // Nothing named: nothing changes.
        let before = partial.boxes.clone();
        partial.refit_moved(&p, &tris, std::iter::empty());
        assert_eq!(partial.boxes, before);
    }

    #[test]
    fn empty_and_bad_input_do_not_panic() {
        let bvh = Bvh::build(&[], &[]);
        assert!(bvh.query_sphere(Vec3::ZERO, 1.0).is_empty());
        let mut bvh = Bvh::build(&[Vec3::ZERO], &[[0, 1, 2]]);
        assert!(bvh.query_sphere(Vec3::ZERO, 1.0).is_empty());
        bvh.refit_moved(&[Vec3::ZERO], &[[0, 1, 2]], [0, 1, 7]);
        assert!(bvh.query_sphere(Vec3::ZERO, 1.0).is_empty());
    }
}
