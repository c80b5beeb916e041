//! A bounding-volume hierarchy of axis-aligned boxes over the surface triangles.
//!
//! Built once from the topology (median split on triangle centroids) and refitted every step:
//! the surface moves but keeps its triangles, so only the boxes change. A refit is one pass
//! over the nodes in reverse order, because children are always stored after their parent.

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
}

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
        };
        if !order.is_empty() {
            let len = order.len();
            bvh.split(&mut order, 0, len, &centroid);
        }
        bvh.order = order;
        bvh.refit(positions, triangles);
        bvh
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
        self.tri_boxes.extend(triangles.iter().map(|tri| {
            tri.iter()
                .filter_map(|&v| positions.get(v as usize))
                .fold(Aabb::EMPTY, |b, &p| b.union(Aabb { min: p, max: p }))
        }));
        let tri_box = |t: u32| {
            self.tri_boxes
                .get(t as usize)
                .copied()
                .unwrap_or(Aabb::EMPTY)
        };
        for id in (0..self.nodes.len()).rev() {
            let b = match self.nodes[id] {
                Node::Leaf { start, end } => self.order[start as usize..end as usize]
                    .iter()
                    .fold(Aabb::EMPTY, |b, &t| b.union(tri_box(t))),
                Node::Inner { left, right } => {
                    self.boxes[left as usize].union(self.boxes[right as usize])
                }
            };
            self.boxes[id] = b;
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

    #[test]
    fn empty_and_bad_input_do_not_panic() {
        let bvh = Bvh::build(&[], &[]);
        assert!(bvh.query_sphere(Vec3::ZERO, 1.0).is_empty());
        let bvh = Bvh::build(&[Vec3::ZERO], &[[0, 1, 2]]);
        assert!(bvh.query_sphere(Vec3::ZERO, 1.0).is_empty());
    }
}
