//! Contacts held along a direction only (`Deformable::set_constraints_along`), solved with
//! the compliance: checked against the full hold of the same equilibrium.

use super::tests::{Rng, liver_static, random_constraints};
use super::*;
use crate::interact::{Constraints, Prescribed};
use crate::model::Deformable;

/// Five contacts on the liver, three held along a random direction only. The solution is
/// an equilibrium where those three sit on their planes with reactions along their normals;
/// holding every vertex fully where that solution put it must give the same reactions and
/// surface (the same equilibrium reached by the plain 3-direction solve).
#[test]
fn a_contact_held_along_its_normal_slides_across_and_pushes_along_it() {
    let (mesh, _, fixed) = liver_static();
    let mut model = FemCondensed::new(&mesh, super::tests::liver_material(), &fixed).unwrap();
    let rest = model.rest_surface().to_vec();
    let mut rng = Rng::new(7);
    let c = random_constraints(&rest, &fixed, 5, 2e-3, &mut rng);
    let normals: Vec<Option<Vec3>> = (0..5)
        .map(|k| {
            (k % 2 == 0).then(|| {
                Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5).normalize()
            })
        })
        .collect();
    assert!(model.set_constraints_along(&c, &normals).unwrap());
    model.step(0.01).unwrap();
    let along: Vec<Vec3> = model.reactions().prescribed.to_vec();
    let reached: Vec<Vec3> = model.surface().positions.to_vec();
    let scale = along.iter().map(|r| r.length()).fold(0.0, Real::max);
    assert!(scale > 0.0);
    for ((p, n), r) in c.prescribed.iter().zip(&normals).zip(&along) {
        let x = reached[p.vertex as usize];
        match n {
            Some(n) => {
                // On its plane, free across it, pushed along it only.
                assert!((x - p.position).dot(*n).abs() < 1e-12, "{x} {}", p.position);
                assert!(r.cross(*n).length() < 1e-9 * scale, "{r} not along {n}");
            }
            None => assert!((x - p.position).length() < 1e-12),
        }
    }
    // Moved across: a contact held along its normal does not stay at its target.
    let slid = c
        .prescribed
        .iter()
        .zip(&normals)
        .filter(|(_, n)| n.is_some())
        .map(|(p, _)| (reached[p.vertex as usize] - p.position).length())
        .fold(0.0, Real::max);
    assert!(slid > 1e-5, "{slid}");
    // The same equilibrium, held in all three directions where it was reached.
    let pinned = Constraints {
        fixed: c.fixed.clone(),
        prescribed: c
            .prescribed
            .iter()
            .map(|p| Prescribed {
                vertex: p.vertex,
                position: reached[p.vertex as usize],
            })
            .collect(),
    };
    model.set_constraints(&pinned).unwrap();
    model.step(0.01).unwrap();
    for (a, b) in along.iter().zip(model.reactions().prescribed) {
        assert!((*a - *b).length() < 1e-8 * scale, "{a} vs {b}");
    }
    for (a, b) in reached.iter().zip(model.surface().positions) {
        assert!((*a - *b).length() < 1e-12, "{a} vs {b}");
    }
}
