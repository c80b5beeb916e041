//! The scalar and small fixed-size types used everywhere, named in one place.
//!
//! tissue computes in `f64` throughout (SI units: m, kg, s, Pa, N). Small 3-D algebra uses
//! `glam`'s double-precision types; large systems go through `faer`.

pub type Real = f64;
pub type Vec3 = glam::DVec3;
pub type Mat3 = glam::DMat3;

/// Signed volume of the tetrahedron (a, b, c, d): positive when (b-a)·((c-a)×(d-a)) > 0.
#[inline]
pub fn tet_signed_volume(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> Real {
    (b - a).dot((c - a).cross(d - a)) / 6.0
}

/// Area vector of the triangle (a, b, c): normal direction (counter-clockwise), length = area.
#[inline]
pub fn triangle_area_vector(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    0.5 * (b - a).cross(c - a)
}

/// True when every component is finite (no NaN, no infinity).
#[inline]
pub fn is_finite_vec(v: Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// Views a slice of 3-vectors as a flat slice of reals (x0, y0, z0, x1, ...), without copying.
#[inline]
pub fn flatten(v: &[Vec3]) -> &[Real] {
    // SAFETY: DVec3 is #[repr(C)] with exactly three f64 fields and no padding.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<Real>(), v.len() * 3) }
}

/// Mutable flat view of a slice of 3-vectors.
#[inline]
pub fn flatten_mut(v: &mut [Vec3]) -> &mut [Real] {
    // SAFETY: as in `flatten`.
    unsafe { std::slice::from_raw_parts_mut(v.as_mut_ptr().cast::<Real>(), v.len() * 3) }
}

/// Views a flat slice of reals as 3-vectors, without copying; a trailing partial vector is
/// left out.
#[inline]
pub fn unflatten(v: &[Real]) -> &[Vec3] {
    // SAFETY: as in `flatten`; DVec3 has the alignment of f64.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<Vec3>(), v.len() / 3) }
}

/// Mutable 3-vector view of a flat slice of reals.
#[inline]
pub fn unflatten_mut(v: &mut [Real]) -> &mut [Vec3] {
    // SAFETY: as in `unflatten`.
    unsafe { std::slice::from_raw_parts_mut(v.as_mut_ptr().cast::<Vec3>(), v.len() / 3) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_tet_volume_is_one_sixth() {
        let v = tet_signed_volume(Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z);
        assert!((v - 1.0 / 6.0).abs() < 1e-15);
        let w = tet_signed_volume(Vec3::ZERO, Vec3::Y, Vec3::X, Vec3::Z);
        assert!((w + 1.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn flat_view_matches_components() {
        let v = vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 5.0, 6.0)];
        assert_eq!(flatten(&v), &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(
            unflatten(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]),
            v.as_slice()
        );
    }
}
