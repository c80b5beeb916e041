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
    split: &dyn Fn([Key; 4]) -> bool,
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
                out,
                steiner,
            );
            Fill::Filled
        }
    }
}

/// Where Steiner points' keys start: above every lattice vertex and cut point key.
pub(crate) const STEINER_BASE: Key = 1 << 48;

/// A pyramid on the quadrilateral `q` (cyclic order) with apex `t`: two tetrahedra, split
/// along the diagonal `split` picks.
fn pyramid(q: [Key; 4], t: Key, split: &dyn Fn([Key; 4]) -> bool, out: &mut Vec<[Key; 4]>) {
    let m = if split(q) { 0 } else { 1 };
    let r = |j: usize| q[(m + j) % 4];
    out.push([r(0), r(1), r(2), t]);
    out.push([r(0), r(2), r(3), t]);
}

/// A triangular prism: bottom `p[0..3]`, top `p[3..6]`, vertical edges (i, i+3). Its three
/// quadrilaterals are split as `split` says. Unless the three diagonals turn the same way
/// round the prism, some vertex ends two of them: renamed vertex 0, the prism is three
/// tetrahedra around it (Dompierre et al. 1999). Otherwise no three tetrahedra fit and a
/// Steiner point at the prism's centre makes eight.
fn prism(
    p: [Key; 6],
    split: &dyn Fn([Key; 4]) -> bool,
    out: &mut Vec<[Key; 4]>,
    steiner: &mut Vec<[Key; 6]>,
) {
    // Quadrilateral i is (i, i+1, i+4, i+3) (bottom indices mod 3); its diagonal is
    // "rising" (i, i+4) or "falling" (i+1, i+3).
    let quad = |i: usize| [p[i], p[(i + 1) % 3], p[(i + 1) % 3 + 3], p[i + 3]];
    let rising = [0, 1, 2].map(|i| split(quad(i)));
    // Diagonal ends per prism vertex.
    let ends = |v: usize| -> usize {
        (0..3)
            .filter(|&i| {
                let (a, b) = if rising[i] {
                    (i, (i + 1) % 3 + 3)
                } else {
                    ((i + 1) % 3, i + 3)
                };
                a == v || b == v
            })
            .count()
    };
    let Some(m) = (0..6).find(|&v| ends(v) == 2) else {
        let s = STEINER_BASE + steiner.len() as Key;
        steiner.push(p);
        for (i, &up) in rising.iter().enumerate() {
            let q = quad(i);
            let d = if up { 0 } else { 1 };
            let r = |j: usize| q[(d + j) % 4];
            out.push([r(0), r(1), r(2), s]);
            out.push([r(0), r(2), r(3), s]);
        }
        out.push([p[0], p[1], p[2], s]);
        out.push([p[3], p[4], p[5], s]);
        return;
    };
    let (rot, flip) = (m % 3, m >= 3);
    let v = |j: usize| {
        let level = usize::from((j >= 3) != flip);
        p[(rot + j % 3) % 3 + 3 * level]
    };
    // The quadrilateral opposite vertex 0 is (1, 2, 5, 4).
    if split([v(1), v(2), v(5), v(4)]) {
        out.push([v(0), v(1), v(2), v(5)]);
        out.push([v(0), v(1), v(5), v(4)]);
        out.push([v(0), v(4), v(5), v(3)]);
    } else {
        out.push([v(0), v(1), v(2), v(4)]);
        out.push([v(0), v(4), v(2), v(5)]);
        out.push([v(0), v(4), v(5), v(3)]);
    }
}

/// The smallest-key rule (Dompierre et al.): split along the diagonal through the
/// quadrilateral's smallest key; `true` for the diagonal (q0, q2).
#[cfg(test)]
pub(crate) fn smallest_key(q: [Key; 4]) -> bool {
    let m = (0..4).min_by_key(|&i| q[i]).unwrap_or(0);
    m % 2 == 0
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
            prism(p, &smallest_key, &mut out, &mut Vec::new());
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
        for rule in [
            &(|_q: [Key; 4]| true) as &dyn Fn([Key; 4]) -> bool,
            &smallest_key,
        ] {
            let (mut out, mut st) = (Vec::new(), Vec::new());
            prism([0, 1, 2, 3, 4, 5], rule, &mut out, &mut st);
            let v: f64 = out
                .iter()
                .map(|t| tet_signed_volume(at(t[0]), at(t[1]), at(t[2]), at(t[3])).abs())
                .sum();
            assert!((v - 0.5).abs() < 1e-12, "{out:?}: {v}");
            assert_eq!(out.len(), if st.is_empty() { 3 } else { 8 });
        }
    }
}
