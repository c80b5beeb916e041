//! A stuffed mesh's boundary made a 2-manifold.
//!
//! Stuffing a shape whose features are about the lattice's size (two gyri of an MRI brain a
//! voxel apart, a muscle with cracks of fat) can leave two parts of the mesh touching along
//! one edge or at one vertex: the boundary then has an edge shared by four triangles, or a
//! vertex whose triangles form two fans. Every tetrahedron is still valid and the volume
//! mesh conforms, but a surface model built on the boundary (`bem`, the spring kinds, a
//! contact search's normals) has no well-defined side there, and `bem` refuses it.
//!
//! 1. Split. Where the tetrahedra around such a vertex (or an end of such an edge) form
//!    several fans (tetrahedra joined through faces that contain the vertex) that meet only
//!    there, the largest fan keeps the vertex and every other gets a copy of it, moved a
//!    fifth of an edge at most into its own fan, as far as the angle bounds allow
//!    (`split_position`). Nothing is removed: the parts stay as the lattice made them, one
//!    step apart at the point where they touched.
//! 2. Remove, where no split parts them (a vertex whose one fan has two rims, an edge both
//!    of whose ends have one fan, a copy that cannot move within the angle bounds): the
//!    fan with the largest volume is kept and the tetrahedra of the others are removed.
//!    This lays bare the far faces of the removed tetrahedra, whose corners can be lattice
//!    vertices up to 0.7 h inside the input (session 14: the pelvis at 10 mm lost 136
//!    tetrahedra so and its boundary was 0.72 h from the input), which is why it comes
//!    second.
//!
//! Until nothing is left to fix. The vertices split, and the count and volume removed, are
//! reported.

use rustc_hash::{FxHashMap, FxHashSet};
use serde::Serialize;

use super::PROVEN_DIHEDRAL_DEG;
use super::report::dihedral_angles;
use crate::math::{Real, Vec3, tet_signed_volume};
use crate::mesh::TetMesh;

/// Rounds of removal before giving up (each round fixes every defect it finds; a removal
/// can expose a new one next to it, rarely more than two rounds deep).
const MAX_ROUNDS: usize = 32;

/// What `make_boundary_manifold` did and left.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ManifoldRepair {
    /// Vertices split: where parts touched only at a vertex (or along an edge through it),
    /// each part but the largest got a copy of the vertex, moved a little into that part
    /// (`SPLIT_STEPS`). No tetrahedron is removed for these.
    pub split: usize,
    /// Tetrahedra removed (where no split could part the mesh).
    pub removed: usize,
    /// Their volume, m³.
    pub removed_volume: Real,
    /// Boundary vertices inside the shape (lattice vertices the removals laid bare) moved
    /// onto its boundary, of which only part of the way (the angles allowed no more), and
    /// left inside (`bare`).
    pub bare_moved: usize,
    pub bare_partly: usize,
    pub bare_left: usize,
    /// Edges shared by more than two boundary triangles, and vertices whose boundary
    /// triangles form more than one fan, left after the repair (0 unless the rounds ran out).
    pub edges_left: usize,
    pub vertices_left: usize,
}

/// The faces of tetrahedron `t` (each sorted), opposite corners 0..4.
fn faces(t: &[u32; 4]) -> [[u32; 3]; 4] {
    let f = |a: u32, b: u32, c: u32| {
        let mut k = [a, b, c];
        k.sort_unstable();
        k
    };
    [
        f(t[1], t[2], t[3]),
        f(t[0], t[2], t[3]),
        f(t[0], t[1], t[3]),
        f(t[0], t[1], t[2]),
    ]
}

/// The boundary's defects: non-manifold edges (with the tetrahedra around them) and
/// non-manifold vertices.
struct Defects {
    edges: Vec<[u32; 2]>,
    vertices: Vec<u32>,
    /// Every vertex of a boundary triangle.
    on_boundary: FxHashSet<u32>,
}

fn find_defects(tets: &[[u32; 4]], alive: &[bool]) -> Defects {
    let mut face_count: FxHashMap<[u32; 3], u32> = FxHashMap::default();
    for (t, tet) in tets.iter().enumerate() {
        if alive[t] {
            for f in faces(tet) {
                *face_count.entry(f).or_insert(0) += 1;
            }
        }
    }
    let boundary: Vec<[u32; 3]> = face_count
        .into_iter()
        .filter_map(|(f, n)| (n == 1).then_some(f))
        .collect();
    let mut edge_count: FxHashMap<[u32; 2], u32> = FxHashMap::default();
    // Per boundary vertex, the edges of its boundary triangles that do not contain it (a
    // fan around the vertex is a chain of such edges joined at their ends).
    let mut rim: FxHashMap<u32, Vec<[u32; 2]>> = FxHashMap::default();
    for f in &boundary {
        for (a, b, c) in [(f[0], f[1], f[2]), (f[1], f[2], f[0]), (f[2], f[0], f[1])] {
            *edge_count.entry([a.min(b), a.max(b)]).or_insert(0) += 1;
            rim.entry(c).or_default().push([a, b]);
        }
    }
    let mut edges: Vec<[u32; 2]> = edge_count
        .into_iter()
        .filter_map(|(e, n)| (n > 2).then_some(e))
        .collect();
    edges.sort_unstable();
    let on_boundary: FxHashSet<u32> = rim.keys().copied().collect();
    let mut vertices: Vec<u32> = rim
        .into_iter()
        .filter_map(|(v, rim)| (fans(&rim) > 1).then_some(v))
        .collect();
    vertices.sort_unstable();
    Defects {
        edges,
        vertices,
        on_boundary,
    }
}

/// Connected components of a vertex's rim edges (its boundary triangles joined through
/// shared edges): 1 for a manifold vertex.
fn fans(rim: &[[u32; 2]]) -> usize {
    let mut ids: Vec<u32> = rim.iter().flatten().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let index = |v: u32| ids.binary_search(&v).unwrap_or(0);
    let mut parent: Vec<usize> = (0..ids.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for e in rim {
        let (a, b) = (
            root(&mut parent, index(e[0])),
            root(&mut parent, index(e[1])),
        );
        parent[a] = b;
    }
    (0..ids.len())
        .filter(|&i| root(&mut parent, i) == i)
        .count()
}

/// Groups `around` (the tetrahedra containing one edge or one vertex) into fans: two are in
/// one fan when they share a face (three vertices), directly or through others.
fn group_fans(tets: &[[u32; 4]], around: &[usize]) -> Vec<Vec<usize>> {
    let n = around.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (&tets[around[i]], &tets[around[j]]);
            let common = a.iter().filter(|v| b.contains(v)).count();
            if common >= 3 {
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                parent[ri] = rj;
            }
        }
    }
    let mut groups: FxHashMap<usize, Vec<usize>> = FxHashMap::default();
    for (i, &t) in around.iter().enumerate() {
        let r = root(&mut parent, i);
        groups.entry(r).or_default().push(t);
    }
    let mut out: Vec<Vec<usize>> = groups.into_values().collect();
    out.sort_unstable();
    out
}

/// How far a split vertex's copy moves into its own part, as fractions of the shortest
/// edge from the vertex in that part: the first that keeps every tetrahedron of the part
/// within the angle bounds is taken (or the angle it had, if that was already outside).
/// Far enough that the parts' boundaries do not coincide (a surface model collocates at
/// the vertices), near enough that the boundary stays on the input (a fifth of an edge,
/// at most h/5, against the h/2 promised).
const SPLIT_STEPS: [Real; 3] = [0.2, 0.1, 0.05];

/// The smallest and largest dihedral angles (radians) of tetrahedra `ts`, and whether all
/// keep the orientation sign `signs` gives (positive volume stays positive).
fn angle_range(
    tets: &[[u32; 4]],
    vertices: &[Vec3],
    ts: &[usize],
    signs: Option<&[bool]>,
) -> (Real, Real, bool) {
    let (mut lo, mut hi, mut same) = (Real::INFINITY, 0.0 as Real, true);
    for (i, &t) in ts.iter().enumerate() {
        let p = tets[t].map(|v| vertices[v as usize]);
        for a in dihedral_angles(p) {
            lo = lo.min(a);
            hi = hi.max(a);
        }
        if let Some(s) = signs {
            same &= (tet_signed_volume(p[0], p[1], p[2], p[3]) > 0.0) == s[i];
        }
    }
    (lo, hi, same)
}

/// Where the copy of `v` for `part` (tetrahedra around `v`) goes: moved towards the mean
/// of the part's other corners by the first of `SPLIT_STEPS` that keeps the part's
/// tetrahedra oriented and within `PROVEN_DIHEDRAL_DEG` (or within what they had), and
/// does not put it inside a tetrahedron of the `rest` of the vertex's star. `None` when no
/// step does.
fn split_position(
    tets: &[[u32; 4]],
    vertices: &mut [Vec3],
    v: u32,
    part: &[usize],
    rest: &[usize],
) -> Option<Vec3> {
    let at = vertices[v as usize];
    // Whether `p` lies in (or on) one of the other fans' tetrahedra (`v` where it is): the
    // copy must move into its own part, never into another's.
    let rest: Vec<[Vec3; 4]> = rest
        .iter()
        .map(|&t| tets[t].map(|u| vertices[u as usize]))
        .collect();
    let in_rest = |p: Vec3| {
        rest.iter().any(|q| {
            let whole = tet_signed_volume(q[0], q[1], q[2], q[3]);
            (0..4).all(|i| {
                let mut r = *q;
                r[i] = p;
                tet_signed_volume(r[0], r[1], r[2], r[3]) / whole >= -1e-9
            })
        })
    };
    let others: Vec<Vec3> = part
        .iter()
        .flat_map(|&t| tets[t])
        .filter(|&u| u != v)
        .map(|u| vertices[u as usize])
        .collect();
    let mean = others.iter().copied().sum::<Vec3>() / others.len().max(1) as Real;
    let shortest = others
        .iter()
        .map(|&p| (p - at).length())
        .fold(Real::INFINITY, Real::min);
    let direction = (mean - at).normalize_or_zero();
    if direction == Vec3::ZERO || !shortest.is_finite() {
        return None;
    }
    let signs: Vec<bool> = part
        .iter()
        .map(|&t| {
            let p = tets[t].map(|u| vertices[u as usize]);
            tet_signed_volume(p[0], p[1], p[2], p[3]) > 0.0
        })
        .collect();
    let (lo0, hi0, _) = angle_range(tets, vertices, part, None);
    let (lo_bound, hi_bound) = (
        PROVEN_DIHEDRAL_DEG.0.to_radians().min(lo0),
        PROVEN_DIHEDRAL_DEG.1.to_radians().max(hi0),
    );
    let mut found = None;
    for step in SPLIT_STEPS {
        let to = at + step * shortest * direction;
        if in_rest(to) {
            continue;
        }
        vertices[v as usize] = to;
        let (lo, hi, same) = angle_range(tets, vertices, part, Some(&signs));
        if same && lo >= lo_bound && hi <= hi_bound {
            found = Some(to);
            break;
        }
    }
    vertices[v as usize] = at;
    found
}

/// Splits boundary vertex `v` when its tetrahedra form several fans joined only at `v`
/// (two parts touching at a vertex, or along an edge through it): the fan with the largest
/// volume keeps `v`, every other gets a copy of it moved a little into that fan
/// (`split_position`). Returns the copies made; a fan whose copy cannot move without
/// leaving the angle bounds keeps `v` (the removal then deals with it).
fn split_vertex(tets: &mut [[u32; 4]], vertices: &mut Vec<Vec3>, v: u32, star: &[usize]) -> usize {
    let fans = group_fans(tets, star);
    if fans.len() < 2 {
        return 0;
    }
    let volume = |tets: &[[u32; 4]], fan: &[usize]| -> Real {
        fan.iter()
            .map(|&t| {
                let p = tets[t].map(|u| vertices[u as usize]);
                tet_signed_volume(p[0], p[1], p[2], p[3]).abs()
            })
            .sum()
    };
    let largest = (0..fans.len())
        .max_by(|&a, &b| {
            volume(tets, &fans[a])
                .total_cmp(&volume(tets, &fans[b]))
                .then(b.cmp(&a))
        })
        .unwrap_or(0);
    let mut made = 0;
    for (i, fan) in fans.iter().enumerate() {
        if i == largest {
            continue;
        }
        let rest: Vec<usize> = star.iter().copied().filter(|t| !fan.contains(t)).collect();
        let Some(to) = split_position(tets, vertices, v, fan, &rest) else {
            continue;
        };
        let copy = vertices.len() as u32;
        vertices.push(to);
        for &t in fan {
            for u in &mut tets[t] {
                if *u == v {
                    *u = copy;
                }
            }
        }
        made += 1;
    }
    made
}

/// The fewest tetrahedra around `v` (its `star`, one fan whose boundary has two rims or
/// more) whose removal joins two rims: a shortest chain of tetrahedra joined through faces
/// containing `v`, from one touching the first rim to one touching another. A rim is a
/// cycle of boundary edges of the link of `v` (the faces opposite `v`), so the link, an
/// annulus, loses a strip across it and becomes a disc. Whatever the cut leaves non-manifold
/// is fixed in the next round. The whole star when the rims cannot be told apart.
fn ring_cut(tets: &[[u32; 4]], v: u32, star: &[usize]) -> Vec<usize> {
    // The link's triangles (each star tetrahedron without `v`) and their edges.
    let link: Vec<[u32; 3]> = star
        .iter()
        .map(|&t| {
            let mut o = [0u32; 3];
            let mut n = 0;
            for &u in &tets[t] {
                if u != v && n < 3 {
                    o[n] = u;
                    n += 1;
                }
            }
            o
        })
        .collect();
    let edge = |a: u32, b: u32| [a.min(b), a.max(b)];
    let mut edge_count: FxHashMap<[u32; 2], u32> = FxHashMap::default();
    for t in &link {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *edge_count.entry(edge(a, b)).or_insert(0) += 1;
        }
    }
    // Rims: the link's boundary edges in connected groups, by their vertices.
    let mut rim_of: FxHashMap<u32, u32> = FxHashMap::default();
    let boundary: Vec<[u32; 2]> = edge_count
        .iter()
        .filter_map(|(e, &n)| (n == 1).then_some(*e))
        .collect();
    for &[a, b] in &boundary {
        let next = rim_of.len() as u32;
        let (ra, rb) = (rim_of.get(&a).copied(), rim_of.get(&b).copied());
        match (ra, rb) {
            (None, None) => {
                rim_of.insert(a, next);
                rim_of.insert(b, next);
            }
            (Some(r), None) => {
                rim_of.insert(b, r);
            }
            (None, Some(r)) => {
                rim_of.insert(a, r);
            }
            (Some(x), Some(y)) if x != y => {
                for r in rim_of.values_mut() {
                    if *r == y {
                        *r = x;
                    }
                }
            }
            _ => {}
        }
    }
    let mut rims: Vec<u32> = rim_of.values().copied().collect();
    rims.sort_unstable();
    rims.dedup();
    if rims.len() < 2 {
        return star.to_vec();
    }
    let first = rims[0];
    let touches = |t: &[u32; 3], other: bool| {
        t.iter().any(|u| {
            rim_of
                .get(u)
                .is_some_and(|&r| if other { r != first } else { r == first })
        })
    };
    // Breadth-first from every triangle touching the first rim, across shared edges.
    let n = link.len();
    let mut from: Vec<Option<usize>> = vec![None; n];
    let mut seen = vec![false; n];
    let mut queue = std::collections::VecDeque::new();
    for (i, t) in link.iter().enumerate() {
        if touches(t, false) {
            seen[i] = true;
            queue.push_back(i);
        }
    }
    let shares_edge = |a: &[u32; 3], b: &[u32; 3]| a.iter().filter(|u| b.contains(u)).count() == 2;
    while let Some(i) = queue.pop_front() {
        if touches(&link[i], true) {
            let mut cut = vec![star[i]];
            let mut at = i;
            while let Some(j) = from[at] {
                cut.push(star[j]);
                at = j;
            }
            return cut;
        }
        for j in 0..n {
            if !seen[j] && shares_edge(&link[i], &link[j]) {
                seen[j] = true;
                from[j] = Some(i);
                queue.push_back(j);
            }
        }
    }
    star.to_vec()
}

/// Makes the boundary a 2-manifold: splits the vertices where parts touch (tags and
/// tetrahedra kept), then removes tetrahedra where that cannot be done; unused vertices are
/// dropped. See the module doc.
pub fn make_boundary_manifold(mesh: &mut TetMesh, tags: &mut Vec<i32>) -> ManifoldRepair {
    let mut tets = mesh.tets.clone();
    let mut vertices = mesh.vertices.clone();
    let volume = |tets: &[[u32; 4]], vertices: &[Vec3], t: usize| {
        let p = tets[t].map(|v| vertices[v as usize]);
        tet_signed_volume(p[0], p[1], p[2], p[3]).abs()
    };
    let mut alive = vec![true; tets.len()];
    let mut repair = ManifoldRepair::default();
    for round in 0..=MAX_ROUNDS {
        let defects = find_defects(&tets, &alive);
        if defects.edges.is_empty() && defects.vertices.is_empty() {
            break;
        }
        if round == MAX_ROUNDS {
            repair.edges_left = defects.edges.len();
            repair.vertices_left = defects.vertices.len();
            break;
        }
        // The tetrahedra around each defect, from a vertex → tetrahedra map of this round.
        let mut at_vertex: FxHashMap<u32, Vec<usize>> = FxHashMap::default();
        for (t, tet) in tets.iter().enumerate() {
            if alive[t] {
                for &v in tet {
                    at_vertex.entry(v).or_default().push(t);
                }
            }
        }
        // First split: the vertex of a defect, or an end of a defect edge, whose
        // tetrahedra are in several fans joined only at it. Nothing is removed, so no
        // vertex inside the shape is laid bare (removing a fan did that: its far faces
        // became boundary up to 0.7 h inside the input).
        let mut candidates: Vec<u32> = defects.vertices.clone();
        candidates.extend(defects.edges.iter().flatten());
        candidates.sort_unstable();
        candidates.dedup();
        let mut split = 0;
        for v in candidates {
            if let Some(star) = at_vertex.get(&v) {
                split += split_vertex(&mut tets, &mut vertices, v, star);
            }
        }
        if split > 0 {
            repair.split += split;
            continue;
        }
        // Every fan but one of the tetrahedra around a defect. The one kept is the one
        // that would lay bare the most vertices inside the shape (corners not yet on the
        // boundary), then the largest by volume: the fans removed are those whose far
        // faces are nearest the surface. (Until session 15 the largest by volume was kept,
        // which could bare lattice vertices 0.7 h inside.)
        let smaller_fans = |around: &[usize]| -> Vec<usize> {
            let fans = group_fans(&tets, around);
            let inner = |fan: &[usize]| {
                let mut corners: Vec<u32> = fan
                    .iter()
                    .flat_map(|&t| tets[t])
                    .filter(|u| !defects.on_boundary.contains(u))
                    .collect();
                corners.sort_unstable();
                corners.dedup();
                corners.len()
            };
            let kept = fans
                .iter()
                .enumerate()
                .map(|(i, f)| {
                    (
                        i,
                        inner(f),
                        f.iter().map(|&t| volume(&tets, &vertices, t)).sum::<Real>(),
                    )
                })
                .max_by(|a, b| a.1.cmp(&b.1).then(a.2.total_cmp(&b.2)).then(b.0.cmp(&a.0)))
                .map(|(i, _, _)| i);
            fans.into_iter()
                .enumerate()
                .filter(|&(i, _)| Some(i) != kept)
                .flat_map(|(_, fan)| fan)
                .collect()
        };
        let mut doomed: Vec<usize> = Vec::new();
        for [a, b] in &defects.edges {
            let around: Vec<usize> = at_vertex
                .get(a)
                .map(|ts| {
                    ts.iter()
                        .copied()
                        .filter(|&t| tets[t].contains(b))
                        .collect()
                })
                .unwrap_or_default();
            doomed.extend(smaller_fans(&around));
        }
        for v in &defects.vertices {
            let star = at_vertex.get(v).cloned().unwrap_or_default();
            let smaller = smaller_fans(&star);
            if smaller.is_empty() {
                // One fan whose boundary still has two rims around the vertex: the solid
                // there is a ring with a conical hole through the vertex (its link is an
                // annulus, not a disc). No fan can be dropped; the fewest tetrahedra that
                // join one rim to the other go (`ring_cut`), which opens the ring. (Until
                // session 15 all the vertex's tetrahedra went, 20 or more, which laid bare
                // lattice vertices deep inside: most of the pelvis's 0.72 h.)
                doomed.extend(ring_cut(&tets, *v, &star));
            } else {
                doomed.extend(smaller);
            }
        }
        doomed.sort_unstable();
        doomed.dedup();
        for t in doomed {
            if alive[t] {
                alive[t] = false;
                repair.removed += 1;
                repair.removed_volume += volume(&tets, &vertices, t);
            }
        }
    }
    if repair.removed > 0 || repair.split > 0 {
        fn kept<T: Copy>(v: &[T], alive: &[bool]) -> Vec<T> {
            v.iter()
                .zip(alive)
                .filter_map(|(x, &a)| a.then_some(*x))
                .collect()
        }
        let survivors = TetMesh::new(vertices, kept(&tets, &alive));
        if tags.len() == alive.len() {
            *tags = kept(tags, &alive);
        }
        *mesh = survivors.compacted();
    }
    repair
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Unit cubes of 6 tetrahedra each (all split around the same diagonal, so they
    /// conform) at `offsets` (in cube lengths), sharing the vertices at the same places.
    pub(in crate::mesh::stuffing) fn cubes(offsets: &[[i32; 3]]) -> TetMesh {
        let mut ids: FxHashMap<[i32; 3], u32> = FxHashMap::default();
        let mut vertices = Vec::new();
        let mut tets = Vec::new();
        for &o in offsets {
            let mut id = |p: [i32; 3]| {
                *ids.entry(p).or_insert_with(|| {
                    vertices.push(Vec3::new(p[0] as Real, p[1] as Real, p[2] as Real));
                    vertices.len() as u32 - 1
                })
            };
            let c = |i: usize| {
                [
                    o[0] + (i & 1) as i32,
                    o[1] + ((i >> 1) & 1) as i32,
                    o[2] + ((i >> 2) & 1) as i32,
                ]
            };
            // The six tetrahedra around the diagonal 0–7, positively oriented.
            for (a, b) in [(1, 3), (3, 2), (2, 6), (6, 4), (4, 5), (5, 1)] {
                let t = [id(c(0)), id(c(a)), id(c(b)), id(c(7))];
                tets.push(t);
            }
        }
        let mut m = TetMesh::new(vertices, tets);
        for t in &mut m.tets {
            let p = t.map(|v| m.vertices[v as usize]);
            if tet_signed_volume(p[0], p[1], p[2], p[3]) < 0.0 {
                t.swap(0, 1);
            }
        }
        m
    }

    fn two_cubes(offset: [i32; 3]) -> TetMesh {
        cubes(&[[0, 0, 0], offset])
    }

    fn total_volume(m: &TetMesh) -> Real {
        m.tets
            .iter()
            .map(|t| {
                let p = t.map(|v| m.vertices[v as usize]);
                tet_signed_volume(p[0], p[1], p[2], p[3])
            })
            .sum()
    }

    fn defects(m: &TetMesh) -> (usize, usize) {
        let d = find_defects(&m.tets, &vec![true; m.tets.len()]);
        (d.edges.len(), d.vertices.len())
    }

    #[test]
    fn cubes_touching_along_an_edge_or_at_a_corner_are_parted_and_reported() {
        // Sharing a face: one body, already manifold; nothing removed.
        let mut m = two_cubes([1, 0, 0]);
        let mut tags = vec![7; m.tets.len()];
        assert_eq!(defects(&m), (0, 0));
        let r = make_boundary_manifold(&mut m, &mut tags);
        assert_eq!(r.removed, 0);
        assert_eq!(m.tets.len(), 12);
        // Along an edge, and at a corner: parted by splitting the shared vertices, the
        // second cube's copies moved a little into it; nothing removed, tags kept, every
        // tetrahedron still within the angle bounds and positively oriented.
        for offset in [[1, 1, 0], [1, 1, 1]] {
            let mut m = two_cubes(offset);
            assert_ne!(defects(&m), (0, 0), "{offset:?}: the defect is found");
            let before = total_volume(&m);
            let shared = if offset == [1, 1, 1] { 1 } else { 2 };
            let mut tags: Vec<i32> = (0..m.tets.len() as i32).collect();
            let r = make_boundary_manifold(&mut m, &mut tags);
            assert_eq!(defects(&m), (0, 0), "{offset:?}: manifold after the repair");
            assert_eq!((r.split, r.removed), (shared, 0), "{offset:?}: {r:?}");
            assert_eq!((r.edges_left, r.vertices_left), (0, 0));
            assert_eq!(m.tets.len(), 12);
            assert_eq!(
                m.vertices.len(),
                16,
                "{offset:?}: 14 or 15 shared places, and the copies"
            );
            assert_eq!(tags, (0..12).collect::<Vec<i32>>());
            assert!(m.validate_indices().is_ok());
            // The copies are apart from the originals, by a fifth of an edge at most.
            let mut gaps: Vec<Real> = Vec::new();
            for (i, p) in m.vertices.iter().enumerate() {
                for q in &m.vertices[i + 1..] {
                    let d = (*p - *q).length();
                    if d < 0.5 {
                        gaps.push(d);
                    }
                }
            }
            assert_eq!(gaps.len(), shared, "{offset:?}: {gaps:?}");
            assert!(
                gaps.iter().all(|&d| d > 0.01 && d <= 0.2 + 1e-12),
                "{gaps:?}"
            );
            for t in &m.tets {
                let p = t.map(|v| m.vertices[v as usize]);
                assert!(tet_signed_volume(p[0], p[1], p[2], p[3]) > 0.0);
                let lo = dihedral_angles(p)
                    .into_iter()
                    .fold(Real::INFINITY, Real::min);
                assert!(
                    lo.to_degrees() >= PROVEN_DIHEDRAL_DEG.0,
                    "{}",
                    lo.to_degrees()
                );
            }
            // The volume moves only by the copies' step (the cube's own corners moved in).
            let after = total_volume(&m);
            assert!((before - after).abs() < 0.1 * before, "{before} {after}");
        }
        // Two cubes along an edge whose ends are each joined round the side by a layer of
        // three cubes (below and above): the edge's fans meet only at it, but neither end's
        // tetrahedra are in two fans, so no split parts them and a fan is removed.
        let l = |z: i32| [[0, 0, z], [1, 0, z], [1, 1, z]];
        let mut offsets: Vec<[i32; 3]> = vec![[0, 0, 0], [1, 1, 0]];
        offsets.extend(l(-1));
        offsets.extend(l(1));
        let mut m = cubes(&offsets);
        assert_ne!(defects(&m), (0, 0));
        let mut tags = vec![3; m.tets.len()];
        let before = total_volume(&m);
        let r = make_boundary_manifold(&mut m, &mut tags);
        assert_eq!(defects(&m), (0, 0), "manifold after the removal: {r:?}");
        assert!(r.removed > 0, "{r:?}");
        assert_eq!((r.edges_left, r.vertices_left), (0, 0));
        assert_eq!(tags.len(), m.tets.len());
        if r.split == 0 {
            assert!((before - total_volume(&m) - r.removed_volume).abs() < 1e-9);
        }
    }
}
