//! Boundary vertices laid bare inside the shape, moved back onto its boundary.
//!
//! The stencils put only cut points and warped vertices (on the boundary) on the mesh's
//! boundary, and lattice vertices inside the shape only inside it. Removing tetrahedra
//! afterwards (the manifold repair where no split parts the
//! mesh, `manifold`) lays bare their far faces, whose corners can be lattice vertices inside
//! the shape: on the pelvis at 10 mm one 0.72 h from the boundary, where h/2 is promised.
//! Each such vertex is moved outward, along the mean normal of its boundary triangles, onto
//! the boundary (the first change of sign within h, `Domain::cut`), or the largest part of
//! the way there that keeps its tetrahedra oriented and within the angle bounds (or within
//! the angles they already had). A vertex between two tags (on an interface between labels)
//! stays: moving it would move the interface.

use rustc_hash::FxHashMap;

use super::domain::Domain;
use super::vertex_move::move_within_bounds;
use crate::math::{Real, Vec3};
use crate::mesh::TetMesh;
use crate::mesh::boundary::boundary_surface;

/// Steps of the outward search, per h (the boundary is looked for within h).
const SEARCH_STEPS: usize = 16;

/// Parts of the way to the boundary tried, largest first.
const FRACTIONS: [Real; 4] = [1.0, 0.75, 0.5, 0.25];

/// A bare vertex nearer the boundary than this (per h) is left where it is.
const ON_BOUNDARY: Real = 0.01;

/// What `snap_bare_vertices` did: vertices moved all the way onto the boundary, part of the
/// way, and left where they were (no boundary within h along their normal, or no move kept
/// the angles).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Snapped {
    pub onto: usize,
    pub partly: usize,
    pub left: usize,
}

/// Moves the boundary vertices of `mesh` that `bare` says were laid bare (a lattice vertex
/// the stencils left inside the shape) onto the boundary of `domain`, as far as the angles
/// allow. See the module doc.
pub fn snap_bare_vertices(
    mesh: &mut TetMesh,
    tags: &[i32],
    domain: &dyn Domain,
    size: Real,
    bare: &dyn Fn(Vec3) -> bool,
) -> Snapped {
    let mut done = Snapped::default();
    let boundary = boundary_surface(mesh);
    let surface = &boundary.surface;
    // Area-weighted outward normal per bare boundary vertex.
    let mut normal: FxHashMap<u32, Vec3> = FxHashMap::default();
    for (t, tri) in surface.triangles.iter().enumerate() {
        let [a, b, c] = surface.corners(t);
        let n = (b - a).cross(c - a);
        for &s in tri {
            let v = boundary.nodes[s as usize];
            if bare(mesh.vertices[v as usize]) {
                *normal.entry(v).or_insert(Vec3::ZERO) += n;
            }
        }
    }
    if normal.is_empty() {
        return done;
    }
    let mut around: FxHashMap<u32, Vec<usize>> = FxHashMap::default();
    for (t, tet) in mesh.tets.iter().enumerate() {
        for v in tet {
            if normal.contains_key(v) {
                around.entry(*v).or_default().push(t);
            }
        }
    }
    let mut bare: Vec<(u32, Vec3)> = normal.into_iter().collect();
    bare.sort_unstable_by_key(|b| b.0);
    let step = size / SEARCH_STEPS as Real;
    for (v, n) in bare {
        let n = n.normalize_or_zero();
        let ts = around.get(&v).cloned().unwrap_or_default();
        let p = mesh.vertices[v as usize];
        let one_tag = ts.windows(2).all(|w| tags.get(w[0]) == tags.get(w[1]));
        if n == Vec3::ZERO || ts.is_empty() || !one_tag {
            done.left += 1;
            continue;
        }
        // The first crossing of the boundary outward, within h.
        let mut target = None;
        let mut inside = p;
        for k in 1..=SEARCH_STEPS {
            let q = p + (k as Real * step) * n;
            if domain.value(q) > 0.0 {
                target = Some(domain.cut(inside, q));
                break;
            }
            inside = q;
        }
        let Some(s) = target else {
            done.left += 1;
            continue;
        };
        if (s - p).length() < ON_BOUNDARY * size {
            continue;
        }
        match move_within_bounds(mesh, v, &ts, s - p, &FRACTIONS) {
            Some(0) => done.onto += 1,
            Some(_) => done.partly += 1,
            None => done.left += 1,
        }
    }
    done
}

#[cfg(test)]
mod tests {
    use super::super::PROVEN_DIHEDRAL_DEG;
    use super::super::report::dihedral_angles;
    use super::*;
    use crate::math::tet_signed_volume;
    use crate::mesh::stuffing::Implicit;

    /// A 2 × 2 × 1 block of unit cubes (the manifold repair's test cubes).
    fn block() -> TetMesh {
        super::super::manifold::tests::cubes(&[[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    }

    #[test]
    fn a_vertex_laid_bare_goes_onto_the_boundary_and_the_rest_stay() {
        // The shape is the slab z < 1.3; the block's top (z = 1) lies 0.3 inside it. Only
        // the top's centre (1, 1, 1) is said to be bare: it moves up onto z = 1.3, along the
        // normal of its boundary triangles, within the angle bounds; nothing else moves.
        let slab = Implicit {
            f: |p: Vec3| p.z - 1.3,
            lo: Vec3::new(0.0, 0.0, -1.0),
            hi: Vec3::new(2.0, 2.0, 1.3),
            volume: None,
        };
        let mut m = block();
        let before = m.vertices.clone();
        let centre = Vec3::new(1.0, 1.0, 1.0);
        let tags = vec![1; m.tets.len()];
        let done = snap_bare_vertices(&mut m, &tags, &slab, 1.0, &|p| p == centre);
        assert_eq!(
            done,
            Snapped {
                onto: 1,
                partly: 0,
                left: 0
            }
        );
        for (p, q) in before.iter().zip(&m.vertices) {
            if *p == centre {
                assert!((*q - Vec3::new(1.0, 1.0, 1.3)).length() < 1e-9, "{q}");
            } else {
                assert_eq!(p, q);
            }
        }
        for t in &m.tets {
            let p = t.map(|v| m.vertices[v as usize]);
            assert!(tet_signed_volume(p[0], p[1], p[2], p[3]) > 0.0);
            let lo = dihedral_angles(p)
                .into_iter()
                .fold(Real::INFINITY, Real::min);
            assert!(
                lo.to_degrees() >= PROVEN_DIHEDRAL_DEG.0,
                "{}",
                lo.to_degrees()
            );
        }
        // Between two tags it stays (it would move the interface); so does a vertex with no
        // boundary within h along its normal.
        let mut m = block();
        let corner = Vec3::new(0.0, 0.0, 1.0);
        let first = (0..m.tets.len())
            .find(|&t| m.tets[t].iter().any(|&v| m.vertices[v as usize] == centre));
        let tags: Vec<i32> = (0..m.tets.len())
            .map(|t| if Some(t) == first { 2 } else { 1 })
            .collect();
        let done = snap_bare_vertices(&mut m, &tags, &slab, 1.0, &|p| p == centre);
        assert_eq!(
            done,
            Snapped {
                onto: 0,
                partly: 0,
                left: 1
            }
        );
        let deep = Implicit {
            f: |p: Vec3| p.z - 3.0,
            lo: Vec3::ZERO,
            hi: Vec3::splat(3.0),
            volume: None,
        };
        let mut m = block();
        let tags = vec![1; m.tets.len()];
        let done = snap_bare_vertices(&mut m, &tags, &deep, 1.0, &|p| p == corner);
        assert_eq!(
            done,
            Snapped {
                onto: 0,
                partly: 0,
                left: 1
            }
        );
        assert_eq!(m.vertices, block().vertices);
    }
}
