//! Several labelled regions stuffed at once, the interfaces between them followed by faces
//! of the mesh (multi-material stuffing on one BCC lattice).
//!
//! Every lattice vertex gets a material: 0 outside, 1..=K for the domain's
//! `material_tags`. An edge whose ends have different materials gets one cut point, on
//! the outer boundary (one end outside) or on the interface between the two labels. The
//! outer boundary and every interface are then stuffed alike:
//!
//! - **Warping.** A vertex near a cut point of one of its edges moves onto it, as in
//!   single-material stuffing, and then lies on the interface between its material and the
//!   other end's (`Side`). It may move only when every lattice neighbour is of one of those
//!   two materials (`may_warp`): every BCC tetrahedron around it then holds at most two
//!   materials, so the two-material stencils below stay complementary. A vertex refused
//!   for that reason (next to a third material: where an interface meets the outer boundary
//!   or another interface) stays, and the cut point too near it is moved to α times the
//!   edge's length from it, so that every cut point left is at least that far from both
//!   ends, as warping guarantees elsewhere. The interface moves by at most α·length there
//!   (0.25 h on long edges, 0.36 h on short ones).
//! - **Two materials in a tetrahedron** (the common case): the ordinary stencil of each
//!   material, with that material inside and the other outside, the signs read from `Side`.
//!   The two parts tile the tetrahedron and share the faces between them: the cut points
//!   are shared, a quadrilateral in a lattice face is split by the lattice rule, and the
//!   quadrilateral of four cut points inside a two-in two-out tetrahedron is split the same
//!   way from both sides (the caller picks the diagonal that keeps both prisms better).
//! - **Three or four materials** (a junction: only unwarped vertices, by the rule above):
//!   each face is divided by its materials (one: whole; two: the stencils' triangle and
//!   quadrilateral, split by the lattice rule; three: six triangles around a point where
//!   the three meet, the mean of its three cut points, shared with the neighbour across the
//!   face), and every triangle is joined to one point inside the tetrahedron, the mean of
//!   its interface points (`junction`). This is cleaving's subdivision (Bronson, Levine &
//!   Whitaker, "Lattice cleaving", IEEE TVCG 2014) reduced to a cone; the angle bound of the
//!   stencils is not proven for these tetrahedra: the report gives their smallest angle.

use crate::mesh::stuffing::stencil::{Key, Split};

use super::lattice::Lattice;

/// A lattice vertex's place among materials: inside material `a` when `a == b`, on the
/// interface between `a` and `b` after warping (0 is the outside).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Side {
    pub a: u16,
    pub b: u16,
}

impl Side {
    pub fn single(m: u16) -> Self {
        Self { a: m, b: m }
    }

    pub fn is_single(self) -> bool {
        self.a == self.b
    }

    pub fn touches(self, m: u16) -> bool {
        self.a == m || self.b == m
    }

    /// The sign stuffing gives this vertex when material `m` is the inside: −1 inside it,
    /// 0 on its boundary, +1 outside it.
    pub fn sign(self, m: u16) -> i8 {
        if !self.touches(m) {
            1
        } else if self.is_single() {
            -1
        } else {
            0
        }
    }
}

/// Whether vertex `v` (of material `material[v]`) may be warped onto an interface with
/// material `to`: every lattice neighbour is of one of the two.
pub(crate) fn may_warp(lattice: &Lattice, material: &[u16], v: u32, to: u16) -> bool {
    let own = material[v as usize];
    let mut ok = true;
    lattice.for_each_neighbour(v, |u| {
        let m = material[u as usize];
        ok &= m == own || m == to;
    });
    ok
}

/// The faces of a tetrahedron, each as three of its corners.
const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// The parts of a junction tetrahedron `t` (all corners unwarped, material `material(v)`),
/// pushed as (tetrahedron, material) for every material but the outside. `cut(a, b)` is
/// the cut point on edge (a, b), `triple(face)` the point where a face's three materials
/// meet (asked with the face's corners sorted), `centre` the point inside the tetrahedron
/// every face triangle is joined to.
pub(crate) fn junction(
    t: [u32; 4],
    material: impl Fn(u32) -> u16,
    cut: impl Fn(u32, u32) -> Key,
    split: &Split<'_>,
    triple: impl Fn([u32; 3]) -> Key,
    centre: Key,
    out: &mut Vec<([Key; 4], u16)>,
) {
    let k = |v: u32| v as Key;
    let mut tris: Vec<([Key; 3], u16)> = Vec::with_capacity(24);
    for f in FACES {
        let f = f.map(|i| t[i]);
        let m = f.map(&material);
        if m[0] == m[1] && m[1] == m[2] {
            tris.push((f.map(k), m[0]));
        } else if m[0] != m[1] && m[1] != m[2] && m[0] != m[2] {
            let mut sorted = f;
            sorted.sort_unstable();
            let tp = triple(sorted);
            for i in 0..3 {
                let (p, q, r) = (f[i], f[(i + 1) % 3], f[(i + 2) % 3]);
                tris.push(([k(p), cut(p, q), tp], m[i]));
                tris.push(([k(p), tp, cut(p, r)], m[i]));
            }
        } else {
            // Two of one material (u, v), one of another (w): the stencils' quadrilateral
            // and triangle, the quadrilateral split by the lattice rule as the neighbour
            // across this face splits it.
            let odd = (0..3)
                .find(|&i| m[i] != m[(i + 1) % 3] && m[i] != m[(i + 2) % 3])
                .unwrap_or(0);
            let (w, u, v) = (f[odd], f[(odd + 1) % 3], f[(odd + 2) % 3]);
            let q = [k(u), k(v), cut(v, w), cut(u, w)];
            let d = if split(q).unwrap_or(true) { 0 } else { 1 };
            let r = |j: usize| q[(d + j) % 4];
            tris.push(([r(0), r(1), r(2)], material(u)));
            tris.push(([r(0), r(2), r(3)], material(u)));
            tris.push(([k(w), cut(w, u), cut(w, v)], material(w)));
        }
    }
    for (tri, m) in tris {
        if m != 0 {
            out.push(([tri[0], tri[1], tri[2], centre], m));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signs_follow_the_side() {
        let inside = Side::single(2);
        let on = Side { a: 2, b: 1 };
        assert_eq!((inside.sign(2), inside.sign(1), inside.sign(0)), (-1, 1, 1));
        assert_eq!((on.sign(2), on.sign(1), on.sign(0)), (0, 0, 1));
    }
}
