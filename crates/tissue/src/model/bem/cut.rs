//! The geometry of an incision in the BEM surface: the surface edges the swept blade crosses
//! are split, and the wound is opened as a narrow V-shaped groove.
//!
//! A collocation BEM needs a closed surface without coincident faces, so the two lips cannot
//! simply be duplicated in place: at every crossed edge inside the incision the crossing
//! becomes two lip vertices a little apart on that edge (`opening`, a fraction of the edge)
//! and one floor vertex at the blade's depth below the surface; the groove's two walls run
//! from each lip down to the floor. At the incision's two ends (the first and the last
//! crossed edge) the lips meet in one vertex, so the groove closes and the surface stays
//! closed, manifold and oriented.
//!
//! The crossed edges are ordered into one chain through the triangles that have two of them;
//! the chain's triangles and the two triangles beyond its ends are replaced. Untouched
//! triangles keep their order and new ones are appended; old vertices keep their numbers and
//! new ones are appended, so constraints, loads and the untouched columns of H and G stay
//! valid.

use std::collections::HashMap;
use std::time::Instant;

use crate::error::SimError;
use crate::interact::Loads;
use crate::math::{Real, Vec3, segment_triangle};
use crate::mesh::SurfaceMesh;
use crate::model::{CutInfo, CutPath, Deformable};

use super::assembly::{Geometry, Influence};
use super::border::{BorderBase, Bordered, influence_after_cut, keep_far_diagonals};
use super::model::{Bem, checked_surface};
use super::system::BemSystem;

/// Crossings are kept this far from the edge ends (fraction of the edge).
const MARGIN: Real = 0.25;
/// The deepest floor, as a fraction of the distance to the opposite side of the body.
const MAX_DEPTH_FRACTION: Real = 0.45;
/// The gap between the lips, as a fraction of the crossed edge.
pub const OPENING: Real = 0.2;

/// A surface after an incision.
#[derive(Clone, Debug)]
pub(crate) struct Incision {
    pub surface: SurfaceMesh,
    /// Old vertices whose triangles changed (their H and G columns change).
    pub changed: Vec<usize>,
    pub removed_triangles: usize,
    pub added_vertices: usize,
}

fn bad(reason: String) -> SimError {
    SimError::BadParameter {
        name: "cut",
        value: "blade sweep".into(),
        reason,
    }
}

/// Distance along the ray x + t d to the nearest triangle other than `skip`, if any.
fn ray_distance(s: &SurfaceMesh, x: Vec3, d: Vec3, skip: [usize; 2]) -> Option<Real> {
    let far = x + d;
    (0..s.triangles.len())
        .filter(|t| !skip.contains(t))
        .filter_map(|t| {
            let [a, b, c] = s.corners(t);
            // The infinite ray: intersect with a long segment.
            let span = 1e3 * ((a - x).length() + 1.0);
            segment_triangle(x, x + (far - x) * span, [a, b, c]).map(|f| f * span)
        })
        .min_by(Real::total_cmp)
}

/// The longest chain of crossed edges: consecutive edges share a triangle in which both are
/// crossed. Returns the edges in order and the triangles between them.
fn chain(
    crossed: &HashMap<[u32; 2], Real>,
    triangles: &[[u32; 3]],
) -> Result<(Vec<[u32; 2]>, Vec<usize>), SimError> {
    // Links: triangle with exactly two crossed edges.
    let mut links: HashMap<[u32; 2], Vec<(usize, [u32; 2])>> = HashMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        let hit: Vec<[u32; 2]> = (0..3)
            .map(|k| key(tri[k], tri[(k + 1) % 3]))
            .filter(|e| crossed.contains_key(e))
            .collect();
        match hit.as_slice() {
            [a, b] => {
                links.entry(*a).or_default().push((t, *b));
                links.entry(*b).or_default().push((t, *a));
            }
            [_, _, _] => {
                return Err(bad(format!(
                    "the blade crosses all three edges of triangle {t}; sweep in shorter steps"
                )));
            }
            _ => {}
        }
    }
    let mut best: (Vec<[u32; 2]>, Vec<usize>) = (Vec::new(), Vec::new());
    let mut starts: Vec<[u32; 2]> = crossed.keys().copied().collect();
    starts.sort_unstable();
    for start in starts {
        if links.get(&start).map_or(0, Vec::len) > 1 {
            continue; // not an end
        }
        let (mut edges, mut tris) = (vec![start], Vec::new());
        let mut cur = start;
        let mut prev_tri = usize::MAX;
        while let Some(&(t, next)) = links
            .get(&cur)
            .and_then(|l| l.iter().find(|(t, _)| *t != prev_tri))
        {
            if edges.contains(&next) || edges.len() > crossed.len() {
                break;
            }
            tris.push(t);
            edges.push(next);
            prev_tri = t;
            cur = next;
        }
        if edges.len() > best.0.len() {
            best = (edges, tris);
        }
    }
    Ok(best)
}

#[inline]
fn key(a: u32, b: u32) -> [u32; 2] {
    if a < b { [a, b] } else { [b, a] }
}

/// Cuts `surface` (at rest) along the blade sweep. `opening` is the gap between the lips as
/// a fraction of each crossed edge. `Ok(None)` when the sweep crosses fewer than three
/// edges in a row (nothing to open yet).
pub(crate) fn incise(
    surface: &SurfaceMesh,
    blade: &CutPath,
    opening: Real,
) -> Result<Option<Incision>, SimError> {
    if !blade.is_finite() {
        return Err(bad("the blade positions are not finite".into()));
    }
    let (x, tris) = (&surface.vertices, &surface.triangles);
    let mut edge_tris: HashMap<[u32; 2], Vec<usize>> = HashMap::new();
    for (t, tri) in tris.iter().enumerate() {
        for k in 0..3 {
            edge_tris
                .entry(key(tri[k], tri[(k + 1) % 3]))
                .or_default()
                .push(t);
        }
    }
    let vx = |v: u32| x.get(v as usize).copied().unwrap_or(Vec3::ZERO);
    let mut crossed = HashMap::new();
    for e in edge_tris.keys() {
        let (p, q) = (vx(e[0]), vx(e[1]));
        if let Some(s) = blade.crossing(p, q) {
            crossed.insert(*e, s.clamp(MARGIN, 1.0 - MARGIN));
        }
    }
    let (edges, chain_tris) = chain(&crossed, tris)?;
    if edges.len() < 3 {
        return Ok(None);
    }
    let m = edges.len() - 1;
    // The triangles beyond the two ends.
    let other = |e: [u32; 2], t: usize| -> Result<usize, SimError> {
        edge_tris
            .get(&e)
            .and_then(|ts| ts.iter().copied().find(|&u| u != t))
            .ok_or_else(|| bad(format!("edge {e:?} has no second triangle")))
    };
    let t_first = other(edges[0], chain_tris[0])?;
    let t_last = other(edges[m], chain_tris[m - 1])?;
    if t_first == t_last || chain_tris.contains(&t_first) || chain_tris.contains(&t_last) {
        return Err(bad(
            "the incision closes on itself; sweep a shorter path".into()
        ));
    }
    // Sides: the first edge's smaller vertex is on side 0; the vertex two consecutive edges
    // share keeps its side, so the labels propagate along the chain.
    let mut side: HashMap<u32, usize> = HashMap::new();
    side.insert(edges[0][0], 0);
    side.insert(edges[0][1], 1);
    for k in 1..=m {
        let (a, b) = (edges[k - 1], edges[k]);
        let shared = if b.contains(&a[0]) { a[0] } else { a[1] };
        let s = *side.get(&shared).unwrap_or(&0);
        let far = if b[0] == shared { b[1] } else { b[0] };
        if side.get(&far).is_some_and(|&f| f == s) {
            return Err(bad("the incision crosses itself".into()));
        }
        side.insert(far, 1 - s);
    }
    let n = x.len();
    let mut vertices = x.clone();
    let delta = (0.5 * opening).clamp(1e-3, 0.5 * MARGIN);
    // lips[k][side] for every chain edge; floors for the interior ones.
    let mut lips = vec![[0u32; 2]; m + 1];
    let mut floor_of = vec![0u32; m + 1];
    let normal_of = |t: usize| {
        let [a, b, c] = surface.corners(t);
        (b - a).cross(c - a).normalize_or_zero()
    };
    let (mid0, mid1) = (
        0.5 * (blade.start[0] + blade.start[1]),
        0.5 * (blade.end[0] + blade.end[1]),
    );
    for (k, e) in edges.iter().enumerate() {
        let s = crossed.get(e).copied().unwrap_or(0.5);
        let (a, b) = (vx(e[0]), vx(e[1]));
        let p = a + (b - a) * s;
        if k == 0 || k == m {
            lips[k] = [vertices.len() as u32; 2];
            vertices.push(p);
            continue;
        }
        // Lip on side of e[0] toward e[0], the other toward e[1].
        let (sa, sb) = (s - delta, s + delta);
        let side_a = *side.get(&e[0]).unwrap_or(&0);
        let ia = vertices.len() as u32;
        vertices.push(a + (b - a) * sa);
        vertices.push(a + (b - a) * sb);
        lips[k][side_a] = ia;
        lips[k][1 - side_a] = ia + 1;
        // Floor: straight in along the surface normal, as deep as the blade reaches, never
        // beyond a fraction of the body's thickness there.
        let ts = edge_tris.get(e).cloned().unwrap_or_default();
        let nrm = ts
            .iter()
            .map(|&t| normal_of(t))
            .fold(Vec3::ZERO, |acc, v| acc + v)
            .normalize_or_zero();
        let axis = mid1 - mid0;
        let sweep = if axis.length_squared() > 0.0 {
            ((p - mid0).dot(axis) / axis.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let ends = [
            blade.start[0].lerp(blade.end[0], sweep),
            blade.start[1].lerp(blade.end[1], sweep),
        ];
        let reach = ends.iter().map(|q| -(*q - p).dot(nrm)).fold(0.0, Real::max);
        let skip = [
            ts.first().copied().unwrap_or(0),
            ts.get(1).copied().unwrap_or(0),
        ];
        let thickness = ray_distance(surface, p, -nrm, skip).unwrap_or(reach);
        let edge = (b - a).length();
        let depth = reach
            .min(MAX_DEPTH_FRACTION * thickness)
            .max(2.0 * delta * edge);
        floor_of[k] = vertices.len() as u32;
        vertices.push(p - nrm * depth);
    }
    // Replace the chain's triangles and the two beyond its ends.
    let mut removed = vec![false; tris.len()];
    let mut pieces: Vec<[u32; 3]> = Vec::new();
    let edge_index: HashMap<[u32; 2], usize> =
        edges.iter().enumerate().map(|(k, e)| (*e, k)).collect();
    let lip = |e: [u32; 2], v: u32| -> u32 {
        let k = edge_index.get(&e).copied().unwrap_or(0);
        lips[k][*side.get(&v).unwrap_or(&0)]
    };
    for &t in chain_tris.iter().chain([&t_first, &t_last]) {
        removed[t] = true;
        let tri = tris[t];
        let cut = |k: usize| {
            crossed.contains_key(&key(tri[k], tri[(k + 1) % 3]))
                && edge_index.contains_key(&key(tri[k], tri[(k + 1) % 3]))
        };
        let hits: Vec<usize> = (0..3).filter(|&k| cut(k)).collect();
        match hits.as_slice() {
            [k] => {
                // An end triangle: its crossed edge (c0, c1) holds the end vertex.
                let (c0, c1, c2) = (tri[*k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                let e = lip(key(c0, c1), c0);
                pieces.push([c0, e, c2]);
                pieces.push([e, c1, c2]);
            }
            [i, j] => {
                // Rotate so that c0 is the corner both crossed edges share.
                let r = if *j == (i + 1) % 3 { *j } else { *i };
                let (c0, c1, c2) = (tri[r], tri[(r + 1) % 3], tri[(r + 2) % 3]);
                let (e01, e20) = (key(c0, c1), key(c2, c0));
                let (p0, q0) = (lip(e01, c0), lip(e20, c0));
                let (p1, q1) = (lip(e01, c1), lip(e20, c2));
                pieces.push([c0, p0, q0]);
                let d1 = (vertices[p1 as usize] - vertices[c2 as usize]).length();
                let d2 = (vertices[c1 as usize] - vertices[q1 as usize]).length();
                if d1 <= d2 {
                    pieces.push([p1, c1, c2]);
                    pieces.push([p1, c2, q1]);
                } else {
                    pieces.push([p1, c1, q1]);
                    pieces.push([c1, c2, q1]);
                }
            }
            _ => return Err(bad(format!("triangle {t} is not cut as expected"))),
        }
    }
    // The groove's walls, one strip per side, oriented against the lip edges they share.
    let directed: std::collections::HashSet<(u32, u32)> = pieces
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .collect();
    for s in 0..2 {
        let lip_chain: Vec<u32> = (0..=m).map(|k| lips[k][s]).collect();
        let floor: Vec<u32> = (0..=m)
            .map(|k| {
                if k == 0 || k == m {
                    lips[k][0]
                } else {
                    floor_of[k]
                }
            })
            .collect();
        let mut strip = Vec::new();
        for k in 0..m {
            let (l0, l1, f0, f1) = (lip_chain[k], lip_chain[k + 1], floor[k], floor[k + 1]);
            if k == 0 {
                strip.push([l0, l1, f1]);
            } else if k == m - 1 {
                strip.push([l0, l1, f0]);
            } else {
                strip.push([l0, l1, f1]);
                strip.push([l0, f1, f0]);
            }
        }
        let first = strip.first().copied().unwrap_or([0; 3]);
        let flip = directed.contains(&(first[0], first[1]));
        pieces.extend(
            strip
                .into_iter()
                .map(|t| if flip { [t[0], t[2], t[1]] } else { t }),
        );
    }
    let mut triangles: Vec<[u32; 3]> = tris
        .iter()
        .zip(&removed)
        .filter(|(_, r)| !**r)
        .map(|(t, _)| *t)
        .collect();
    triangles.extend(pieces);
    let mut changed: Vec<usize> = chain_tris
        .iter()
        .chain([&t_first, &t_last])
        .flat_map(|&t| tris[t].map(|v| v as usize))
        .collect();
    changed.sort_unstable();
    changed.dedup();
    Ok(Some(Incision {
        added_vertices: vertices.len() - n,
        surface: SurfaceMesh::new(vertices, triangles),
        changed,
        removed_triangles: removed.iter().filter(|&&r| r).count(),
    }))
}

/// How the system follows an incision.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CutUpdate {
    /// Columns and rows that changed are assembled, A₀⁻¹ and W extended by bordering:
    /// O(n² k).
    Bordering,
    /// The cut surface is assembled and factorised afresh, O(n³): the reference.
    Reassembly,
}

/// An incision's new surface, before the system follows it.
pub(super) struct PlannedIncision {
    cut: Incision,
    /// `cut.surface`, checked (closed, manifold, oriented).
    surface: SurfaceMesh,
    /// Vertices before the cut.
    n0: usize,
}

/// The system's part of an incision by bordering: O(n² k), the expensive part, computed
/// without touching the model (on a worker in real time, `super::incision_worker`).
pub(super) enum SystemUpdate {
    /// Boxed: a bordering carries its layer's factors inline, far larger than the other.
    Bordered(Box<Bordered>),
    /// The system was not factorised yet: the cut surface's H and G, factorised later.
    Unfactored { inf: Influence, geometry: Geometry },
}

/// What `SystemUpdate::compute` reads from the model: shared, not copied.
pub(super) struct UpdateBase {
    border: Option<BorderBase>,
    old: std::sync::Arc<Influence>,
    material: crate::material::Material,
}

impl PlannedIncision {
    /// The vertices whose H and G columns change: the old ones whose triangles changed and
    /// every new one.
    fn changed(&self) -> Vec<usize> {
        let mut k = self.cut.changed.clone();
        k.extend(self.n0..self.surface.vertices.len());
        k
    }
}

impl SystemUpdate {
    /// H and G where the surface changed, then the bordering (or nothing more when the
    /// system is not factorised yet).
    pub(super) fn compute(plan: &PlannedIncision, base: &UpdateBase) -> Result<Self, SimError> {
        let geometry = Geometry::new(&plan.surface, &base.material)?;
        let k = plan.changed();
        let (inf, far_rows) = influence_after_cut(
            &base.old,
            &plan.surface.vertices,
            &geometry.elements,
            &geometry.kelvin,
            &k,
        );
        match &base.border {
            Some(b) => {
                let bordered = b.border(inf, Some(geometry), &k, &far_rows)?;
                Ok(Self::Bordered(Box::new(bordered)))
            }
            None => Ok(Self::Unfactored { inf, geometry }),
        }
    }
}

impl Bem {
    /// Cuts along `blade` and updates the system as `update` says; the constraints and point
    /// loads are kept (they refer to old vertices, whose numbers do not change).
    pub fn incise(&mut self, blade: &CutPath, update: CutUpdate) -> Result<CutInfo, SimError> {
        let Some(plan) = self.plan_incision(blade)? else {
            return Ok(self.no_cut());
        };
        let start = Instant::now();
        let system = match update {
            CutUpdate::Bordering => {
                let computed = SystemUpdate::compute(&plan, &self.update_base()?)?;
                self.updated_system(computed)?
            }
            CutUpdate::Reassembly => self.reassembled_system(&plan)?,
        };
        self.land_incision(plan, system, start.elapsed().as_secs_f64())
    }

    /// The `CutInfo` of a sweep that opened nothing.
    pub(super) fn no_cut(&self) -> CutInfo {
        CutInfo {
            topology_version: self.cuts,
            ..CutInfo::default()
        }
    }

    /// The cut surface along `blade`, or `None` when the blade opens nothing.
    pub(super) fn plan_incision(
        &mut self,
        blade: &CutPath,
    ) -> Result<Option<PlannedIncision>, SimError> {
        // A scene-built model assembles at its first constraints; a cut may come first.
        self.assemble_pending();
        let Some(cut) = incise(&self.surface, blade, OPENING)? else {
            return Ok(None);
        };
        let surface = checked_surface(&cut.surface)?;
        if surface.vertices.len() != cut.surface.vertices.len() {
            return Err(bad("the incision left unused vertices".into()));
        }
        Ok(Some(PlannedIncision {
            n0: self.surface.vertices.len(),
            cut,
            surface,
        }))
    }

    /// What `SystemUpdate::compute` reads, shared with the model.
    pub(super) fn update_base(&self) -> Result<UpdateBase, SimError> {
        Ok(UpdateBase {
            border: if self.system.is_factored() {
                Some(self.system.border_base()?)
            } else {
                None
            },
            old: std::sync::Arc::clone(&self.system.inf),
            material: self.material,
        })
    }

    /// Whether an update computed from `base` still applies to this model's system.
    pub(super) fn update_applies(&self, base_generation: u64) -> bool {
        self.system.generation == base_generation
    }

    /// The system with `computed` applied (the model's system is taken out; on error it is
    /// put back unchanged).
    pub(super) fn updated_system(&mut self, computed: SystemUpdate) -> Result<BemSystem, SimError> {
        let mut system = std::mem::replace(&mut self.system, BemSystem::new(empty()));
        match computed {
            SystemUpdate::Bordered(b) => {
                if let Err(e) = system.apply_border(*b) {
                    self.system = system;
                    return Err(e);
                }
                Ok(system)
            }
            SystemUpdate::Unfactored { inf, geometry } => {
                let rims = system.contact_rims;
                let mut fresh = BemSystem::new(inf);
                fresh.set_geometry(Some(geometry));
                fresh.set_contact_rims(rims);
                Ok(fresh)
            }
        }
    }

    /// The reference update: the cut surface assembled and factorised afresh.
    fn reassembled_system(&self, plan: &PlannedIncision) -> Result<BemSystem, SimError> {
        let surface = &plan.surface;
        let fresh = Bem::new(surface, self.material, self.params)
            .map_err(|e| bad(format!("re-assembly failed: {e}")))?;
        let mut system = fresh.system;
        let mut in_k = vec![false; surface.vertices.len()];
        for v in plan.changed() {
            in_k[v] = true;
        }
        keep_far_diagonals(
            &self.system.inf,
            std::sync::Arc::make_mut(&mut system.inf),
            &in_k,
        );
        if self.system.is_factored() {
            let mut fixed = self.system.fixed().to_vec();
            fixed.resize(surface.vertices.len(), false);
            system.factor(&fixed)?;
        }
        Ok(system)
    }

    /// Replaces the model by the cut one with `system`, carrying positions, constraints and
    /// loads over.
    pub(super) fn land_incision(
        &mut self,
        plan: PlannedIncision,
        mut system: BemSystem,
        seconds: Real,
    ) -> Result<CutInfo, SimError> {
        let PlannedIncision { cut, surface, n0 } = plan;
        system.last_cut_seconds = seconds;
        let mut next = Bem::from_parts(surface, self.material, self.params, empty(), 0.0);
        next.system = system;
        next.assembly_seconds = self.assembly_seconds;
        next.cuts = self.cuts + 1;
        next.progress = self.progress.clone();
        next.real_time = self.real_time;
        next.incisions = std::mem::take(&mut self.incisions);
        next.positions[..n0].copy_from_slice(&self.positions);
        let loads = Loads {
            gravity: self.gravity,
            point_loads: (0..n0)
                .filter(|&v| self.point_forces[v] != Vec3::ZERO)
                .map(|v| (v as u32, self.point_forces[v]))
                .collect(),
        };
        // The system is already bordered, so the uncut model cannot come back: if the
        // constraints or loads no longer fit the cut body, the cut model (consistent, with
        // what it accepted) is kept and the error says why.
        let applied = next
            .set_constraints(self.reactions.constraints())
            .and_then(|()| next.set_loads(&loads));
        *self = next;
        applied?;
        Ok(CutInfo {
            removed_elements: cut.removed_triangles,
            added_vertices: cut.added_vertices,
            topology_version: self.cuts,
        })
    }
}

fn empty() -> Influence {
    Influence {
        vertices: 0,
        h: Vec::new(),
        g: Vec::new(),
    }
}
