//! The tensors against fem-static and fem-condensed, and the single-contact closed form.

use super::*;
use crate::interact::{Constraints, Loads, Prescribed};
use crate::mesh::generate::BoxSplit;
use crate::model::Deformable;
use crate::model::fem::FemCondensed;
use crate::model::fem::condensed::tests::{
    Rng, applied_load, apply, assert_cannot_cut, box_matches_fem_static_with, check_balance,
    compare, liver_material, liver_static, loads, random_constraints,
    stiffness_matches_fem_static_differences_with,
};
use crate::model::testing::{check_held_along, every_other_direction};

#[test]
fn liver_matches_fem_static_and_fem_condensed() {
    let (mesh, mut reference, fixed) = liver_static();
    let mut tensors = FemPrecomputedTensors::new(&mesh, liver_material(), &fixed).unwrap();
    let mut condensed = FemCondensed::new(&mesh, liver_material(), &fixed).unwrap();
    let rest = reference.rest_surface().to_vec();
    let mut rng = Rng::new(19);
    let l = loads(fixed[0] + 2);
    for count in [1, 4, 10, 25] {
        let c = random_constraints(&rest, &fixed, count, 2e-3, &mut rng);
        apply(&mut [&mut reference, &mut tensors, &mut condensed], &c, &l);
        let (du, dr) = compare(&tensors, &reference);
        assert!(du < 1e-8 && dr < 1e-8, "{count} contacts: {du:e} {dr:e}");
        let (du, dr) = compare(&tensors, &condensed);
        assert!(du < 1e-9 && dr < 1e-9, "vs condensed: {du:e} {dr:e}");
        check_balance(&tensors, applied_load(&reference, &l));
    }
    // n²·9 + 2n·9 doubles for the 137 free surface nodes of the liver: about 1.37 MB.
    assert_eq!(tensors.tensor_bytes(), (137 * 137 + 2 * 137) * 72);
    let info = tensors.info();
    assert!(info.is_static && info.memory_bytes > tensors.tensor_bytes());
}

#[test]
fn box_matches_fem_static() {
    box_matches_fem_static_with(BoxSplit::Five, 23, 30, [3, 9], |mesh, material, fixed| {
        FemPrecomputedTensors::new(mesh, material, fixed).unwrap()
    });
}

#[test]
fn stiffness_matches_fem_static_differences() {
    stiffness_matches_fem_static_differences_with(|mesh, material, fixed| {
        FemPrecomputedTensors::new(mesh, material, fixed).unwrap()
    });
}

/// One contact, no load: u_i = T^U_{i,k} ū, P_k = T^F_k ū, T^U_{k,k} = I, T^F symmetric.
#[test]
fn single_contact_is_the_tensor_closed_form() {
    let (mesh, mut reference, fixed) = liver_static();
    let mut model = FemPrecomputedTensors::new(&mesh, liver_material(), &fixed).unwrap();
    let free = model.free_vertices().to_vec();
    let rest = model.rest_surface().to_vec();
    let ubar = Vec3::new(1e-3, -2e-3, 0.5e-3);
    for k in [0, 40, 136] {
        let tkk = model.displacement_tensor(k, k).unwrap();
        assert!((tkk - Mat3::IDENTITY).abs_diff_eq(Mat3::ZERO, 1e-12));
        let tf = model.force_tensor(k).unwrap();
        assert!(tf.abs_diff_eq(tf.transpose(), 1e-9 * tf.col(0).length()));
        let v = free[k];
        let mut c = Constraints::fixed(fixed.clone());
        c.prescribed.push(Prescribed {
            vertex: v,
            position: rest[v as usize] + ubar,
        });
        apply(&mut [&mut reference, &mut model], &c, &Loads::default());
        let (du, dr) = compare(&model, &reference);
        assert!(du < 1e-8 && dr < 1e-8, "{du:e} {dr:e}");
        let pos = model.surface().positions;
        let scale = ubar.length();
        for (i, &w) in free.iter().enumerate() {
            let expect = model.displacement_tensor(i, k).unwrap() * ubar;
            let got = pos[w as usize] - rest[w as usize];
            assert!((got - expect).length() <= 1e-12 * scale);
        }
        // The tissue pushes back on the probe with −P_k.
        let p = tf * ubar;
        let r = model.reactions().prescribed[0];
        assert!((r + p).length() <= 1e-10 * p.length(), "{r} vs {p}");
    }
    assert!(model.displacement_tensor(137, 0).is_none() && model.force_tensor(137).is_none());
}

#[test]
fn bad_input_is_refused_and_keeps_the_state() {
    let (mesh, fem, fixed) = liver_static();
    let rest = fem.rest_surface().to_vec();
    let mut model = FemPrecomputedTensors::new(&mesh, liver_material(), &fixed).unwrap();
    let c = random_constraints(&rest, &fixed, 6, 1e-3, &mut Rng::new(2));
    model.set_constraints(&c).unwrap();
    model.step(0.0).unwrap();
    let before = model.surface().positions.to_vec();
    let mut bad = c.clone();
    bad.prescribed[0].position.x = Real::INFINITY;
    assert!(model.set_constraints(&bad).is_err());
    model.step(0.0).unwrap();
    assert_eq!(model.surface().positions, &before[..]);
    assert_cannot_cut(&mut model);
    model.reset();
    assert_eq!(model.surface().positions, &rest[..]);
}

/// Seven contacts on the liver under gravity and a point load, four held along a random
/// direction only: the tensors' solve in the contact forces (`solve::along`, an LU: their
/// block is W_CC only up to roundoff) is the equilibrium of the full hold where it put the
/// vertices (`check_held_along`), and `fem-condensed`'s along the same normals (its
/// compliance, a Cholesky): the same reactions and surface.
#[test]
fn contacts_held_along_normals_match_the_full_hold_and_fem_condensed() {
    let (mesh, _, fixed) = liver_static();
    let mut tensors = FemPrecomputedTensors::new(&mesh, liver_material(), &fixed).unwrap();
    let mut condensed = FemCondensed::new(&mesh, liver_material(), &fixed).unwrap();
    let rest = tensors.rest_surface().to_vec();
    let c = random_constraints(&rest, &fixed, 7, 2e-3, &mut Rng::new(23));
    let normals = every_other_direction(7, 23);
    let l = loads(fixed[0] + 2);
    tensors.set_loads(&l).unwrap();
    condensed.set_loads(&l).unwrap();
    let (along, reached) = check_held_along(&mut tensors, &c, &normals);
    assert!(condensed.set_constraints_along(&c, &normals).unwrap());
    condensed.step(0.01).unwrap();
    let scale = along.iter().map(|r| r.length()).fold(0.0, Real::max);
    for (a, b) in along.iter().zip(condensed.reactions().prescribed) {
        assert!((*a - *b).length() < 1e-9 * scale, "{a} vs {b}");
    }
    for (a, b) in reached.iter().zip(condensed.surface().positions) {
        assert!((*a - *b).length() < 1e-12, "{a} vs {b}");
    }
}
