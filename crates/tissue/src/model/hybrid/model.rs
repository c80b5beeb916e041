//! `Hybrid`: the tensor-mass region, the pre-computed rest, the surface drawn over both,
//! and the split of constraints and loads between them.

use std::cell::{OnceCell, RefCell};
use std::time::Instant;

use faer::Mat;

use crate::error::{Error, SimError};
use crate::integrate::Scheme;
use crate::integrate::coupling::NodeCoupling;
use crate::interact::{Constraints, Loads, PointContact, Prescribed, SurfaceHold};
use crate::material::Material;
use crate::math::{Mat3, Real, Vec3, closest_point_on_triangle};
use crate::mesh::TET_FACES;
use crate::mesh::TetMesh;
use crate::mesh::topology::tet_neighbours;
use crate::model::tensor_mass::{TensorMass, TensorMassParams};
use crate::model::{
    ConstraintReactions, CutInfo, CutPath, Deformable, Progress, StepInfo, VolumeView,
};

use super::CutRegion;
use super::grow::{Built, Growth};
use super::rest::{RestPart, Site};
use super::split::{NONE, Split, centroids};

/// What the model was built with, kept for region growths.
#[derive(Clone, Debug)]
pub(super) struct Recipe {
    pub material: Material,
    pub tm_params: TensorMassParams,
    pub nonlinear: bool,
    pub scheme: Scheme,
}

/// One region growth: when it was asked for, how long its build took, its size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GrowthRecord {
    /// Build time (split, condensation, tensors), in s, off the interactive thread when the
    /// model runs in real time.
    pub seconds: Real,
    /// Region tetrahedra after the growth.
    pub region_tets: usize,
    /// Steps the old region answered while the new one was built (0 when synchronous).
    pub steps_waited: u64,
}

/// The survey's hybrid model (see the module doc of `hybrid`).
pub struct Hybrid {
    pub(super) recipe: Recipe,
    pub(super) mode: CutRegion,
    pub(super) auto_radius: Real,
    /// Mean edge length: the depth of the region's border is about two of them.
    edge: Real,
    pub(super) mesh: TetMesh,
    neighbours: Vec<[Option<u32>; 4]>,
    centroids: Vec<Vec3>,
    /// Per global tetrahedron: not removed by a cut.
    pub(super) alive: Vec<bool>,
    pub(super) split: Split,
    pub(super) tm: TensorMass,
    pub(super) rest: RestPart,
    /// Region node of each interface node.
    region_iface: Vec<u32>,
    /// Region node → the region model's surface vertex, or `NONE`.
    tm_vertex: Vec<u32>,
    /// The drawn surface: global node of each vertex (stable numbers, appended by cuts).
    pub(super) surf_nodes: Vec<u32>,
    pub(super) surf_of_node: Vec<u32>,
    pub(super) surf_rest: Vec<Vec3>,
    /// The drawn surface's current positions, computed on the first read after a step: the
    /// rest's outer surface is G·u_I (3n_O × 3n_I, megabytes) plus the contacts' columns,
    /// which a caller that steps without looking (a haptic loop between display frames)
    /// need not pay for every step. Never stale: every step and every cut empties it.
    surf_pos: OnceCell<Vec<Vec3>>,
    /// Where contact searches look (`Deformable::set_contact_reach`); `None`: everywhere.
    reach: Option<Vec<(Vec3, Real)>>,
    /// The surface a contact search within `reach` needs (`contact_positions`): positions
    /// and slack, emptied with `surf_pos` and whenever the reach or the held set changes.
    near: OnceCell<NearSurface>,
    /// The last partial surface dropped, kept for its memory: the next one starts from it
    /// and puts back only the vertices it had moved, instead of copying the reference.
    spare: RefCell<Option<NearSurface>>,
    /// The last whole surface computed, with the interface displacements and contact forces
    /// it came from: `contact_positions` bounds how far each vertex has moved since.
    /// Dropped when the surface's vertices, the split or the loads change.
    surf_ref: RefCell<Option<SurfaceRef>>,
    /// What `near_positions` looks up per vertex, resolved once per surface (rebuilt with
    /// the triangles: after a cut, a growth, a reset): the search is then a few flops per
    /// outer vertex instead of three node maps and a bound each.
    search: SearchMaps,

    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) constraints: Constraints,
    pub(super) loads: Loads,
    pub(super) reactions: ConstraintReactions,
    /// Per surface vertex: the prescribed entry of the region model holding it, or `NONE`.
    tm_entry: Vec<u32>,
    /// Surface vertex of each contact of the rest (the active ones, in the rest's order;
    /// `NONE` for a fine surface's point).
    rest_contact: Vec<u32>,
    /// The outer slots the rest's active contacts name (a point's three among them): the
    /// vertices a partial contact surface computes exactly.
    rest_site_slots: Vec<u32>,
    /// The fine surface's points of the last `set_point_contacts` (cleared by the
    /// constraints), where each went, and each one's push after the last step (N).
    points: Vec<PointContact>,
    point_routes: Vec<PointRoute>,
    point_pushes: Vec<Real>,
    /// The directions given with the constraints (`set_constraints_along`), kept to apply
    /// them again after a cut, growth or reset.
    normals: Vec<Option<Vec3>>,
    /// Every entry on the rest's outer surface, active or not (`contact_set`).
    rest_cands: Vec<RestCandidate>,
    /// Per candidate: held in the step being taken.
    rest_active: Vec<bool>,
    /// The rest's contacts that pushed at the end of the last step.
    rest_pushed: Vec<Key>,
    /// Steps the rest's active set settled in, their solves, and the steps stopped at
    /// `MAX_CONTACT_SOLVES`.
    pub(super) contact_stats: ContactStats,
    /// Forces applied to the rest at its contacts after the last step (3 per contact).
    pub(super) contact_forces: Mat<Real>,
    pub(super) topology_version: u32,
    pub(super) real_time: bool,
    pub(super) growth: Option<Growth>,
    pub(super) growths: Vec<GrowthRecord>,
    pub(super) steps: u64,
    /// Cut tetrahedra that reached the region's border (through the sliver guard).
    pub(super) border_removals: usize,
    pub(super) precompute_seconds: Real,
    /// The surviving tetrahedra (global numbers), for the volume view.
    alive_tets: Vec<[u32; 4]>,
    /// Every node's position, the rest's interior included (a sparse solve): filled on the
    /// first volume read after a step.
    volume_positions: OnceCell<Vec<Vec3>>,
    /// The automatic region's seed when neither the scene nor a scalpel gave one.
    pub(super) default_seed: Option<Vec3>,
    /// Whether a fine surface's points are held exactly (`[model] exact_fine_points`; off by
    /// default: a point across the interface cannot be held yet and stops the run, so an
    /// instrument that may reach the interface keeps the coarse vertices' planes).
    pub(super) exact_points: bool,
    /// Where the notice that the region covers the organ goes (once).
    pub(super) progress: Progress,
    /// That notice was given.
    whole_noticed: bool,
}

/// Per surface vertex, what part it is on, for the partial contact search.
#[derive(Default)]
struct SearchMaps {
    /// (surface vertex, region node) of the vertices on the region.
    region: Vec<(u32, u32)>,
    /// Surface vertex of each outer slot of the rest (`NONE` for a slot with no vertex).
    vertex_of_slot: Vec<u32>,
    /// Outer slot of each surface vertex, or `NONE`.
    slot_of_vertex: Vec<u32>,
    /// The triangles at each surface vertex (compressed rows: `tri_start[v]..tri_start[v
    /// + 1]` in `tris`).
    tri_start: Vec<u32>,
    tris: Vec<u32>,
}

/// A partial contact surface (`contact_positions`).
struct NearSurface {
    positions: Vec<Vec3>,
    slack: Vec<Real>,
    /// The vertices whose positions differ from the reference's: the region's and the
    /// rows computed (the next partial surface puts them back, see `spare`).
    moved: Vec<u32>,
    /// The reference's number (`SurfaceRef::number`).
    base: u64,
}

/// A whole surface as computed, and the state of the rest it came from.
struct SurfaceRef {
    /// A number no other reference of this process has had (a partial surface's buffers
    /// are reused only on the reference they came from).
    number: u64,
    u: Mat<Real>,
    z: Vec<(u32, Vec3)>,
    positions: Vec<Vec3>,
    /// The largest |position|: the rounding of a position is within 4 ε of it.
    largest: Real,
    /// Rows of the rest's outer surface the partial surfaces computed since (in vertices).
    rows_since: std::cell::Cell<usize>,
}

/// A number for a new whole-surface reference, unique in the process.
fn fresh_reference_number() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

/// An entry of the constraints on the rest's outer surface: a support or grasp (held in
/// full, always active), an instrument's frictionless contact (held along its normal while
/// active: it only pushes, `Hybrid::advance`) or a fine surface's point on the rest (the
/// same, on the nodes it follows: `rest::Site`).
#[derive(Clone, Debug, PartialEq)]
struct RestCandidate {
    /// The surface vertex of a contact; `NONE` for a point.
    vertex: u32,
    site: Site,
    /// What names it from one step to the next (its slot, or the point's vertices).
    key: Key,
    /// Target displacement (a point's: its reach along the normal).
    target: Vec3,
    /// Outward from the instrument (toward the tissue); `None`: held in full.
    normal: Option<Vec3>,
}

impl RestCandidate {
    /// How far a site displaced by `u` is out of the contact's plane (negative: past it).
    fn gap(&self, u: Vec3) -> Real {
        self.normal.map_or(0.0, |n| n.dot(u - self.target))
    }
}

/// A rest contact's name across steps: a contact's outer slot, or a point's vertices and
/// weights (a fine surface's vertex keeps both while its coarse triangle stays).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Key {
    Slot(u32),
    Point([u32; 3], [u64; 3]),
}

/// Where a fine surface's point is held (`Hybrid::route_points`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum PointRoute {
    /// By the region's integrator (`integrate::PointHold`): the region model's point `k`.
    Region(usize),
    /// By the rest's contacts: candidate `k` of the rest.
    Rest(usize),
    /// Nowhere: every node it follows is held in full (the supports take it).
    Held,
}

/// How the rest's contacts settled (`ModelInfo::details`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct ContactStats {
    /// Region steps taken for the last step (1: the first guess was right).
    pub last_solves: usize,
    /// The most any step took.
    pub max_solves: usize,
    /// Steps that stopped at `MAX_CONTACT_SOLVES` with the set still changing.
    pub capped_steps: u64,
}

/// At most this many tries of a step while the rest's active set changes (each is a whole
/// step of the region); a step stopped here says `capped` in its `StepInfo`. A contact let
/// go is not taken again within the step, so a set of m contacts settles in at most 2m + 1.
pub(super) const MAX_CONTACT_SOLVES: usize = 12;

/// A contact search that needs more than this fraction of the rest's outer vertices gets
/// the whole surface (which becomes the new reference): the rows cost what the whole
/// product does, and a fresh reference shrinks the next searches' slack.
const NEAR_FRACTION: Real = 0.3;

/// Power iterations of the stability re-measure when the rest's contact set changes
/// (warm-started from the last dominant vector; see `apply_constraints`).
pub(super) const CONTACT_RECHECK_ITERATIONS: usize = 4;

/// What `ModelInfo::details` (`whole_organ`) and the one notice say when the region covers
/// every tetrahedron.
pub const WHOLE_ORGAN_NOTICE: &str = "hybrid: the cut region covers every tetrahedron; the \
    model is now whole-organ tensor-mass (nothing is pre-computed, cutting continues \
    everywhere)";

impl Hybrid {
    /// Builds the model on a validated mesh with the region's tetrahedra `in_region`.
    pub(super) fn build(
        mesh: TetMesh,
        in_region: Vec<bool>,
        mode: CutRegion,
        auto_radius: Real,
        recipe: Recipe,
    ) -> Result<Self, Error> {
        let start = Instant::now();
        let built = Built::new(&mesh, in_region, &mode, &recipe)?;
        let neighbours = tet_neighbours(&mesh.tets);
        let mut surf_nodes: Vec<u32> = Vec::new();
        for (t, tet) in mesh.tets.iter().enumerate() {
            for k in 0..4 {
                if neighbours[t][k].is_none() {
                    surf_nodes.extend(TET_FACES[k].map(|c| tet[c]));
                }
            }
        }
        surf_nodes.sort_unstable();
        surf_nodes.dedup();
        let mut surf_of_node = vec![NONE; mesh.vertices.len()];
        for (s, &n) in surf_nodes.iter().enumerate() {
            surf_of_node[n as usize] = s as u32;
        }
        let surf_rest: Vec<Vec3> = surf_nodes
            .iter()
            .map(|&n| mesh.vertices[n as usize])
            .collect();
        let Built {
            split, rest, tm, ..
        } = built;
        let mut m = Self {
            recipe,
            mode,
            auto_radius,
            centroids: centroids(&mesh),
            edge: super::mean_edge(&mesh),
            alive: vec![true; mesh.tets.len()],
            neighbours,
            split,
            tm,
            rest,
            region_iface: Vec::new(),
            tm_vertex: Vec::new(),
            surf_pos: OnceCell::new(),
            reach: None,
            near: OnceCell::new(),
            spare: RefCell::new(None),
            surf_ref: RefCell::new(None),
            search: SearchMaps::default(),

            surf_rest,
            surf_nodes,
            surf_of_node,
            triangles: Vec::new(),
            constraints: Constraints::default(),
            loads: Loads::default(),
            reactions: ConstraintReactions::default(),
            tm_entry: Vec::new(),
            rest_contact: Vec::new(),
            rest_site_slots: Vec::new(),
            points: Vec::new(),
            point_routes: Vec::new(),
            point_pushes: Vec::new(),
            normals: Vec::new(),
            rest_cands: Vec::new(),
            rest_active: Vec::new(),
            rest_pushed: Vec::new(),
            contact_stats: ContactStats::default(),
            contact_forces: Mat::zeros(0, 1),
            topology_version: 0,
            real_time: false,
            growth: None,
            growths: Vec::new(),
            steps: 0,
            border_removals: 0,
            precompute_seconds: 0.0,
            alive_tets: Vec::new(),
            volume_positions: OnceCell::new(),
            default_seed: None,
            exact_points: false,
            progress: Progress::silent(),
            whole_noticed: false,
            mesh,
        };
        m.adopt_split();
        m.set_loads_checked(&Loads::default())?;
        m.update_state()?;
        m.measure_stability();
        m.precompute_seconds = start.elapsed().as_secs_f64();
        Ok(m)
    }

    /// The drawn surface's current positions (the rest's outer part computed here, once per
    /// step, on the first read).
    pub(super) fn surface_positions(&self) -> &[Vec3] {
        self.surf_pos.get_or_init(|| {
            // From the current state of both parts (never from a copy that a growth could
            // have left behind): the gather and the contact forces are small.
            let u = self.interface_u();
            let z = self.rest.contact_forces(&u);
            let uo = self.rest.outer_displacements(&u, &z);
            let x = self.tm.positions();
            let positions: Vec<Vec3> = self
                .surf_nodes
                .iter()
                .zip(&self.surf_rest)
                .map(|(&g, &p)| {
                    let r = self.split.region.local[g as usize];
                    if r != NONE {
                        x[r as usize]
                    } else if let Some(slot) =
                        self.rest.outer_slot(self.split.rest.local[g as usize])
                    {
                        let s = 3 * slot as usize;
                        p + Vec3::new(uo[(s, 0)], uo[(s + 1, 0)], uo[(s + 2, 0)])
                    } else {
                        p
                    }
                })
                .collect();
            *self.surf_ref.borrow_mut() = Some(SurfaceRef {
                number: fresh_reference_number(),
                z: self.rest.forces_by_slot(&z),
                u,
                largest: positions.iter().fold(0.0, |a: Real, p| a.max(p.length())),
                positions: positions.clone(),
                rows_since: std::cell::Cell::new(0),
            });
            positions
        })
    }

    /// Empties the partial contact surface, keeping its buffers for the next one.
    fn drop_near(&mut self) {
        if let Some(near) = self.near.take() {
            *self.spare.get_mut() = Some(near);
        }
    }

    /// Sets where contact searches look (see `contact_positions`).
    pub(super) fn set_reach(&mut self, reach: Option<&[(Vec3, Real)]>) {
        if self.reach.as_deref() != reach {
            self.reach = reach.map(<[_]>::to_vec);
            self.drop_near();
        }
    }

    /// The surface as a contact search within the reach needs it, with each vertex's slack
    /// (empty: every vertex exact; see `ContactSurface`). The whole surface when it was
    /// already read this step, when the reach is everywhere, or when there is no whole
    /// surface to start from. Otherwise the region's vertices (free to read), and of the
    /// rest's outer surface only the vertices that can be within the reach, those of their
    /// triangles and the held ones, are computed (three rows of G·u_I each); every other
    /// vertex is left where the last whole surface had it, with the slack
    /// ‖G_o‖_F |Δu_I| + Σ_c ‖W_oc‖_F |Δλ_c| (rounding included), a bound on how far it has
    /// moved since: when that position is farther than this from every ball, the vertex is
    /// outside all of them wherever it is exactly.
    pub(super) fn contact_positions(&self) -> (&[Vec3], &[Real]) {
        if let Some(full) = self.surf_pos.get() {
            return (full, &[]);
        }
        let Some(reach) = self.reach.as_deref() else {
            return (self.surface_positions(), &[]);
        };
        if !self.rest.exists() {
            return (self.surface_positions(), &[]);
        }
        let near = match self.near.get() {
            Some(near) => near,
            None => match self.near_positions(reach) {
                Some(near) => self.near.get_or_init(|| near),
                None => return (self.surface_positions(), &[]),
            },
        };
        (&near.positions, &near.slack)
    }

    /// `contact_positions`' partial surface, or `None` when the whole one is due (no
    /// reference, a state that is not finite, or too many vertices near the reach).
    fn near_positions(&self, reach: &[(Vec3, Real)]) -> Option<NearSurface> {
        let reference = self.surf_ref.borrow();
        let reference = reference.as_ref()?;
        let n = self.surf_nodes.len();
        if reference.positions.len() != n {
            return None;
        }
        let u = self.interface_u();
        if reference.u.nrows() != u.nrows() {
            return None;
        }
        let z = self.rest.contact_forces(&u);
        let norm = |m: &Mat<Real>| m.col_as_slice(0).iter().map(|x| x * x).sum::<Real>().sqrt();
        let du = u
            .col_as_slice(0)
            .iter()
            .zip(reference.u.col_as_slice(0))
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<Real>()
            .sqrt();
        // Contact force changes by slot, over the contacts now and at the reference.
        let now = self.rest.forces_by_slot(&z);
        let mut dz: Vec<(u32, Real)> = now
            .iter()
            .map(|&(s, f)| {
                let before = reference.z.iter().find(|(r, _)| *r == s).map(|(_, g)| *g);
                (s, (f - before.unwrap_or(Vec3::ZERO)).length())
            })
            .collect();
        dz.extend(
            reference
                .z
                .iter()
                .filter(|(s, _)| !now.iter().any(|(r, _)| r == s))
                .map(|&(s, g)| (s, g.length())),
        );
        // Both surfaces' rounding: relative to the sizes of the products themselves.
        let mut sizes: Vec<(u32, Real)> = now.iter().map(|&(s, f)| (s, f.length())).collect();
        sizes.extend(reference.z.iter().map(|&(s, g)| (s, g.length())));
        let u_size = norm(&u) + norm(&reference.u);
        if !(du.is_finite() && dz.iter().all(|(_, z)| z.is_finite()) && u_size.is_finite()) {
            return None;
        }
        // One bound per vertex: the change with a margin (1e-6) plus both surfaces'
        // rounding (1e-9 of the products' sizes), as one set of terms; the contacts'
        // compliance norms looked up once, not per vertex.
        let mut terms: Vec<(u32, Real)> = dz
            .iter()
            .map(|&(s, d)| (s, d * (1.0 + 1e-6)))
            .chain(sizes.iter().map(|&(s, z)| (s, 1e-9 * z)))
            .collect();
        // One term per contact (one pass over the slots each): the sums of a slot's terms.
        terms.sort_unstable_by_key(|&(s, _)| s);
        terms.dedup_by(|b, a| {
            let same = a.0 == b.0;
            if same {
                a.1 += b.1;
            }
            same
        });
        let terms = self.rest.bound_terms(&terms);
        let du = du * (1.0 + 1e-6) + 1e-9 * u_size;
        let maps = &self.search;
        if maps.slot_of_vertex.len() != n || maps.vertex_of_slot.len() != self.rest.outer_slots() {
            return None;
        }
        let x = self.tm.positions();
        // The reference's positions: the last partial surface's buffers with the vertices
        // it moved put back when it came from the same reference, else a copy.
        let spare = self
            .spare
            .borrow_mut()
            .take()
            .filter(|sp| sp.base == reference.number && sp.positions.len() == n);
        let (mut positions, mut slack, mut moved) = match spare {
            Some(sp) => {
                let mut positions = sp.positions;
                for &v in &sp.moved {
                    positions[v as usize] = reference.positions[v as usize];
                }
                (positions, sp.slack, sp.moved)
            }
            None => (reference.positions.clone(), vec![0.0; n], Vec::new()),
        };
        for &(v, r) in &maps.region {
            positions[v as usize] = x[r as usize];
        }
        // Every outer slot's bound at once, then one test per outer vertex: its last
        // position farther than bound + radius from every ball is outside all of them.
        let mut bound = Vec::new();
        self.rest.displacement_bounds(du, &terms, &mut bound);
        let rounding = 4.0 * Real::EPSILON * reference.largest;
        // Every outer vertex's slack is written below; the others' stay 0 (the region's,
        // and those of no part), as do the rows a partial surface computed, now outer ones.
        slack.resize(n, 0.0);
        let mut seeds = Vec::new();
        let mut outer = 0;
        for (&v, &b) in maps.vertex_of_slot.iter().zip(&bound) {
            if v == NONE {
                continue;
            }
            outer += 1;
            let s = b + rounding;
            slack[v as usize] = s;
            let p = positions[v as usize];
            if reach.iter().any(|&(c, r)| {
                let reach = r + s;
                (p - c).length_squared() <= reach * reach * (1.0 + 1e-12)
            }) {
                seeds.push(v);
            }
        }
        // The vertices of a triangle with one that can be inside: a contact's normal is
        // taken from its triangles. The held vertices are exact too, but their triangles
        // only when they are within the reach (an instrument's contact): a support far
        // from every instrument needs no normal.
        let mut exact = vec![false; n];
        let mut rows: Vec<u32> = Vec::new();
        let mut take = |v: u32| {
            if !exact[v as usize] && maps.slot_of_vertex[v as usize] != NONE {
                exact[v as usize] = true;
                rows.push(v);
            }
        };
        for &s in &self.rest_site_slots {
            if let Some(&v) = maps.vertex_of_slot.get(s as usize)
                && v != NONE
            {
                take(v);
            }
        }
        for &v in &seeds {
            take(v);
            let (a, b) = (
                maps.tri_start[v as usize] as usize,
                maps.tri_start[v as usize + 1] as usize,
            );
            for &t in &maps.tris[a..b] {
                for &w in &self.triangles[t as usize] {
                    take(w);
                }
            }
        }
        let count = rows.len();
        // The slack grows with the state's distance from the reference, and with it the
        // rows each search computes (79 per step on the 7k liver under a held probe, from
        // a reference taken during the press): once the searches since the reference
        // have computed as many rows as the whole surface has, the next one computes the
        // whole surface, a fresh reference (at most twice the cheaper of the two).
        let since = reference.rows_since.get() + count;
        if count as Real > NEAR_FRACTION * outer as Real || since > outer {
            return None;
        }
        reference.rows_since.set(since);
        for &v in &rows {
            let slot = maps.slot_of_vertex[v as usize];
            positions[v as usize] =
                self.surf_rest[v as usize] + self.rest.outer_displacement(slot, &u, &z);
            slack[v as usize] = 0.0;
        }
        moved.clear();
        moved.extend_from_slice(&rows);
        moved.extend(maps.region.iter().map(|&(v, _)| v));
        Some(NearSurface {
            positions,
            slack,
            moved,
            base: reference.number,
        })
    }

    /// Resolves, per surface vertex, what the partial contact search looks up (the part it
    /// is on, its outer slot, its triangles).
    fn rebuild_search_maps(&mut self) {
        let n = self.surf_nodes.len();
        let mut maps = SearchMaps {
            region: Vec::new(),
            vertex_of_slot: vec![NONE; self.rest.outer_slots()],
            slot_of_vertex: vec![NONE; n],
            tri_start: vec![0; n + 1],
            tris: vec![0; 3 * self.triangles.len()],
        };
        for (v, &g) in self.surf_nodes.iter().enumerate() {
            let r = self.split.region.local[g as usize];
            if r != NONE {
                maps.region.push((v as u32, r));
            } else if let Some(slot) = self.rest.outer_slot(self.split.rest.local[g as usize]) {
                maps.slot_of_vertex[v] = slot;
                maps.vertex_of_slot[slot as usize] = v as u32;
            }
        }
        for t in &self.triangles {
            for &v in t {
                maps.tri_start[v as usize + 1] += 1;
            }
        }
        for v in 0..n {
            maps.tri_start[v + 1] += maps.tri_start[v];
        }
        let mut fill = maps.tri_start.clone();
        for (k, t) in self.triangles.iter().enumerate() {
            for &v in t {
                maps.tris[fill[v as usize] as usize] = k as u32;
                fill[v as usize] += 1;
            }
        }
        self.search = maps;
    }

    /// The interface displacements u_I (3 per interface node) from the region's state:
    /// a gather, without the coupling's scratch vectors.
    fn interface_u(&self) -> Mat<Real> {
        let x = self.tm.positions();
        let rest = &self.split.region.mesh.vertices;
        Mat::from_fn(3 * self.region_iface.len(), 1, |i, _| {
            let n = self.region_iface[i / 3] as usize;
            x[n][i % 3] - rest[n][i % 3]
        })
    }

    /// Rebuilds the maps that follow the split and the region model's surface.
    fn adopt_split(&mut self) {
        self.region_iface = self
            .split
            .interface
            .iter()
            .map(|&g| self.split.region.local[g as usize])
            .collect();
        self.refresh_tm_vertices();
        self.rebuild_triangles();
    }

    fn refresh_tm_vertices(&mut self) {
        self.tm_vertex = vec![NONE; self.split.region.global.len()];
        for (s, &n) in self.tm.surface_nodes().iter().enumerate() {
            self.tm_vertex[n as usize] = s as u32;
        }
    }

    /// The boundary faces of the surviving tetrahedra, outward, over the surface vertices
    /// (nodes a cut exposes get new vertex numbers at the end).
    fn rebuild_triangles(&mut self) {
        self.surf_pos.take();
        self.drop_near();
        self.surf_ref.take();
        self.alive_tets = self
            .mesh
            .tets
            .iter()
            .zip(&self.alive)
            .filter(|&(_, &a)| a)
            .map(|(t, _)| *t)
            .collect();
        self.triangles.clear();
        for (t, tet) in self.mesh.tets.iter().enumerate() {
            if !self.alive[t] {
                continue;
            }
            for (k, face) in TET_FACES.iter().enumerate() {
                let open = match self.neighbours[t][k] {
                    None => true,
                    Some(n) => !self.alive[n as usize],
                };
                if !open {
                    continue;
                }
                let tri = face.map(|c| {
                    let n = tet[c];
                    let s = self.surf_of_node[n as usize];
                    if s != NONE {
                        return s;
                    }
                    let s = self.surf_nodes.len() as u32;
                    self.surf_of_node[n as usize] = s;
                    self.surf_nodes.push(n);
                    self.surf_rest.push(self.mesh.vertices[n as usize]);
                    s
                });
                self.triangles.push(tri);
            }
        }
        self.rebuild_search_maps();
    }

    /// Region tetrahedra count.
    pub fn region_tets(&self) -> usize {
        self.split.region.tets.len()
    }

    /// Fraction of the organ's volume in the cut region.
    pub fn region_fraction(&self) -> Real {
        self.split.volume_fraction
    }

    /// Interface nodes between the region and the rest.
    pub fn interface_nodes(&self) -> usize {
        self.split.interface.len()
    }

    /// Per global tetrahedron: in the cut region.
    pub fn region_mask(&self) -> &[bool] {
        &self.split.in_region
    }

    /// The region growths so far.
    pub fn growths(&self) -> &[GrowthRecord] {
        &self.growths
    }

    /// The region model (tensor-mass on the region's tetrahedra).
    pub fn region_model(&self) -> &TensorMass {
        &self.tm
    }

    /// Per surface vertex: 1 on the cut region (its node is a region node), 0 on the rest.
    pub fn region_field(&self) -> Vec<Real> {
        self.surf_nodes
            .iter()
            .map(|&n| {
                if self.split.region.local[n as usize] != NONE {
                    1.0
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// Per surface vertex, what part of the model it is on: 0 the pre-computed rest, 1 the
    /// region's border (region nodes a cut may not reach: on the interface or on a region
    /// tetrahedron touching it), 2 the cuttable region.
    pub fn region_labels(&self) -> Vec<u8> {
        self.surf_nodes
            .iter()
            .map(|&n| {
                if self.split.region.local[n as usize] == NONE {
                    0
                } else if self.split.border[n as usize] {
                    1
                } else {
                    2
                }
            })
            .collect()
    }

    /// The volume view: every node's current position (the rest's interior from its
    /// displacement field, one sparse solve per step read) and the surviving tetrahedra.
    pub(super) fn volume_view(&self) -> VolumeView<'_> {
        let positions = self.volume_positions.get_or_init(|| {
            let mut x = self.mesh.vertices.clone();
            let u = self.interface_u();
            if let Ok(rest_u) = self.rest.node_displacements(&u) {
                for (l, &g) in self.split.rest.global.iter().enumerate() {
                    x[g as usize] += rest_u[l];
                }
            }
            for (l, &g) in self.split.region.global.iter().enumerate() {
                x[g as usize] = self.tm.positions()[l];
            }
            x
        });
        VolumeView {
            positions,
            rest_positions: &self.mesh.vertices,
            tets: &self.alive_tets,
        }
    }

    /// `Deformable::prescribed_stiffness`: the instantaneous stiffness of the prescribed
    /// entries, everything else held — the region's tangent at its nodes (St Venant–Kirchhoff
    /// at the current state), the rest's condensed response at the interface and its
    /// contacts: −(T_region + d_Iᵀ S d_I + yᵀ W_cc⁻¹ y), y = G_c d_I − d_c (reactions are
    /// the tissue's forces on the instrument, so pushing in lowers them).
    pub(super) fn held_stiffness(&self, entries: std::ops::Range<usize>) -> Option<Mat3> {
        // A fine surface's points move with the instrument too, which the formula below
        // does not see: the haptic loop estimates the stiffness instead (as the
        // pre-computed kinds say with points).
        if !self.points.is_empty() {
            return None;
        }
        let picked = self.constraints.prescribed.get(entries)?;
        let mut region_held = vec![false; self.split.region.global.len()];
        let mut contact_held = vec![false; self.rest_contact.len()];
        let mut any = false;
        for p in picked {
            if self.constraints.fixed.contains(&p.vertex) {
                continue; // fixed wins: that vertex does not follow the instrument
            }
            let g = *self.surf_nodes.get(p.vertex as usize)? as usize;
            let r = self.split.region.local[g];
            if r != NONE {
                if self.tm_vertex[r as usize] != NONE {
                    region_held[r as usize] = true;
                    any = true;
                }
            } else if let Some(k) = self.rest_contact.iter().position(|&c| c == p.vertex) {
                contact_held[k] = true;
                any = true;
            }
        }
        if !any {
            return None;
        }
        let iface_held: Vec<bool> = self
            .region_iface
            .iter()
            .map(|&r| region_held[r as usize])
            .collect();
        let k = self
            .tm
            .system()
            .translation_stiffness(self.tm.positions(), &region_held)
            + self.rest.translation_stiffness(&iface_held, &contact_held);
        (-k).is_finite().then_some(-k)
    }

    /// The forces the rest exerts on the interface nodes after the last step (global node,
    /// force), and the forces the contacts on the rest apply to it.
    pub fn interface_balance(&self) -> (Vec<(u32, Vec3)>, Vec<Vec3>) {
        // F_I from the current state (one product with S): `update_state` does not keep it,
        // a step needs only the contact forces.
        let u = self.interface_u();
        let mut f = Mat::zeros(u.nrows(), 1);
        self.rest.interface_forces(&u, &mut f);
        let iface = self
            .split
            .interface
            .iter()
            .enumerate()
            .map(|(a, &g)| {
                (
                    g,
                    Vec3::new(f[(3 * a, 0)], f[(3 * a + 1, 0)], f[(3 * a + 2, 0)]),
                )
            })
            .collect();
        let z = &self.contact_forces;
        let contacts = (0..z.nrows() / 3)
            .map(|k| Vec3::new(z[(3 * k, 0)], z[(3 * k + 1, 0)], z[(3 * k + 2, 0)]))
            .collect();
        (iface, contacts)
    }

    /// The total load on the rest (its weight and point loads), in N.
    pub fn rest_load(&self) -> Vec3 {
        self.rest.total_load()
    }

    /// Current position of global node `g` (rest interior nodes: at rest; only the
    /// blade test uses them).
    fn node_position(&self, g: u32) -> Vec3 {
        let r = self.split.region.local[g as usize];
        if r != NONE {
            return self.tm.positions()[r as usize];
        }
        let s = self.surf_of_node[g as usize];
        if s != NONE {
            return self.surface_positions()[s as usize];
        }
        self.mesh.vertices[g as usize]
    }

    /// Checks and splits the constraints between the two parts; nothing changes on error.
    /// An entry with a direction in `normals` is a frictionless contact that only pushes:
    /// on the region, the tensor-mass integrator's projection (`integrate::Hold::contact`);
    /// on the rest, a row of its condensed response held along the normal while active
    /// (`advance` settles which are).
    pub(super) fn apply_constraints(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<(), SimError> {
        let holds = c.surface_holds(&self.surf_rest, normals)?;
        let tm_rest = self.tm.rest_surface().to_vec();
        let mut tm_c = Constraints::default();
        let mut tm_normals = Vec::new();
        let mut tm_entry = vec![NONE; self.surf_nodes.len()];
        let mut cands = Vec::new();
        for (v, h) in holds.iter().enumerate() {
            let Some(h) = h else { continue };
            let g = self.surf_nodes[v] as usize;
            let r = self.split.region.local[g];
            if r != NONE {
                let sv = self.tm_vertex[r as usize];
                if sv == NONE {
                    continue; // a node no surviving region tetrahedron exposes
                }
                tm_entry[v] = tm_c.prescribed.len() as u32;
                tm_c.prescribed.push(Prescribed {
                    vertex: sv,
                    position: tm_rest[sv as usize] + h.displacement,
                });
                tm_normals.push(h.along);
            } else if let Some(slot) = self.rest.outer_slot(self.split.rest.local[g]) {
                cands.push(RestCandidate {
                    vertex: v as u32,
                    site: Site::outer(slot),
                    key: Key::Slot(slot),
                    target: h.displacement,
                    normal: h.along,
                });
            }
        }
        let contacts = cands.len();
        let (routes, tm_points) = self.route_points(&holds, &mut cands)?;
        // The first guess of the active set: the contacts held in full, those that pushed
        // at the end of the last step, and those whose site is past its plane now (its
        // three rows of the rest's surface, not the whole surface). Points past their
        // planes are guessed deepest first, each only if it names an outer node no point
        // guessed before names (`solve::lcp::first_guess`: about one point per node can
        // push independently).
        let mut now = None;
        let mut active = Vec::with_capacity(cands.len());
        let mut depth = Vec::new();
        for (i, k) in cands.iter().enumerate() {
            let pushed = self.rest_pushed.contains(&k.key);
            let on = k.normal.is_none() || pushed || {
                let (u, z) = now.get_or_insert_with(|| {
                    let u = self.interface_u();
                    let z = self.rest.contact_forces(&u);
                    (u, z)
                });
                let gap = k.gap(self.rest.site_displacement(&k.site, u, z));
                if i >= contacts && gap < 0.0 {
                    depth.push((gap, i));
                }
                i < contacts && gap < 0.0
            };
            active.push(on);
        }
        depth.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut named: Vec<u32> = cands[contacts..]
            .iter()
            .zip(&active[contacts..])
            .filter(|(_, a)| **a)
            .flat_map(|(k, _)| outer_slots(&k.site))
            .collect();
        for (_, i) in depth {
            let slots: Vec<u32> = outer_slots(&cands[i].site).collect();
            if slots.iter().any(|s| !named.contains(s)) {
                named.extend(slots);
                active[i] = true;
            }
        }
        let before = (
            std::mem::replace(&mut self.rest_cands, cands),
            std::mem::replace(&mut self.rest_active, active),
        );
        if let Err(e) = self
            .install_rest_set()
            .and_then(|()| self.let_go_of_pulls_at_start())
        {
            (self.rest_cands, self.rest_active) = before;
            return Err(e);
        }
        self.tm.set_constraints_along(&tm_c, &tm_normals)?;
        self.tm.set_point_contacts(&tm_points)?;
        self.point_routes = routes;
        self.point_pushes.clear();
        self.point_pushes.resize(self.points.len(), 0.0);
        self.tm_entry = tm_entry;
        self.drop_near();
        self.constraints = c.clone();
        self.normals = normals.to_vec();
        self.reactions.set(c);
        Ok(())
    }

    /// Sends each fine surface's point (`points`) to the part that holds it:
    ///
    /// - every vertex it follows (with a weight) on the region: the region's integrator
    ///   (`integrate::PointHold`), exactly as `tensor-mass` holds it;
    /// - every one on the rest's outer surface: a push-only contact of the rest's condensed
    ///   response on those nodes (`rest::Site`), settled with the rest's other contacts
    ///   within the step, exactly as the pre-computed kinds hold it; one whose nodes are all
    ///   held in full is the supports' (not pushed);
    /// - across the interface (a triangle of the rest touching it: some of its vertices
    ///   are interface nodes, which the region moves, the others the rest's): refused,
    ///   naming the point. Two ways were tried and failed on the block pressed across the
    ///   interface (docs/contact.md): as a contact of the rest's response with the
    ///   interface nodes' share through the coupling, two such points on one rest node
    ///   with different interface nodes are one row of the rest's compliance but two of
    ///   the coupling, a constraint on the region's nodes that the rest's force law can
    ///   give only as an unbounded stiffness (29 substeps where 5 were needed, the active
    ///   set changing at every step, the force off the static answer by up to 9 %); by the
    ///   region's projection with the rest's vertices held where the step found them, the
    ///   rest's share is not pushed and the interface nodes make it up, a lagged iteration
    ///   whose gain is −(w_rest / w_region)·(how far the rest node follows them): it blew
    ///   up at step 144.
    ///
    /// Appends the rest's candidates to `cands`; returns each point's route and the region
    /// model's points.
    fn route_points(
        &self,
        holds: &[Option<SurfaceHold>],
        cands: &mut Vec<RestCandidate>,
    ) -> Result<(Vec<PointRoute>, Vec<PointContact>), SimError> {
        let mut routes = Vec::with_capacity(self.points.len());
        let mut tm_points = Vec::new();
        for pt in &self.points {
            let used: Vec<usize> = (0..3).filter(|&i| pt.weights[i] != 0.0).collect();
            let node = |i: usize| self.surf_nodes[pt.vertices[i] as usize] as usize;
            let tm_of = |i: usize| {
                let r = self.split.region.local[node(i)];
                (r != NONE)
                    .then(|| self.tm_vertex.get(r as usize).copied())
                    .flatten()
                    .filter(|&sv| sv != NONE)
            };
            let slot_of = |i: usize| {
                (self.split.region.local[node(i)] == NONE)
                    .then(|| self.rest.outer_slot(self.split.rest.local[node(i)]))
                    .flatten()
            };
            if let Some(&i) = used
                .iter()
                .find(|&&i| tm_of(i).is_none() && slot_of(i).is_none())
            {
                return Err(SimError::BadParameter {
                    name: "point contact",
                    value: format!("on surface vertices {:?}", pt.vertices),
                    reason: format!(
                        "hybrid cannot hold it: vertex {} is on neither part's surface",
                        pt.vertices[i]
                    ),
                });
            }
            let on_region: Vec<usize> = used
                .iter()
                .copied()
                .filter(|&i| tm_of(i).is_some())
                .collect();
            if on_region.is_empty() {
                let terms: Vec<(u32, Real)> = used
                    .iter()
                    .filter_map(|&i| slot_of(i).map(|s| (s, pt.weights[i])))
                    .collect();
                let held = used
                    .iter()
                    .all(|&i| holds[pt.vertices[i] as usize].is_some_and(|h| h.along.is_none()));
                if held || terms.is_empty() {
                    routes.push(PointRoute::Held);
                    continue;
                }
                routes.push(PointRoute::Rest(cands.len()));
                cands.push(RestCandidate {
                    vertex: NONE,
                    site: Site { terms, point: true },
                    key: Key::Point(pt.vertices, pt.weights.map(Real::to_bits)),
                    target: pt.reach() * pt.normal,
                    normal: Some(pt.normal),
                });
                continue;
            }
            if on_region.len() < used.len() {
                return Err(SimError::BadParameter {
                    name: "point contact",
                    value: format!("on surface vertices {:?}", pt.vertices),
                    reason: "hybrid cannot hold a fine surface's point that follows vertices of \
                             both parts (a triangle of the pre-computed rest touching the cut \
                             region); keep the frictionless instrument on one part (a \
                             cut_region that covers where it presses, or none of it) or make \
                             it sticking (docs/contact.md, exact fine points on hybrid)"
                        .into(),
                });
            }
            let first = tm_of(on_region[0]).unwrap_or(0);
            routes.push(PointRoute::Region(tm_points.len()));
            tm_points.push(PointContact {
                vertices: std::array::from_fn(|i| tm_of(i).unwrap_or(first)),
                ..*pt
            });
        }
        Ok((routes, tm_points))
    }

    /// `Deformable::set_point_contacts`: checks the points, keeps them, and splits them and
    /// the constraints again between the parts (`route_points`). Nothing changes on error.
    pub(super) fn apply_points(&mut self, points: &[PointContact]) -> Result<(), SimError> {
        if points.is_empty() && self.points.is_empty() {
            // `Simulation` sets the points every step, none without a fine surface: the
            // constraints are split once, as before points existed.
            return Ok(());
        }
        let count = self.surf_nodes.len();
        for p in points {
            p.check(count)?;
        }
        let before = std::mem::replace(&mut self.points, points.to_vec());
        let (c, normals) = (self.constraints.clone(), self.normals.clone());
        if let Err(e) = self.apply_constraints(&c, &normals) {
            self.points = before;
            return Err(e);
        }
        Ok(())
    }

    /// The pushes on the points of the last `set_point_contacts` after the last step.
    pub(super) fn point_pushes(&self) -> &[Real] {
        &self.point_pushes
    }

    /// Forgets the points (`set_constraints` clears them).
    pub(super) fn clear_points(&mut self) {
        self.points.clear();
    }

    /// Hands the active candidates to the rest (nothing new when the set, its directions
    /// and targets are those already held).
    fn install_rest_set(&mut self) -> Result<(), SimError> {
        let (mut sites, mut targets, mut normals, mut vertices) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (k, _) in self
            .rest_cands
            .iter()
            .zip(&self.rest_active)
            .filter(|(_, a)| **a)
        {
            sites.push(k.site.clone());
            targets.extend_from_slice(&k.target.to_array());
            normals.push(k.normal);
            vertices.push(k.vertex);
        }
        if !self.rest.same_contacts(&sites, &targets, &normals) {
            let new_set = self.rest.contact_sites() != sites.as_slice()
                || self.rest.contact_normals() != normals.as_slice();
            self.rest.set_contacts(&sites, &targets, &normals)?;
            // The coupling's forces and energy changed under the integrator's feet; its
            // stiffness (S + G_cᵀ P G_c) only when the contact set or its directions did.
            self.tm.forget_forces();
            if new_set {
                // A new contact set changes the interface stiffness by a low-rank term (the
                // contacts' G_cᵀ P G_c): the stability limit is re-measured from the last
                // dominant vector in a few iterations, never below the last full measure
                // (which the build and every growth or cut take), instead of 30 cold ones.
                let coupling = self
                    .rest
                    .coupling(&self.region_iface, &self.split.region.mesh.vertices);
                self.tm
                    .recheck_stability(&coupling, CONTACT_RECHECK_ITERATIONS);
            }
        }
        self.rest_contact = vertices;
        self.rest_site_slots = sites.iter().flat_map(outer_slots).collect();
        self.surf_pos.take();
        self.drop_near();
        Ok(())
    }

    /// Each candidate's push on the rest for the contact forces `z` of the active set (λ·n,
    /// positive pushing; infinite for one held in full, 0 for one not held), and the sum of
    /// the finite ones' sizes: the scale below which a pull is rounding.
    fn pushes(&self, z: &Mat<Real>) -> (Vec<Real>, Real) {
        let mut pushes = Vec::with_capacity(self.rest_cands.len());
        let mut row = 0;
        for (k, &a) in self.rest_cands.iter().zip(&self.rest_active) {
            let push = if a && 3 * row + 2 < z.nrows() {
                let f = Vec3::new(z[(3 * row, 0)], z[(3 * row + 1, 0)], z[(3 * row + 2, 0)]);
                row += 1;
                k.normal.map_or(Real::INFINITY, |n| n.dot(f))
            } else {
                0.0
            };
            pushes.push(push);
        }
        let scale = pushes
            .iter()
            .filter(|p| p.is_finite())
            .map(|p| p.abs())
            .sum();
        (pushes, scale)
    }

    /// Lets go, before the step, of the frictionless contacts of the first guess that pull
    /// where the step starts (their force with the new targets at the current interface
    /// displacements): their instrument moved away from them. A contact that pushed at the
    /// end of the last step is guessed held, and when its instrument left within one step
    /// (the viewer lifting its probe 0.3 m away in 10 ms) its target is far behind its site:
    /// held, it pulled the site toward the instrument's new place with a force the region's
    /// step could not take, and the step diverged before the pull was seen after it. Let go
    /// here, such a contact is free for the step and taken again only if its site ends past
    /// its plane (`advance_settling`). A contact that pushes at the start is kept, as are
    /// the supports.
    fn let_go_of_pulls_at_start(&mut self) -> Result<(), SimError> {
        let held = |(k, a): (&RestCandidate, &bool)| *a && k.normal.is_some();
        if !self.rest_cands.iter().zip(&self.rest_active).any(held) {
            return Ok(());
        }
        let z = self.rest.contact_forces(&self.interface_u());
        let (pushes, scale) = self.pushes(&z);
        let mut changed = false;
        for (i, k) in self.rest_cands.iter().enumerate() {
            if self.rest_active[i] && k.normal.is_some() && pushes[i] < -1e-9 * scale {
                self.rest_active[i] = false;
                changed = true;
            }
        }
        if changed {
            self.install_rest_set()?;
        }
        Ok(())
    }

    /// Splits the loads: gravity on each part's own tetrahedra, point loads on the part of
    /// their vertex's node. Nothing changes on error.
    pub(super) fn set_loads_checked(&mut self, loads: &Loads) -> Result<(), SimError> {
        if !loads.gravity.is_finite() {
            return Err(SimError::BadParameter {
                name: "gravity",
                value: loads.gravity.to_string(),
                reason: "must be finite".into(),
            });
        }
        let mut tm_loads = Loads {
            gravity: loads.gravity,
            point_loads: Vec::new(),
        };
        let mut rest_points = Vec::new();
        for &(v, f) in &loads.point_loads {
            let g = *self
                .surf_nodes
                .get(v as usize)
                .ok_or(SimError::BadConstraint {
                    vertex: v as usize,
                    count: self.surf_nodes.len(),
                })? as usize;
            if !f.is_finite() {
                return Err(SimError::BadParameter {
                    name: "point_loads",
                    value: format!("surface vertex {v} -> {f}"),
                    reason: "the force must be finite".into(),
                });
            }
            let r = self.split.region.local[g];
            if r != NONE {
                if let Some(&sv) = self.tm_vertex.get(r as usize).filter(|&&s| s != NONE) {
                    tm_loads.point_loads.push((sv, f));
                }
            } else {
                rest_points.push((self.split.rest.local[g], f));
            }
        }
        self.rest.set_loads(loads.gravity, &rest_points)?;
        self.tm.set_loads(&tm_loads)?;
        self.drop_near();
        self.surf_ref.take();
        self.loads = loads.clone();
        Ok(())
    }

    /// One step: the region integrates with the rest's interface forces in every force
    /// evaluation; then the rest's outer surface and the reactions follow.
    pub(super) fn advance(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        if self.real_time {
            self.poll_growth()?;
        }
        let info = if self.rest_cands.iter().any(|k| k.normal.is_some()) {
            self.advance_settling(dt)?
        } else {
            let coupling = self
                .rest
                .coupling(&self.region_iface, &self.split.region.mesh.vertices);
            // A region that covers the organ is whole-organ tensor-mass: nothing to couple.
            let coupled: Option<&dyn NodeCoupling> = if self.rest.exists() {
                Some(&coupling)
            } else {
                None
            };
            self.tm.advance_coupled(dt, coupled)?
        };
        self.steps += 1;
        if let Some(g) = self.growth.as_mut() {
            g.steps_waited += 1;
        }
        self.update_state()?;
        Ok(info)
    }

    /// A step with contacts on the rest that only push: the region steps with the active
    /// set held along their normals (fixed for the whole step: every stage and substep of
    /// the scheme sees one smooth force law); then a held contact whose force pulls is let
    /// go (for the rest of the step, so that the loop ends), a free one whose node ended
    /// past its plane is taken, and the step is taken again from its start until nothing
    /// changes, at most `MAX_CONTACT_SOLVES` times (then `capped`). The rest has no inertia
    /// of its own, so its contacts are decided at the step's resolution, the resolution at
    /// which the instrument moves them.
    fn advance_settling(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        let start = self.tm.step_checkpoint();
        let mut released = vec![false; self.rest_cands.len()];
        let mut solves = 0;
        loop {
            solves += 1;
            let tried = {
                let coupling = self
                    .rest
                    .coupling(&self.region_iface, &self.split.region.mesh.vertices);
                self.tm.advance_coupled(dt, Some(&coupling))
            };
            let mut info = match tried {
                Ok(info) => info,
                Err(e) => {
                    // A held contact whose instrument left within the step (a probe lifted
                    // away in one step) pulls its node toward a target far off before the
                    // pull can be seen, and the region's step diverges. Such a contact can
                    // only let go: the step is taken again without the held frictionless
                    // contacts (the ones still past their planes are taken next step), and
                    // says so (`capped`). Without any to let go, the error stands.
                    let held: Vec<usize> = (0..self.rest_cands.len())
                        .filter(|&i| self.rest_active[i] && self.rest_cands[i].normal.is_some())
                        .collect();
                    if held.is_empty() || solves > MAX_CONTACT_SOLVES {
                        return Err(e);
                    }
                    for &i in &held {
                        self.rest_active[i] = false;
                        released[i] = true;
                    }
                    self.tm.roll_back(&start);
                    self.install_rest_set()?;
                    let coupling = self
                        .rest
                        .coupling(&self.region_iface, &self.split.region.mesh.vertices);
                    let mut info = self.tm.advance_coupled(dt, Some(&coupling))?;
                    info.capped = true;
                    info
                }
            };
            let u = self.interface_u();
            let z = self.rest.contact_forces(&u);
            // Pulls and penetrations below roundoff of the pushes and of the motion are none.
            let (pushes, scale) = self.pushes(&z);
            let depth = 1e-12 * self.edge;
            let mut next = self.rest_active.clone();
            for (i, k) in self.rest_cands.iter().enumerate() {
                if k.normal.is_none() {
                    continue;
                }
                if next[i] && pushes[i] < -1e-9 * scale {
                    next[i] = false;
                    released[i] = true;
                } else if !next[i] && !released[i] {
                    let d = self.rest.site_displacement(&k.site, &u, &z);
                    next[i] = k.gap(d) < -depth;
                }
            }
            let changed = next != self.rest_active;
            if !changed || solves >= MAX_CONTACT_SOLVES {
                info.capped |= changed;
                let st = &mut self.contact_stats;
                st.last_solves = solves;
                st.max_solves = st.max_solves.max(solves);
                st.capped_steps += u64::from(changed);
                self.rest_pushed = self
                    .rest_cands
                    .iter()
                    .zip(&pushes)
                    .filter(|(k, p)| k.normal.is_some() && **p > 0.0)
                    .map(|(k, _)| k.key)
                    .collect();
                return Ok(info);
            }
            self.rest_active = next;
            self.tm.roll_back(&start);
            self.install_rest_set()?;
        }
    }

    /// Surface positions and reactions from the region's state.
    pub(super) fn update_state(&mut self) -> Result<(), SimError> {
        self.volume_positions.take();
        let u = self.interface_u();
        // The reactions need the contact forces only (G_c u_I, small), not F_I (S u_I:
        // `interface_balance` computes it when asked).
        let z = self.rest.contact_forces(&u);
        // The surface follows on its first read (`surface_positions`).
        self.surf_pos.take();
        self.drop_near();
        let mut force = vec![Vec3::ZERO; self.surf_nodes.len()];
        let tm_prescribed = self.tm.reactions().prescribed;
        for (v, &e) in self.tm_entry.iter().enumerate() {
            if e != NONE {
                force[v] = tm_prescribed.get(e as usize).copied().unwrap_or(Vec3::ZERO);
            }
        }
        for (k, &v) in self.rest_contact.iter().enumerate() {
            if v == NONE {
                continue; // a point: its push is read below
            }
            // The rest pushes its contact with −λ.
            force[v as usize] = -Vec3::new(z[(3 * k, 0)], z[(3 * k + 1, 0)], z[(3 * k + 2, 0)]);
        }
        // Each point's push λ = n·f, f the force its site applies to the rest (its row of
        // z when active); the region's from its integrator.
        let mut row_of = vec![NONE; self.rest_cands.len()];
        let mut row = 0;
        for (i, &a) in self.rest_active.iter().enumerate() {
            if a {
                row_of[i] = row;
                row += 1;
            }
        }
        let region = self.tm.point_reactions();
        for (p, route) in self.point_pushes.iter_mut().zip(&self.point_routes) {
            *p =
                match *route {
                    PointRoute::Region(j) => region.get(j).copied().unwrap_or(0.0),
                    PointRoute::Rest(i) => {
                        let (k, r) = (&self.rest_cands[i], row_of[i] as usize);
                        match k.normal {
                            Some(n) if row_of[i] != NONE && 3 * r + 2 < z.nrows() => n.dot(
                                Vec3::new(z[(3 * r, 0)], z[(3 * r + 1, 0)], z[(3 * r + 2, 0)]),
                            ),
                            _ => 0.0,
                        }
                    }
                    PointRoute::Held => 0.0,
                };
        }
        self.reactions
            .distribute(|v| force.get(v as usize).copied().unwrap_or(Vec3::ZERO));
        self.contact_forces = z;
        Ok(())
    }

    /// The global tetrahedra a blade touches, at the current positions.
    fn touched(&self, blade: &CutPath) -> Vec<usize> {
        let quads = blade.triangles();
        let pts = [blade.start[0], blade.start[1], blade.end[0], blade.end[1]];
        let lo = pts.iter().fold(pts[0], |a, &b| a.min(b));
        let hi = pts.iter().fold(pts[0], |a, &b| a.max(b));
        (0..self.mesh.tets.len())
            .filter(|&t| {
                if !self.alive[t] {
                    return false;
                }
                let p = self.mesh.tets[t].map(|v| self.node_position(v));
                let pl = p[0].min(p[1]).min(p[2]).min(p[3]);
                let ph = p[0].max(p[1]).max(p[2]).max(p[3]);
                pl.cmple(hi).all()
                    && ph.cmpge(lo).all()
                    && quads
                        .iter()
                        .any(|q| crate::model::tensor_mass::cut::tet_meets_triangle(&p, q))
            })
            .collect()
    }

    /// The tetrahedra whose rest or current centroid is within `radius` of the surface the
    /// blade swept. The whole swept quad counts, not its edges: a fast blade sweeps a wide
    /// quad whose middle is far from every edge, and `touched` finds the tetrahedra it
    /// crosses there. The current centroid too, because `touched` meets the blade with the
    /// deformed tetrahedra: with the rest centroid alone, a liver pressed toward the blade by
    /// a probe brought tetrahedra the region had not grown over under it, and the cut was
    /// refused ("within one element of the region's border", `liver-hybrid-auto.toml` with
    /// a fine contact surface, at 0.57 s).
    fn near_blade(&self, blade: &CutPath, radius: Real) -> Vec<usize> {
        let swept = blade.triangles();
        let near = |c: Vec3| {
            swept
                .iter()
                .any(|&tri| (closest_point_on_triangle(c, tri) - c).length() <= radius)
        };
        (0..self.mesh.tets.len())
            .filter(|&t| {
                self.alive[t]
                    && (near(self.centroids[t]) || {
                        let now = self.mesh.tets[t]
                            .iter()
                            .map(|&v| self.node_position(v))
                            .sum::<Vec3>()
                            / 4.0;
                        near(now)
                    })
            })
            .collect()
    }

    /// Cuts inside the region; a blade that reaches outside it grows the region (automatic
    /// mode) or is refused, naming the region.
    pub(super) fn cut_along(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        blade.check()?;
        let auto = matches!(self.mode, CutRegion::Auto);
        if auto {
            // Ahead of the blade: grow before it reaches the border.
            let near = self.near_blade(blade, 0.5 * self.auto_radius);
            if near
                .iter()
                .any(|&t| !self.split.cuttable(&self.mesh.tets, t))
            {
                self.request_growth(blade)?;
            }
        }
        let touched = self.touched(blade);
        if let Some(&t) = touched
            .iter()
            .find(|&&t| !self.split.cuttable(&self.mesh.tets, t))
        {
            if !auto {
                return Err(self.refusal(t));
            }
            // The blade outran the growth: wait for it (the step waits, once).
            self.finish_growth()?;
            if let Some(&t) = self
                .touched(blade)
                .iter()
                .find(|&&t| !self.split.cuttable(&self.mesh.tets, t))
            {
                return Err(self.refusal(t));
            }
        }
        let tm_info = self.tm.cut(blade)?;
        if tm_info.removed_elements == 0 {
            return Ok(CutInfo {
                removed_elements: 0,
                added_vertices: 0,
                topology_version: self.topology_version,
            });
        }
        let removed: Vec<usize> = self.tm.last_cut().removed.clone();
        Ok(self.after_region_removal(&removed))
    }

    /// Marks the region model's removed tetrahedra dead globally, redraws the surface.
    fn after_region_removal(&mut self, removed: &[usize]) -> CutInfo {
        for &t in removed {
            let g = self.split.region.tets[t] as usize;
            self.alive[g] = false;
            if self.mesh.tets[g]
                .iter()
                .any(|&v| self.split.border[v as usize])
            {
                self.border_removals += 1;
            }
        }
        let before = self.surf_nodes.len();
        self.refresh_tm_vertices();
        self.rebuild_triangles();
        self.topology_version += 1;
        // Constraints name surface vertices, which keep their numbers; the region model's
        // surface grew, so its entries are re-derived.
        let c = self.constraints.clone();
        let normals = self.normals.clone();
        let _ = self.apply_constraints(&c, &normals);
        let _ = self.update_state();
        CutInfo {
            removed_elements: removed.len(),
            added_vertices: self.surf_nodes.len() - before,
            topology_version: self.topology_version,
        }
    }

    fn refusal(&self, t: usize) -> SimError {
        let place = if self.split.in_region[t] {
            "within one element of the region's border"
        } else {
            "outside the region"
        };
        let advice = match self.mode {
            CutRegion::Auto => "the region grows by auto_radius around the blade: raise it",
            CutRegion::Given(_) => "enlarge the region or use cut_region = \"auto\"",
        };
        SimError::Unsupported {
            model: "hybrid",
            operation: "cutting",
            reason: format!(
                "the blade reaches tetrahedron {t}, {place} (cut_region = {}); {advice}",
                self.mode.describe()
            ),
        }
    }

    /// The region grown around the blade: the current one plus every tetrahedron whose
    /// centroid is within `auto_radius` of it.
    fn grown_mask(&self, blade: &CutPath) -> Vec<bool> {
        let mut mask = self.split.in_region.clone();
        if let Some(g) = &self.growth {
            for (m, &p) in mask.iter_mut().zip(&g.mask) {
                *m |= p;
            }
        }
        for t in self.near_blade(blade, self.auto_radius + 2.5 * self.edge) {
            mask[t] = true;
        }
        mask
    }

    /// Starts a growth around the blade (in the background in real time, else now).
    fn request_growth(&mut self, blade: &CutPath) -> Result<(), SimError> {
        let mask = self.grown_mask(blade);
        if mask == self.split.in_region {
            return Ok(());
        }
        if let Some(g) = &self.growth
            && g.mask == mask
        {
            return Ok(());
        }
        if self.growth.is_some() {
            // One at a time: the next request (next step) asks again with the union.
            return Ok(());
        }
        self.growth = Some(Growth::start(
            self.mesh.clone(),
            mask,
            self.mode.clone(),
            self.recipe.clone(),
        ));
        if !self.real_time {
            self.finish_growth()?;
        }
        Ok(())
    }

    /// Installs a growth that finished; leaves one still running.
    fn poll_growth(&mut self) -> Result<(), SimError> {
        if let Some(g) = self.growth.as_mut()
            && let Some(built) = g.try_take()
        {
            let waited = g.steps_waited;
            self.growth = None;
            self.install(built?, waited)?;
        }
        Ok(())
    }

    /// Waits for the growth under way, if any, and installs it.
    pub(super) fn finish_growth(&mut self) -> Result<(), SimError> {
        if let Some(g) = self.growth.take() {
            let waited = g.steps_waited;
            let built = g.wait()?;
            self.install(built, waited)?;
        }
        Ok(())
    }

    /// Switches to a grown region: the new region model starts from the current positions
    /// and velocities (nodes new to it from the rest's displacement field), the cuts made so
    /// far are removed again, constraints and loads are re-split.
    fn install(&mut self, built: Built, steps_waited: u64) -> Result<(), SimError> {
        let u = self.interface_u();
        let rest_u = self.rest.node_displacements(&u)?;
        let n = self.mesh.vertices.len();
        let mut x: Vec<Vec3> = self.mesh.vertices.clone();
        let mut v = vec![Vec3::ZERO; n];
        for (l, &g) in self.split.rest.global.iter().enumerate() {
            x[g as usize] += rest_u[l];
        }
        for (l, &g) in self.split.region.global.iter().enumerate() {
            x[g as usize] = self.tm.positions()[l];
            v[g as usize] = self.tm.velocities()[l];
        }
        let Built {
            split,
            rest,
            mut tm,
            seconds,
        } = built;
        let dead: Vec<usize> = split
            .region
            .tets
            .iter()
            .enumerate()
            .filter(|&(_, &g)| !self.alive[g as usize])
            .map(|(l, _)| l)
            .collect();
        let xs: Vec<Vec3> = split.region.global.iter().map(|&g| x[g as usize]).collect();
        let vs: Vec<Vec3> = split.region.global.iter().map(|&g| v[g as usize]).collect();
        tm.set_state(&xs, &vs)?;
        if !dead.is_empty() {
            tm.remove_tets(&dead);
        }
        self.split = split;
        self.rest = rest;
        self.tm = tm;
        self.precompute_seconds += seconds;
        self.growths.push(GrowthRecord {
            seconds,
            region_tets: self.split.region.tets.len(),
            steps_waited,
        });
        self.adopt_split();
        self.topology_version += 1;
        let loads = self.loads.clone();
        self.set_loads_checked(&loads)?;
        let c = self.constraints.clone();
        let normals = self.normals.clone();
        self.apply_constraints(&c, &normals)?;
        self.update_state()?;
        self.measure_stability();
        self.notice_whole();
        Ok(())
    }

    /// Says once, through the progress handle, that the region now covers the organ.
    pub(super) fn notice_whole(&mut self) {
        if self.split.whole() && !self.whole_noticed {
            self.whole_noticed = true;
            self.progress.report(WHOLE_ORGAN_NOTICE, 1.0);
        }
    }

    /// Does the cut region cover every tetrahedron (the model is whole-organ tensor-mass)?
    pub fn is_whole_organ(&self) -> bool {
        self.split.whole()
    }

    /// The region's stability limit measured with the rest's interface stiffness (the
    /// region model measured itself alone when built).
    pub(super) fn measure_stability(&mut self) {
        let coupling = self
            .rest
            .coupling(&self.region_iface, &self.split.region.mesh.vertices);
        self.tm
            .measure_stability(self.rest.exists().then_some(&coupling as &dyn NodeCoupling));
    }

    /// Back to rest, uncut (the region stays as grown).
    pub(super) fn reset_state(&mut self) {
        self.finish_growth().ok();
        self.tm.reset();
        self.alive.iter_mut().for_each(|a| *a = true);
        self.refresh_tm_vertices();
        self.rebuild_triangles();
        self.topology_version += 1;
        let c = self.constraints.clone();
        let normals = self.normals.clone();
        let _ = self.apply_constraints(&c, &normals);
        let _ = self.update_state();
    }

    /// The moment about the origin of the rest's loads and contact forces (rest positions).
    #[cfg(test)]
    pub(super) fn rest_moment_of_loads_and_contacts(&self) -> Vec3 {
        self.rest.moment(&self.contact_forces)
    }

    /// The coupled stable step a cold measure (`iterations` power iterations from the
    /// fixed start vector) gives now; the model is unchanged.
    #[cfg(test)]
    pub(super) fn cold_stable_dt(&mut self, iterations: usize) -> Real {
        let coupling = self
            .rest
            .coupling(&self.region_iface, &self.split.region.mesh.vertices);
        let coupled = self.rest.exists().then_some(&coupling as &dyn NodeCoupling);
        self.tm.cold_stable_dt(coupled, iterations)
    }

    #[cfg(test)]
    pub(super) fn rest_contacts(&self) -> usize {
        self.rest_contact.len()
    }

    #[cfg(test)]
    pub(super) fn region_iface_nodes(&self) -> Vec<u32> {
        self.region_iface.clone()
    }

    /// Whether a growth is being built.
    pub fn growth_pending(&self) -> bool {
        self.growth.is_some()
    }

    pub(super) fn memory_bytes(&self) -> usize {
        self.tm.info().memory_bytes
            + self.rest.memory_bytes()
            + self.mesh.tets.len() * (16 + 16 + 24 + 1)
            + self.surf_nodes.len() * (4 + 48)
    }
}

/// The outer slots a rest contact's site names.
fn outer_slots(site: &Site) -> impl Iterator<Item = u32> + '_ {
    site.outer_terms().map(|(s, _)| s)
}
