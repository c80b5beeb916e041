//! A summary of a mesh for people and scripts: sizes, volume, area, bounds, topology,
//! element quality and problems (what `tissue mesh inspect FILE` prints, as text or JSON).

use std::fmt;

use serde::Serialize;

use crate::math::{Real, is_finite_vec};
use crate::mesh::check::{Problem, check};
use crate::mesh::quality::{BINS, QualityStats};
use crate::mesh::topology::{components, edge_faces, euler_characteristic};
use crate::mesh::{MeshData, SurfaceMesh, TetMesh, boundary_surface};

/// Axis-aligned bounds of the finite vertices.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Bounds {
    pub min: [Real; 3],
    pub max: [Real; 3],
}

/// A problem with its human-readable message, for JSON output.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ProblemReport {
    #[serde(flatten)]
    pub problem: Problem,
    pub message: String,
}

/// Everything `inspect` finds out about a mesh.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Inspection {
    pub vertices: usize,
    pub triangles: usize,
    pub tetrahedra: usize,
    pub tetrahedra10: usize,
    /// Tetrahedra volume if any; else the enclosed volume of a closed surface; else none
    /// (also when it is not finite: a vertex named in `problems` makes it so).
    pub volume: Option<Real>,
    /// Area of the boundary (volume meshes) or of the triangles; none when not finite.
    pub surface_area: Option<Real>,
    pub bounds: Option<Bounds>,
    /// Connected components (through shared vertices) of the volume, else of the surface.
    pub components: usize,
    /// V − E + F of the boundary (volume meshes) or of the triangles.
    pub euler_characteristic: i64,
    /// Whether that surface has no border and no non-manifold edge.
    pub closed: bool,
    /// Triangles of the volume's boundary; none for a surface mesh.
    pub boundary_triangles: Option<usize>,
    pub fixed_vertices: usize,
    /// Tetrahedron quality for volume meshes, triangle quality otherwise.
    pub quality: Option<QualityStats>,
    pub problems: Vec<ProblemReport>,
}

/// Inspects a mesh. Elements with out-of-range indices are reported as problems and left
/// out of the measurements.
pub fn inspect(mesh: &MeshData) -> Inspection {
    let n = mesh.vertices.len();
    let ok = |e: &[u32]| e.iter().all(|&i| (i as usize) < n);
    let mut tets: Vec<[u32; 4]> = mesh.tets.iter().copied().filter(|t| ok(t)).collect();
    tets.extend(
        mesh.tets10
            .iter()
            .filter(|t| ok(&t[..]))
            .map(|t| [t[0], t[1], t[2], t[3]]),
    );
    let triangles: Vec<[u32; 3]> = mesh.triangles.iter().copied().filter(|t| ok(t)).collect();
    let volume_mesh = mesh.has_volume();

    let (surface, boundary_triangles, volume, comps, quality) = if volume_mesh {
        let tm = TetMesh::new(mesh.vertices.clone(), tets);
        let b = boundary_surface(&tm);
        let count = b.surface.triangles.len();
        let q = QualityStats::of_tets(&tm);
        let comps = components(&tm.tets).count;
        (b.surface, Some(count), Some(tm.volume()), comps, q)
    } else {
        let s = SurfaceMesh::new(mesh.vertices.clone(), triangles);
        let q = QualityStats::of_triangles(&s);
        let comps = components(&s.triangles).count;
        (s, None, None, comps, q)
    };
    let ef = edge_faces(&surface.triangles);
    let closed = !surface.triangles.is_empty() && ef.with_face_count(|k| k != 2).next().is_none();
    let volume = volume.or_else(|| closed.then(|| surface.signed_volume()));
    // A NaN or 1e308 coordinate is a named problem; its overflow is no measurement.
    let volume = volume.filter(|v| v.is_finite());
    let area = Some(surface.area()).filter(|a| a.is_finite());
    let finite: Vec<_> = mesh
        .vertices
        .iter()
        .copied()
        .filter(|p| is_finite_vec(*p))
        .collect();
    let bounds = crate::mesh::surface::bounds_of(&finite).map(|(lo, hi)| Bounds {
        min: lo.to_array(),
        max: hi.to_array(),
    });
    let problems = check(mesh)
        .into_iter()
        .map(|problem| ProblemReport {
            message: problem.to_string(),
            problem,
        })
        .collect();
    Inspection {
        vertices: n,
        triangles: mesh.triangles.len(),
        tetrahedra: mesh.tets.len(),
        tetrahedra10: mesh.tets10.len(),
        volume,
        surface_area: area,
        bounds,
        components: comps,
        euler_characteristic: euler_characteristic(&surface.triangles),
        closed,
        boundary_triangles,
        fixed_vertices: mesh.fixed_vertices.len(),
        quality,
        problems,
    }
}

impl fmt::Display for Inspection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let row = |f: &mut fmt::Formatter<'_>, name: &str, value: String| {
            writeln!(f, "{name:<22}{value}")
        };
        row(f, "vertices", self.vertices.to_string())?;
        row(f, "triangles", self.triangles.to_string())?;
        row(f, "tetrahedra", self.tetrahedra.to_string())?;
        if self.tetrahedra10 > 0 {
            row(f, "tetrahedra (10-node)", self.tetrahedra10.to_string())?;
        }
        if let Some(b) = self.boundary_triangles {
            row(f, "boundary triangles", b.to_string())?;
        }
        if self.fixed_vertices > 0 {
            row(f, "fixed vertices", self.fixed_vertices.to_string())?;
        }
        const NOT_FINITE: &str = "- (not finite: see the problems)";
        let volume = match self.volume {
            Some(v) => num(v),
            None if self.tetrahedra + self.tetrahedra10 > 0 || self.closed => NOT_FINITE.into(),
            None => "- (surface not closed)".into(),
        };
        row(f, "volume", volume)?;
        let area = self.surface_area.map_or(NOT_FINITE.into(), num);
        row(f, "surface area", area)?;
        if let Some(b) = &self.bounds {
            let v = |a: [Real; 3]| format!("({}, {}, {})", num(a[0]), num(a[1]), num(a[2]));
            row(f, "bounds", format!("{} .. {}", v(b.min), v(b.max)))?;
        }
        row(f, "components", self.components.to_string())?;
        let closed = if self.closed { "closed" } else { "open" };
        row(
            f,
            "surface",
            format!(
                "{closed}, Euler characteristic {}",
                self.euler_characteristic
            ),
        )?;
        if let Some(q) = &self.quality {
            row(
                f,
                &format!("{} quality", q.element),
                format!("min {:.3}  median {:.3}  max {:.3}", q.min, q.median, q.max),
            )?;
            let widest = q.histogram.iter().copied().max().unwrap_or(0).max(1);
            for (k, &count) in q.histogram.iter().enumerate() {
                let lo = k as Real / BINS as Real;
                let bar = "#".repeat((count * 40).div_ceil(widest));
                writeln!(f, "  {lo:.1}-{:.1}  {count:>8}  {bar}", lo + 0.1)?;
            }
            if q.inverted > 0 {
                writeln!(f, "  inverted {:>8}", q.inverted)?;
            }
        }
        if self.problems.is_empty() {
            row(f, "problems", "none".into())
        } else {
            row(f, "problems", self.problems.len().to_string())?;
            for p in &self.problems {
                writeln!(f, "  - {}", p.message)?;
            }
            Ok(())
        }
    }
}

/// Six significant digits, plain for everyday magnitudes, scientific otherwise.
fn num(v: Real) -> String {
    let mag = v.abs().log10().floor();
    if v == 0.0 || !v.is_finite() {
        v.to_string()
    } else if (-3.0..6.0).contains(&mag) {
        format!("{:.*}", (5.0 - mag) as usize, v)
    } else {
        format!("{v:.5e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::mesh::generate::{BoxSplit, box_tets, icosphere, tube};

    #[test]
    fn numbers_have_six_digits() {
        assert_eq!(num(36.56085106), "36.5609");
        assert_eq!(num(-0.00123456789), "-0.00123457");
        assert_eq!(num(9.28e-5), "9.28000e-5");
        assert_eq!(num(1234567.0), "1.23457e6");
        assert_eq!(num(0.0), "0");
    }

    #[test]
    fn box_inspection_numbers() {
        let m = box_tets(
            Vec3::ZERO,
            Vec3::new(2.0, 1.0, 0.5),
            [4, 2, 1],
            BoxSplit::Six,
        );
        let i = inspect(&MeshData::from_tets(&m));
        assert_eq!((i.vertices, i.tetrahedra, i.components), (30, 48, 1));
        assert_eq!(i.boundary_triangles, Some(2 * 2 * (8 + 4 + 2)));
        assert!((i.volume.unwrap_or(0.0) - 1.0).abs() < 1e-12);
        assert!((i.surface_area.unwrap_or(0.0) - 2.0 * (2.0 + 1.0 + 0.5)).abs() < 1e-12);
        assert_eq!(i.euler_characteristic, 2);
        assert!(i.closed && i.problems.is_empty());
        assert_eq!(i.bounds.as_ref().map(|b| b.max), Some([2.0, 1.0, 0.5]));
        let text = i.to_string();
        assert!(
            text.contains("tetrahedron quality") && text.contains("problems              none")
        );
    }

    #[test]
    fn open_tube_has_no_volume_and_json_tags_problems() {
        let i = inspect(&MeshData::from_surface(&tube(0.1, 1.0, 12, 4)));
        assert_eq!(i.volume, None);
        assert!(!i.closed);
        // An open cylinder is an annulus: χ = 0.
        assert_eq!(i.euler_characteristic, 0);
        let json = serde_json::to_value(&i).unwrap_or_default();
        assert_eq!(json["problems"][0]["kind"], "border_edges");
        assert_eq!(json["problems"][0]["count"], 24);
        assert!(
            json["problems"][0]["message"]
                .as_str()
                .is_some_and(|m| m.contains("24 border"))
        );
        let s = inspect(&MeshData::from_surface(&icosphere(Vec3::ZERO, 1.0, 2)));
        assert_eq!((s.components, s.euler_characteristic), (1, 2));
        assert!(s.volume.is_some_and(|v| v > 0.0));
    }

    /// A vertex at 1e308 or NaN is a named problem, not `inf` / `NaN` printed as an area
    /// or a volume, and does not make the other vertices "coincide".
    #[test]
    fn absurd_coordinates_are_problems_not_numbers() {
        let base = box_tets(Vec3::ZERO, Vec3::ONE, [2, 2, 2], BoxSplit::Six);
        for (bad, kind) in [
            (Vec3::new(1e308, 0.0, -1e308), "far_vertex"),
            (Vec3::new(Real::NAN, 0.0, 0.0), "non_finite_vertex"),
            (Vec3::new(0.0, Real::INFINITY, 0.0), "non_finite_vertex"),
        ] {
            for surface in [false, true] {
                let mut m = MeshData::from_tets(&base);
                if surface {
                    m = MeshData::from_surface(&boundary_surface(&base).surface);
                }
                m.vertices[0] = bad;
                let i = inspect(&m);
                let kinds: Vec<_> = i.problems.iter().map(|p| p.problem.kind()).collect();
                assert!(kinds.contains(&kind), "{bad}: {kinds:?}");
                assert!(!kinds.contains(&"duplicate_vertices"), "{bad}: {kinds:?}");
                let text = i.to_string().to_lowercase();
                for word in ["inf", "nan"] {
                    let lines: Vec<_> = text
                        .lines()
                        .filter(|l| l.contains(word) && !l.starts_with("  - "))
                        .collect();
                    assert!(lines.is_empty(), "{bad} {surface}: {lines:?}\n{text}");
                }
                let json = serde_json::to_string(&i).unwrap_or_default().to_lowercase();
                assert!(!json.contains("nan") && !json.contains("inf"), "{json}");
            }
        }
    }
}
