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

/// Where the segment p→q crosses the triangle (a, b, c), as a fraction of p→q
/// (Möller–Trumbore; the triangle's edges and the segment's ends count as crossing, within
/// 1e-12 in barycentric terms; a segment parallel to the plane does not cross).
pub fn segment_triangle(p: Vec3, q: Vec3, [a, b, c]: [Vec3; 3]) -> Option<Real> {
    const EPS: Real = 1e-12;
    let d = q - p;
    let (e1, e2) = (b - a, c - a);
    let h = d.cross(e2);
    let det = e1.dot(h);
    if det.abs() <= EPS * e1.length() * e2.length() * d.length() {
        return None;
    }
    let s = p - a;
    let u = s.dot(h) / det;
    let k = s.cross(e1);
    let v = d.dot(k) / det;
    let t = e2.dot(k) / det;
    (u >= -EPS && v >= -EPS && u + v <= 1.0 + EPS && (0.0..=1.0).contains(&t)).then_some(t)
}

/// The point of the triangle (a, b, c) nearest to p, by the Voronoi regions of its corners,
/// edges and face.
pub fn closest_point_on_triangle(p: Vec3, [a, b, c]: [Vec3; 3]) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    a + ab * (vb / denom) + ac * (vc / denom)
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

/// Checks shared by the tests of several model families.
#[cfg(test)]
pub(crate) mod testing {
    use super::{Mat3, Real, Vec3};

    /// The Jacobian of `f` at the origin of its argument by central differences of step
    /// `h`: column j is (f(h e_j) − f(−h e_j)) / 2h. Exact to rounding for a linear `f`.
    pub fn central_jacobian(h: Real, mut f: impl FnMut(Vec3) -> Vec3) -> Mat3 {
        let mut columns = [Vec3::ZERO; 3];
        for (column, axis) in columns.iter_mut().zip(Vec3::AXES) {
            *column = (f(axis * h) - f(-axis * h)) / (2.0 * h);
        }
        Mat3::from_cols(columns[0], columns[1], columns[2])
    }

    /// The largest entry of `m` in magnitude.
    pub fn max_entry(m: Mat3) -> Real {
        m.to_cols_array().iter().fold(0.0, |a, b| a.max(b.abs()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_triangle_gives_the_crossing_fraction_and_counts_edges() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let through =
            |x: Real, y: Real| segment_triangle(Vec3::new(x, y, -1.0), Vec3::new(x, y, 3.0), tri);
        assert_eq!(through(0.25, 0.25), Some(0.25));
        assert_eq!(through(0.5, 0.5), Some(0.25)); // on the hypotenuse
        assert_eq!(through(0.0, 0.0), Some(0.25)); // a corner
        assert_eq!(through(0.6, 0.6), None);
        assert_eq!(through(-0.01, 0.5), None);
        // Ends: touching counts, stopping short does not; parallel never crosses.
        assert_eq!(
            segment_triangle(Vec3::new(0.2, 0.2, 0.0), Vec3::new(0.2, 0.2, 1.0), tri),
            Some(0.0)
        );
        assert_eq!(
            segment_triangle(Vec3::new(0.2, 0.2, 0.5), Vec3::new(0.2, 0.2, 1.0), tri),
            None
        );
        assert_eq!(
            segment_triangle(Vec3::new(-1.0, 0.2, 0.0), Vec3::new(2.0, 0.2, 0.0), tri),
            None
        );
    }

    #[test]
    fn closest_point_on_triangle_agrees_with_a_dense_sampling() {
        let tri = [
            Vec3::new(0.1, -0.2, 0.3),
            Vec3::new(1.3, 0.1, -0.2),
            Vec3::new(0.4, 0.9, 0.5),
        ];
        // Points in every Voronoi region (corners, edges, face, both sides).
        let mut seed = 7u64;
        let mut rand = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as Real / (1u64 << 53) as Real * 4.0 - 2.0
        };
        for _ in 0..200 {
            let p = Vec3::new(rand(), rand(), rand());
            let q = closest_point_on_triangle(p, tri);
            let mut best = Real::INFINITY;
            let m = 300;
            for i in 0..=m {
                for j in 0..=(m - i) {
                    let (u, v) = (i as Real / m as Real, j as Real / m as Real);
                    let s = tri[0] + (tri[1] - tri[0]) * u + (tri[2] - tri[0]) * v;
                    best = best.min((s - p).length());
                }
            }
            let d = (q - p).length();
            assert!(
                d <= best + 1e-12 && d > best - 5e-3,
                "{p}: {d} vs sampled {best}"
            );
        }
    }

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
