//! The pieces of a stuffed mesh (tetrahedra joined through shared vertices), and keeping the
//! largest when the input is one piece.
//!
//! A lattice of spacing h cannot follow a connection thinner than h: an image whose
//! largest part was kept (one 6-connected set of voxels) can still come out as a mesh in
//! two pieces, the small one joined to the rest by a strand of voxels the lattice skipped.
//! No support holds such a piece, so every model built on it is singular (a static solve
//! refuses it; a dynamic one lets it drift). When the domain says its input is one piece
//! (`Domain::one_piece`), the mesh keeps its largest piece and the report says what went;
//! otherwise the pieces are counted and reported (a surface file may hold two organs).

use serde::Serialize;

use crate::math::{Real, tet_signed_volume};
use crate::mesh::TetMesh;

/// What `pieces` found and dropped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Pieces {
    /// Pieces left in the mesh.
    pub count: usize,
    /// Pieces dropped, their tetrahedra and volume (m³).
    pub dropped: usize,
    pub dropped_tets: usize,
    pub dropped_volume: Real,
}

/// The piece of each tetrahedron (0 for the one of largest volume, then by volume).
fn piece_of_each(mesh: &TetMesh) -> (Vec<usize>, Vec<Real>) {
    let n = mesh.vertices.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for t in &mesh.tets {
        let r0 = root(&mut parent, t[0] as usize);
        for &v in &t[1..] {
            let r = root(&mut parent, v as usize);
            parent[r] = r0;
        }
    }
    let mut index = vec![usize::MAX; n];
    let mut volumes: Vec<Real> = Vec::new();
    let mut of_tet = Vec::with_capacity(mesh.tets.len());
    for t in &mesh.tets {
        let r = root(&mut parent, t[0] as usize);
        if index[r] == usize::MAX {
            index[r] = volumes.len();
            volumes.push(0.0);
        }
        let p = t.map(|v| mesh.vertices[v as usize]);
        volumes[index[r]] += tet_signed_volume(p[0], p[1], p[2], p[3]).abs();
        of_tet.push(index[r]);
    }
    // Renumber by decreasing volume (ties by first appearance).
    let mut order: Vec<usize> = (0..volumes.len()).collect();
    order.sort_by(|&a, &b| volumes[b].total_cmp(&volumes[a]).then(a.cmp(&b)));
    let mut rank = vec![0; volumes.len()];
    for (r, &p) in order.iter().enumerate() {
        rank[p] = r;
    }
    let sorted = order.iter().map(|&p| volumes[p]).collect();
    (of_tet.iter().map(|&p| rank[p]).collect(), sorted)
}

/// Counts the mesh's pieces; with `keep_largest`, drops all but the largest (their tags
/// with them, unused vertices too).
pub fn pieces(mesh: &mut TetMesh, tags: &mut Vec<i32>, keep_largest: bool) -> Pieces {
    if mesh.tets.is_empty() {
        return Pieces::default();
    }
    let (piece, volumes) = piece_of_each(mesh);
    if !keep_largest || volumes.len() == 1 {
        return Pieces {
            count: volumes.len(),
            ..Pieces::default()
        };
    }
    let keep: Vec<bool> = piece.iter().map(|&p| p == 0).collect();
    let dropped_tets = keep.iter().filter(|&&k| !k).count();
    let filter = |t: &[[u32; 4]]| -> Vec<[u32; 4]> {
        t.iter()
            .zip(&keep)
            .filter_map(|(t, &k)| k.then_some(*t))
            .collect()
    };
    let kept = TetMesh::new(mesh.vertices.clone(), filter(&mesh.tets));
    if tags.len() == keep.len() {
        *tags = tags
            .iter()
            .zip(&keep)
            .filter_map(|(t, &k)| k.then_some(*t))
            .collect();
    }
    *mesh = kept.compacted();
    Pieces {
        count: 1,
        dropped: volumes.len() - 1,
        dropped_tets,
        dropped_volume: volumes[1..].iter().sum(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// Two tetrahedra apart and a third sharing a vertex with the first.
    #[test]
    fn pieces_are_counted_and_the_largest_kept_with_its_tags() {
        let unit = |o: Vec3, s: Real| {
            vec![
                o,
                o + Vec3::new(s, 0.0, 0.0),
                o + Vec3::new(0.0, s, 0.0),
                o + Vec3::new(0.0, 0.0, s),
            ]
        };
        let mut vertices = unit(Vec3::ZERO, 1.0);
        vertices.extend(unit(Vec3::new(5.0, 0.0, 0.0), 0.5));
        vertices.extend(unit(Vec3::new(-1.0, 0.0, 0.0), 1.0)); // its corner 1 is vertex 0
        let tets = vec![[0, 1, 2, 3], [4, 5, 6, 7], [8, 0, 10, 11]];
        let mesh = TetMesh::new(vertices, tets);
        let (mut m, mut tags) = (mesh.clone(), vec![1, 2, 3]);
        assert_eq!(pieces(&mut m, &mut tags, false).count, 2);
        assert_eq!(m, mesh);
        let p = pieces(&mut m, &mut tags, true);
        assert_eq!((p.count, p.dropped, p.dropped_tets), (1, 1, 1));
        assert!((p.dropped_volume - 0.125 / 6.0).abs() < 1e-15);
        assert_eq!(tags, vec![1, 3]);
        assert_eq!(m.tets.len(), 2);
        assert_eq!(m.vertices.len(), 7);
        assert!(m.validate_indices().is_ok());
    }
}
