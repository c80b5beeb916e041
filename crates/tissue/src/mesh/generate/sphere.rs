//! Spheres as closed, outward triangle surfaces: subdivided icosahedra (even triangles, no
//! poles), the usual test body for contact and for closed-surface checks.

use std::collections::HashMap;

use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;

/// Subdivision levels above this would overflow memory long before `u32` indices.
pub const MAX_SUBDIVISIONS: u32 = 10;

/// A sphere of `radius` around `center`: the icosahedron with each triangle split into four
/// `subdivisions` times (clamped to `MAX_SUBDIVISIONS`), every vertex on the sphere.
/// 10·4^s + 2 vertices and 20·4^s triangles, counter-clockwise seen from outside.
pub fn icosphere(center: Vec3, radius: Real, subdivisions: u32) -> SurfaceMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut unit: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions.min(MAX_SUBDIVISIONS) {
        // Each edge gets one midpoint, shared by the two triangles on it.
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 2);
        let mut mid = |a: u32, b: u32, unit: &mut Vec<Vec3>| {
            let key = (a.min(b), a.max(b));
            *midpoint.entry(key).or_insert_with(|| {
                unit.push((unit[a as usize] + unit[b as usize]).normalize());
                (unit.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(triangles.len() * 4);
        for &[a, b, c] in &triangles {
            let ab = mid(a, b, &mut unit);
            let bc = mid(b, c, &mut unit);
            let ca = mid(c, a, &mut unit);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    let vertices = unit.into_iter().map(|u| center + radius * u).collect();
    SurfaceMesh::new(vertices, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosahedron_matches_closed_form() {
        // Circumradius 1: edge a = 4 / √(10 + 2√5), V = 5/12 (3 + √5) a³, A = 5√3 a².
        let m = icosphere(Vec3::new(1.0, 2.0, 3.0), 1.0, 0);
        let a = 4.0 / (10.0 + 2.0 * 5f64.sqrt()).sqrt();
        let v = 5.0 / 12.0 * (3.0 + 5f64.sqrt()) * a * a * a;
        let moved = SurfaceMesh::new(
            m.vertices
                .iter()
                .map(|p| *p - Vec3::new(1.0, 2.0, 3.0))
                .collect(),
            m.triangles.clone(),
        );
        assert!((moved.signed_volume() - v).abs() < 1e-14);
        assert!((m.area() - 5.0 * 3f64.sqrt() * a * a).abs() < 1e-13);
        // Signed volume is translation invariant for a closed surface.
        assert!((m.signed_volume() - v).abs() < 1e-12);
    }

    #[test]
    fn counts_follow_subdivision() {
        for s in 0..4 {
            let m = icosphere(Vec3::ZERO, 2.0, s);
            assert_eq!(m.vertices.len(), 10 * 4usize.pow(s) + 2);
            assert_eq!(m.triangles.len(), 20 * 4usize.pow(s));
            assert!(m.vertices.iter().all(|p| (p.length() - 2.0).abs() < 1e-14));
        }
    }
}
