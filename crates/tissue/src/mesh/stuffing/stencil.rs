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
//! neighbouring BCC tetrahedron, so both must split it along the same diagonal. The rule
//! here depends only on the quadrilateral's vertices: the diagonal through the vertex of
//! smallest key (Dompierre et al. 1999, "How to subdivide pyramids, prisms and hexahedra
//! into tetrahedra"), which also always leaves a prism splittable into three tetrahedra.
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
    out: &mut Vec<[Key; 4]>,
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
            pyramid([k(a), k(b), cut(b, c), cut(a, c)], k(zeros[0]), out);
            Fill::Filled
        }
        (2, 2) => {
            let (a, b, c, d) = (ins[0], ins[1], outs[0], outs[1]);
            prism(
                [k(a), cut(a, c), cut(a, d), k(b), cut(b, c), cut(b, d)],
                out,
            );
            Fill::Filled
        }
        _ => {
            // (3, 1)
            let (a, b, c, d) = (ins[0], ins[1], ins[2], outs[0]);
            prism([k(a), k(b), k(c), cut(a, d), cut(b, d), cut(c, d)], out);
            Fill::Filled
        }
    }
}

/// A pyramid on the quadrilateral `q` (cyclic order) with apex `t`: two tetrahedra, split
/// along the diagonal through the quadrilateral's smallest key.
fn pyramid(q: [Key; 4], t: Key, out: &mut Vec<[Key; 4]>) {
    let m = (0..4).min_by_key(|&i| q[i]).unwrap_or(0);
    let r = |j: usize| q[(m + j) % 4];
    out.push([r(0), r(1), r(2), t]);
    out.push([r(0), r(2), r(3), t]);
}

/// A triangular prism: bottom `p[0..3]`, top `p[3..6]`, vertical edges (i, i+3). Three
/// tetrahedra (Dompierre et al.): rename so that the smallest key is vertex 0, then split the
/// quadrilateral opposite it along the diagonal through its smallest key.
fn prism(p: [Key; 6], out: &mut Vec<[Key; 4]>) {
    let m = (0..6).min_by_key(|&i| p[i]).unwrap_or(0);
    let (rot, flip) = (m % 3, m >= 3);
    let v = |j: usize| {
        let level = usize::from((j >= 3) != flip);
        p[(rot + j % 3) % 3 + 3 * level]
    };
    if v(1).min(v(5)) < v(2).min(v(4)) {
        out.push([v(0), v(1), v(2), v(5)]);
        out.push([v(0), v(1), v(5), v(4)]);
        out.push([v(0), v(4), v(5), v(3)]);
    } else {
        out.push([v(0), v(1), v(2), v(4)]);
        out.push([v(0), v(4), v(2), v(5)]);
        out.push([v(0), v(4), v(5), v(3)]);
    }
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
            prism(p, &mut out);
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
}
