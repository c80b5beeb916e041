//! Element shape quality: a number in [0, 1] per element (1 for the regular shape, near 0 for
//! slivers and needles, negative for inverted tetrahedra), and its distribution over a mesh.
//!
//! Stiffness-matrix conditioning and explicit time steps are ruled by the worst elements, so
//! the minimum and the low bins of the histogram are what matter to a simulation.

use serde::Serialize;

use crate::math::{Real, Vec3, tet_signed_volume, triangle_area_vector};
use crate::mesh::{SurfaceMesh, TetMesh};

/// Tetrahedron quality 6√2·V / rms_edge³: 1 for the regular tetrahedron, 0 when flat,
/// negative when inverted. 0 when all corners coincide.
pub fn tet_quality(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> Real {
    let sq = [b - a, c - a, d - a, c - b, d - b, d - c]
        .iter()
        .map(|e| e.length_squared())
        .sum::<Real>();
    let rms = (sq / 6.0).sqrt();
    let denom = rms * rms * rms;
    if denom > 0.0 {
        6.0 * std::f64::consts::SQRT_2 * tet_signed_volume(a, b, c, d) / denom
    } else {
        0.0
    }
}

/// Triangle quality 4√3·A / Σ edge²: 1 for the equilateral triangle, 0 when flat.
pub fn triangle_quality(a: Vec3, b: Vec3, c: Vec3) -> Real {
    let sq = (b - a).length_squared() + (c - b).length_squared() + (a - c).length_squared();
    if sq > 0.0 {
        4.0 * 3f64.sqrt() * triangle_area_vector(a, b, c).length() / sq
    } else {
        0.0
    }
}

/// Quality of every tetrahedron, in order; 0 for a tetrahedron with an invalid vertex index.
pub fn tet_qualities(mesh: &TetMesh) -> Vec<Real> {
    let p = |i: u32| mesh.vertices.get(i as usize).copied();
    mesh.tets
        .iter()
        .map(|&[a, b, c, d]| match (p(a), p(b), p(c), p(d)) {
            (Some(a), Some(b), Some(c), Some(d)) => tet_quality(a, b, c, d),
            _ => 0.0,
        })
        .collect()
}

/// Quality of every triangle, in order; 0 for a triangle with an invalid vertex index.
pub fn triangle_qualities(mesh: &SurfaceMesh) -> Vec<Real> {
    let p = |i: u32| mesh.vertices.get(i as usize).copied();
    mesh.triangles
        .iter()
        .map(|&[a, b, c]| match (p(a), p(b), p(c)) {
            (Some(a), Some(b), Some(c)) => triangle_quality(a, b, c),
            _ => 0.0,
        })
        .collect()
}

/// Number of histogram bins over [0, 1].
pub const BINS: usize = 10;

/// The distribution of element qualities over a mesh.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct QualityStats {
    /// "tetrahedron" or "triangle".
    pub element: &'static str,
    /// Elements counted (finite qualities).
    pub count: usize,
    pub min: Real,
    /// Median; the mean of the two middle values for an even count.
    pub median: Real,
    pub max: Real,
    /// Counts over [0, 0.1), [0.1, 0.2), ..., [0.9, 1.0]; negatives are not in it.
    pub histogram: [usize; BINS],
    /// Elements with negative quality (inverted tetrahedra).
    pub inverted: usize,
    /// Elements whose quality is not a number (non-finite coordinates).
    pub non_finite: usize,
}

impl QualityStats {
    /// Statistics of a list of qualities; `None` when it holds no finite value.
    pub fn of(element: &'static str, qualities: &[Real]) -> Option<Self> {
        let mut q: Vec<Real> = qualities
            .iter()
            .copied()
            .filter(|q| q.is_finite())
            .collect();
        if q.is_empty() {
            return None;
        }
        q.sort_unstable_by(Real::total_cmp);
        let n = q.len();
        let median = if n % 2 == 1 {
            q[n / 2]
        } else {
            0.5 * (q[n / 2 - 1] + q[n / 2])
        };
        let mut histogram = [0usize; BINS];
        let mut inverted = 0;
        for &v in &q {
            if v < 0.0 {
                inverted += 1;
            } else {
                // Quality 1 (and rounding just above it) belongs to the last bin.
                let bin = ((v * BINS as Real) as usize).min(BINS - 1);
                histogram[bin] += 1;
            }
        }
        Some(Self {
            element,
            count: n,
            min: q[0],
            median,
            max: q[n - 1],
            histogram,
            inverted,
            non_finite: qualities.len() - n,
        })
    }

    /// Statistics over the tetrahedra of a mesh.
    pub fn of_tets(mesh: &TetMesh) -> Option<Self> {
        Self::of("tetrahedron", &tet_qualities(mesh))
    }

    /// Statistics over the triangles of a surface.
    pub fn of_triangles(mesh: &SurfaceMesh) -> Option<Self> {
        Self::of("triangle", &triangle_qualities(mesh))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn regular_tet() -> [Vec3; 4] {
        [
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
        ]
    }

    #[test]
    fn regular_shapes_have_quality_one() {
        let [a, b, c, d] = regular_tet();
        let s = tet_signed_volume(a, b, c, d).signum();
        assert!((tet_quality(a, b, c, d) - s).abs() < 1e-14);
        // Quality is invariant under scaling and translation.
        let t = |p: Vec3| 3.7 * p + Vec3::new(5.0, -2.0, 1.0);
        assert!((tet_quality(t(a), t(b), t(c), t(d)) - s).abs() < 1e-13);
        let (p, q, r) = (Vec3::ZERO, Vec3::X, Vec3::new(0.5, 0.75f64.sqrt(), 0.0));
        assert!((triangle_quality(p, q, r) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn inverted_tet_is_negative_and_flat_is_zero() {
        let [a, b, c, d] = regular_tet();
        assert!((tet_quality(a, b, c, d) + tet_quality(b, a, c, d)).abs() < 1e-15);
        let flat = tet_quality(Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(flat, 0.0);
        assert_eq!(tet_quality(Vec3::ONE, Vec3::ONE, Vec3::ONE, Vec3::ONE), 0.0);
        // Right-angle corner tet: V = 1/6, Σe² = 3 + 3·2 = 9, rms = √1.5.
        let q = tet_quality(Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z);
        let expected = 6.0 * 2f64.sqrt() / 6.0 / 1.5f64.powf(1.5);
        assert!((q - expected).abs() < 1e-15);
        // Right isosceles triangle: A = 1/2, Σe² = 4 → √3/2.
        let q = triangle_quality(Vec3::ZERO, Vec3::X, Vec3::Y);
        assert!((q - 3f64.sqrt() / 2.0).abs() < 1e-15);
    }

    #[test]
    fn stats_bins_median_and_inverted() {
        let s = QualityStats::of("tetrahedron", &[0.05, 1.0, 0.55, -0.2, 0.3, f64::NAN])
            .unwrap_or_else(|| panic!("finite values present"));
        assert_eq!(s.count, 5);
        assert_eq!(s.non_finite, 1);
        assert_eq!(s.inverted, 1);
        assert_eq!(s.histogram, [1, 0, 0, 1, 0, 1, 0, 0, 0, 1]);
        assert_eq!((s.min, s.median, s.max), (-0.2, 0.3, 1.0));
        let even = QualityStats::of("triangle", &[0.2, 0.4]).unwrap_or_else(|| panic!());
        assert!((even.median - 0.3).abs() < 1e-15);
        assert!(QualityStats::of("triangle", &[f64::NAN]).is_none());
    }
}
