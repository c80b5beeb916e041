use super::*;
use crate::mesh::generate::{BoxSplit, box_tets, icosphere};

fn sphere() -> SurfaceMesh {
    icosphere(Vec3::ZERO, 1.0, 2)
}

#[test]
fn generated_meshes_pass() {
    for split in [BoxSplit::Five, BoxSplit::Six] {
        let m = box_tets(Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0), [2, 3, 4], split);
        assert_eq!(check_tets(&m), vec![]);
    }
    assert_eq!(check_surface(&sphere()), vec![]);
}

#[test]
fn flipped_triangle_is_named_on_all_three_edges() {
    let mut s = sphere();
    s.triangles[17].swap(0, 1);
    let p = check_surface(&s);
    assert_eq!(p.len(), 3, "{p:?}");
    for q in &p {
        let Problem::InconsistentOrientation {
            triangle_a,
            triangle_b,
            edge,
        } = q
        else {
            panic!("unexpected {q}")
        };
        assert!(*triangle_a == 17 || *triangle_b == 17);
        assert!(s.triangles[17].contains(&edge[0]) && s.triangles[17].contains(&edge[1]));
    }
    assert!(p[0].to_string().contains("17"));
}

#[test]
fn reversed_sphere_is_inward() {
    let mut s = sphere();
    s.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    let v = s.signed_volume();
    assert!(v < 0.0);
    let p = check_surface(&s);
    assert!(
        matches!(p[..], [Problem::InwardOrientation { component: 0, volume }]
        if (volume - v).abs() < 1e-13),
        "{p:?}"
    );
}

#[test]
fn holes_count_their_border_edges() {
    let mut s = sphere();
    // Triangle 0 and triangle 3 of the first subdivision's children share no edge.
    let [a, b, _] = s.triangles[0];
    let far = (1..s.triangles.len())
        .rev()
        .find(|&t| !s.triangles[t].iter().any(|v| s.triangles[0].contains(v)))
        .unwrap_or(1);
    s.triangles.remove(far);
    s.triangles.remove(0);
    let p = check_surface(&s);
    assert_eq!(p.len(), 1, "{p:?}");
    let Problem::BorderEdges { count, examples } = &p[0] else {
        panic!("{p:?}")
    };
    assert_eq!(*count, 6);
    assert!(examples.contains(&[a.min(b), a.max(b)]));
}

#[test]
fn fin_is_a_non_manifold_edge() {
    let mut s = sphere();
    let [a, b, _] = s.triangles[5];
    s.vertices.push(Vec3::new(3.0, 0.0, 0.0));
    let n = (s.vertices.len() - 1) as u32;
    s.triangles.push([a, b, n]);
    let p = check_surface(&s);
    let nm = Problem::NonManifoldEdge {
        a: a.min(b) as usize,
        b: a.max(b) as usize,
        faces: 3,
    };
    assert!(p.contains(&nm), "{p:?}");
    assert!(
        p.iter()
            .any(|q| matches!(q, Problem::BorderEdges { count: 2, .. }))
    );
    assert!(
        !p.iter()
            .any(|q| matches!(q, Problem::InconsistentOrientation { .. }))
    );
}

#[test]
fn inverted_and_flat_tets_are_named() {
    let mut m = box_tets(Vec3::ZERO, Vec3::ONE, [2, 2, 2], BoxSplit::Six);
    m.tets[7].swap(0, 1);
    let v = m.tet_volume(7);
    assert_eq!(
        check_tets(&m),
        vec![Problem::InvertedTet { tet: 7, volume: v }]
    );

    let flat = TetMesh::new(
        vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.3, 0.3, 1e-6)],
        vec![[0, 1, 2, 3]],
    );
    let p = check_tets(&flat);
    assert!(
        matches!(p[..], [Problem::DegenerateTet { tet: 0, .. }]),
        "{p:?}"
    );
}

#[test]
fn tets_sharing_only_an_edge_make_a_non_manifold_boundary() {
    let v = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::Y,
        Vec3::Z,
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::new(0.0, 0.0, -1.0),
    ];
    // Both contain edge (0, 1) and nothing else in common.
    let m = TetMesh::new(v, vec![[0, 1, 2, 3], [0, 1, 4, 5]]);
    assert!(m.tet_volume(1) > 0.0);
    let p = check_tets(&m);
    assert_eq!(
        p,
        vec![Problem::NonManifoldEdge {
            a: 0,
            b: 1,
            faces: 4
        }]
    );
}

#[test]
fn duplicates_unused_components_and_bad_indices() {
    let s = icosphere(Vec3::ZERO, 1.0, 0);
    let mut tris = s.triangles.clone();
    tris.push([s.triangles[4][1], s.triangles[4][2], s.triangles[4][0]]);
    let n = s.vertices.len() as u32;
    tris.push([0, 1, n + 40]);
    let mut verts = s.vertices.clone();
    verts.push(Vec3::splat(9.0));
    verts.push(Vec3::new(f64::INFINITY, 0.0, 0.0));
    let p = check_surface(&SurfaceMesh::new(verts, tris));
    let expected = [
        Problem::NonFiniteVertex { vertex: 13 },
        Problem::IndexOutOfRange {
            element_kind: "triangle",
            element: 21,
            index: 52,
            vertex_count: 14,
        },
        Problem::DuplicateElement {
            element_kind: "triangle",
            element: 20,
            first: 4,
        },
        Problem::UnusedVertices {
            count: 2,
            examples: vec![12, 13],
        },
    ];
    for e in &expected {
        assert!(p.contains(e), "missing {e}: {p:?}");
    }
    let two = crate::mesh::MeshData {
        vertices: [
            s.vertices.clone(),
            s.vertices.iter().map(|v| *v + Vec3::X * 5.0).collect(),
        ]
        .concat(),
        triangles: [
            s.triangles.clone(),
            s.triangles.iter().map(|t| t.map(|i| i + 12)).collect(),
        ]
        .concat(),
        ..Default::default()
    };
    assert_eq!(check(&two), vec![Problem::MultipleComponents { count: 2 }]);
}

#[test]
fn reports_are_bounded() {
    // 1000 collinear triangles: 20 named, then one summary with the total.
    let vertices = (0..1002).map(|i| Vec3::new(i as f64, 0.0, 0.0)).collect();
    let triangles = (0..1000u32).map(|i| [i, i + 1, i + 2]).collect();
    let p = check_surface(&SurfaceMesh::new(vertices, triangles));
    let degenerate = p
        .iter()
        .filter(|q| q.kind() == "degenerate_triangle")
        .count();
    assert_eq!(degenerate, MAX_PER_KIND);
    let summary = Problem::MoreOfKind {
        problem_kind: "degenerate_triangle",
        total: 1000,
        shown: MAX_PER_KIND,
    };
    let at = p.iter().position(|q| *q == summary);
    assert_eq!(at, Some(MAX_PER_KIND));
    assert_eq!(
        summary.to_string(),
        "... and 980 more degenerate_triangle problems (1000 in all)"
    );
    assert!(p.len() < 60);
}

#[test]
fn json_has_kind_tag() {
    let p = Problem::InvertedTet {
        tet: 3,
        volume: -0.5,
    };
    let j = serde_json::to_string(&p).unwrap_or_default();
    assert_eq!(j, r#"{"kind":"inverted_tet","tet":3,"volume":-0.5}"#);
    assert_eq!(
        p.to_string(),
        "tetrahedron 3 is inverted (signed volume -5.000e-1)"
    );
}

#[test]
fn skin_triangles_of_a_volume_may_be_open() {
    // A box volume with one face of its boundary as a separate, open skin patch.
    let b = box_tets(Vec3::ZERO, Vec3::ONE, [2, 2, 2], BoxSplit::Six);
    let bs = crate::mesh::boundary_surface(&b);
    let skin: Vec<[u32; 3]> = bs
        .surface
        .triangles
        .iter()
        .map(|t| t.map(|v| bs.nodes[v as usize]))
        .filter(|t| t.iter().all(|&v| b.vertices[v as usize].z == 1.0))
        .collect();
    assert_eq!(skin.len(), 8);
    let mut m = MeshData::from_tets(&b);
    m.triangles = skin.clone();
    assert_eq!(check(&m), vec![]);
    // Alone, the same patch is an open surface with 8 border edges.
    let p = check_surface(&SurfaceMesh::new(b.vertices.clone(), skin));
    assert!(
        p.iter()
            .any(|q| matches!(q, Problem::BorderEdges { count: 8, .. }))
    );
}
