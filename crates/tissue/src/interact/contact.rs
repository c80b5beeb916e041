//! Sphere contact against the deformed surface: which vertices are inside an instrument's
//! ball, where they go (radially onto the sphere), and whether a contact force is adhesive.
//!
//! Contact is vertex-based, as in the survey's prescribed-position view: a touched vertex
//! becomes a prescribed vertex, and the model returns the force it needs there.

use crate::interact::bvh::Bvh;
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
    let mut inside: Vec<u32> = candidates
        .iter()
        .filter_map(|&t| triangles.get(t as usize))
        .flatten()
        .copied()
        .filter(|&v| {
            positions
                .get(v as usize)
                .is_some_and(|p| p.distance(center) < limit)
        })
        .collect();
    inside.sort_unstable();
    inside.dedup();
    inside.retain(|&v| !skip(v));
    inside
        .into_iter()
        .map(|v| {
            let p = positions[v as usize];
            // Its triangles are all among the candidates: the vertex lies inside the query box.
            let normal = vertex_normal(v, &candidates, positions, triangles);
            Contact {
                vertex: v,
                target: push_out(p, center, radius, normal),
            }
        })
        .collect()
}

/// Where a vertex inside the ball goes. Radially out while the tool is on the outer side of
/// the surface; but when the centre has gone past the vertex (a coarse surface lets the ball
/// slip between vertices, or a vertex springs back behind it), radial projection would put
/// the vertex on the far side of the ball and the tissue would hold the tool from behind.
/// Then the vertex is pushed inward along its normal to the ball's inner side instead.
fn push_out(p: Vec3, center: Vec3, radius: Real, normal: Vec3) -> Vec3 {
    let n = normal.normalize_or_zero();
    let d = p - center;
    let along = d.dot(n);
    if n == Vec3::ZERO || along <= 0.0 {
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
}
