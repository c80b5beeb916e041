use super::*;
use crate::mesh::boundary_surface;
use crate::mesh::generate::{BoxSplit, box_tets, icosphere};

#[test]
fn single_tet_edges_and_neighbours() {
    let tets = [[0, 1, 2, 3]];
    assert_eq!(
        tet_edges(&tets),
        vec![[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    );
    let nb = vertex_neighbours(4, &tet_edges(&tets));
    assert_eq!(nb.row(2), &[0, 1, 3]);
    assert_eq!(nb.row(7), &[] as &[u32]);
    assert_eq!(tet_neighbours(&tets), vec![[None; 4]]);
}

#[test]
fn box_tets_satisfy_euler_for_a_ball() {
    // V − E + F − T = 1 for any triangulated ball; the Kuhn split also has a closed-form edge
    // count: grid edges, one diagonal per grid face, one per cell.
    for split in [BoxSplit::Five, BoxSplit::Six] {
        let [nx, ny, nz] = [3usize, 2, 2];
        let m = box_tets(Vec3::ZERO, Vec3::ONE, [nx, ny, nz], split);
        let e = tet_edges(&m.tets).len();
        let mut faces: Vec<[u32; 3]> = m
            .tets
            .iter()
            .flat_map(|t| {
                crate::mesh::TET_FACES
                    .map(|f| crate::mesh::boundary::sorted([t[f[0]], t[f[1]], t[f[2]]]))
            })
            .collect();
        faces.sort_unstable();
        faces.dedup();
        let chi = m.vertices.len() as i64 - e as i64 + faces.len() as i64 - m.tets.len() as i64;
        assert_eq!(chi, 1, "{split:?}");
        if split == BoxSplit::Six {
            let axis =
                nx * (ny + 1) * (nz + 1) + (nx + 1) * ny * (nz + 1) + (nx + 1) * (ny + 1) * nz;
            let grid_faces = nx * ny * (nz + 1) + nx * (ny + 1) * nz + (nx + 1) * ny * nz;
            assert_eq!(e, axis + grid_faces + nx * ny * nz);
        }
        // Faces without a neighbour are exactly the boundary triangles, and neighbours are
        // mutual across the same face.
        let nb = tet_neighbours(&m.tets);
        let free = nb.iter().flatten().filter(|n| n.is_none()).count();
        assert_eq!(free, boundary_surface(&m).surface.triangles.len());
        for (t, row) in nb.iter().enumerate() {
            for (k, n) in row.iter().enumerate() {
                let Some(u) = n else { continue };
                let back = nb[*u as usize].iter().position(|x| *x == Some(t as u32));
                let Some(j) = back else {
                    panic!("tet {u} does not see {t}")
                };
                let face = |t: usize, k: usize| {
                    let f = crate::mesh::TET_FACES[k];
                    crate::mesh::boundary::sorted([
                        m.tets[t][f[0]],
                        m.tets[t][f[1]],
                        m.tets[t][f[2]],
                    ])
                };
                assert_eq!(face(t, k), face(*u as usize, j));
            }
        }
    }
}

#[test]
fn icosphere_adjacency_counts() {
    let s = icosphere(Vec3::ZERO, 1.0, 2);
    let e = triangle_edges(&s.triangles);
    assert_eq!(e.len(), 30 * 16);
    assert!(e.windows(2).all(|w| w[0] < w[1]));
    let nb = vertex_neighbours(s.vertices.len(), &e);
    let valence: Vec<usize> = (0..s.vertices.len()).map(|v| nb.row(v).len()).collect();
    assert_eq!(valence.iter().filter(|&&k| k == 5).count(), 12);
    assert_eq!(
        valence.iter().filter(|&&k| k == 6).count(),
        s.vertices.len() - 12
    );
    let vt = vertex_elements(s.vertices.len(), &s.triangles);
    assert!((0..s.vertices.len()).all(|v| vt.row(v).len() == valence[v]));
    assert!(
        vt.row(0)
            .iter()
            .all(|&t| s.triangles[t as usize].contains(&0))
    );
    let ef = edge_faces(&s.triangles);
    assert_eq!(ef.edges, e);
    assert!(ef.with_face_count(|n| n != 2).next().is_none());
    assert_eq!(euler_characteristic(&s.triangles), 2);
}

#[test]
fn edge_faces_find_borders_and_fins() {
    // Two triangles on edge (1, 2), plus a third (a fin) on it, plus an isolated triangle.
    let tris = [[0, 1, 2], [2, 1, 3], [1, 2, 4], [5, 6, 7]];
    let ef = edge_faces(&tris);
    let nm: Vec<_> = ef.non_manifold_edges().collect();
    assert_eq!(nm, vec![([1, 2], &[0u32, 1, 2][..])]);
    assert_eq!(ef.border_edges().count(), 6 + 3);
    let c = components(&tris);
    assert_eq!((c.count, c.of_element.clone()), (2, vec![0, 0, 0, 1]));
    // χ = V − E + F = 8 − 10 + 4.
    assert_eq!(euler_characteristic(&tris), 2);
}

#[test]
fn components_of_two_spheres() {
    let a = icosphere(Vec3::ZERO, 1.0, 1);
    let n = a.vertices.len() as u32;
    let mut tris = a.triangles.clone();
    tris.extend(a.triangles.iter().map(|t| t.map(|v| v + n)));
    let c = components(&tris);
    assert_eq!(c.count, 2);
    assert!(c.of_element[..80].iter().all(|&k| k == 0));
    assert!(c.of_element[80..].iter().all(|&k| k == 1));
    assert_eq!(euler_characteristic(&tris), 4);
}

#[test]
fn coincident_vertices_map_to_the_first() {
    let v = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(1e-12, 0.0, 0.0),
        Vec3::new(f64::NAN, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 5e-10),
        Vec3::new(1.0, 0.0, 5e-9),
        Vec3::new(1e300, -1e300, 0.0),
        Vec3::new(1e300, -1e300, 0.0),
    ];
    assert_eq!(coincident_map(&v, 1e-9), vec![0, 1, 0, 3, 1, 5, 6, 6]);
    assert_eq!(coincident_map(&v, 0.0), vec![0, 1, 2, 3, 4, 5, 6, 6]);
    let same = vec![Vec3::ONE; 1000];
    assert!(coincident_map(&same, 1e-9).iter().all(|&r| r == 0));
}

#[test]
fn bad_indices_do_not_panic() {
    let tris = [[0, 1, 9]];
    assert_eq!(vertex_elements(3, &tris).row(0), &[0]);
    assert!(vertex_elements(3, &tris).row(9).is_empty());
    // Rows exist for the given vertex count; neighbours are what the edges say.
    let nb = vertex_neighbours(2, &triangle_edges(&tris));
    assert_eq!(nb.row(0), &[1, 9]);
    assert!(nb.row(9).is_empty());
    assert_eq!(components(&tris).count, 1);
    let huge = [[0, u32::MAX, 5], [7, 8, 6], [9, u32::MAX - 1, u32::MAX]];
    assert_eq!(components(&huge).of_element, vec![0, 1, 0]);
    assert_eq!(euler_characteristic(&huge), 8 - 9 + 3);
}
