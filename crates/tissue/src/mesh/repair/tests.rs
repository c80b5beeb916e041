use super::*;
use crate::mesh::check::{Problem, check};
use crate::mesh::generate::{BoxSplit, box_tets, icosphere};
use crate::mesh::{Field, SurfaceMesh};

/// Each triangle with its own three vertices, as an STL file stores a surface.
fn soup(s: &SurfaceMesh) -> MeshData {
    let mut m = MeshData::default();
    for t in &s.triangles {
        let base = m.vertices.len() as u32;
        m.vertices.extend(t.map(|v| s.vertices[v as usize]));
        m.triangles.push([base, base + 1, base + 2]);
    }
    m
}

#[test]
fn merging_a_soup_restores_the_sphere() {
    let s = icosphere(Vec3::ZERO, 1.0, 2);
    let mut m = soup(&s);
    let n = m.vertices.len();
    m.point_data.push(Field {
        name: "id".into(),
        components: 1,
        values: (0..n).map(|i| i as f64).collect(),
    });
    m.fixed_vertices = vec![5, 3, 0];
    let merged = merge_duplicate_vertices(&mut m, 1e-9);
    assert_eq!(merged, n - s.vertices.len());
    assert_eq!(m.vertices.len(), s.vertices.len());
    assert_eq!(check(&m), vec![]);
    assert!(
        (SurfaceMesh::new(m.vertices.clone(), m.triangles.clone()).signed_volume()
            - s.signed_volume())
        .abs()
            < 1e-14
    );
    // Survivors keep the data of the first copy, which is what they were renumbered from.
    let ids = &m.point_data[0].values;
    assert!(ids.windows(2).all(|w| w[0] < w[1]));
    // Old vertices 0 and 3 are distinct corners unless they coincide; fixed stays in range.
    assert!(
        m.fixed_vertices
            .iter()
            .all(|&v| (v as usize) < m.vertices.len())
    );
}

#[test]
fn unused_vertices_go_with_their_data() {
    let mut m = MeshData {
        vertices: (0..6)
            .map(|i| Vec3::new(i as f64, (i * i) as f64, 1.0))
            .collect(),
        triangles: vec![[1, 3, 5]],
        triangle_tags: vec![7],
        fixed_vertices: vec![4, 3],
        point_data: vec![Field {
            name: "v".into(),
            components: 2,
            values: (0..12).map(f64::from).collect(),
        }],
        ..Default::default()
    };
    assert_eq!(remove_unused_vertices(&mut m), 3);
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    assert_eq!(m.vertices[1], Vec3::new(3.0, 9.0, 1.0));
    assert_eq!(m.fixed_vertices, vec![1]);
    assert_eq!(m.point_data[0].values, vec![2.0, 3.0, 6.0, 7.0, 10.0, 11.0]);
    assert_eq!(m.triangle_tags, vec![7]);
}

#[test]
fn degenerate_and_duplicate_elements_go_with_their_tags() {
    let mut m = MeshData {
        vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::X],
        triangles: vec![
            [0, 1, 2],
            [0, 0, 1],
            [2, 1, 0],
            [1, 2, 3],
            [0, 1, 4],
            [1, 0, 9],
        ],
        triangle_tags: vec![1, 2, 3, 4, 5, 6],
        tets: vec![[0, 1, 2, 3], [0, 1, 1, 3], [3, 2, 1, 0]],
        tet_tags: vec![10, 20, 30],
        ..Default::default()
    };
    assert_eq!(remove_invalid_elements(&mut m), 1);
    // [0, 0, 1] repeats a vertex; [0, 1, 4] has zero area (4 sits on 1).
    assert_eq!(remove_degenerate_triangles(&mut m), 2);
    assert_eq!(remove_collapsed_tets(&mut m), 1);
    assert_eq!(remove_duplicate_elements(&mut m), 2);
    assert_eq!(m.triangles, vec![[0, 1, 2], [1, 2, 3]]);
    assert_eq!(m.triangle_tags, vec![1, 4]);
    assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
    assert_eq!(m.tet_tags, vec![10]);
}

#[test]
fn inverted_tets_are_turned() {
    let b = box_tets(Vec3::ZERO, Vec3::ONE, [2, 2, 2], BoxSplit::Five);
    let mut m = MeshData::from_tets(&b);
    for t in [0, 3, 17] {
        m.tets[t].swap(0, 1);
    }
    assert_eq!(orient_outward(&mut m), 3);
    assert_eq!(check(&m), vec![]);
    assert_eq!(orient_outward(&mut m), 0);
}

#[test]
fn quadratic_tet_mid_nodes_follow_the_swap() {
    let c = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
    // VTK order of mid-edge nodes.
    let edges = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)];
    let mut vertices = c.to_vec();
    vertices.extend(edges.iter().map(|&(a, b)| 0.5 * (c[a] + c[b])));
    // The same tetrahedron with corners 0 and 1 exchanged (inverted), mid nodes relabelled.
    let t: [u32; 10] = [1, 0, 2, 3, 4, 6, 5, 8, 7, 9];
    let mut m = MeshData {
        vertices,
        tets10: vec![t],
        ..Default::default()
    };
    assert_eq!(orient_outward(&mut m), 1);
    let t = m.tets10[0];
    let p = |k: usize| m.vertices[t[k] as usize];
    assert!(tet_signed_volume(p(0), p(1), p(2), p(3)) > 0.0);
    for (k, &(a, b)) in edges.iter().enumerate() {
        assert_eq!(p(4 + k), 0.5 * (p(a) + p(b)), "mid node {k}");
    }
}

#[test]
fn non_manifold_and_non_orientable_input_does_not_panic() {
    // A Möbius strip of 5 quads, a fin, a collapsed triangle and a bad index.
    let n = 5;
    let mut vertices = Vec::new();
    for i in 0..n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        let w = 0.3 * (0.5 * a).cos();
        let h = 0.3 * (0.5 * a).sin();
        let r = Vec3::new(a.cos(), a.sin(), 0.0);
        vertices.push(r * (1.0 + w) + Vec3::Z * h);
        vertices.push(r * (1.0 - w) - Vec3::Z * h);
    }
    let mut triangles = Vec::new();
    for i in 0..n as u32 {
        let (a, b) = (2 * i, 2 * i + 1);
        // The last quad joins with a half twist.
        let (c, d) = if i + 1 == n as u32 {
            (1, 0)
        } else {
            (a + 2, b + 2)
        };
        triangles.extend([[a, b, d], [a, d, c]]);
    }
    triangles.extend([[0, 1, 5], [0, 0, 1], [0, 1, 99]]);
    let mut m = MeshData {
        vertices,
        triangles,
        ..Default::default()
    };
    let _ = check(&m);
    let r = repair(&mut m, &RepairOptions::default());
    assert_eq!(r.invalid_elements_removed, 1);
    assert_eq!(r.degenerate_elements_removed, 1);
    assert!(
        check(&m)
            .iter()
            .any(|p| matches!(p, Problem::NonManifoldEdge { .. }))
    );
}

#[test]
fn repair_report_counts_everything() {
    let s = icosphere(Vec3::ZERO, 2.0, 1);
    let mut m = soup(&s);
    m.triangles.iter_mut().step_by(3).for_each(|t| t.swap(0, 2));
    m.triangles.push(m.triangles[0]);
    m.vertices.push(Vec3::splat(7.0));
    let r = repair(&mut m, &RepairOptions::default());
    let expected = RepairReport {
        invalid_elements_removed: 0,
        vertices_merged: 3 * 80 - 42,
        degenerate_elements_removed: 0,
        duplicate_elements_removed: 1,
        unused_vertices_removed: 1,
        elements_reoriented: 27,
    };
    assert_eq!(r, expected);
    assert_eq!(check(&m), vec![]);
    let v = SurfaceMesh::new(m.vertices.clone(), m.triangles.clone()).signed_volume();
    assert!((v - s.signed_volume()).abs() < 1e-13);
}
