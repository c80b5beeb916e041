//! Triangle surface meshes: what the user sees, draws and touches.

use crate::error::MeshError;
use crate::math::{Real, Vec3, triangle_area_vector};

/// A triangle surface. Triangles are counter-clockwise seen from outside for a closed,
/// outward-oriented surface.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceMesh {
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl SurfaceMesh {
    pub fn new(vertices: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Self {
        Self {
            vertices,
            triangles,
        }
    }

    /// Checks indices and coordinates; the cheapest checks every consumer relies on.
    pub fn validate_indices(&self) -> Result<(), MeshError> {
        validate_vertices(&self.vertices)?;
        let n = self.vertices.len();
        for (t, tri) in self.triangles.iter().enumerate() {
            check_element("triangle", t, tri, n)?;
        }
        Ok(())
    }

    /// Corner positions of triangle `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Total area, in m².
    pub fn area(&self) -> Real {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.corners(t);
                triangle_area_vector(a, b, c).length()
            })
            .sum()
    }

    /// Signed enclosed volume Σ a·(b×c)/6, in m³: positive for a closed outward surface.
    /// Meaningless for an open surface.
    pub fn signed_volume(&self) -> Real {
        signed_volume_of(&self.vertices, &self.triangles)
    }

    /// Axis-aligned bounds (min, max); `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        bounds_of(&self.vertices)
    }

    /// Area-weighted vertex normals (unit length; zero for unused vertices).
    pub fn vertex_normals(&self) -> Vec<Vec3> {
        let mut n = vec![Vec3::ZERO; self.vertices.len()];
        for t in 0..self.triangles.len() {
            let [a, b, c] = self.corners(t);
            let an = triangle_area_vector(a, b, c);
            for &v in &self.triangles[t] {
                n[v as usize] += an;
            }
        }
        for v in &mut n {
            *v = v.normalize_or_zero();
        }
        n
    }
}

/// Signed volume enclosed by triangles over the given positions.
pub fn signed_volume_of(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Real {
    triangles
        .iter()
        .map(|&[a, b, c]| {
            let (a, b, c) = (
                vertices[a as usize],
                vertices[b as usize],
                vertices[c as usize],
            );
            a.dot(b.cross(c))
        })
        .sum::<Real>()
        / 6.0
}

pub(crate) fn bounds_of(vertices: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let first = *vertices.first()?;
    Some(
        vertices
            .iter()
            .fold((first, first), |(lo, hi), &v| (lo.min(v), hi.max(v))),
    )
}

pub(crate) fn validate_vertices(vertices: &[Vec3]) -> Result<(), MeshError> {
    for (i, v) in vertices.iter().enumerate() {
        if !crate::math::is_finite_vec(*v) {
            return Err(MeshError::NonFiniteVertex {
                vertex: i,
                x: v.x,
                y: v.y,
                z: v.z,
            });
        }
    }
    Ok(())
}

pub(crate) fn check_element(
    element_kind: &'static str,
    element: usize,
    ids: &[u32],
    vertex_count: usize,
) -> Result<(), MeshError> {
    for (k, &i) in ids.iter().enumerate() {
        if i as usize >= vertex_count {
            return Err(MeshError::IndexOutOfRange {
                element_kind,
                element,
                index: i as usize,
                vertex_count,
            });
        }
        if ids[..k].contains(&i) {
            return Err(MeshError::RepeatedVertex {
                element_kind,
                element,
                vertex: i as usize,
            });
        }
    }
    Ok(())
}
