//! Which diagonal splits a quadrilateral that lies in a face of the BCC lattice.
//!
//! A stencil's quadrilateral in a lattice face joins the face's two inside lattice vertices
//! u, v to the cut points on the edges from them to the face's outside vertex w. Both BCC
//! tetrahedra sharing the face must split it the same way, so the choice may depend only on
//! the face: here on the lattice positions of u, v and w (doubled integer coordinates).
//! The diagonal ends at u or at v; `touches_u` says which.

use super::stencil::Key;

/// Where a polyhedron vertex lies on the unwarped lattice, in doubled integer coordinates
/// (black vertices even, red odd): a lattice vertex, or a cut point on the edge (a, b).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Site {
    Vertex([i64; 3]),
    Cut([i64; 3], [i64; 3]),
}

/// A rule: `touch(u, v, w)` is true when the diagonal ends at u.
pub(crate) type Touch = fn([i64; 3], [i64; 3], [i64; 3]) -> bool;

/// The split of `q` (cyclic order) by `touch`: `Some(true)` for the diagonal (q0, q2),
/// `None` for a quadrilateral of four cut points (inside one BCC tetrahedron).
pub(crate) fn lattice_split(q: [Key; 4], site: impl Fn(Key) -> Site, touch: Touch) -> Option<bool> {
    let s = q.map(site);
    let j = (0..4)
        .find(|&j| matches!(s[j], Site::Vertex(_)) && matches!(s[(j + 1) % 4], Site::Vertex(_)))?;
    let (Site::Vertex(u), Site::Vertex(v), Site::Cut(a, b)) =
        (s[j], s[(j + 1) % 4], s[(j + 2) % 4])
    else {
        return None;
    };
    // The cut point after v in the cycle is on the edge (v, w).
    let w = if a == v { b } else { a };
    let end = if touch(u, v, w) { j } else { (j + 1) % 4 };
    Some(end % 2 == 0)
}

pub(crate) fn is_red(d: [i64; 3]) -> bool {
    d[0] & 1 == 1
}

/// The axis along which a long edge (u, v) runs (the sampling study's rules use it).
#[cfg(test)]
pub(crate) fn axis(u: [i64; 3], v: [i64; 3]) -> usize {
    (0..3).find(|&i| u[i] != v[i]).unwrap_or(0)
}

/// The rule stuffing uses: Labelle & Shewchuk's (2007, section 3.3).
/// - u, v joined by a long edge (two black or two red vertices): the paper's parity rule.
///   Of the two diagonals exactly one, lattice vertex X to cut point C, has an odd number
///   of coordinates in which X > C (the other differs from it in the edge's coordinate
///   only); a black edge takes that one, a red edge the other. The choice depends on the
///   face's shape, not on where it lies, and it turns the two faces that share a long edge
///   opposite ways (their outside vertices differ in one coordinate's side), so the prism
///   of a two-in two-out tetrahedron has its diagonals at different ends of the edge.
/// - u, v joined by a short edge (one of them, the "base", shares the face's long edge with
///   w): the diagonal ends at the other one, the apex, and so meets the cut point on the
///   long edge (the paper's stencils draw it so).
///
/// Before session 13 a long edge took the end whose cube index along the edge is even (the
/// same end for both faces sharing the edge). The sampling in `stencil_bounds` measured
/// both rules at the same worst angle (the worst cases are a pyramid with a short inside
/// edge and tetrahedra without quadrilaterals); the paper's is kept as the one its proof
/// is about.
pub(crate) const PARITY: Touch = |u, v, w| {
    if is_red(u) == is_red(v) {
        paper_parity(u, v, w)
    } else {
        is_red(u) != is_red(w)
    }
};

/// Whether the diagonal of a face with inside long edge (u, v) and outside vertex w ends
/// at u, by the parity rule: `odd` counts the coordinates in which u exceeds the cut point
/// on (v, w) (any point strictly inside that edge compares as its midpoint does, as the
/// lattice coordinates are integers: doubled, 2·u > v + w).
pub(crate) fn paper_parity(u: [i64; 3], v: [i64; 3], w: [i64; 3]) -> bool {
    let odd = (0..3).filter(|&i| 2 * u[i] > v[i] + w[i]).count() % 2 == 1;
    odd != is_red(u)
}
