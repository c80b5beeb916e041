//! Sphere contact against the deformed surface: which vertices are inside an instrument's
//! ball, where they go (radially onto the sphere), and whether a contact force is adhesive.
//!
//! Contact is vertex-based, as in the survey's prescribed-position view: a touched vertex
//! becomes a prescribed vertex, and the model returns the force it needs there.

use crate::interact::bvh::Bvh;
use crate::interact::shape::{Closest, Shape};
use crate::math::{Real, Vec3, triangle_area_vector};

/// Relative slack of "inside": a vertex counts as penetrating when it is deeper than
/// `PENETRATION_TOLERANCE · radius`, so vertices left exactly on the sphere by the previous
/// solve (up to rounding) are not re-detected.
pub const PENETRATION_TOLERANCE: Real = 1e-9;

/// A vertex in contact and the position it is held at, in m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    pub vertex: u32,
    pub target: Vec3,
    /// `Some(n)`: held by a face contact (a point of the fine surface tied to a face of this
    /// vertex touches the instrument, `hold_points`): the target is off the instrument's
    /// surface, where it keeps that point on it, and `n` is the instrument's outward normal
    /// there (toward the tissue). `None`: the target is on the instrument's surface.
    pub face: Option<Vec3>,
}

impl Contact {
    /// A contact whose target lies on the instrument's surface.
    pub fn on_surface(vertex: u32, target: Vec3) -> Self {
        Self {
            vertex,
            target,
            face: None,
        }
    }

    /// The instrument's outward normal at this contact (`shape` placed at `at`).
    pub fn normal(&self, shape: &Shape, at: Vec3) -> Vec3 {
        self.face
            .unwrap_or_else(|| shape.closest(at, self.target, Vec3::ZERO).normal)
    }
}

/// Barycentric weights of `q` (a point of the triangle's plane) in triangle `[a, b, c]`;
/// the vertex nearest `q` for a degenerate triangle.
pub fn barycentric(q: Vec3, [a, b, c]: [Vec3; 3]) -> [Real; 3] {
    let (e0, e1, e2) = (b - a, c - a, q - a);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (e2.dot(e0), e2.dot(e1));
    let den = d00 * d11 - d01 * d01;
    if den.abs() <= 1e-24 * (d00 * d11).max(Real::MIN_POSITIVE) {
        let d = [q.distance(a), q.distance(b), q.distance(c)];
        let i = (0..3).fold(0, |m, i| if d[i] < d[m] { i } else { m });
        let mut w = [0.0; 3];
        w[i] = 1.0;
        return w;
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    [1.0 - v - w, v, w]
}

/// Moves the movable vertices of face `tri` (held at `y`, `index` into `contacts`) so that
/// its point of weights `w` goes `push` along `n`: Δᵢ = wᵢ push n / Σ w² over the movable
/// ones, the least move that does it. They become face contacts with normal `n` (averaged
/// with the one they had). Returns the largest move.
#[allow(clippy::too_many_arguments)]
fn push_face(
    contacts: &mut Vec<Contact>,
    tri: [u32; 3],
    w: [Real; 3],
    movable: [bool; 3],
    index: [Option<usize>; 3],
    y: [Vec3; 3],
    n: Vec3,
    push: Real,
) -> Real {
    let norm: Real = (0..3).filter(|&i| movable[i]).map(|i| w[i] * w[i]).sum();
    if norm <= 1e-12 {
        return 0.0;
    }
    let mut largest: Real = 0.0;
    for i in (0..3).filter(|&i| movable[i]) {
        let delta = (w[i] * push / norm) * n;
        largest = largest.max(delta.length());
        match index[i] {
            Some(j) => {
                let k = &mut contacts[j];
                k.target = y[i] + delta;
                k.face = Some(match k.face {
                    Some(m) => (m + n).normalize_or(n),
                    None => n,
                });
            }
            None => {
                // Two slots of one face can name the same vertex only in a broken face.
                if contacts.iter().any(|k| k.vertex == tri[i]) {
                    continue;
                }
                contacts.push(Contact {
                    vertex: tri[i],
                    target: y[i] + delta,
                    face: Some(n),
                });
            }
        }
    }
    largest
}

/// What `hold_points` needs to know of a model whose contacts only push
/// (`Deformable::contacts_push_only`): its face planes are held in its step, so a plane
/// placed in front of its vertex is a velocity the step must give the vertex, and its
/// reaction is reported in full.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PushOnly {
    /// How far outside the instrument (m) the free vertices of fine points are handed over
    /// as planes behind them (`hand_over_near_faces`).
    pub margin: Real,
    /// Where the instrument was at the step's start (the last step's end): a fine point
    /// already inside it there is a penetration the last step left, not this step's motion
    /// (`owed_depth`).
    pub from: Vec3,
    /// How much of such a penetration the step may take back (m): the instrument's move in
    /// the step, at least `RECOVERY_SPEED` times the step (`recovery`).
    pub recover: Real,
}

/// The least speed (m/s) at which a push-only model's tissue is taken back out of an
/// instrument it was found inside at a step's start (`owed_depth`): 10 mm/s, a probe's
/// ordinary speed (the demo's). A faster instrument takes it back at its own speed. Without
/// a floor a still instrument kept what it owed for good: a probe held on a block settled
/// 0.4 % off the static answer (`tests/hybrid_points.rs`, 1.6e-5 with the floor).
pub const RECOVERY_SPEED: Real = 0.01;

/// The depth a step of `dt` s may take back of a penetration it starts with (m), the
/// instrument moved from `from` to `at` (`PushOnly::recover`).
pub fn recovery(from: Vec3, at: Vec3, dt: Real) -> Real {
    at.distance(from).max(RECOVERY_SPEED * dt)
}

/// Contact on a fine surface mapped onto the model's surface (`MappedSurface`): every
/// fine vertex inside the instrument (any shape) is pushed out to its surface along its
/// normal there, through the three coarse vertices it is tied to, by `push_face`'s least
/// move, in a few Gauss–Seidel sweeps. `contacts` are this instrument's; their vertices move
/// with the fine points and become face contacts, free coarse vertices (`skip(v)` false)
/// are added. A fine vertex all of whose movable coarse vertices satisfy `kept` is held at
/// any depth up to the tolerance (resting on the instrument). With `push_only` (a model
/// whose contacts only push), the free vertices of the fine points outside the instrument
/// by less than its margin are handed over too (`hand_over_near_faces`), a vertex in front
/// of its plane counts where it is (free there, not on the plane), and a point already
/// inside the instrument at the step's start is pushed out only as fast as the instrument
/// moves (`owed_depth`). Returns the largest move, m.
#[allow(clippy::too_many_arguments)]
pub fn hold_points(
    fine: &crate::interact::fine_surface::MappedSurface,
    coarse_rest: &[Vec3],
    positions: &[Vec3],
    shape: &Shape,
    at: Vec3,
    contacts: &mut Vec<Contact>,
    skip: &dyn Fn(u32) -> bool,
    kept: &dyn Fn(u32) -> bool,
    push_only: Option<PushOnly>,
) -> Real {
    let tolerance = PENETRATION_TOLERANCE * shape.size();
    let mut now = Vec::new();
    fine.positions(coarse_rest, positions, &mut now);
    // Candidates: the fine vertices near the instrument now (targets move them by less
    // than the instrument's size).
    let near: Vec<usize> = match shape.bounds(at) {
        Some((c, r)) => (0..now.len())
            .filter(|&j| now[j].distance(c) <= 2.0 * r)
            .collect(),
        None => (0..now.len()).collect(),
    };
    // The tissue's outward normals, formed the first time a point penetrates (most steps
    // have none, and they cost a pass over the whole fine surface).
    let mut outward: Option<Vec<Vec3>> = None;
    let mut largest: Real = 0.0;
    for _sweep in 0..4 {
        let mut moved = false;
        for &j in &near {
            let Some((tri, w)) = fine.tie(j) else {
                continue;
            };
            if tri.iter().any(|&v| positions.get(v as usize).is_none())
                || tri.iter().any(|&v| coarse_rest.get(v as usize).is_none())
            {
                continue;
            }
            let index = tri.map(|v| contacts.iter().position(|k| k.vertex == v));
            // A free vertex the point does not follow (weight 0: the point lies on the
            // opposite edge, as every vertex and edge point of a flat-subdivided surface
            // does) takes no part in it. Where contacts only push, handed its plane (through
            // itself, the least move giving it none), it was held where it stood: vertices
            // 7 mm from the probe stopped the pressed liver from coming back to it.
            let movable = [0, 1, 2].map(|i| {
                index[i].is_some() || (!skip(tri[i]) && (push_only.is_none() || w[i] > 0.0))
            });
            if !movable.iter().any(|&m| m) {
                continue;
            }
            // Where each vertex is held: a held one on its target's plane across its face
            // normal, where the last solve let it slide (a vertex held in full is at its
            // target, so this is its target); a free one where it is. Where contacts only
            // push, a vertex in front of its plane is free and stays where it is: read on
            // its plane (a carried plane drawn back 3 to 9 mm behind it), a fine point 4 mm
            // outside the probe counted 4.6 mm inside it, and the push that put it out set
            // a free vertex's plane 0.4 mm in front of it (the liver's 0.385 N one-step
            // spike at 0.707 s under implicit Euler at 1 ms).
            let y = [0, 1, 2].map(|i| {
                let p = positions[tri[i] as usize];
                match index[i].map(|k| &contacts[k]) {
                    Some(Contact {
                        target,
                        face: Some(n),
                        ..
                    }) => {
                        let past = n.dot(*target - p);
                        p + *n
                            * if push_only.is_some() {
                                past.max(0.0)
                            } else {
                                past
                            }
                    }
                    Some(k) => k.target,
                    None => p,
                }
            });
            let p = fine.rest[j]
                + (0..3)
                    .map(|i| w[i] * (y[i] - coarse_rest[tri[i] as usize]))
                    .sum::<Vec3>();
            let mut closest = shape.closest(at, p, Vec3::ZERO);
            let resting = (0..3).all(|i| !movable[i] || kept(tri[i]));
            let limit = if resting { tolerance } else { -tolerance };
            if closest.depth >= limit {
                continue;
            }
            // A point the instrument's nearest surface would push out of the tissue (its
            // normal along the tissue's outward one: the instrument arrived deeper than its
            // centre, a jump of the viewer's probe) leaves along the tissue's inward
            // normal instead. Pushed out over the top, the liver wrapped round the probe and
            // pushed it down.
            if let Some(&outward) = outward
                .get_or_insert_with(|| outward_normals(&now, &fine.triangles))
                .get(j)
                && passed_to_far_side(shape, &closest, outward)
            {
                closest = exit_along(shape, at, p, -outward);
            }
            let push = -closest.depth
                - push_only.map_or(0.0, |o| owed_depth(shape, o.from, now[j], o.recover));
            if push <= tolerance {
                // Inside, but owed less than the step gives back: its free vertices are
                // handed over with planes behind them, where the point reaches the depth
                // still owed (held ones keep theirs).
                let free = [0, 1, 2].map(|i| movable[i] && index[i].is_none());
                push_face(contacts, tri, w, free, index, y, closest.normal, push);
                continue;
            }
            let m = push_face(contacts, tri, w, movable, index, y, closest.normal, push);
            largest = largest.max(m);
            moved |= m > tolerance;
        }
        if !moved {
            break;
        }
    }
    if let Some(PushOnly { margin, .. }) = push_only {
        hand_over_near_faces(fine, &now, positions, shape, at, contacts, skip, margin);
    }
    contacts.sort_unstable_by_key(|k| k.vertex);
    largest
}

/// How deep a fine point at `q` (where the last step left it) may still be inside `shape`
/// at the end of this step, for a model whose contacts only push: the depth it already had
/// with the instrument where the step starts (`from`), less `recover` (`recovery`: the
/// instrument's move in the step, at least `RECOVERY_SPEED` times the step). Zero for a
/// point that was outside.
///
/// Such a penetration is the last step's, not this step's motion: the instrument starts
/// inside the tissue (the demo's probe starts 0.4 mm into the smooth liver), or the point
/// passed its plane unseen. Pushed out in one step, its plane starts in front of its vertex,
/// the step must give the vertex that whole move as velocity, and an implicit step reports
/// the reaction in full (the liver's 0.137 N first step at 1 ms, against 0.02 N after).
/// So the plane goes through where the point is, moves with the instrument from there,
/// and takes back the owed depth no faster than the instrument moves (or `RECOVERY_SPEED`):
/// the force it costs is that of a surface met at such a speed, and it is counted, not
/// hidden.
pub fn owed_depth(shape: &Shape, from: Vec3, q: Vec3, recover: Real) -> Real {
    let before = -shape.closest(from, q, Vec3::ZERO).depth;
    (before - recover).max(0.0)
}

/// Per vertex of a closed triangle surface, its unit normal pointing out of the enclosed
/// volume (area-weighted over its triangles; the file's orientation is read from the sign of
/// the enclosed volume). Zero for an unused vertex.
pub(crate) fn outward_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; positions.len()];
    let mut volume: Real = 0.0;
    for t in triangles {
        let Some(x) = corners(positions, t) else {
            continue;
        };
        volume += x[0].dot(x[1].cross(x[2]));
        let area = triangle_area_vector(x[0], x[1], x[2]);
        for &v in t {
            normals[v as usize] += area;
        }
    }
    let sign = if volume < 0.0 { -1.0 } else { 1.0 };
    normals
        .iter()
        .map(|n| sign * n.normalize_or_zero())
        .collect()
}

/// The three corners of triangle `t`, if its indices are in range.
fn corners(positions: &[Vec3], t: &[u32; 3]) -> Option<[Vec3; 3]> {
    Some([
        *positions.get(t[0] as usize)?,
        *positions.get(t[1] as usize)?,
        *positions.get(t[2] as usize)?,
    ])
}

/// Whether a point of the tissue (its outward unit normal `outward`) inside `shape`, whose
/// nearest way out of the shape is along `push`, is on the shape's far side: the instrument
/// came through the tissue's surface there (a jump of the viewer's probe past its centre),
/// and the nearest way out would push the tissue out of itself. It then leaves along the
/// tissue's inward normal instead (`exit_along`).
///
/// A curved shape's normal turns continuously, so crossing the tissue's tangent plane
/// (`push · outward > 0`) marks its far half. A flat face's normal is one for the whole
/// face: a side face of the tissue slipping under a box's bottom (its outward normal across
/// the push, tilted a little either way as the tissue bulges) is plain contact, so a box
/// counts as passed through only where the face turns toward the tissue's outside by more
/// than `FACE_THROUGH_COS`. A half-space has no far side. Sending such side points through
/// the box to its far side gave a wide box pressed on a block 20 % more force than the
/// plane it equals there.
pub(crate) fn on_far_side(shape: &Shape, push: Vec3, outward: Vec3) -> bool {
    match shape {
        Shape::Plane { .. } => false,
        Shape::Box { .. } => push.dot(outward) > FACE_THROUGH_COS,
        Shape::Sphere { .. } | Shape::Capsule { .. } => push.dot(outward) > 0.0,
    }
}

/// `on_far_side` for a point of the tissue at `closest` inside `shape` (its outward unit
/// normal `outward`), except where a curved instrument has only just reached it: less than
/// `SHALLOW` of the radius inside, a ball or capsule touches the tissue where it meets it,
/// whatever the tissue's normal there says (the rule `push_out` keeps for vertices). A
/// surface folded under the instrument turns its normal inward: the comparison's deep probe
/// on `volumetric-spring-mass` (a spring lattice, whose tetrahedra under it invert) at
/// k = 3 met fine points 0.1 mm inside on a fold, and their exit along the tissue's inward
/// normal, 45 mm through the 24.7 mm probe, moved a particle 163 mm in one substep: the
/// run diverged. A box's flat face keeps `on_far_side`'s own rule.
pub(crate) fn passed_to_far_side(shape: &Shape, closest: &Closest, outward: Vec3) -> bool {
    let curved = matches!(shape, Shape::Sphere { .. } | Shape::Capsule { .. });
    if curved && -closest.depth < SHALLOW * shape.size() {
        return false;
    }
    on_far_side(shape, closest.normal, outward)
}

/// The depth, as a fraction of a curved instrument's radius, within which the instrument has
/// only just reached a point of the tissue and pushes it the nearest way out, whatever the
/// tissue's normal there (`push_out`, `passed_to_far_side`).
const SHALLOW: Real = 0.25;

/// cos 60°: a box face within 60° of the tissue's outward normal pushes the tissue out of
/// itself (`on_far_side`).
const FACE_THROUGH_COS: Real = 0.5;

/// Where a point `p` inside `shape` (at `at`) leaves it moving along the unit direction
/// `d`: the contact there as `Shape::closest` gives one (depth minus the way to go, normal
/// `d`), found by bisection on the signed distance (any shape).
pub(crate) fn exit_along(shape: &Shape, at: Vec3, p: Vec3, d: Vec3) -> Closest {
    let mut hi = 2.0 * shape.size() - shape.closest(at, p, Vec3::ZERO).depth;
    for _ in 0..8 {
        if shape.closest(at, p + hi * d, Vec3::ZERO).depth >= 0.0 {
            break;
        }
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..48 {
        let mid = 0.5 * (lo + hi);
        if shape.closest(at, p + mid * d, Vec3::ZERO).depth >= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Closest {
        depth: -hi,
        normal: d,
        point: p + hi * d,
    }
}

/// For a model whose contacts only push (`Deformable::contacts_push_only`): the free coarse
/// vertices of the fine points outside the instrument by less than `margin` become face
/// contacts whose planes lie where the point would touch (behind the vertex: free until it
/// gets there), so the model settles them within its step instead of finding them a step
/// late and deep (the vertex contacts' `sim::CONTACT_MARGIN`). The nearest points go first,
/// and a vertex already held keeps its plane (the more demanding one). `now`: the fine
/// vertices where the coarse `positions` put them (`hold_points` has them).
///
/// Only the vertices a point follows by more than `SETTLE_WEIGHT` are handed over, each
/// plane as far behind its vertex as the point is from the instrument (where the point
/// touches if its face moves whole; `settle_carried_faces` draws a plane back so too). The
/// least move's share, wᵢ·gap/Σw², put the plane of a vertex of weight 0 (every corner and
/// edge point of a flat-subdivided surface has one) through the vertex: held where it
/// stood, 7 mm from the probe, it kept `linked-volumes`' liver off the probe.
#[allow(clippy::too_many_arguments)]
fn hand_over_near_faces(
    fine: &crate::interact::fine_surface::MappedSurface,
    now: &[Vec3],
    positions: &[Vec3],
    shape: &Shape,
    at: Vec3,
    contacts: &mut Vec<Contact>,
    skip: &dyn Fn(u32) -> bool,
    margin: Real,
) {
    let reach = shape.bounds(at);
    let mut near: Vec<(Real, usize, Vec3)> = now
        .iter()
        .enumerate()
        .filter(|(_, q)| reach.is_none_or(|(c, r)| q.distance(c) <= r + margin))
        .filter_map(|(j, q)| {
            let closest = shape.closest(at, *q, Vec3::ZERO);
            (closest.depth >= 0.0 && closest.depth <= margin).then_some((
                closest.depth,
                j,
                closest.normal,
            ))
        })
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (gap, j, n) in near {
        let Some((tri, w)) = fine.tie(j) else {
            continue;
        };
        if tri.iter().any(|&v| positions.get(v as usize).is_none()) {
            continue;
        }
        for (&v, &wv) in tri.iter().zip(&w) {
            if wv <= SETTLE_WEIGHT || skip(v) || contacts.iter().any(|k| k.vertex == v) {
                continue;
            }
            contacts.push(Contact {
                vertex: v,
                target: positions[v as usize] - gap * n,
                face: Some(n),
            });
        }
    }
}

/// Fine vertices tied to a coarse vertex by less than this weight do not decide how far
/// `settle_carried_faces` draws it back (they hang on the other vertices of their face).
const SETTLE_WEIGHT: Real = 0.1;

/// Face contacts carried into a new step with their instrument (`contacts`, this
/// instrument's, sorted by vertex; targets moved along their normals) for a model whose
/// contacts only push: each plane is drawn back along its normal by the least gap between
/// the instrument and the fine vertices tied to it (by a weight above `SETTLE_WEIGHT`), so
/// that the nearest of them would touch again if its face moved back whole; never pushed
/// forward here (`hold_points` pushes out what penetrates). A plane behind its vertex holds
/// nothing until the vertex gets there, so drawing back never pulls. A carried contact none
/// of whose fine points is near the instrument is dropped. Without this the planes of faces
/// that slid off the probe's flank were carried on into the tissue (the dynamic liver
/// pushed back 0.119–0.125 N where the static one pushes 0.096 N); drawn back by gap / w
/// instead of the gap, the faces overshot and chattered (0.30 N jumps on fem-explicit).
pub fn settle_carried_faces(
    fine: &crate::interact::fine_surface::MappedSurface,
    coarse_rest: &[Vec3],
    positions: &[Vec3],
    shape: &Shape,
    at: Vec3,
    contacts: &mut Vec<Contact>,
) {
    // The fine surface with every carried vertex on its plane.
    let mut held = positions.to_vec();
    for k in contacts.iter() {
        if let (Some(n), Some(p)) = (k.face, held.get_mut(k.vertex as usize)) {
            *p += n * n.dot(k.target - *p);
        }
    }
    let mut now = Vec::new();
    fine.positions(coarse_rest, &held, &mut now);
    let reach = shape.bounds(at);
    let mut draw: Vec<Option<Real>> = vec![None; contacts.len()];
    for (j, q) in now.iter().enumerate() {
        if reach.is_some_and(|(c, r)| q.distance(c) > 2.0 * r) {
            continue;
        }
        let Some((tri, w)) = fine.tie(j) else {
            continue;
        };
        let gap = shape.closest(at, *q, Vec3::ZERO).depth;
        for i in 0..3 {
            if w[i] <= SETTLE_WEIGHT {
                continue;
            }
            let Ok(k) = contacts.binary_search_by_key(&tri[i], |k| k.vertex) else {
                continue;
            };
            if contacts[k].face.is_some() {
                let d = gap;
                draw[k] = Some(draw[k].map_or(d, |m: Real| m.min(d)));
            }
        }
    }
    let size = shape.size();
    let mut k = 0;
    contacts.retain_mut(|c| {
        let d = draw.get(k).copied().flatten();
        k += 1;
        match (c.face, d) {
            (None, _) => true,
            (Some(_), None) => false,
            (Some(n), Some(d)) => {
                c.target -= n * d.clamp(0.0, size);
                true
            }
        }
    });
}

/// The point of the sphere (center, radius) radially outward from `p`; a vertex at the
/// center goes along `fallback` (its normal), or +z when that is zero too.
pub fn project_to_sphere(p: Vec3, center: Vec3, radius: Real, fallback: Vec3) -> Vec3 {
    let d = p - center;
    let dir = if d.length() > 1e-300 {
        d.normalize()
    } else if fallback.length() > 0.0 {
        fallback.normalize()
    } else {
        Vec3::Z
    };
    center + radius * dir
}

/// The vertices of the `candidates` triangles whose position passes `inside`, ascending,
/// each once, without those `skip` leaves out.
fn vertices_of(
    candidates: &[u32],
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    skip: &dyn Fn(u32) -> bool,
    inside: impl Fn(Vec3) -> bool,
) -> Vec<u32> {
    let mut found: Vec<u32> = candidates
        .iter()
        .filter_map(|&t| triangles.get(t as usize))
        .flatten()
        .copied()
        .filter(|&v| positions.get(v as usize).is_some_and(|&p| inside(p)))
        .collect();
    found.sort_unstable();
    found.dedup();
    found.retain(|&v| !skip(v));
    found
}

/// Surface vertices deeper than the tolerance inside the ball, ascending, with their
/// targets on the sphere. `skip(v)` leaves out vertices that are taken (fixed, other tools).
pub fn vertices_in_ball(
    bvh: &Bvh,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    center: Vec3,
    radius: Real,
    skip: &dyn Fn(u32) -> bool,
) -> Vec<Contact> {
    let candidates = bvh.query_sphere(center, radius);
    let limit = radius * (1.0 - PENETRATION_TOLERANCE);
    vertices_of(&candidates, positions, triangles, skip, |p| {
        p.distance(center) < limit
    })
    .into_iter()
    .map(|v| {
        let p = positions[v as usize];
        // Its triangles are all among the candidates: the vertex lies inside the query box.
        let normal = vertex_normal(v, &candidates, positions, triangles);
        Contact::on_surface(v, push_out(p, center, radius, normal))
    })
    .collect()
}

/// Surface vertices deeper than the tolerance inside `shape` placed at `at`, ascending, with
/// their targets on its surface (the sphere keeps `vertices_in_ball`'s rule for a centre that
/// went past a vertex). `skip(v)` leaves out vertices that are taken.
pub fn vertices_in_shape(
    bvh: &Bvh,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    shape: &Shape,
    at: Vec3,
    skip: &dyn Fn(u32) -> bool,
) -> Vec<Contact> {
    if let Shape::Sphere { radius } = *shape {
        return vertices_in_ball(bvh, positions, triangles, at, radius, skip);
    }
    let candidates: Vec<u32> = match shape.bounds(at) {
        Some((c, r)) => bvh.query_sphere(c, r),
        None => (0..triangles.len() as u32).collect(),
    };
    let limit = -PENETRATION_TOLERANCE * shape.size();
    vertices_of(&candidates, positions, triangles, skip, |p| {
        shape.closest(at, p, Vec3::ZERO).depth < limit
    })
    .into_iter()
    .map(|v| {
        let normal = vertex_normal(v, &candidates, positions, triangles);
        Contact::on_surface(v, shape.closest(at, positions[v as usize], normal).point)
    })
    .collect()
}

/// Surface vertices outside `shape` placed at `at` by less than `margin` (or inside it),
/// ascending, with their targets at its nearest point: the contacts a dynamic model holds
/// as pushes only (`integrate::Hold::contact`), free until they touch within a substep, so
/// that a vertex reaching the instrument mid-step is stopped there instead of found inside
/// at the next step and thrown out. `skip(v)` leaves out vertices that are taken.
pub fn vertices_near_shape(
    bvh: &Bvh,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    shape: &Shape,
    at: Vec3,
    margin: Real,
    skip: &dyn Fn(u32) -> bool,
) -> Vec<Contact> {
    let candidates: Vec<u32> = match shape.bounds(at) {
        Some((c, r)) => bvh.query_sphere(c, r + margin),
        None => (0..triangles.len() as u32).collect(),
    };
    vertices_of(&candidates, positions, triangles, skip, |p| {
        shape.closest(at, p, Vec3::ZERO).depth < margin
    })
    .into_iter()
    .map(|v| {
        let normal = vertex_normal(v, &candidates, positions, triangles);
        Contact::on_surface(v, shape.closest(at, positions[v as usize], normal).point)
    })
    .collect()
}

/// True when the force the tissue exerts on the instrument at a contact on its surface (with
/// outward `normal` there) pulls the instrument toward the tissue: adhesion. Forces below
/// `1e-9 · scale` (the instrument's largest contact force) in that direction are rounding.
pub fn pulls(reaction: Vec3, normal: Vec3, scale: Real) -> bool {
    reaction.dot(normal) > 1e-9 * scale
}

/// Where a vertex inside the ball goes. Radially out while the tool is on the outer side of
/// the surface; but when the centre has gone past the vertex (a coarse surface lets the ball
/// slip between vertices, or a vertex springs back behind it), radial projection would put
/// the vertex on the far side of the ball and the tissue would hold the tool from behind.
/// Then the vertex is pushed inward along its normal to the ball's inner side instead.
/// A vertex less than `SHALLOW` of the radius inside is where the ball has just reached it,
/// whatever its normal says, and goes radially out (a small move): a ball wider than a thin
/// lobe touches the lobe's far side from within, and the inner side sent that vertex 42 mm
/// through the tissue in one step (`hybrid` on compare's random path 0).
fn push_out(p: Vec3, center: Vec3, radius: Real, normal: Vec3) -> Vec3 {
    let n = normal.normalize_or_zero();
    let d = p - center;
    let along = d.dot(n);
    if n == Vec3::ZERO || along <= 0.0 || d.length() >= (1.0 - SHALLOW) * radius {
        return project_to_sphere(p, center, radius, normal);
    }
    // p − t·n on the sphere, the far root: t = d·n + sqrt((d·n)² − |d|² + r²).
    let t = along
        + (along * along - d.length_squared() + radius * radius)
            .max(0.0)
            .sqrt();
    p - t * n
}

/// Area-weighted normal of vertex `v` from the listed triangles that use it.
fn vertex_normal(v: u32, tris: &[u32], positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec3 {
    tris.iter()
        .filter_map(|&t| triangles.get(t as usize))
        .filter(|tri| tri.contains(&v))
        .filter_map(|tri| {
            let [a, b, c] = tri.map(|i| positions.get(i as usize).copied());
            Some(triangle_area_vector(a?, b?, c?))
        })
        .sum()
}

/// True when the force the tissue exerts on the instrument at a contact pulls the instrument
/// toward the contact point, i.e. the tissue sticks to it instead of pushing it away.
/// `scale` is the largest contact force of the instrument: forces below `1e-9 · scale` in
/// that direction are rounding, not adhesion.
pub fn is_adhesive(reaction: Vec3, target: Vec3, center: Vec3, scale: Real) -> bool {
    let n = (target - center).normalize_or_zero();
    reaction.dot(n) > 1e-9 * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vertex_behind_the_centre_goes_to_the_inner_side() {
        // Surface normal +y; the ball's centre is 2 mm below the vertex (it went through).
        let (c, r) = (Vec3::ZERO, 0.005);
        let p = Vec3::new(0.001, 0.002, 0.0);
        let q = push_out(p, c, r, Vec3::Y);
        assert!((q.distance(c) - r).abs() < 1e-15);
        assert!(q.y < 0.0 && (q.x - p.x).abs() < 1e-18, "{q}");
        // In front of the centre: plain radial projection.
        let p = Vec3::new(0.001, -0.002, 0.0);
        assert_eq!(
            push_out(p, c, r, Vec3::Y),
            project_to_sphere(p, c, r, Vec3::Y)
        );
        // Behind it but barely inside (0.1 mm of 5 mm): the nearest point of the sphere.
        let p = Vec3::new(0.0, 0.0049, 0.0);
        assert_eq!(
            push_out(p, c, r, Vec3::Y),
            project_to_sphere(p, c, r, Vec3::Y)
        );
    }

    /// One coarse triangle at z = 0 as its own fine surface (its three corners, weights 1),
    /// under a flat instrument coming down (solid above its plane, normal −z). Returns the
    /// corners and the surface.
    fn flat_triangle() -> (
        Vec<Vec3>,
        [[u32; 3]; 1],
        crate::interact::fine_surface::MappedSurface,
    ) {
        let rest = vec![
            Vec3::ZERO,
            Vec3::new(0.01, 0.0, 0.0),
            Vec3::new(0.0, 0.01, 0.0),
        ];
        let tris = [[0, 1, 2]];
        let fine = crate::interact::fine_surface::MappedSurface::subdivided(&rest, &tris, 1)
            .expect("a triangle");
        (rest, tris, fine)
    }

    /// How far each vertex's plane lies in front of it (+: the vertex is past it), along +z.
    fn ahead(contacts: &[Contact], positions: &[Vec3]) -> Vec<Real> {
        contacts
            .iter()
            .map(|k| {
                let n = k.face.expect("a face contact");
                n.dot(k.target - positions[k.vertex as usize])
            })
            .collect()
    }

    /// The instrument starts the step 0.4 mm into the tissue and moves 10 µm further: a
    /// model whose contacts only push gets planes 20 µm in front of its vertices (the
    /// step's move, and as much of the owed depth again), not the 0.41 mm a static model's
    /// active set takes in one solve; with nothing to take back, planes through them.
    #[test]
    fn a_penetration_the_step_starts_with_is_taken_back_no_faster_than_the_instrument() {
        let (rest, _, fine) = flat_triangle();
        let plane = Shape::Plane { normal: -Vec3::Z };
        let from = Vec3::new(0.0, 0.0, -0.4e-3);
        let at = from - Vec3::Z * 1e-5;
        let hold = |push_only: Option<PushOnly>, at: Vec3| {
            let mut contacts = Vec::new();
            hold_points(
                &fine,
                &rest,
                &rest,
                &plane,
                at,
                &mut contacts,
                &|_| false,
                &|_| false,
                push_only,
            );
            ahead(&contacts, &rest)
        };
        // A 1 ms step: the move (10 µm) is RECOVERY_SPEED's.
        let recover = recovery(from, at, 1e-3);
        assert!((recover - 1e-5).abs() < 1e-15);
        let push_only = |recover| {
            Some(PushOnly {
                margin: 1e-4,
                from,
                recover,
            })
        };
        for a in hold(push_only(recover), at) {
            assert!((a - 2e-5).abs() < 1e-12, "{a}");
        }
        for a in hold(push_only(0.0), from) {
            assert!(a.abs() < 1e-12, "{a}");
        }
        for a in hold(None, at) {
            assert!((a - 4.1e-4).abs() < 1e-12, "{a}");
        }
        assert!((owed_depth(&plane, from, Vec3::ZERO, recover) - 3.9e-4).abs() < 1e-15);
        assert_eq!(owed_depth(&plane, from, Vec3::Z * -1e-3, recover), 0.0);
        // A still instrument takes it back at RECOVERY_SPEED.
        assert!((recovery(from, from, 2e-3) - 2e-5).abs() < 1e-15);
    }

    /// A vertex whose plane (carried, drawn back) lies 3 mm behind it is free where it is:
    /// its fine point, 1 mm outside the instrument, is not read as 2 mm inside it, and no
    /// plane is set in front of any vertex. A static model's vertex is read on its plane.
    #[test]
    fn a_vertex_in_front_of_its_plane_counts_where_it_is() {
        let (rest, _, fine) = flat_triangle();
        let plane = Shape::Plane { normal: -Vec3::Z };
        let at = Vec3::new(0.0, 0.0, 1e-3);
        let behind = |v: u32| Contact {
            vertex: v,
            target: rest[v as usize] + Vec3::Z * 3e-3,
            face: Some(-Vec3::Z),
        };
        let start = vec![behind(0), behind(1), behind(2)];
        let push_only = Some(PushOnly {
            margin: 1e-4,
            from: at,
            recover: 0.0,
        });
        let mut contacts = start.clone();
        let moved = hold_points(
            &fine,
            &rest,
            &rest,
            &plane,
            at,
            &mut contacts,
            &|_| false,
            &|_| false,
            push_only,
        );
        assert_eq!((moved, &contacts), (0.0, &start));
        let mut contacts = start.clone();
        hold_points(
            &fine,
            &rest,
            &rest,
            &plane,
            at,
            &mut contacts,
            &|_| false,
            &|_| false,
            None,
        );
        assert!(
            ahead(&contacts, &rest)
                .iter()
                .all(|a| (a + 1e-3).abs() < 1e-12)
        );
    }

    /// A fine point on a coarse vertex (weights 1, 0, 0, as every corner and edge point of
    /// a flat-subdivided surface has a zero weight) near a probe: where contacts only push,
    /// that vertex alone is handed over, its plane as far behind it as the point is from the
    /// probe; the other two, which the point does not follow, get no plane (before, planes
    /// through themselves: held where they stood, 7 mm from the probe on the liver), whether
    /// the point is near the probe or inside it. A static model's active set still takes
    /// the whole face of a point inside.
    #[test]
    fn a_vertex_a_fine_point_does_not_follow_gets_no_plane_from_it() {
        let (rest, _, fine) = flat_triangle();
        let r = 0.05;
        let probe = Shape::Sphere { radius: r };
        let push_only = |at| {
            Some(PushOnly {
                margin: 3e-4,
                from: at,
                recover: 1.0,
            })
        };
        let hold = |at: Vec3, push_only: Option<PushOnly>| {
            let mut contacts = Vec::new();
            hold_points(
                &fine,
                &rest,
                &rest,
                &probe,
                at,
                &mut contacts,
                &|_| false,
                &|_| false,
                push_only,
            );
            contacts
        };
        // Corner 0 is 0.2 mm from the probe, the rest of the triangle beyond the margin.
        let near = rest[0] + Vec3::Z * (r + 2e-4);
        let contacts = hold(near, push_only(near));
        assert_eq!(contacts.len(), 1, "{contacts:?}");
        assert_eq!(contacts[0].vertex, 0);
        assert!((ahead(&contacts, &rest)[0] + 2e-4).abs() < 1e-12);
        // Corner 0 0.1 mm inside: its plane 0.1 mm in front of it, no other vertex held.
        let inside = rest[0] + Vec3::Z * (r - 1e-4);
        let contacts = hold(inside, push_only(rest[0] + Vec3::Z * 0.1));
        assert_eq!(contacts.len(), 1, "{contacts:?}");
        assert!((ahead(&contacts, &rest)[0] - 1e-4).abs() < 1e-12);
        assert_eq!(hold(inside, None).len(), 3);
    }

    #[test]
    fn projection_lands_on_the_sphere() {
        let c = Vec3::new(1.0, 2.0, 3.0);
        let p = project_to_sphere(c + Vec3::new(0.1, -0.2, 0.05), c, 0.5, Vec3::ZERO);
        assert!((p.distance(c) - 0.5).abs() < 1e-15);
        let p = project_to_sphere(c, c, 0.5, Vec3::new(0.0, -3.0, 0.0));
        assert!(p.distance(c + Vec3::new(0.0, -0.5, 0.0)) < 1e-15);
    }

    #[test]
    fn adhesion_is_a_pull_toward_the_contact() {
        let c = Vec3::ZERO;
        let below = Vec3::new(0.0, -1.0, 0.0);
        // The tissue below pushes up (toward the center): not adhesive.
        assert!(!is_adhesive(Vec3::new(0.0, 2.0, 0.0), below, c, 2.0));
        // It pulls down: adhesive.
        assert!(is_adhesive(Vec3::new(0.0, -2.0, 0.0), below, c, 2.0));
    }

    #[test]
    fn only_a_shape_the_instrument_came_through_sends_a_point_back_the_other_way() {
        let up = Vec3::Z;
        // A side face bulged a little downward under a flat face pushing down: contact.
        let side = Vec3::new(1.0, 0.0, -0.1).normalize();
        let half = Vec3::splat(0.01);
        assert!(!on_far_side(&Shape::Plane { normal: -up }, -up, side));
        assert!(!on_far_side(&Shape::Box { half }, -up, side));
        // The same box come down through the top: its top face pushes the tissue's top out.
        assert!(on_far_side(&Shape::Box { half }, up, up));
        // A half-space has no far side, whatever the tissue's normal there.
        assert!(!on_far_side(&Shape::Plane { normal: -up }, -up, -up));
        // A ball whose centre went below the tissue's top pushes the top up and out.
        let ball = Shape::Sphere { radius: 0.005 };
        assert!(on_far_side(&ball, Vec3::new(0.3, 0.0, 1.0).normalize(), up));
        assert!(!on_far_side(
            &ball,
            Vec3::new(0.3, 0.0, -1.0).normalize(),
            up
        ));
        // Where it leaves instead: through the ball's bottom, below its centre.
        let exit = exit_along(&ball, Vec3::ZERO, Vec3::new(0.0, 0.0, 0.002), -up);
        assert!((exit.point - Vec3::new(0.0, 0.0, -0.005)).length() < 1e-12);
    }

    /// A ball of radius 5 mm pressing down on a surface folded under it (the tissue's normal
    /// there turned down, along the ball's push): a point 0.1 mm inside is where the ball has
    /// just reached it and goes the nearest way out (down, 0.1 mm), not 9.9 mm up through the
    /// ball; 2 mm inside (beyond a quarter of the radius) the far-side rule holds as before.
    /// A box keeps its face rule at any depth.
    #[test]
    fn a_ball_just_reaching_a_folded_surface_pushes_it_the_nearest_way() {
        let (up, ball) = (Vec3::Z, Shape::Sphere { radius: 0.005 });
        let folded = -up;
        let at = Vec3::new(0.0, 0.0, 0.005 - 1e-4);
        let just = ball.closest(at, Vec3::ZERO, Vec3::ZERO);
        assert!((just.depth + 1e-4).abs() < 1e-12 && just.normal.dot(-up) > 0.999);
        assert!(on_far_side(&ball, just.normal, folded));
        assert!(!passed_to_far_side(&ball, &just, folded));
        let deep = ball.closest(Vec3::new(0.0, 0.0, 0.003), Vec3::ZERO, Vec3::ZERO);
        assert!(passed_to_far_side(&ball, &deep, folded));
        let half = Vec3::splat(0.01);
        let boxed = Shape::Box { half };
        let near_top = boxed.closest(Vec3::new(0.0, 0.0, -0.01 + 1e-4), Vec3::ZERO, Vec3::ZERO);
        assert_eq!(
            passed_to_far_side(&boxed, &near_top, near_top.normal),
            on_far_side(&boxed, near_top.normal, near_top.normal)
        );
    }
}
