//! Interfaces between labels moved outward by their chords' sag, so that each label keeps
//! its volume.
//!
//! Stuffing puts every vertex of an interface between labels on the input's interface, so
//! each interface triangle is a chord: on a curved interface it cuts inside the convex
//! label, which loses the volume between the chord and the surface. On a small label this
//! is large: the tumour ball of `scenes/organ-fem-tumour.toml` (radius 9 mm, 3 h) lost
//! 3.9 % of its volume at h = 3 mm, of which 0.5 % is the voxels' staircase against their
//! interpolated interface and the rest the chords.
//!
//! For a surface that is quadratic over a triangle and meets it at its three corners, the
//! mean gap between the two is 3/4 of the gap at the centroid (the quadratic is a sum of
//! products λᵢλⱼ of the barycentric coordinates, whose mean over a triangle is 1/12 and
//! whose value at the centroid is 1/9). So each interior interface vertex moves by 3/4 of
//! the area-weighted mean gap vector of its interface triangles (from each centroid to the
//! input's interface along the triangle's normal, within h/4): a triangle then moves by its
//! own share and the volume between mesh and input vanishes to first order. The vertex
//! leaves the input's interface by a fraction of the sag (0.08 mm for the tumour at 3 mm),
//! and the triangles' middles come nearer to it.
//!
//! Vertices on the outer boundary, or where three labels meet, stay (the outer boundary is
//! held to its own promises); a move that would invert a tetrahedron or take its angles
//! outside the proven bounds (or those it already had) is halved, then dropped.

use rustc_hash::{FxHashMap, FxHashSet};

use super::domain::{Domain, bisect};
use super::vertex_move::move_within_bounds;
use crate::math::{Real, Vec3};
use crate::mesh::TetMesh;

/// The mean gap between a chord and a quadratic surface through its corners, per gap at
/// its centroid (see the module doc).
const MEAN_PER_CENTROID_GAP: Real = 0.75;

/// How far (per h) from a triangle's centroid the input's interface is looked for.
const SEARCH: Real = 0.25;

/// Parts of the move tried, largest first.
const FRACTIONS: [Real; 2] = [1.0, 0.5];

/// What `keep_label_volumes` did: interface vertices moved all the way, half way, and
/// left (the angles refused both).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Moved {
    pub full: usize,
    pub half: usize,
    pub left: usize,
}

/// Moves the interior vertices of the interfaces between labels of `mesh` (`tags`, one
/// per tetrahedron) so that each interface triangle's mean gap to `domain`'s interface
/// vanishes. See the module doc.
pub fn keep_label_volumes(
    mesh: &mut TetMesh,
    tags: &[i32],
    domain: &dyn Domain,
    size: Real,
) -> Moved {
    let mut done = Moved::default();
    let material_tags = domain.material_tags();
    let index_of = |tag: i32| material_tags.iter().position(|&t| t == tag);
    let mut faces: FxHashMap<[u32; 3], Vec<i32>> = FxHashMap::default();
    for (t, tet) in mesh.tets.iter().enumerate() {
        let tag = tags.get(t).copied().unwrap_or(0);
        for skip in 0..4 {
            let mut f = [0u32; 3];
            let mut n = 0;
            for (i, &v) in tet.iter().enumerate() {
                if i != skip {
                    f[n] = v;
                    n += 1;
                }
            }
            f.sort_unstable();
            faces.entry(f).or_default().push(tag);
        }
    }
    let mut outer: FxHashSet<u32> = FxHashSet::default();
    let mut interface: Vec<([u32; 3], usize, usize)> = Vec::new();
    for (f, sides) in &faces {
        match sides.as_slice() {
            [_] => outer.extend(f.iter().copied()),
            [a, b] if a != b => {
                if let (Some(a), Some(b)) = (index_of(*a), index_of(*b)) {
                    interface.push((*f, a, b));
                }
            }
            _ => {}
        }
    }
    if interface.is_empty() {
        return done;
    }
    interface.sort_unstable();
    // Per vertex: Σ area · gap, Σ area.
    let mut gaps: FxHashMap<u32, (Vec3, Real)> = FxHashMap::default();
    let reach = SEARCH * size;
    for &(f, a, b) in &interface {
        let [p, q, r] = f.map(|v| mesh.vertices[v as usize]);
        let value = |x: Vec3| domain.interface_value(x, a, b);
        let Some(FaceGap { area, gap, .. }) = face_gap([p, q, r], reach, value) else {
            continue;
        };
        for v in f {
            let e = gaps.entry(v).or_insert((Vec3::ZERO, 0.0));
            e.0 += area * gap;
            e.1 += area;
        }
    }
    let mut around: FxHashMap<u32, Vec<usize>> = FxHashMap::default();
    for (t, tet) in mesh.tets.iter().enumerate() {
        for v in tet {
            if gaps.contains_key(v) {
                around.entry(*v).or_default().push(t);
            }
        }
    }
    // Every move from the positions as stuffed; applied one vertex at a time, each checked
    // against the tetrahedra as they are by then.
    let mut moves: Vec<(u32, Vec3)> = gaps
        .into_iter()
        .filter(|(v, (_, area))| *area > 0.0 && !outer.contains(v))
        .map(|(v, (sum, area))| (v, MEAN_PER_CENTROID_GAP * sum / area))
        .collect();
    moves.sort_unstable_by_key(|m| m.0);
    for (v, d) in moves {
        let ts = around.get(&v).map(Vec::as_slice).unwrap_or(&[]);
        let mut own: Vec<i32> = ts.iter().filter_map(|&t| tags.get(t).copied()).collect();
        own.sort_unstable();
        own.dedup();
        if own.len() != 2 {
            done.left += 1;
            continue;
        }
        match move_within_bounds(mesh, v, ts, d, &FRACTIONS) {
            Some(0) => done.full += 1,
            Some(_) => done.half += 1,
            None => done.left += 1,
        }
    }
    done
}

/// A boundary face's chord against the surface it approximates: its area, unit normal, and
/// the gap from its centroid to where the level set of `value` crosses the normal line
/// within `reach` of the centroid (found by bisection). None for a degenerate face or no
/// crossing. Shared by the interface correction here and the outer boundary's
/// (`follow`).
pub(super) struct FaceGap {
    pub area: Real,
    pub normal: Vec3,
    pub gap: Vec3,
}

/// The chord of the face with corners `[p, q, r]` (see `FaceGap`).
pub(super) fn face_gap(
    [p, q, r]: [Vec3; 3],
    reach: Real,
    value: impl Fn(Vec3) -> Real + Copy,
) -> Option<FaceGap> {
    let cross = (q - p).cross(r - p);
    let normal = cross.normalize_or_zero();
    if normal == Vec3::ZERO {
        return None;
    }
    let c = (p + q + r) / 3.0;
    let (lo, hi) = (c - reach * normal, c + reach * normal);
    let (f_lo, f_hi) = (value(lo), value(hi));
    let crossing = if f_lo < 0.0 && f_hi > 0.0 {
        bisect(value, lo, hi)
    } else if f_lo > 0.0 && f_hi < 0.0 {
        bisect(value, hi, lo)
    } else {
        return None;
    };
    Some(FaceGap {
        area: 0.5 * cross.length(),
        normal,
        gap: crossing - c,
    })
}
