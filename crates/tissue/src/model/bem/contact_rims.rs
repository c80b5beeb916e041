//! Contacts whose tractions are discontinuous at the contact rim (`discontinuous_contacts`)
//! inside the Woodbury update, at the default model's cost per static update.
//!
//! A contact's traction acts only on its triangles whose three vertices are all constrained
//! (fixed or in contact); on its rim triangles τ the free side's known traction applies, so
//! its reordered column is −G_c + R_c with R_c = Σ_τ g_{τ,c}, the G share of corner c of τ.
//! A₀⁻¹ of that column change is −W̃_{:,c} − E_c with
//!   W̃_{:,c} = W_{:,c} − Σ_τ q_{τ,c},   q_{τ,c} = A₀⁻¹ g_{τ,c}   (3n × 3),
//! so the update is the default one with W̃ in place of W: capacitance W̃_CC, static update
//! x = u_L + W̃_{:,C} P_C, O(n·|C|). Since Σ over all triangles of c of q_{τ,c} is W_{:,c},
//! also W̃_{:,c} = Σ_{inner τ} q_{τ,c} over its fully constrained triangles: each contact
//! uses whichever list is shorter (fewer pairs to solve).
//!
//! q depends on the surface and A₀ only, not on the contact set, so it is cached per
//! (triangle, corner) pair up to a byte budget (the least recently used pairs go first) and
//! dropped with A₀ (factorisation, bordering, new H and G). A contact change integrates the
//! missing pairs only (in parallel) and solves for all of them in one batch through the kept
//! LU and bordering layers (`BaseInverse`); A₀⁻¹ itself is never formed. Each q is summed
//! into W̃ in the same order whether it was cached or just solved, so a cache hit gives the
//! same bits as a cold computation (as long as the batched solve treats its columns
//! independently, which `tests::rim_cache_hits_equal_cold_computations` checks).

use std::collections::HashMap;
use std::sync::Arc;

use faer::Mat;

use crate::math::Real;

use super::assembly::Geometry;
use super::border::BaseInverse;
use super::quadrature::Rules;
use super::rim_worker::Poll;
use super::system::BemSystem;

/// Default byte budget of the q cache: 256 MiB, about 1700 pairs on a 2194-vertex surface
/// (W there is 346 MB; all 13 152 pairs would take 2.1 GB).
pub const DEFAULT_RIM_CACHE_BYTES: usize = 256 << 20;

/// The current contacts' effective responses and support areas.
pub(super) struct ContactRims {
    /// W̃_{:,C} (3n × 3|C|): column 3k + l is contact k's response to a unit traction
    /// along l acting on its fully constrained triangles only.
    pub wt: Mat<Real>,
    /// Per contact, the area its traction acts on.
    pub area: Vec<Real>,
    /// The contacts are on the continuous rule (W's columns, tributary areas) while the
    /// worker solves the rim pairs they need (`background_rim_solves`).
    pub waiting: bool,
    /// The pairs that were missing then.
    pub missing: Vec<(usize, usize)>,
    /// Per contact: its vertex, and whether its columns are summed from its inner
    /// triangles' q, with the pairs summed. Equal keys give equal columns (for the same
    /// A₀, which drops the contact set when it changes), so the next contact set copies
    /// them instead of summing again.
    keys: Vec<ContactKey>,
}

/// A contact's vertex, whether its W̃ columns are summed from its inner triangles' q, and
/// the (triangle, corner) pairs summed.
type ContactKey = (usize, bool, Vec<(usize, usize)>);

/// (triangle, corner) → q = A₀⁻¹ g (3n × 3), least recently used first out.
#[derive(Debug)]
pub(super) struct RimCache {
    entries: HashMap<(u32, u8), Entry>,
    bytes: usize,
    budget: usize,
    clock: u64,
    /// Pairs integrated and solved (cache misses and warm-ups), since the system was built.
    pub solved: usize,
    /// Pairs taken from the cache.
    pub hits: usize,
    /// Contacts whose W̃ columns were copied from the previous contact set.
    pub reused: usize,
}

#[derive(Debug)]
struct Entry {
    q: Mat<Real>,
    used: u64,
}

impl Default for RimCache {
    fn default() -> Self {
        Self {
            entries: HashMap::new(),
            bytes: 0,
            budget: DEFAULT_RIM_CACHE_BYTES,
            clock: 0,
            solved: 0,
            hits: 0,
            reused: 0,
        }
    }
}

impl RimCache {
    /// Drops every q (A₀ changed); the budget and the counters stay.
    pub fn clear(&mut self) {
        self.entries = HashMap::new();
        self.bytes = 0;
    }

    pub fn bytes(&self) -> usize {
        self.bytes
    }

    pub fn pairs(&self) -> usize {
        self.entries.len()
    }

    pub fn budget(&self) -> usize {
        self.budget
    }

    pub fn set_budget(&mut self, bytes: usize) {
        self.budget = bytes;
        self.evict();
    }

    fn contains(&self, pair: (usize, usize)) -> bool {
        self.entries.contains_key(&key(pair))
    }

    /// Stores the pairs just solved (column block j of `fresh` is `pairs[j]`), marks every
    /// pair of `used` as used now and evicts beyond the budget.
    fn store(&mut self, pairs: &[(usize, usize)], fresh: &Mat<Real>, used: &[(usize, usize)]) {
        self.clock += 1;
        let rows = fresh.nrows();
        for (j, &pair) in pairs.iter().enumerate() {
            let mut q = Mat::zeros(rows, 3);
            for c in 0..3 {
                q.col_as_slice_mut(c)
                    .copy_from_slice(fresh.col_as_slice(3 * j + c));
            }
            self.bytes += 3 * rows * size_of::<Real>();
            let old = self.entries.insert(
                key(pair),
                Entry {
                    q,
                    used: self.clock,
                },
            );
            if let Some(old) = old {
                self.bytes -= 3 * old.q.nrows() * size_of::<Real>();
            }
        }
        for &pair in used {
            if let Some(e) = self.entries.get_mut(&key(pair)) {
                e.used = self.clock;
            }
        }
        self.evict();
    }

    /// Marks the pairs as used now (those not cached are skipped).
    fn touch(&mut self, pairs: &[(usize, usize)]) {
        self.store(&[], &Mat::zeros(0, 0), pairs);
    }

    /// Removes the least recently used pairs until the cache fits its budget.
    fn evict(&mut self) {
        if self.bytes <= self.budget {
            return;
        }
        let mut order: Vec<((u32, u8), u64)> =
            self.entries.iter().map(|(k, e)| (*k, e.used)).collect();
        order.sort_unstable_by_key(|&(k, used)| (used, k));
        for (k, _) in order {
            if self.bytes <= self.budget {
                break;
            }
            if let Some(e) = self.entries.remove(&k) {
                self.bytes -= 3 * e.q.nrows() * size_of::<Real>();
            }
        }
    }
}

fn key((e, corner): (usize, usize)) -> (u32, u8) {
    (e as u32, corner as u8)
}

/// q for each pair, as column block j of a 3n × 3|pairs| matrix: the G shares integrated
/// (over the thread pool if `parallel`), then one batched solve with A₀⁻¹.
pub(super) fn solve_pairs(
    geo: &Geometry,
    inverse: &BaseInverse,
    pairs: &[(usize, usize)],
    parallel: bool,
) -> Mat<Real> {
    let dofs = 3 * geo.vertices.len();
    let rules = Rules::new();
    let integrate = |&(e, corner): &(usize, usize)| geo.element_g_columns(e, corner, &rules);
    let shares: Vec<Vec<Real>> = if parallel {
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            pairs.par_iter().map(integrate).collect()
        }
        #[cfg(not(feature = "parallel"))]
        pairs.iter().map(integrate).collect()
    } else {
        pairs.iter().map(integrate).collect()
    };
    // element_g_columns: entry 3 row + k is (row, column k) of the pair's block.
    let mut rhs = Mat::from_fn(dofs, 3 * pairs.len(), |r, c| shares[c / 3][3 * r + c % 3]);
    inverse.solve_in_place(rhs.as_mut());
    rhs
}

impl BemSystem {
    /// W̃_{:,C} and the support areas for `contacts` (valid, not fixed) if contact rims are
    /// on and the system has its surface and factorisation; `None` otherwise (continuous
    /// contact tractions). With background solves, pairs not cached are handed to the
    /// worker and the contacts that need them take the continuous rule until they land.
    pub(super) fn contact_rim_response(&mut self, contacts: &[usize]) -> Option<ContactRims> {
        if !self.contact_rims || contacts.is_empty() {
            return None;
        }
        self.absorb_rim_solves(false);
        let geo = Arc::clone(self.geometry.as_ref()?);
        self.inverse.as_ref()?;
        if geo.vertices.len() != self.inf.vertices {
            return None;
        }
        let mut constrained = self.fixed.clone();
        for &c in contacts {
            *constrained.get_mut(c)? = true;
        }
        let (rim, area) = geo.traction_supports(&constrained);
        // The inner triangles of the contacts with a rim.
        let mut inner = vec![Vec::new(); rim.len()];
        for (e, el) in geo.elements.iter().enumerate() {
            if el.nodes.iter().all(|&v| constrained[v]) {
                for (corner, &v) in el.nodes.iter().enumerate() {
                    if !rim[v].is_empty() {
                        inner[v].push((e, corner));
                    }
                }
            }
        }
        // Per contact: true when W̃ is summed from its inner triangles' q.
        let from_inner: Vec<bool> = contacts
            .iter()
            .map(|&c| !rim[c].is_empty() && inner[c].len() < rim[c].len())
            .collect();
        let pairs = |k: usize| {
            let c = contacts[k];
            if from_inner[k] { &inner[c] } else { &rim[c] }
        };
        let needed: Vec<(usize, usize)> = (0..contacts.len())
            .flat_map(|k| pairs(k).iter().copied())
            .collect();
        // Contacts whose columns the current set already has (not while it waits: those
        // are W's columns): a probe that moves on changes a few contacts' rims at a time,
        // and summing q columns again would read them all from memory.
        let reused: Vec<Option<usize>> = match self.rims.as_ref().filter(|r| !r.waiting) {
            Some(prev) => {
                let at: HashMap<usize, usize> = prev
                    .keys
                    .iter()
                    .enumerate()
                    .map(|(j, key)| (key.0, j))
                    .collect();
                (0..contacts.len())
                    .map(|k| {
                        at.get(&contacts[k]).copied().filter(|&j| {
                            let (_, inner, list) = &prev.keys[j];
                            *inner == from_inner[k] && list.as_slice() == pairs(k).as_slice()
                        })
                    })
                    .collect()
            }
            None => vec![None; contacts.len()],
        };
        let missing: Vec<(usize, usize)> = (0..contacts.len())
            .filter(|&k| reused[k].is_none())
            .flat_map(|k| pairs(k).iter().copied())
            .filter(|&p| !self.rim_cache.contains(p))
            .collect();
        // In the background only while the cache can hold what the contacts need: else
        // the pairs would be evicted before use and the contacts never upgraded.
        let missing_count = missing.len();
        let per_pair = 3 * self.dofs() * size_of::<Real>();
        let background = self.rim_background
            && !missing.is_empty()
            && needed.len() * per_pair <= self.rim_cache.budget();
        let dofs = self.dofs();
        if background {
            // The whole set waits on the continuous rule: mixing the rules (rims for the
            // contacts whose pairs are cached, hats for the others) is a valid basis but a
            // poor one (on a sphere it gave a sideways probe force of 60% of the push).
            let mut wanted = Vec::new();
            for &p in &missing {
                if !self.rim_worker.in_flight(p) && !wanted.contains(&p) {
                    wanted.push(p);
                }
            }
            self.ahead_of(contacts, &mut wanted);
            self.rim_worker
                .request(wanted, self.geometry.as_ref()?, self.inverse.as_ref()?);
            self.rim_cache.hits += needed.len() - missing_count;
            self.rim_cache.store(&[], &Mat::zeros(dofs, 0), &needed);
            let tributary = geo.tributary_areas();
            let mut wt = self.response_buffer(3 * contacts.len());
            for (c, column) in (0..3 * contacts.len()).map(|c| (c, 3 * contacts[c / 3] + c % 3)) {
                wt.col_as_slice_mut(c)
                    .copy_from_slice(self.w.col_as_slice(column));
            }
            return Some(ContactRims {
                wt,
                area: contacts.iter().map(|&c| tributary[c]).collect(),
                waiting: true,
                missing,
                keys: Vec::new(),
            });
        }
        let fresh = if missing.is_empty() {
            Mat::zeros(dofs, 0)
        } else {
            solve_pairs(&geo, self.inverse.as_ref()?, &missing, true)
        };
        if self.rim_background {
            let mut ahead = Vec::new();
            self.ahead_of(contacts, &mut ahead);
            self.rim_worker
                .request(ahead, self.geometry.as_ref()?, self.inverse.as_ref()?);
        }
        let mut wt = self.response_buffer(3 * contacts.len());
        // The same summation order whether q was cached or just solved. Whole columns at a
        // time: on 50 contacts this runs at every contact change of a moving probe.
        let mut next = 0;
        let previous = self.rims.as_ref();
        for k in 0..contacts.len() {
            if let (Some(j), Some(prev)) = (reused[k], previous) {
                self.rim_cache.reused += 1;
                for l in 0..3 {
                    wt.col_as_slice_mut(3 * k + l)
                        .copy_from_slice(prev.wt.col_as_slice(3 * j + l));
                }
                continue;
            }
            let sign = if from_inner[k] { 1.0 } else { -1.0 };
            for l in 0..3 {
                let column = wt.col_as_slice_mut(3 * k + l);
                if from_inner[k] {
                    column.fill(0.0);
                } else {
                    column.copy_from_slice(self.w.col_as_slice(3 * contacts[k] + l));
                }
            }
            for &pair in pairs(k) {
                let q = match self.rim_cache.entries.get(&key(pair)) {
                    Some(e) => e.q.as_ref(),
                    None => {
                        next += 1;
                        fresh.as_ref().subcols(3 * (next - 1), 3)
                    }
                };
                for l in 0..3 {
                    let target = wt.col_as_slice_mut(3 * k + l);
                    for (t, v) in target.iter_mut().zip(q.col(l).iter()) {
                        *t += sign * v;
                    }
                }
            }
        }
        self.rim_cache.hits += needed.len() - missing_count;
        self.rim_cache.solved += missing.len();
        self.rim_cache.store(&missing, &fresh, &needed);
        let keys = (0..contacts.len())
            .map(|k| (contacts[k], from_inner[k], pairs(k).clone()))
            .collect();
        Some(ContactRims {
            wt,
            area: contacts.iter().map(|&c| area[c]).collect(),
            waiting: false,
            missing: Vec::new(),
            keys,
        })
    }

    /// A 3n × `columns` matrix for W̃, in the memory of the contact set before last: a fresh
    /// 9 MB matrix per contact change of 55 contacts took 1.6-4.7 ms in page faults and
    /// zeroing, more than forming W̃. Column capacity goes in powers of two, so a growing
    /// contact set reallocates only when it doubles. Its entries are stale: every column
    /// must be written.
    fn response_buffer(&mut self, columns: usize) -> Mat<Real> {
        let dofs = self.dofs();
        let mut wt = std::mem::replace(&mut self.spare_response, Mat::zeros(0, 0));
        if wt.nrows() != dofs {
            wt = Mat::zeros(0, 0);
        }
        wt.reserve(dofs, columns.next_power_of_two().max(48));
        wt.resize_with(dofs, columns, |_, _| 0.0);
        wt
    }

    /// Appends to `wanted` (the pairs the current contacts still need, first in the queue)
    /// the pairs the next contact sets are likely to need, nearest first: those of the
    /// vertices on either side of the contact set's edge (a triangle with a contact and a
    /// free corner; a contact's list is whichever side of its rim is shorter, so both sides
    /// are asked for), then ring by ring outward over the free surface, where a sliding
    /// probe goes. The region covers half the cache's budget: what it holds already is
    /// marked used, so that the least recently used pairs evicted to make room are those
    /// farthest from the probe, never the region's or the contacts' own.
    fn ahead_of(&mut self, contacts: &[usize], wanted: &mut Vec<(usize, usize)>) {
        let Some(geo) = self.geometry.clone() else {
            return;
        };
        let n = geo.vertices.len();
        let per_pair = 3 * self.dofs() * size_of::<Real>();
        let region = self.rim_cache.budget() / per_pair / 2;
        let mut contact = vec![false; n];
        for &c in contacts {
            contact[c] = true;
        }
        let fixed = &self.fixed;
        let free = |v: usize| !contact[v] && !fixed.get(v).copied().unwrap_or(true);
        let mut ring = vec![usize::MAX; n];
        let mut order = Vec::new();
        for el in &geo.elements {
            let nodes = el.nodes;
            if nodes.iter().any(|&v| contact[v]) && nodes.iter().any(|&v| free(v)) {
                for v in nodes {
                    if (contact[v] || free(v)) && ring[v] == usize::MAX {
                        ring[v] = 0;
                        order.push(v);
                    }
                }
            }
        }
        let known: std::collections::HashSet<(usize, usize)> = wanted.iter().copied().collect();
        let mut held = Vec::new();
        let mut counted = 0;
        let mut k = 0;
        'walk: while k < order.len() {
            let v = order[k];
            k += 1;
            for &pair in &geo.corners[v] {
                counted += 1;
                if counted > region {
                    break 'walk;
                }
                if self.rim_cache.contains(pair) {
                    held.push(pair);
                } else if !known.contains(&pair) && !self.rim_worker.in_flight(pair) {
                    wanted.push(pair);
                }
            }
            for &w in &geo.neighbours[v] {
                if ring[w] == usize::MAX && free(w) {
                    ring[w] = ring[v] + 1;
                    order.push(w);
                }
            }
        }
        self.rim_cache.touch(&held);
    }

    /// Whether the contacts wait for rim pairs and re-forming them would now change
    /// something: every missing pair has landed, or the worker stopped short of them (a
    /// lost batch, an eviction) and must be asked again.
    pub(super) fn rims_due(&self) -> bool {
        let Some(rims) = self.rims.as_ref().filter(|r| r.waiting) else {
            return false;
        };
        self.rim_worker.pending() == 0 || rims.missing.iter().all(|&p| self.rim_cache.contains(p))
    }

    /// Stores the worker's finished batches, if any (`wait`: waits for every running one),
    /// and starts the next. Returns whether a batch landed (or was lost, so that its pairs
    /// are asked for again).
    pub(super) fn absorb_rim_solves(&mut self, wait: bool) -> bool {
        let mut landed = false;
        loop {
            let poll = if wait {
                self.rim_worker.wait()
            } else {
                self.rim_worker.poll()
            };
            match poll {
                Poll::Idle | Poll::Busy => break,
                Poll::Lost => landed = true,
                Poll::Done(solved) => {
                    self.rim_cache.solved += solved.pairs.len();
                    self.rim_cache.store(&solved.pairs, &solved.q, &[]);
                    landed = true;
                }
            }
        }
        if landed && let (Some(geo), Some(inverse)) = (&self.geometry, &self.inverse) {
            self.rim_worker.start_next(geo, inverse);
        }
        landed
    }

    /// Computes and caches q for every (triangle, corner) pair of the given vertices that
    /// is not cached yet (fixed vertices are skipped: their rims are part of A₀), e.g. the
    /// vertices around a probe before it touches them, or all of them when memory allows.
    /// Within the cache's budget only. Returns the number of pairs solved.
    pub fn warm_rim_cache(&mut self, vertices: &[usize]) -> usize {
        let (Some(geo), Some(inverse)) = (self.geometry.as_ref(), self.inverse.as_ref()) else {
            return 0;
        };
        if geo.vertices.len() != self.inf.vertices {
            return 0;
        }
        let mut wanted = vec![false; self.inf.vertices];
        for &v in vertices {
            if let Some(w) = wanted.get_mut(v) {
                *w = !self.fixed.get(v).copied().unwrap_or(true);
            }
        }
        let mut missing = Vec::new();
        for (e, el) in geo.elements.iter().enumerate() {
            for (corner, &v) in el.nodes.iter().enumerate() {
                if wanted[v] && !self.rim_cache.contains((e, corner)) {
                    missing.push((e, corner));
                }
            }
        }
        let per_pair = 3 * self.dofs() * size_of::<Real>();
        let room = (self
            .rim_cache
            .budget()
            .saturating_sub(self.rim_cache.bytes()))
            / per_pair;
        missing.truncate(room);
        if missing.is_empty() {
            return 0;
        }
        let fresh = solve_pairs(geo, inverse, &missing, true);
        self.rim_cache.solved += missing.len();
        self.rim_cache.store(&missing, &fresh, &[]);
        missing.len()
    }

    /// Bytes the cache of q = A₀⁻¹ g per (triangle, corner) holds now, and its pairs.
    pub fn rim_cache_usage(&self) -> (usize, usize) {
        (self.rim_cache.bytes(), self.rim_cache.pairs())
    }

    /// Pairs solved (misses and warm-ups) and pairs served from the cache so far.
    pub fn rim_cache_counts(&self) -> (usize, usize) {
        (self.rim_cache.solved, self.rim_cache.hits)
    }

    /// Contacts whose W̃ columns a contact change copied from the set before, so far.
    pub fn rim_contacts_reused(&self) -> usize {
        self.rim_cache.reused
    }

    /// The cache's byte budget.
    pub fn rim_cache_budget(&self) -> usize {
        self.rim_cache.budget()
    }

    /// The cache's byte budget (default `DEFAULT_RIM_CACHE_BYTES`); lowering it evicts.
    pub fn set_rim_cache_budget(&mut self, bytes: usize) {
        self.rim_cache.set_budget(bytes);
    }
}
