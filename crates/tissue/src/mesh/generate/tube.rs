//! Cylinders and tubes along z as triangle surfaces: organ stand-ins, vessels and ducts.
//!
//! Cross-sections are regular polygons inscribed in the circle (vertices on the circle), so
//! the enclosed volume is that of the prism over the polygon, not πr²h.

use std::f64::consts::TAU;

use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;

/// Rings of `segments` vertices at z = 0, length/rings, ..., length, of the given radius.
fn rings_of(radius: Real, length: Real, segments: usize, rings: usize) -> Vec<Vec3> {
    let mut v = Vec::with_capacity(segments * (rings + 1));
    for k in 0..=rings {
        let z = length * k as Real / rings as Real;
        for i in 0..segments {
            let a = TAU * i as Real / segments as Real;
            v.push(Vec3::new(radius * a.cos(), radius * a.sin(), z));
        }
    }
    v
}

/// Side triangles between ring layers starting at vertex `base`, normals pointing away from
/// the axis (or towards it when `inward`).
fn side(base: u32, segments: usize, rings: usize, inward: bool, out: &mut Vec<[u32; 3]>) {
    let s = segments as u32;
    for k in 0..rings as u32 {
        for i in 0..s {
            let j = (i + 1) % s;
            let (p00, p10) = (base + k * s + i, base + k * s + j);
            let (p01, p11) = (p00 + s, p10 + s);
            if inward {
                out.extend([[p00, p11, p10], [p00, p01, p11]]);
            } else {
                out.extend([[p00, p10, p11], [p00, p11, p01]]);
            }
        }
    }
}

/// A cylinder of `radius` from z = 0 to z = `height`, `segments` (≥ 3) around and `rings`
/// (≥ 1) along. Capped, it is closed and outward; the caps are fans around a centre vertex.
pub fn cylinder(
    radius: Real,
    height: Real,
    segments: usize,
    rings: usize,
    capped: bool,
) -> SurfaceMesh {
    let (segments, rings) = (segments.max(3), rings.max(1));
    let mut vertices = rings_of(radius, height, segments, rings);
    let mut triangles = Vec::with_capacity(2 * segments * (rings + 1));
    side(0, segments, rings, false, &mut triangles);
    if capped {
        let s = segments as u32;
        let bottom = vertices.len() as u32;
        let top_ring = rings as u32 * s;
        vertices.push(Vec3::ZERO);
        vertices.push(Vec3::new(0.0, 0.0, height));
        for i in 0..s {
            let j = (i + 1) % s;
            triangles.push([bottom, j, i]);
            triangles.push([bottom + 1, top_ring + i, top_ring + j]);
        }
    }
    SurfaceMesh::new(vertices, triangles)
}

/// An open tube (a vessel) of `radius` from z = 0 to z = `length`, normals outward.
pub fn tube(radius: Real, length: Real, segments: usize, rings: usize) -> SurfaceMesh {
    cylinder(radius, length, segments, rings, false)
}

/// A tube with a wall: outer and inner cylinders joined by annular end faces, a closed
/// outward surface enclosing the wall material.
pub fn tube_with_wall(
    inner: Real,
    outer: Real,
    length: Real,
    segments: usize,
    rings: usize,
) -> SurfaceMesh {
    let (segments, rings) = (segments.max(3), rings.max(1));
    let mut vertices = rings_of(outer, length, segments, rings);
    let inner_base = vertices.len() as u32;
    vertices.extend(rings_of(inner, length, segments, rings));
    let mut triangles = Vec::with_capacity(4 * segments * (rings + 1));
    side(0, segments, rings, false, &mut triangles);
    side(inner_base, segments, rings, true, &mut triangles);
    let s = segments as u32;
    let top = rings as u32 * s;
    for i in 0..s {
        let j = (i + 1) % s;
        let (o, n) = (0, inner_base);
        // Bottom annulus faces -z, top annulus +z.
        triangles.extend([[o + i, n + i, n + j], [o + i, n + j, o + j]]);
        let (o, n) = (top, inner_base + top);
        triangles.extend([[o + i, o + j, n + j], [o + i, n + j, n + i]]);
    }
    SurfaceMesh::new(vertices, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Area of the regular n-gon inscribed in a circle of radius r.
    fn polygon_area(r: Real, n: usize) -> Real {
        0.5 * n as Real * r * r * (TAU / n as Real).sin()
    }

    #[test]
    fn capped_cylinder_volume_and_area_are_the_prism_s() {
        let (r, h, n) = (0.3, 1.2, 24);
        let m = cylinder(r, h, n, 5, true);
        let side = n as Real * 2.0 * r * (TAU / (2.0 * n as Real)).sin() * h;
        assert!((m.signed_volume() - polygon_area(r, n) * h).abs() < 1e-14);
        assert!((m.area() - (2.0 * polygon_area(r, n) + side)).abs() < 1e-13);
    }

    #[test]
    fn walled_tube_encloses_the_annulus() {
        let (a, b, l, n) = (0.5, 0.8, 2.0, 16);
        let m = tube_with_wall(a, b, l, n, 3);
        let expected = (polygon_area(b, n) - polygon_area(a, n)) * l;
        assert!((m.signed_volume() - expected).abs() < 1e-13);
    }
}
