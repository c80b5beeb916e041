//! The ChainMail lattice: one element per occupied voxel, linked to its six face
//! neighbours, with the two operations of Gibson's 3D ChainMail: propagation of imposed
//! moves as a wavefront and elastic relaxation toward the rest shape.
//!
//! A link from element a to its neighbour b one lattice step h along axis k holds when
//! d = x_b − x_a satisfies lo ≤ ±d_k ≤ hi (compression, stretch) and |d_j| ≤ s for the two
//! other axes (shear). The limits come from the two voxels' material classes, each voxel
//! bringing half of the link's free range (enhanced ChainMail, Schill et al. 1998):
//! lo = h (c_a + c_b)/2, hi = h (t_a + t_b)/2, s = h (s_a + s_b)/2, from per-class
//! compression c < 1, stretch t > 1 and shear s fractions.
//!
//! Propagation: moved elements (sponsors) are pinned and queued; a popped element checks
//! its links and moves each unpinned neighbour whose link is violated by the least amount
//! that satisfies it (a clamp into the box the link allows), queueing it. An element is
//! only ever visited because a neighbour moved, and only moved if its link was violated,
//! so the work is proportional to the disturbed region, not to the lattice. The queue
//! empties with every link satisfied unless two pinned elements conflict; a cap on the
//! pops guards against such conflicts looping. Each coordinate obeys difference
//! constraints only, so a one-sided push converges monotonically.
//!
//! Relaxation: each unpinned displaced element moves a fraction ω of the way toward the
//! mean of the positions its linked neighbours imply at rest offsets (a Gauss-Seidel step
//! on Σ|x_b − x_a − (r_b − r_a)|²), activating neighbours as it moves. Elements back at
//! rest drop out of the active list, so an undisturbed object costs nothing.

use crate::math::{Real, Vec3};
use crate::voxel::topology::Link;
use crate::voxel::{VoxelGrid, VoxelLinks};

/// Per-voxel link limits, as fractions of the lattice spacing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Shortest link length / rest length (< 1).
    pub compression: Real,
    /// Longest link length / rest length (> 1).
    pub stretch: Real,
    /// Largest sideways offset / rest length (≥ 0).
    pub shear: Real,
}

/// What a propagation did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Propagation {
    /// Elements moved by the wavefront (sponsors not counted).
    pub moved: usize,
    /// Link checks made.
    pub checks: usize,
    /// False if the pop cap stopped it (conflicting pinned elements).
    pub converged: bool,
}

/// Direction d: axis d / 2, sign − for even d, + for odd d.
const DIRS: usize = 6;

#[derive(Clone, Debug)]
pub struct Lattice {
    pub dims: [usize; 3],
    pub spacing: Vec3,
    /// Elements (voxel labels: material class, 0 for none) and their face links, shared
    /// with `linked-volumes` (`voxel::topology`).
    pub topology: VoxelLinks,
    pub rest: Vec<Vec3>,
    pub x: Vec<Vec3>,
    pub pinned: Vec<bool>,
    /// Per class pair (a·n + b) and axis: (lo, hi, shear) in m.
    table: Vec<[[Real; 3]; 3]>,
    classes: usize,
    strides: [isize; DIRS],
    queue: Vec<u32>,
    queued: Vec<bool>,
    moved_flag: Vec<bool>,
    moved: Vec<u32>,
    active: Vec<u32>,
    is_active: Vec<bool>,
}

impl Lattice {
    /// A lattice over the occupied voxels of `grid`; `limits[c]` for voxels of label c
    /// (label 0 unused; labels beyond the table use the last entry).
    pub fn new(grid: &VoxelGrid, limits: &[Limits]) -> Self {
        let [nx, ny, _] = grid.dims;
        let n = grid.len();
        let rest: Vec<Vec3> = (0..n).map(|i| grid.centre_of(i)).collect();
        let (sx, sy) = (nx as isize, (nx * ny) as isize);
        let mut lattice = Self {
            dims: grid.dims,
            spacing: grid.spacing,
            topology: VoxelLinks::new(grid, DIRS),
            x: rest.clone(),
            rest,
            pinned: vec![false; n],
            table: Vec::new(),
            classes: 0,
            strides: [-1, 1, -sx, sx, -sy, sy],
            queue: Vec::new(),
            queued: vec![false; n],
            moved_flag: vec![false; n],
            moved: Vec::new(),
            active: Vec::new(),
            is_active: vec![false; n],
        };
        lattice.set_limits(limits);
        lattice
    }

    /// Replaces the per-class limits (`limits[c]` for label c; index 0 is ignored).
    pub fn set_limits(&mut self, limits: &[Limits]) {
        let max_label = self.topology.labels.iter().copied().max().unwrap_or(0) as usize;
        let n = max_label + 1;
        let get = |c: usize| {
            limits.get(c).or(limits.last()).copied().unwrap_or(Limits {
                compression: 0.9,
                stretch: 1.1,
                shear: 0.1,
            })
        };
        let h = [self.spacing.x, self.spacing.y, self.spacing.z];
        self.table = Vec::with_capacity(n * n);
        for a in 0..n {
            for b in 0..n {
                let (la, lb) = (get(a), get(b));
                self.table.push(h.map(|h| {
                    [
                        h * 0.5 * (la.compression + lb.compression),
                        h * 0.5 * (la.stretch + lb.stretch),
                        h * 0.5 * (la.shear + lb.shear),
                    ]
                }));
            }
        }
        self.classes = n;
    }

    pub fn len(&self) -> usize {
        self.x.len()
    }

    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Number of links (each counted once).
    pub fn link_count(&self) -> usize {
        self.topology.link_count()
    }

    /// The neighbour of v in direction d, if linked.
    #[inline]
    pub fn neighbour(&self, v: usize, d: usize) -> Option<usize> {
        (self.topology.bits[v] & (1 << d) != 0).then(|| (v as isize + self.strides[d]) as usize)
    }

    /// The (lo, hi, shear) of the link from a in direction d.
    #[inline]
    fn limits_of(&self, a: usize, b: usize, axis: usize) -> [Real; 3] {
        let class = &self.topology.labels;
        let (ca, cb) = (class[a] as usize, class[b] as usize);
        self.table[ca.min(self.classes - 1) * self.classes + cb.min(self.classes - 1)][axis]
    }

    /// Where x_b must be clamped to satisfy the link from a (position `xa`) in direction d.
    #[inline]
    fn clamp_into(&self, a: usize, b: usize, d: usize, xa: Vec3, xb: Vec3) -> Vec3 {
        let axis = d >> 1;
        let [lo, hi, s] = self.limits_of(a, b, axis);
        let mut p = xb.to_array();
        let c = xa.to_array();
        for (j, pj) in p.iter_mut().enumerate() {
            let (min, max) = if j != axis {
                (c[j] - s, c[j] + s)
            } else if d & 1 == 1 {
                (c[j] + lo, c[j] + hi)
            } else {
                (c[j] - hi, c[j] - lo)
            };
            *pj = pj.clamp(min, max);
        }
        Vec3::from_array(p)
    }

    /// True if the link from a in direction d (to b) holds, within `tol` (m).
    pub fn link_holds(&self, a: usize, d: usize, tol: Real) -> bool {
        let Some(b) = self.neighbour(a, d) else {
            return true;
        };
        let c = self.clamp_into(a, b, d, self.x[a], self.x[b]);
        c.distance(self.x[b]) <= tol
    }

    /// Every link that does not hold, as (element, direction).
    pub fn violated_links(&self, tol: Real) -> Vec<(usize, usize)> {
        (0..self.len())
            .flat_map(|a| (0..DIRS).map(move |d| (a, d)))
            .filter(|&(a, d)| !self.link_holds(a, d, tol))
            .collect()
    }

    /// Moves the sponsors to their positions, pins them, and propagates. Sponsors stay
    /// pinned (with any elements pinned before) until `unpin_all`.
    pub fn move_elements(&mut self, moves: &[(u32, Vec3)]) -> Propagation {
        self.queue.clear();
        for &(v, p) in moves {
            let v = v as usize;
            if !self.topology.is_occupied(v) {
                continue;
            }
            self.x[v] = p;
            self.pinned[v] = true;
            self.activate(v);
            if !self.queued[v] {
                self.queued[v] = true;
                self.queue.push(v as u32);
            }
        }
        self.propagate()
    }

    /// Propagates from every displaced element: restores the limits after relaxation,
    /// which moves elements without looking at them.
    pub fn enforce(&mut self) -> Propagation {
        self.queue.clear();
        for k in 0..self.active.len() {
            let v = self.active[k] as usize;
            if !self.queued[v] {
                self.queued[v] = true;
                self.queue.push(v as u32);
            }
        }
        self.propagate()
    }

    fn activate(&mut self, v: usize) {
        if !self.is_active[v] {
            self.is_active[v] = true;
            self.active.push(v as u32);
        }
    }

    fn propagate(&mut self) -> Propagation {
        let cap = 64 * self.len().max(64);
        let mut head = 0;
        let mut checks = 0;
        let mut pops = 0;
        while head < self.queue.len() && pops < cap {
            let a = self.queue[head] as usize;
            head += 1;
            pops += 1;
            self.queued[a] = false;
            let xa = self.x[a];
            let bits = self.topology.bits[a];
            for d in 0..DIRS {
                if bits & (1 << d) == 0 {
                    continue;
                }
                let b = (a as isize + self.strides[d]) as usize;
                checks += 1;
                if self.pinned[b] {
                    continue;
                }
                let xb = self.x[b];
                let c = self.clamp_into(a, b, d, xa, xb);
                if c != xb {
                    self.x[b] = c;
                    if !self.moved_flag[b] {
                        self.moved_flag[b] = true;
                        self.moved.push(b as u32);
                    }
                    if !self.queued[b] {
                        self.queued[b] = true;
                        self.queue.push(b as u32);
                    }
                }
            }
            // Keep the queue from growing without bound on long waves.
            if head > 4096 && head * 2 > self.queue.len() {
                self.queue.drain(..head);
                head = 0;
            }
        }
        let converged = head >= self.queue.len();
        for &v in &self.queue[head.min(self.queue.len())..] {
            self.queued[v as usize] = false;
        }
        self.queue.clear();
        let moved = self.moved.len();
        for k in 0..self.moved.len() {
            let v = self.moved[k] as usize;
            self.moved_flag[v] = false;
            self.activate(v);
        }
        self.moved.clear();
        Propagation {
            moved,
            checks,
            converged,
        }
    }

    /// Unpins the given elements (cheaper than `unpin_all` on a large lattice).
    pub fn unpin(&mut self, elements: &[u32]) {
        for &v in elements {
            if let Some(p) = self.pinned.get_mut(v as usize) {
                *p = false;
            }
        }
    }

    pub fn unpin_all(&mut self) {
        self.pinned.fill(false);
    }

    /// Elements moved from rest and not yet relaxed back.
    pub fn active(&self) -> &[u32] {
        &self.active
    }

    /// `iterations` relaxation sweeps over the displaced elements with rate ω in (0, 1];
    /// returns the largest move of the last sweep (m).
    pub fn relax(&mut self, iterations: usize, omega: Real) -> Real {
        // Moves below `still` are not made; displacements below `snap` count as rest (a
        // geometric decay would otherwise keep far-away elements active for ever).
        let h = self.spacing.min_element();
        let (still, snap) = (1e-12 * h, 1e-7 * h);
        let mut largest = 0.0;
        for _ in 0..iterations {
            largest = 0.0;
            let mut k = 0;
            while k < self.active.len() {
                let a = self.active[k] as usize;
                k += 1;
                if self.pinned[a] {
                    continue;
                }
                let mut sum = Vec3::ZERO;
                let mut count = 0;
                for d in 0..DIRS {
                    if let Some(b) = self.neighbour(a, d) {
                        sum += self.x[b] - self.rest[b];
                        count += 1;
                    }
                }
                let u = self.x[a] - self.rest[a];
                // Unlinked elements (carved free) stay where they are.
                if count == 0 {
                    continue;
                }
                let step = omega * (sum / count as Real - u);
                let len = step.length();
                if len > still {
                    self.x[a] += step;
                    largest = Real::max(largest, len);
                    for d in 0..DIRS {
                        if let Some(b) = self.neighbour(a, d) {
                            self.activate(b);
                        }
                    }
                }
            }
            // Drop elements at rest whose neighbours are at rest too.
            let mut k = 0;
            while k < self.active.len() {
                let a = self.active[k] as usize;
                let at_rest = |v: usize| (self.x[v] - self.rest[v]).length() <= snap;
                let quiet =
                    at_rest(a) && (0..DIRS).all(|d| self.neighbour(a, d).is_none_or(at_rest));
                if quiet {
                    self.x[a] = self.rest[a];
                    self.is_active[a] = false;
                    self.active.swap_remove(k);
                } else {
                    k += 1;
                }
            }
        }
        largest
    }

    /// Returns every element to rest, keeping pins.
    pub fn reset(&mut self) {
        for &a in &self.active {
            self.x[a as usize] = self.rest[a as usize];
            self.is_active[a as usize] = false;
        }
        self.active.clear();
    }

    /// True if element v exists (not carved away, not an empty voxel).
    pub fn exists(&self, v: usize) -> bool {
        self.topology.is_occupied(v)
    }

    /// Links elements that are lattice neighbours, unlinked, and whose current offset
    /// satisfies the link's limits to `tol` m (they touch as at rest); returns the links
    /// added.
    pub fn join(&mut self, tol: Real) -> Vec<Link> {
        // The limits need the labels while the links change: edit a copy (join is rare).
        let mut topology = self.topology.clone();
        let added = topology.join(|a, b, d| {
            self.clamp_into(a, b, d, self.x[a], self.x[b])
                .distance(self.x[b])
                <= tol
        });
        self.topology = topology;
        added
    }
}
