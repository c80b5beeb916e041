//! The stencils: what part of one BCC tetrahedron is inside, as tetrahedra, from the signs
//! of its four vertices (after warping) and the cut points on its edges.
//!
//! With `i` vertices inside, `o` outside and `z` on the surface, the inside part is
//! - nothing when `i = 0` (the all-zero tetrahedron is decided by the caller);
//! - the whole tetrahedron when `o = 0`;
//! - one tetrahedron when `i = 1` (the inside vertex, the zero vertices, the cut points);
//! - a pyramid when `i = 2, o = 1, z = 1` (two tetrahedra);
//! - a triangular prism when `i = 2, o = 2` or `i = 3, o = 1` (three tetrahedra).
//!
//! A quadrilateral face of a pyramid or prism lies in a face of the lattice shared with the
//! neighbouring BCC tetrahedron, so both must split it along the same diagonal: the caller's
//! `split` rule sees only the quadrilateral's four vertices.
//! Orientation is not decided here: the caller orients every output tetrahedron.

/// A polyhedron vertex: a lattice vertex id, or `CUT_BASE + cut index` for a cut point.
pub(crate) type Key = u64;

/// How a quadrilateral (four keys in cyclic order) is split: `Some(true)` along the diagonal
/// (q0, q2), `Some(false)` along (q1, q3), `None` when it lies inside one BCC tetrahedron
/// and the stencil may choose.
pub(crate) type Split<'a> = dyn Fn([Key; 4]) -> Option<bool> + 'a;

/// What a tetrahedron's signs asked for.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Fill {
    /// Nothing of it is inside.
    Nothing,
    /// All four vertices are on the surface: the caller decides.
    AllZero,
    /// Tetrahedra were pushed.
    Filled,
}

/// Fills `out` with the inside part of the BCC tetrahedron `t`. `sign(v)` is -1 inside, 0
/// on the surface, +1 outside; `cut(a, b)` is the key of the cut point on edge (a, b), asked
/// only for an edge whose ends have strictly opposite signs.
pub(crate) fn fill(
    t: [u32; 4],
    sign: impl Fn(u32) -> i8,
    cut: impl Fn(u32, u32) -> Key,
    split: &Split<'_>,
    quality: &dyn Fn(&[[Key; 4]]) -> f64,
    out: &mut Vec<[Key; 4]>,
    steiner: &mut Vec<[Key; 6]>,
) -> Fill {
    let mut ins = [0u32; 4];
    let mut outs = [0u32; 4];
    let mut zeros = [0u32; 4];
    let (mut i, mut o, mut z) = (0, 0, 0);
    for &v in &t {
        match sign(v) {
            s if s < 0 => {
                ins[i] = v;
                i += 1;
            }
            s if s > 0 => {
                outs[o] = v;
                o += 1;
            }
            _ => {
                zeros[z] = v;
                z += 1;
            }
        }
    }
    let k = |v: u32| v as Key;
    match (i, o) {
        (0, _) if z == 4 => Fill::AllZero,
        (0, _) => Fill::Nothing,
        (_, 0) => {
            out.push(t.map(k));
            Fill::Filled
        }
        (1, _) => {
            let a = ins[0];
            let mut tet = [k(a); 4];
            for (slot, &v) in tet[1..].iter_mut().zip(t.iter().filter(|&&v| v != a)) {
                *slot = if sign(v) == 0 { k(v) } else { cut(a, v) };
            }
            out.push(tet);
            Fill::Filled
        }
        (2, 1) => {
            let (a, b, c) = (ins[0], ins[1], outs[0]);
            pyramid([k(a), k(b), cut(b, c), cut(a, c)], k(zeros[0]), split, out);
            Fill::Filled
        }
        (2, 2) => {
            let (a, b, c, d) = (ins[0], ins[1], outs[0], outs[1]);
            prism(
                [k(a), cut(a, c), cut(a, d), k(b), cut(b, c), cut(b, d)],
                split,
                quality,
                out,
                steiner,
            );
            Fill::Filled
        }
        _ => {
            // (3, 1)
            let (a, b, c, d) = (ins[0], ins[1], ins[2], outs[0]);
            prism(
                [k(a), k(b), k(c), cut(a, d), cut(b, d), cut(c, d)],
                split,
                quality,
                out,
                steiner,
            );
            Fill::Filled
        }
    }
}

/// Whether a tetrahedron whose four (warped) corners are all on the boundary is kept
/// (when its centre is inside). Warping may squash it into a sliver (the sampling in
/// `stencil_bounds` found 4.7° with the paper's α) or open it past the largest bound. Such a
/// tetrahedron has all its faces on the boundary side, so leaving it out keeps the mesh
/// conforming (its faces become boundary faces, their corners on the surface) and loses
/// only its small volume.
pub(crate) fn keep_all_zero(p: [crate::math::Vec3; 4]) -> bool {
    let (lo, hi) = super::PROVEN_DIHEDRAL_DEG;
    super::report::dihedral_angles(p).iter().all(|a| {
        let a = a.to_degrees();
        (lo..=hi).contains(&a)
    })
}

/// Where Steiner points' keys start: above every lattice vertex and cut point key.
pub(crate) const STEINER_BASE: Key = 1 << 48;

/// A pyramid on the quadrilateral `q` (cyclic order) with apex `t`: two tetrahedra, split
/// along the diagonal `split` picks (a pyramid's quadrilateral is always in a lattice face).
fn pyramid(q: [Key; 4], t: Key, split: &Split<'_>, out: &mut Vec<[Key; 4]>) {
    let m = if split(q).unwrap_or(true) { 0 } else { 1 };
    let r = |j: usize| q[(m + j) % 4];
    out.push([r(0), r(1), r(2), t]);
    out.push([r(0), r(2), r(3), t]);
}

/// A triangular prism: bottom `p[0..3]`, top `p[3..6]`, vertical edges (i, i+3). Its
/// quadrilaterals in lattice faces are split as `split` says; one inside the BCC
/// tetrahedron (`split` gives `None`) is split whichever way `quality` prefers among those
/// that leave a three-tetrahedron split. Unless the three diagonals turn the same way round
/// the prism, some vertex ends two of them: renamed vertex 0, the prism is three tetrahedra
/// around it (Dompierre et al. 1999). Otherwise no three tetrahedra fit and a Steiner point
/// at the prism's centre makes eight.
fn prism(
    p: [Key; 6],
    split: &Split<'_>,
    quality: &dyn Fn(&[[Key; 4]]) -> f64,
    out: &mut Vec<[Key; 4]>,
    steiner: &mut Vec<[Key; 6]>,
) {
    // Quadrilateral i is (i, i+1, i+4, i+3) (bottom indices mod 3); its diagonal is
    // "rising" (i, i+4) or "falling" (i+1, i+3).
    let quad = |i: usize| [p[i], p[(i + 1) % 3], p[(i + 1) % 3 + 3], p[i + 3]];
    let fixed = [0, 1, 2].map(|i| split(quad(i)));
    let mut best: Option<(f64, [[Key; 4]; 3])> = None;
    for choice in 0..8usize {
        let free = |i: usize| choice >> i & 1 == 1;
        if (0..3).any(|i| fixed[i].is_some() && free(i)) {
            continue;
        }
        let rising = [0, 1, 2].map(|i| fixed[i].unwrap_or(free(i)));
        if let Some(tets) = three_tets(p, rising) {
            let q = if fixed.iter().all(Option::is_some) {
                0.0
            } else {
                quality(&tets)
            };
            if best.as_ref().is_none_or(|(b, _)| q > *b) {
                best = Some((q, tets));
            }
        }
    }
    if let Some((_, tets)) = best {
        out.extend_from_slice(&tets);
        return;
    }
    let s = STEINER_BASE + steiner.len() as Key;
    steiner.push(p);
    for (i, r) in fixed.iter().enumerate() {
        let q = quad(i);
        let d = if r.unwrap_or(true) { 0 } else { 1 };
        let r = |j: usize| q[(d + j) % 4];
        out.push([r(0), r(1), r(2), s]);
        out.push([r(0), r(2), r(3), s]);
    }
    out.push([p[0], p[1], p[2], s]);
    out.push([p[3], p[4], p[5], s]);
}

/// The three tetrahedra of prism `p` whose quadrilaterals are split as `rising` says, or
/// `None` when the three diagonals turn the same way round it.
fn three_tets(p: [Key; 6], rising: [bool; 3]) -> Option<[[Key; 4]; 3]> {
    let diagonal = |i: usize| {
        if rising[i] {
            (i, (i + 1) % 3 + 3)
        } else {
            ((i + 1) % 3, i + 3)
        }
    };
    let ends = |v: usize| {
        (0..3)
            .filter(|&i| {
                let (a, b) = diagonal(i);
                a == v || b == v
            })
            .count()
    };
    let m = (0..6).find(|&v| ends(v) == 2)?;
    let (rot, flip) = (m % 3, m >= 3);
    let index = |j: usize| {
        let level = usize::from((j >= 3) != flip);
        (rot + j % 3) % 3 + 3 * level
    };
    let v = |j: usize| p[index(j)];
    // The quadrilateral opposite vertex 0 is (1, 2, 5, 4): is its diagonal (1, 5)?
    let opposite = (0..3)
        .find(|&i| {
            let (a, b) = diagonal(i);
            a != m && b != m && i != m % 3 && (i + 1) % 3 != m % 3
        })
        .map(diagonal)?;
    let one_five = [index(1), index(5)];
    Some(
        if one_five.contains(&opposite.0) && one_five.contains(&opposite.1) {
            [
                [v(0), v(1), v(2), v(5)],
                [v(0), v(1), v(5), v(4)],
                [v(0), v(4), v(5), v(3)],
            ]
        } else {
            [
                [v(0), v(1), v(2), v(4)],
                [v(0), v(4), v(2), v(5)],
                [v(0), v(4), v(5), v(3)],
            ]
        },
    )
}

/// The smallest-key rule (Dompierre et al.): split along the diagonal through the
/// quadrilateral's smallest key; `true` for the diagonal (q0, q2).
#[cfg(test)]
pub(crate) fn smallest_key(q: [Key; 4]) -> Option<bool> {
    let m = (0..4).min_by_key(|&i| q[i]).unwrap_or(0);
    Some(m % 2 == 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every prism split covers the prism: 3 tetrahedra, each using vertex 0 of the renamed
    /// prism, and the 3 quadrilaterals split through their smallest keys.
    #[test]
    fn prism_splits_are_consistent_with_the_smallest_key_rule() {
        let perms = [
            [0u64, 1, 2, 3, 4, 5],
            [5, 4, 3, 2, 1, 0],
            [3, 0, 4, 1, 5, 2],
            [2, 5, 1, 4, 0, 3],
        ];
        for p in perms {
            let mut out = Vec::new();
            prism(p, &smallest_key, &|_| 0.0, &mut out, &mut Vec::new());
            assert_eq!(out.len(), 3);
            // Each quadrilateral (i, i+1, i+4, i+3) is split by the diagonal through its
            // smallest key: that diagonal must appear as an edge of some tetrahedron.
            for i in 0..3 {
                let q = [p[i], p[(i + 1) % 3], p[(i + 1) % 3 + 3], p[i + 3]];
                let m = (0..4).min_by_key(|&j| q[j]).unwrap_or(0);
                let (a, b) = (q[m], q[(m + 2) % 4]);
                assert!(
                    out.iter().any(|t| t.contains(&a) && t.contains(&b)),
                    "{p:?}: diagonal {a}-{b} missing in {out:?}"
                );
            }
        }
    }

    #[test]
    fn a_cyclic_prism_gets_a_steiner_point_and_keeps_its_volume() {
        use crate::math::{Vec3, tet_signed_volume};
        let pts = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let centre = pts.iter().sum::<Vec3>() / 6.0;
        let at = |k: Key| {
            if k >= STEINER_BASE {
                centre
            } else {
                pts[k as usize]
            }
        };
        for rule in [&(|_q: [Key; 4]| Some(true)) as &Split<'_>, &smallest_key] {
            let (mut out, mut st) = (Vec::new(), Vec::new());
            prism([0, 1, 2, 3, 4, 5], rule, &|_| 0.0, &mut out, &mut st);
            let v: f64 = out
                .iter()
                .map(|t| tet_signed_volume(at(t[0]), at(t[1]), at(t[2]), at(t[3])).abs())
                .sum();
            assert!((v - 0.5).abs() < 1e-12, "{out:?}: {v}");
            assert_eq!(out.len(), if st.is_empty() { 3 } else { 8 });
        }
    }
}
