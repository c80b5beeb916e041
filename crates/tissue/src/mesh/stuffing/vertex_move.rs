//! A vertex of a stuffed mesh moved only as far as the mesh's guarantees allow: what the
//! bare-vertex repair (`bare`) and the labels' volume correction (`interface_volume`) share.

use super::PROVEN_DIHEDRAL_DEG;
use super::report::dihedral_angles;
use crate::math::{Real, Vec3, tet_signed_volume};
use crate::mesh::TetMesh;

/// Moves vertex `v` by the first of `fractions` of `d` that keeps every tetrahedron of
/// `around` (those that use `v`) oriented as it was and its dihedral angles within the
/// proven bounds (or within those they already had, when already wider). Returns the index
/// of the fraction taken; `None` leaves the vertex where it was.
pub(super) fn move_within_bounds(
    mesh: &mut TetMesh,
    v: u32,
    around: &[usize],
    d: Vec3,
    fractions: &[Real],
) -> Option<usize> {
    let range = |m: &TetMesh| {
        let (mut lo, mut hi) = (Real::INFINITY, 0.0 as Real);
        let mut positive = Vec::with_capacity(around.len());
        for &t in around {
            let q = m.tets[t].map(|u| m.vertices[u as usize]);
            for a in dihedral_angles(q) {
                lo = lo.min(a);
                hi = hi.max(a);
            }
            positive.push(tet_signed_volume(q[0], q[1], q[2], q[3]) > 0.0);
        }
        (lo, hi, positive)
    };
    let p = mesh.vertices[v as usize];
    let (lo0, hi0, signs) = range(mesh);
    let lo_bound = PROVEN_DIHEDRAL_DEG.0.to_radians().min(lo0);
    let hi_bound = PROVEN_DIHEDRAL_DEG.1.to_radians().max(hi0);
    for (i, &f) in fractions.iter().enumerate() {
        mesh.vertices[v as usize] = p + f * d;
        let (lo, hi, now) = range(mesh);
        if now == signs && lo >= lo_bound && hi <= hi_bound {
            return Some(i);
        }
    }
    mesh.vertices[v as usize] = p;
    None
}
