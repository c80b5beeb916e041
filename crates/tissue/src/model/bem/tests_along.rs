//! Contacts held along a direction only (`Deformable::set_constraints_along`), solved with
//! the pre-inverted response (`BemSystem::solve_along`): checked against the full hold of
//! the same equilibrium.

use super::tests::{material, press, sphere, top};
use super::*;
use crate::interact::Loads;
use crate::math::Vec3;
use crate::model::Deformable;
use crate::model::testing::{check_held_along, every_other_direction};

/// The sphere under gravity, its lower part fixed, a cap of seven vertices pressed toward
/// the centre, four of them held along a random direction only: an equilibrium where those
/// sit on their planes and are pushed along their normals only, which the full hold where
/// it put them reproduces (`check_held_along`), with the contacts' tractions continuous
/// across their rim and discontinuous (the default: the block of the held directions then
/// comes from the rim-corrected responses W̃).
#[test]
fn a_contact_held_along_its_normal_slides_across_and_pushes_along_it() {
    for params in [BemParams::continuous(), BemParams::default()] {
        let mut model = Bem::new(&sphere(2), material(), params).unwrap();
        let rest = model.rest_surface().to_vec();
        let cap = &top(&rest)[..7];
        let c = press(&rest, -0.03, cap);
        model.set_constraints(&c).unwrap();
        model
            .set_loads(&Loads {
                gravity: Vec3::new(0.0, 0.0, -9.81),
                point_loads: Vec::new(),
            })
            .unwrap();
        check_held_along(&mut model, &c, &every_other_direction(cap.len(), 11));
        // The full hold has its closed-form stiffness back; a hold along a normal has none.
        assert!(model.prescribed_stiffness(0..1).is_some());
        let along = every_other_direction(cap.len(), 11);
        assert!(model.set_constraints_along(&c, &along).unwrap());
        assert!(model.prescribed_stiffness(0..1).is_none());
    }
}
