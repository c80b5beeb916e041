//! A stuffed mesh's boundary made a 2-manifold.
//!
//! Stuffing a shape whose features are about the lattice's size (two gyri of an MRI brain a
//! voxel apart, a muscle with cracks of fat) can leave two parts of the mesh touching along
//! one edge or at one vertex: the boundary then has an edge shared by four triangles, or a
//! vertex whose triangles form two fans. Every tetrahedron is still valid and the volume
//! mesh conforms, but a surface model built on the boundary (`bem`, the spring kinds, a
//! contact search's normals) has no well-defined side there, and `bem` refuses it. So at
//! each such edge or vertex, the tetrahedra around it are grouped into fans (tetrahedra
//! joined through faces that contain the edge or vertex), the fan with the largest volume
//! is kept and the tetrahedra of the others are removed; until nothing is left to fix. The
//! parts that touched are then apart by a dent of a few tetrahedra, which is what the
//! lattice could resolve of them anyway. The count and volume removed are reported.

use rustc_hash::FxHashMap;
use serde::Serialize;

use crate::math::{Real, tet_signed_volume};
use crate::mesh::TetMesh;

/// Rounds of removal before giving up (each round fixes every defect it finds; a removal
/// can expose a new one next to it, rarely more than two rounds deep).
const MAX_ROUNDS: usize = 32;

/// What `make_boundary_manifold` did and left.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ManifoldRepair {
    /// Tetrahedra removed.
    pub removed: usize,
    /// Their volume, m³.
    pub removed_volume: Real,
    /// Edges shared by more than two boundary triangles, and vertices whose boundary
    /// triangles form more than one fan, left after the repair (0 unless the rounds ran out).
    pub edges_left: usize,
    pub vertices_left: usize,
}

/// The faces of tetrahedron `t` (each sorted), opposite corners 0..4.
fn faces(t: &[u32; 4]) -> [[u32; 3]; 4] {
    let f = |a: u32, b: u32, c: u32| {
        let mut k = [a, b, c];
        k.sort_unstable();
        k
    };
    [
        f(t[1], t[2], t[3]),
        f(t[0], t[2], t[3]),
        f(t[0], t[1], t[3]),
        f(t[0], t[1], t[2]),
    ]
}

/// The boundary's defects: non-manifold edges (with the tetrahedra around them) and
/// non-manifold vertices.
struct Defects {
    edges: Vec<[u32; 2]>,
    vertices: Vec<u32>,
}

fn find_defects(tets: &[[u32; 4]], alive: &[bool]) -> Defects {
    let mut face_count: FxHashMap<[u32; 3], u32> = FxHashMap::default();
    for (t, tet) in tets.iter().enumerate() {
        if alive[t] {
            for f in faces(tet) {
                *face_count.entry(f).or_insert(0) += 1;
            }
        }
    }
    let boundary: Vec<[u32; 3]> = face_count
        .into_iter()
        .filter_map(|(f, n)| (n == 1).then_some(f))
        .collect();
    let mut edge_count: FxHashMap<[u32; 2], u32> = FxHashMap::default();
    // Per boundary vertex, the edges of its boundary triangles that do not contain it (a
    // fan around the vertex is a chain of such edges joined at their ends).
    let mut rim: FxHashMap<u32, Vec<[u32; 2]>> = FxHashMap::default();
    for f in &boundary {
        for (a, b, c) in [(f[0], f[1], f[2]), (f[1], f[2], f[0]), (f[2], f[0], f[1])] {
            *edge_count.entry([a.min(b), a.max(b)]).or_insert(0) += 1;
            rim.entry(c).or_default().push([a, b]);
        }
    }
    let mut edges: Vec<[u32; 2]> = edge_count
        .into_iter()
        .filter_map(|(e, n)| (n > 2).then_some(e))
        .collect();
    edges.sort_unstable();
    let mut vertices: Vec<u32> = rim
        .into_iter()
        .filter_map(|(v, rim)| (fans(&rim) > 1).then_some(v))
        .collect();
    vertices.sort_unstable();
    Defects { edges, vertices }
}

/// Connected components of a vertex's rim edges (its boundary triangles joined through
/// shared edges): 1 for a manifold vertex.
fn fans(rim: &[[u32; 2]]) -> usize {
    let mut ids: Vec<u32> = rim.iter().flatten().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let index = |v: u32| ids.binary_search(&v).unwrap_or(0);
    let mut parent: Vec<usize> = (0..ids.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for e in rim {
        let (a, b) = (
            root(&mut parent, index(e[0])),
            root(&mut parent, index(e[1])),
        );
        parent[a] = b;
    }
    (0..ids.len())
        .filter(|&i| root(&mut parent, i) == i)
        .count()
}

/// Groups `around` (the tetrahedra containing one edge or one vertex) into fans: two are in
/// one fan when they share a face (three vertices), directly or through others.
fn group_fans(tets: &[[u32; 4]], around: &[usize]) -> Vec<Vec<usize>> {
    let n = around.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (&tets[around[i]], &tets[around[j]]);
            let common = a.iter().filter(|v| b.contains(v)).count();
            if common >= 3 {
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                parent[ri] = rj;
            }
        }
    }
    let mut groups: FxHashMap<usize, Vec<usize>> = FxHashMap::default();
    for (i, &t) in around.iter().enumerate() {
        let r = root(&mut parent, i);
        groups.entry(r).or_default().push(t);
    }
    let mut out: Vec<Vec<usize>> = groups.into_values().collect();
    out.sort_unstable();
    out
}

/// Removes tetrahedra (and their tags) until the boundary is a 2-manifold; unused vertices
/// are dropped. See the module doc.
pub fn make_boundary_manifold(mesh: &mut TetMesh, tags: &mut Vec<i32>) -> ManifoldRepair {
    let tets = mesh.tets.clone();
    let volume = |t: usize| {
        let p = tets[t].map(|v| mesh.vertices[v as usize]);
        tet_signed_volume(p[0], p[1], p[2], p[3]).abs()
    };
    let mut alive = vec![true; tets.len()];
    let mut repair = ManifoldRepair::default();
    for round in 0..=MAX_ROUNDS {
        let defects = find_defects(&tets, &alive);
        if defects.edges.is_empty() && defects.vertices.is_empty() {
            break;
        }
        if round == MAX_ROUNDS {
            repair.edges_left = defects.edges.len();
            repair.vertices_left = defects.vertices.len();
            break;
        }
        // The tetrahedra around each defect, from a vertex → tetrahedra map of this round.
        let mut at_vertex: FxHashMap<u32, Vec<usize>> = FxHashMap::default();
        for (t, tet) in tets.iter().enumerate() {
            if alive[t] {
                for &v in tet {
                    at_vertex.entry(v).or_default().push(t);
                }
            }
        }
        // Every fan but the largest (by volume) of the tetrahedra around a defect.
        let smaller_fans = |around: &[usize]| -> Vec<usize> {
            let fans = group_fans(&tets, around);
            let largest = fans
                .iter()
                .enumerate()
                .map(|(i, f)| (i, f.iter().map(|&t| volume(t)).sum::<Real>()))
                .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
                .map(|(i, _)| i);
            fans.into_iter()
                .enumerate()
                .filter(|&(i, _)| Some(i) != largest)
                .flat_map(|(_, fan)| fan)
                .collect()
        };
        let mut doomed: Vec<usize> = Vec::new();
        for [a, b] in &defects.edges {
            let around: Vec<usize> = at_vertex
                .get(a)
                .map(|ts| {
                    ts.iter()
                        .copied()
                        .filter(|&t| tets[t].contains(b))
                        .collect()
                })
                .unwrap_or_default();
            doomed.extend(smaller_fans(&around));
        }
        for v in &defects.vertices {
            let star = at_vertex.get(v).cloned().unwrap_or_default();
            let smaller = smaller_fans(&star);
            if smaller.is_empty() {
                // One fan whose boundary still has two rims around the vertex: the solid
                // there is a ring with a conical hole through the vertex (its link is an
                // annulus, not a disc). No fan can be dropped; the vertex's tetrahedra go,
                // which opens the ring.
                doomed.extend(star);
            } else {
                doomed.extend(smaller);
            }
        }
        doomed.sort_unstable();
        doomed.dedup();
        for t in doomed {
            if alive[t] {
                alive[t] = false;
                repair.removed += 1;
                repair.removed_volume += volume(t);
            }
        }
    }
    if repair.removed > 0 {
        fn kept<T: Copy>(v: &[T], alive: &[bool]) -> Vec<T> {
            v.iter()
                .zip(alive)
                .filter_map(|(x, &a)| a.then_some(*x))
                .collect()
        }
        let survivors = TetMesh::new(mesh.vertices.clone(), kept(&mesh.tets, &alive));
        if tags.len() == alive.len() {
            *tags = kept(tags, &alive);
        }
        *mesh = survivors.compacted();
    }
    repair
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// Two unit cubes of 6 tetrahedra each, the second shifted by `offset` (in cube
    /// lengths), sharing the vertices at the same places.
    fn two_cubes(offset: [i32; 3]) -> TetMesh {
        let mut ids: FxHashMap<[i32; 3], u32> = FxHashMap::default();
        let mut vertices = Vec::new();
        let mut tets = Vec::new();
        for o in [[0, 0, 0], offset] {
            let mut id = |p: [i32; 3]| {
                *ids.entry(p).or_insert_with(|| {
                    vertices.push(Vec3::new(p[0] as Real, p[1] as Real, p[2] as Real));
                    vertices.len() as u32 - 1
                })
            };
            let c = |i: usize| {
                [
                    o[0] + (i & 1) as i32,
                    o[1] + ((i >> 1) & 1) as i32,
                    o[2] + ((i >> 2) & 1) as i32,
                ]
            };
            // The six tetrahedra around the diagonal 0–7, positively oriented.
            for (a, b) in [(1, 3), (3, 2), (2, 6), (6, 4), (4, 5), (5, 1)] {
                let t = [id(c(0)), id(c(a)), id(c(b)), id(c(7))];
                tets.push(t);
            }
        }
        let mut m = TetMesh::new(vertices, tets);
        for t in &mut m.tets {
            let p = t.map(|v| m.vertices[v as usize]);
            if tet_signed_volume(p[0], p[1], p[2], p[3]) < 0.0 {
                t.swap(0, 1);
            }
        }
        m
    }

    fn total_volume(m: &TetMesh) -> Real {
        m.tets
            .iter()
            .map(|t| {
                let p = t.map(|v| m.vertices[v as usize]);
                tet_signed_volume(p[0], p[1], p[2], p[3])
            })
            .sum()
    }

    fn defects(m: &TetMesh) -> (usize, usize) {
        let d = find_defects(&m.tets, &vec![true; m.tets.len()]);
        (d.edges.len(), d.vertices.len())
    }

    #[test]
    fn cubes_touching_along_an_edge_or_at_a_corner_are_parted_and_reported() {
        // Sharing a face: one body, already manifold; nothing removed.
        let mut m = two_cubes([1, 0, 0]);
        let mut tags = vec![7; m.tets.len()];
        assert_eq!(defects(&m), (0, 0));
        let r = make_boundary_manifold(&mut m, &mut tags);
        assert_eq!(r.removed, 0);
        assert_eq!(m.tets.len(), 12);
        // Along an edge, and at a corner: parted by removing the tetrahedra of one cube
        // around the defect, its tags with them; the rest untouched, the volume accounted.
        for offset in [[1, 1, 0], [1, 1, 1]] {
            let mut m = two_cubes(offset);
            assert_ne!(defects(&m), (0, 0), "{offset:?}: the defect is found");
            let before = total_volume(&m);
            let mut tags: Vec<i32> = (0..m.tets.len() as i32).collect();
            let r = make_boundary_manifold(&mut m, &mut tags);
            assert_eq!(defects(&m), (0, 0), "{offset:?}: manifold after the repair");
            assert!(r.removed > 0 && r.removed <= 6, "{offset:?}: {r:?}");
            assert_eq!((r.edges_left, r.vertices_left), (0, 0));
            assert_eq!(m.tets.len(), 12 - r.removed);
            assert_eq!(tags.len(), m.tets.len());
            let after = total_volume(&m);
            assert!((before - after - r.removed_volume).abs() < 1e-12);
            assert!(m.validate_indices().is_ok());
        }
    }
}
