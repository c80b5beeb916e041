//! Topology, quality, checks and repairs on generated meshes, hand-broken meshes and the
//! shipped organ meshes.

use std::f64::consts::{PI, TAU};

use proptest::prelude::*;
use tissue::Vec3;
use tissue::mesh::check::Problem;
use tissue::mesh::generate::{BoxSplit, box_tets, cylinder, icosphere, tube, tube_with_wall};
use tissue::mesh::quality::QualityStats;
use tissue::mesh::repair::{merge_duplicate_vertices, orient_outward};
use tissue::mesh::topology::{components, edge_faces, euler_characteristic, triangle_edges};
use tissue::mesh::{
    MeshData, RepairOptions, SurfaceMesh, TetMesh, boundary_surface, check, check_surface,
    check_tets, inspect, repair,
};

fn asset(name: &str) -> String {
    format!("{}/../../assets/meshes/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn volume_of(m: &MeshData) -> f64 {
    SurfaceMesh::new(m.vertices.clone(), m.triangles.clone()).signed_volume()
}

// ---------------------------------------------------------------- generated meshes

#[test]
fn box_boundaries_are_closed_spheres() {
    for split in [BoxSplit::Five, BoxSplit::Six] {
        let m = box_tets(Vec3::ZERO, Vec3::new(0.1, 0.05, 0.02), [5, 3, 2], split);
        assert_eq!(check_tets(&m), vec![], "{split:?}");
        let b = boundary_surface(&m);
        assert_eq!(check_surface(&b.surface), vec![], "{split:?}");
        assert_eq!(euler_characteristic(&b.surface.triangles), 2);
        assert_eq!(components(&m.tets).count, 1);
    }
}

#[test]
fn icosphere_converges_to_the_sphere() {
    // Relative volume and area deficits of the inscribed icosphere, computed independently;
    // each subdivision divides them by more than 3, tending to 4 (second order).
    let volume_deficit = [0.394539, 0.126547, 0.033839, 0.008606, 0.002161];
    let area_deficit = [0.238082, 0.071655, 0.018822, 0.004765, 0.001195];
    let r = 0.04;
    let (exact_v, exact_a) = (4.0 / 3.0 * PI * r * r * r, 4.0 * PI * r * r);
    let mut last = f64::INFINITY;
    for s in 0..5u32 {
        let m = icosphere(Vec3::new(0.1, -0.2, 0.3), r, s);
        let (v, e, f) = (
            m.vertices.len() as i64,
            triangle_edges(&m.triangles).len() as i64,
            m.triangles.len() as i64,
        );
        assert_eq!(v - e + f, 2);
        assert_eq!(check_surface(&m), vec![]);
        let dv = 1.0 - m.signed_volume() / exact_v;
        let da = 1.0 - m.area() / exact_a;
        assert!(
            (dv - volume_deficit[s as usize]).abs() < 1e-6,
            "s={s}: {dv}"
        );
        assert!((da - area_deficit[s as usize]).abs() < 1e-6, "s={s}: {da}");
        assert!(dv > 0.0 && dv < last / 3.0);
        last = dv;
    }
}

/// Area of the regular n-gon inscribed in a circle of radius r.
fn polygon_area(r: f64, n: usize) -> f64 {
    0.5 * n as f64 * r * r * (TAU / n as f64).sin()
}

#[test]
fn cylinders_match_the_inscribed_prism() {
    for n in [3, 8, 64] {
        let (r, h) = (0.02, 0.15);
        let c = cylinder(r, h, n, 4, true);
        assert_eq!(check_surface(&c), vec![]);
        assert_eq!(euler_characteristic(&c.triangles), 2);
        let side = n as f64 * 2.0 * r * (PI / n as f64).sin() * h;
        assert!((c.signed_volume() - polygon_area(r, n) * h).abs() < 1e-16);
        assert!((c.area() - 2.0 * polygon_area(r, n) - side).abs() < 1e-15);
        if n == 64 {
            // And they approach πr²h from below.
            let rel = 1.0 - c.signed_volume() / (PI * r * r * h);
            assert!(rel > 0.0 && rel < 2e-3);
        }
    }
    // An open tube: two rims of n border edges, an annulus (χ = 0), outward normals.
    let t = tube(0.005, 0.1, 16, 10);
    let ef = edge_faces(&t.triangles);
    assert_eq!(ef.border_edges().count(), 32);
    assert_eq!(euler_characteristic(&t.triangles), 0);
    let n = t.vertex_normals();
    assert!(
        t.vertices
            .iter()
            .zip(&n)
            .all(|(p, n)| Vec3::new(p.x, p.y, 0.0).dot(*n) > 0.0)
    );
    // A walled tube is a closed torus-like surface: χ = 0, volume of the annular prism.
    let w = tube_with_wall(0.004, 0.006, 0.1, 16, 10);
    assert_eq!(check_surface(&w), vec![]);
    assert_eq!(euler_characteristic(&w.triangles), 0);
    let expected = (polygon_area(0.006, 16) - polygon_area(0.004, 16)) * 0.1;
    assert!((w.signed_volume() - expected).abs() < 1e-18);
}

// ---------------------------------------------------------------- broken meshes

#[test]
fn flipped_triangle_is_named() {
    let mut s = icosphere(Vec3::ZERO, 1.0, 3);
    s.triangles[1000].swap(1, 2);
    let p = check_surface(&s);
    assert_eq!(p.len(), 3);
    assert!(p.iter().all(|q| matches!(q,
        Problem::InconsistentOrientation { triangle_a, triangle_b, .. }
            if *triangle_a == 1000 || *triangle_b == 1000)));
}

#[test]
fn inverted_tet_is_named() {
    let mut m = box_tets(Vec3::ZERO, Vec3::ONE, [3, 3, 3], BoxSplit::Five);
    m.tets[42].swap(2, 3);
    let p = check_tets(&m);
    assert_eq!(p.len(), 1);
    assert!(matches!(p[0], Problem::InvertedTet { tet: 42, volume } if volume < 0.0));
    assert!(p[0].to_string().starts_with("tetrahedron 42 is inverted"));
}

#[test]
fn hole_border_edges_are_counted_exactly() {
    // Remove the 6 triangles around a valence-6 vertex: a hexagonal hole, 6 border edges.
    let s = icosphere(Vec3::ZERO, 1.0, 2);
    let v = 100u32;
    let fan = s.triangles.iter().filter(|t| t.contains(&v)).count();
    assert_eq!(fan, 6);
    let holed = SurfaceMesh::new(
        s.vertices.clone(),
        s.triangles
            .iter()
            .copied()
            .filter(|t| !t.contains(&v))
            .collect(),
    );
    let p = check_surface(&holed);
    assert!(
        p.iter()
            .any(|q| matches!(q, Problem::BorderEdges { count: 6, .. })),
        "{p:?}"
    );
    assert!(p.contains(&Problem::UnusedVertices {
        count: 1,
        examples: vec![v]
    }));
    assert_eq!(euler_characteristic(&holed.triangles), 1);
}

#[test]
fn non_manifold_edge_is_named() {
    let mut s = icosphere(Vec3::ZERO, 1.0, 1);
    let [a, b, _] = s.triangles[9];
    s.vertices.push(Vec3::new(0.0, 0.0, 4.0));
    s.triangles.push([b, a, s.vertices.len() as u32 - 1]);
    let p = check_surface(&s);
    let (lo, hi) = (a.min(b) as usize, a.max(b) as usize);
    assert!(p.contains(&Problem::NonManifoldEdge {
        a: lo,
        b: hi,
        faces: 3
    }));
    assert!(p[0].to_string().contains(&format!("({lo}, {hi})")));
    // Repairs leave it in place without panicking, and change nothing that was right.
    let mut m = MeshData::from_surface(&s);
    let r = repair(&mut m, &RepairOptions::default());
    assert_eq!(r.total(), 0, "{r:?}");
}

#[test]
fn duplicate_vertices_are_merged_then_the_mesh_passes() {
    // Triangles starting in the upper hemisphere get their own copies of their corners, so
    // the count of duplicates is exact and known.
    let s = icosphere(Vec3::ZERO, 0.03, 2);
    let mut m = MeshData::from_surface(&s);
    let mut extra = 0;
    for tri in &mut m.triangles {
        if s.vertices[tri[0] as usize].z > 0.0 {
            for v in tri.iter_mut() {
                m.vertices.push(s.vertices[*v as usize]);
                *v = m.vertices.len() as u32 - 1;
                extra += 1;
            }
        }
    }
    let p = check(&m);
    let found = p.iter().find_map(|q| match q {
        Problem::DuplicateVertices { count, .. } => Some(*count),
        _ => None,
    });
    assert_eq!(found, Some(extra));
    let before = volume_of(&m);
    assert_eq!(merge_duplicate_vertices(&mut m, 1e-12), extra);
    assert_eq!(m.vertices.len(), s.vertices.len());
    assert_eq!(check(&m), vec![]);
    assert!((volume_of(&m) - before).abs() < 1e-18);
}

#[test]
fn inward_sphere_is_reported_and_turned_out() {
    let s = icosphere(Vec3::new(1.0, 1.0, 1.0), 0.5, 3);
    let mut m = MeshData::from_surface(&s);
    m.triangles.iter_mut().for_each(|t| t.swap(0, 1));
    let p = check(&m);
    assert!(
        matches!(p[..], [Problem::InwardOrientation { component: 0, volume }]
        if (volume + s.signed_volume()).abs() < 1e-14)
    );
    assert_eq!(orient_outward(&mut m), s.triangles.len());
    assert!((volume_of(&m) - s.signed_volume()).abs() < 1e-14);
    assert_eq!(check(&m), vec![]);
}

#[test]
fn repair_restores_a_shuffled_sphere() {
    let s = icosphere(Vec3::ZERO, 1.0, 2);
    let mut m = MeshData::from_surface(&s);
    // Flip triangles by a fixed pseudo-random pattern: more than half of them.
    let mut flipped = 0;
    for (t, tri) in m.triangles.iter_mut().enumerate() {
        if (t * 7919) % 13 < 8 {
            tri.swap(1, 2);
            flipped += 1;
        }
    }
    assert!(2 * flipped > s.triangles.len());
    let r = repair(&mut m, &RepairOptions::default());
    assert_eq!(r.elements_reoriented, flipped);
    assert_eq!(m.triangles, s.triangles);
    assert_eq!(check(&m), vec![]);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn random_flips_are_always_repaired(flips in proptest::collection::vec(any::<bool>(), 320)) {
        let s = icosphere(Vec3::new(0.3, 0.0, -0.1), 0.7, 2);
        let mut m = MeshData::from_surface(&s);
        for (t, f) in m.triangles.iter_mut().zip(&flips) {
            if *f {
                t.swap(1, 2);
            }
        }
        let n = orient_outward(&mut m);
        prop_assert_eq!(n, flips.iter().filter(|f| **f).count());
        prop_assert!((volume_of(&m) - s.signed_volume()).abs() < 1e-13);
        prop_assert_eq!(&m.triangles, &s.triangles);
    }
}

// ---------------------------------------------------------------- organ meshes

/// Reads liver.msh (Gmsh v1: `$NOD`, count, `id x y z`; `$ELM`, count,
/// `id type phys elem n ids...`) for the quality checks while the library's reader is being
/// written elsewhere. Test fixture only: it trusts the file.
fn liver_by_hand() -> TetMesh {
    let text = std::fs::read_to_string(asset("liver.msh")).expect("liver.msh is shipped");
    let lines: Vec<&str> = text.lines().map(str::trim).collect();
    let nod = lines.iter().position(|l| *l == "$NOD").expect("$NOD");
    let n: usize = lines[nod + 1].parse().expect("node count");
    let mut id_of = std::collections::HashMap::new();
    let mut vertices = Vec::new();
    for l in &lines[nod + 2..nod + 2 + n] {
        let f: Vec<f64> = l
            .split_whitespace()
            .map(|x| x.parse().expect("number"))
            .collect();
        id_of.insert(f[0] as u32, vertices.len() as u32);
        vertices.push(Vec3::new(f[1], f[2], f[3]));
    }
    let elm = lines.iter().position(|l| *l == "$ELM").expect("$ELM");
    let m: usize = lines[elm + 1].parse().expect("element count");
    let tets = lines[elm + 2..elm + 2 + m]
        .iter()
        .map(|l| {
            let f: Vec<u32> = l
                .split_whitespace()
                .map(|x| x.parse().expect("id"))
                .collect();
            assert_eq!(f[1], 4, "only tetrahedra in liver.msh");
            [f[5], f[6], f[7], f[8]].map(|id| id_of[&id])
        })
        .collect();
    TetMesh::new(vertices, tets)
}

fn assert_liver_tets(m: &TetMesh) {
    assert_eq!((m.vertices.len(), m.tets.len()), (181, 596));
    let q = QualityStats::of_tets(m).expect("finite qualities");
    assert_eq!(format!("{:.3} {:.3}", q.min, q.median), "0.079 0.595");
    assert_eq!(q.histogram, [2, 9, 40, 62, 88, 104, 116, 105, 60, 10]);
    assert_eq!(q.inverted, 0);
    assert!((m.volume() - 36.561).abs() < 5e-4);
    assert_eq!(check_tets(m), vec![]);
    let b = boundary_surface(m);
    assert_eq!(
        (b.surface.triangles.len(), b.surface.vertices.len()),
        (276, 140)
    );
    assert_eq!(euler_characteristic(&b.surface.triangles), 2);
    assert!((b.surface.signed_volume() - m.volume()).abs() < 1e-9);
}

#[test]
fn liver_msh_quality_by_hand_reader() {
    assert_liver_tets(&liver_by_hand());
}

#[test]
fn liver_msh_quality_and_checks() {
    let data = tissue::io::read(asset("liver.msh")).expect("liver.msh reads");
    let m = data.tet_mesh("liver.msh").expect("tetrahedra");
    assert_liver_tets(&m);
    let i = inspect(&data);
    assert_eq!(
        (i.components, i.euler_characteristic, i.boundary_triangles),
        (1, 2, Some(276))
    );
    assert!(i.problems.is_empty());
}

#[test]
fn liver_obj_has_unused_vertices_only() {
    let mut data = tissue::io::read(asset("liver.obj")).expect("liver.obj reads");
    let p = check(&data);
    assert_eq!(p.len(), 1, "{p:?}");
    assert!(matches!(p[0], Problem::UnusedVertices { count: 42, .. }));
    let r = repair(&mut data, &RepairOptions::default());
    assert_eq!(r.unused_vertices_removed, 42);
    assert_eq!(r.total(), 42);
    assert_eq!(check(&data), vec![]);
    assert!((volume_of(&data) - 36.569).abs() < 5e-4);
}

#[test]
fn liver_smooth_is_a_clean_sphere() {
    let data = tissue::io::read(asset("liver-smooth.obj")).expect("liver-smooth.obj reads");
    assert_eq!(check(&data), vec![]);
    let i = inspect(&data);
    assert_eq!(
        (i.vertices, i.triangles, i.euler_characteristic),
        (2194, 4384, 2)
    );
    assert!((i.volume.unwrap_or(0.0) - 39.267).abs() < 5e-4);
}

#[test]
fn wound_ply_volume_and_skin() {
    let data = tissue::io::read(asset("wound_deformable.ply")).expect("ply reads");
    let i = inspect(&data);
    assert_eq!((i.vertices, i.tetrahedra, i.triangles), (391, 1476, 407));
    assert_eq!((i.boundary_triangles, i.fixed_vertices), (Some(540), 79));
    assert!((i.volume.unwrap_or(0.0) - 9.28e-5).abs() < 5e-7);
    assert!(i.quality.as_ref().is_some_and(|q| q.inverted == 0));
    // The skin patch alone is open with two components.
    let skin = SurfaceMesh::new(data.vertices.clone(), data.triangles.clone());
    let p = check_surface(&skin);
    assert!(
        p.iter()
            .any(|q| matches!(q, Problem::BorderEdges { count: 41, .. })),
        "{p:?}"
    );
    assert!(p.contains(&Problem::MultipleComponents { count: 2 }));
}

#[test]
fn liver_inspection_report_by_hand_reader() {
    let data = MeshData::from_tets(&liver_by_hand());
    let i = inspect(&data);
    let text = i.to_string();
    println!("{text}");
    println!("{}", serde_json::to_string_pretty(&i).unwrap_or_default());
    assert!(text.contains("tetrahedron quality   min 0.079  median 0.595  max 0.966"));
    assert!(text.contains("boundary triangles    276"));
    assert!(text.contains("problems              none"));
    assert_eq!(
        (i.components, i.euler_characteristic, i.boundary_triangles),
        (1, 2, Some(276))
    );
    assert!((i.volume.unwrap_or(0.0) - 36.561).abs() < 5e-4);
}

#[test]
fn a_badly_broken_large_mesh_gives_a_short_report() {
    // 81920 triangles, every other one flipped, every tenth vertex duplicated, a hole.
    let s = icosphere(Vec3::ZERO, 1.0, 6);
    let mut m = MeshData::from_surface(&s);
    m.triangles.iter_mut().step_by(2).for_each(|t| t.swap(1, 2));
    m.triangles.truncate(m.triangles.len() - 1);
    let n = m.vertices.len();
    m.vertices.extend((0..n).step_by(10).map(|v| s.vertices[v]));
    let start = std::time::Instant::now();
    let p = check(&m);
    assert!(p.len() <= 2 * 20 + 6, "{} entries", p.len());
    let total = |kind: &str| {
        p.iter().find_map(|q| match q {
            Problem::MoreOfKind {
                problem_kind,
                total,
                ..
            } if *problem_kind == kind => Some(*total),
            _ => None,
        })
    };
    assert!(
        total("inconsistent_orientation").is_some_and(|t| t > 50_000),
        "{p:#?}"
    );
    assert!(p.contains(&Problem::BorderEdges {
        count: 3,
        examples: match p.iter().find(|q| q.kind() == "border_edges") {
            Some(Problem::BorderEdges { examples, .. }) => examples.clone(),
            _ => vec![],
        }
    }));
    let dup = (0..n).step_by(10).count();
    assert!(
        p.iter()
            .any(|q| matches!(q, Problem::DuplicateVertices { count, .. } if *count == dup))
    );
    let r = repair(&mut m, &RepairOptions::default());
    assert_eq!(r.vertices_merged, dup);
    // Open now (the hole), so orientation follows the majority of each component.
    let after = check(&m);
    assert_eq!(after.len(), 1, "{after:?}");
    assert!(matches!(after[0], Problem::BorderEdges { count: 3, .. }));
    assert!(start.elapsed().as_secs_f64() < 10.0);
}

fn coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => (-2i32..3).prop_map(f64::from),
        1 => Just(f64::NAN),
        1 => any::<f64>(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    /// Garbage in (repeated and out-of-range indices, NaN, coincident points, fins,
    /// duplicates): checks, inspection and repairs answer without panicking, and a repaired
    /// mesh has no invalid, collapsed or duplicate element and no unused vertex left.
    #[test]
    fn garbage_never_panics(
        vertices in proptest::collection::vec((coordinate(), coordinate(), coordinate()), 0..12),
        triangles in proptest::collection::vec([0u32..14, 0u32..14, 0u32..14], 0..16),
        tets in proptest::collection::vec([0u32..14, 0u32..14, 0u32..14, 0u32..14], 0..8),
        tets10 in proptest::collection::vec(proptest::array::uniform10(0u32..14), 0..2),
        fixed in proptest::collection::vec(0u32..14, 0..4),
    ) {
        let mut m = MeshData {
            vertices: vertices.into_iter().map(|(x, y, z)| Vec3::new(x, y, z)).collect(),
            triangles,
            tets,
            tets10,
            fixed_vertices: fixed,
            ..MeshData::default()
        };
        let _ = check(&m);
        let _ = inspect(&m).to_string();
        let _ = repair(&mut m, &RepairOptions::default());
        let after = check(&m);
        for p in &after {
            prop_assert!(!matches!(p,
                Problem::IndexOutOfRange { .. }
                    | Problem::DuplicateElement { .. }
                    | Problem::UnusedVertices { .. }
            ), "{}", p);
        }
        let n = m.vertices.len();
        prop_assert!(m.fixed_vertices.iter().all(|&v| (v as usize) < n));
        let _ = inspect(&m);
    }
}
