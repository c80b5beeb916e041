//! Linked volumes cut, carved and joined: exact counts of removed and restored springs,
//! halves that no longer feel each other, momentum and energy across a cut, and the drawn
//! surface closed, split into the expected pieces and moving with its elements.

use super::*;
use crate::integrate::ParticleSystem;
use crate::model::{CutPath, Deformable};
use crate::voxel::boundary::closed_pieces;

const H: Real = 0.01;

fn block(neighbours: usize, integrator: Scheme) -> LinkedVolumes {
    block_with_poisson(neighbours, integrator, 0.3)
}

/// ν = 1/4 is springs alone (no volume term).
fn block_with_poisson(neighbours: usize, integrator: Scheme, nu: Real) -> LinkedVolumes {
    let mut material = Material::new(3000.0, nu).unwrap();
    material.damping = 0.0;
    material.stiffness_damping = 0.0;
    let params = LinkedVolumesParams {
        neighbours,
        integrator,
        ..Default::default()
    };
    LinkedVolumes::new(VoxelGrid::filled([6, 6, 6], H), None, material, params).unwrap()
}

/// A blade sweeping the whole plane x = 2.5 h (between voxel columns 2 and 3).
fn plane_blade() -> CutPath {
    let x = 2.5 * H;
    CutPath {
        start: [Vec3::new(x, -H, -H), Vec3::new(x, 7.0 * H, -H)],
        end: [Vec3::new(x, -H, 7.0 * H), Vec3::new(x, 7.0 * H, 7.0 * H)],
    }
}

/// Elements of a 6³ block are its voxels; column i = id mod 6.
fn left(e: usize) -> bool {
    e % 6 < 3
}

#[test]
fn a_plane_cut_removes_exactly_the_springs_across_it() {
    // Column 2 to 3: 36 axis springs; 4·30 face diagonals; 4·25 body diagonals.
    for (neighbours, across) in [(6, 36), (18, 156), (26, 256)] {
        let mut m = block(neighbours, Scheme::ImplicitEuler);
        let springs = m.system.springs.len();
        assert_eq!(m.link_count(), springs);
        let info = m.cut(&plane_blade()).unwrap();
        assert_eq!(info.removed_elements, across, "{neighbours}");
        assert_eq!(info.topology_version, 1);
        assert_eq!(m.system.springs.len(), springs - across);
        assert_eq!(m.link_count(), springs - across);
        // No spring joins the halves any more.
        assert!(
            m.system
                .springs
                .iter()
                .all(|s| left(s.a as usize) == left(s.b as usize))
        );
        // Cutting again along the same plane finds nothing and changes nothing.
        let again = m.cut(&plane_blade()).unwrap();
        assert_eq!((again.removed_elements, again.topology_version), (0, 1));
    }
}

#[test]
fn after_a_cut_a_pull_on_one_half_leaves_the_other_at_rest_and_the_surface_parts() {
    let mut m = block(26, Scheme::ImplicitEuler);
    m.cut(&plane_blade()).unwrap();
    let s = m.surface();
    assert_eq!(
        closed_pieces(s.triangles, s.positions, 1e-8 * H * H).unwrap(),
        vec![2, 2]
    );
    // Pull the left half toward −x through its element forces.
    for (e, f) in m.system.external.iter_mut().enumerate() {
        *f = if left(e) { -0.01 * Vec3::X } else { Vec3::ZERO };
    }
    m.integrator.invalidate();
    for _ in 0..20 {
        m.step(1e-3).unwrap();
    }
    for e in 0..m.rest.len() {
        let u = m.state.x[e] - m.rest[e];
        if left(e) {
            assert!(u.x < -1e-6, "{e} {u}");
        } else {
            assert!(
                u.length() <= 1e-12 && m.state.v[e].length() <= 1e-12,
                "{e} {u}"
            );
        }
    }
    // The surface follows: the right piece is at rest, every vertex of the left piece
    // (its lip included) has moved left.
    let s = m.surface();
    let drawn: Vec<usize> = s.triangles.iter().flatten().map(|&v| v as usize).collect();
    let (mut moved, mut still) = (0, 0);
    for &v in &drawn {
        let d = s.positions[v] - m.embedding.rest[v];
        if d.length() <= 1e-12 {
            still += 1;
            assert!(m.embedding.rest[v].x > 2.4 * H, "{v}");
        } else {
            moved += 1;
            assert!(
                d.x < 0.0 && m.embedding.rest[v].x < 2.6 * H,
                "{v} {d} {}",
                m.embedding.rest[v] / H
            );
        }
    }
    assert!(moved > 0 && still > 0);
    assert_eq!(
        closed_pieces(s.triangles, s.positions, 1e-8 * H * H).unwrap(),
        vec![2, 2]
    );
}

#[test]
fn a_cut_keeps_momentum_and_removes_exactly_the_cut_springs_energy() {
    // Springs alone: with ν > 1/4 the volume term's stencils at the cut change too.
    let mut m = block_with_poisson(26, Scheme::SymplecticEuler, 0.25);
    for (i, (x, v)) in m.state.x.iter_mut().zip(m.state.v.iter_mut()).enumerate() {
        let s = (i as Real * 0.37).sin();
        *x += Vec3::new(s, -s * 0.5, s * s) * 1e-4;
        *v = Vec3::new(0.01 * s, 0.02, -0.005 * (i % 3) as Real);
    }
    let mass = m.system.masses[0];
    let momentum = |m: &LinkedVolumes| m.state.v.iter().sum::<Vec3>() * mass;
    let energy = |m: &LinkedVolumes| {
        m.state.kinetic_energy(&m.system.masses) + m.system.elastic_energy(&m.state.x)
    };
    for _ in 0..50 {
        m.step(1e-4).unwrap();
    }
    let (p0, e0) = (momentum(&m), energy(&m));
    let crossing: Real = m
        .system
        .springs
        .iter()
        .filter(|s| left(s.a as usize) != left(s.b as usize))
        .map(|s| {
            let l = (m.state.x[s.b as usize] - m.state.x[s.a as usize]).length();
            0.5 * s.k * (l - s.rest) * (l - s.rest)
        })
        .sum();
    m.cut(&plane_blade()).unwrap();
    let e1 = energy(&m);
    assert!(
        (e1 - (e0 - crossing)).abs() <= 1e-12 * e0,
        "{e1} {e0} {crossing}"
    );
    assert_eq!(momentum(&m), p0);
    for _ in 0..400 {
        m.step(1e-4).unwrap();
    }
    let p = momentum(&m);
    assert!((p - p0).length() <= 1e-12 * p0.length(), "{p} {p0}");
    // Symplectic Euler without damping: the energy oscillates but does not drift.
    let e2 = energy(&m);
    assert!((e2 - e1).abs() < 0.02 * e1, "{e2} {e1}");
}

#[test]
fn join_restores_the_springs_and_the_uncut_forces() {
    let fresh = block(26, Scheme::ImplicitEuler);
    let mut m = block(26, Scheme::ImplicitEuler);
    m.cut(&plane_blade()).unwrap();
    // Elements that are not back at their rest offsets are not touching: nothing joins.
    m.state.x[2] += Vec3::X * 0.3 * H;
    let before = m.system.springs.len();
    let joined = m.join(1e-9);
    assert!(joined < 256);
    assert_eq!(m.system.springs.len(), before + joined);
    m.reset();
    assert_eq!(m.join(1e-12), 256 - joined);
    assert_eq!(m.system.springs.len(), fresh.system.springs.len());
    let s = m.surface();
    assert_eq!(
        closed_pieces(s.triangles, s.positions, 1e-8 * H * H).unwrap(),
        vec![2]
    );
    // The same forces as the uncut block on a deformed state.
    let x: Vec<Vec3> = fresh
        .rest
        .iter()
        .enumerate()
        .map(|(i, p)| *p + Vec3::new((i as Real).sin(), (i as Real * 0.3).cos(), 0.5) * 1e-3)
        .collect();
    let v = vec![Vec3::ZERO; x.len()];
    let (mut f0, mut f1) = (vec![Vec3::ZERO; x.len()], vec![Vec3::ZERO; x.len()]);
    let mut a = fresh.system.clone();
    a.forces(&x, &v, &mut f0);
    m.system.forces(&x, &v, &mut f1);
    let scale = f0.iter().map(|f| f.length()).fold(0.0, Real::max);
    for (p, q) in f0.iter().zip(&f1) {
        assert!((*p - *q).length() <= 1e-12 * scale);
    }
}

#[test]
fn carving_a_corner_removes_its_elements_springs_and_surface() {
    let mut m = block(6, Scheme::ImplicitEuler);
    let springs = m.system.springs.len();
    assert_eq!(springs, 540);
    assert_eq!(m.carve(Vec3::ZERO, 1.1 * H).unwrap(), 4);
    assert_eq!(m.system.springs.len(), springs - 12);
    let s = m.surface();
    assert_eq!(
        closed_pieces(s.triangles, s.positions, 1e-8 * H * H).unwrap(),
        vec![2]
    );
    // No drawn vertex follows a carved element.
    let carved = [0u32, 1, 6, 36];
    for t in s.triangles {
        for &v in t {
            let (ids, w) = (
                m.embedding.nodes[v as usize],
                m.embedding.weights[v as usize],
            );
            assert!((0..8).all(|k| w[k] == 0.0 || !carved.contains(&ids[k])));
        }
    }
    assert!(m.carve(Vec3::NAN, 1.0).is_err());
    assert_eq!(m.carve(Vec3::splat(-1.0), 0.001).unwrap(), 0);
}
