//! Contacts held along a direction only (`Deformable::set_constraints_along`), solved with
//! the compliance: checked against the full hold of the same equilibrium.

use super::tests::{Rng, liver_static, random_constraints};
use super::*;
use crate::model::Deformable;
use crate::model::testing::{check_held_along, every_other_direction};

/// Five contacts on the liver, three held along a random direction only. The solution is
/// an equilibrium where those three sit on their planes with reactions along their normals;
/// holding every vertex fully where that solution put it must give the same reactions and
/// surface (the same equilibrium reached by the plain 3-direction solve).
#[test]
fn a_contact_held_along_its_normal_slides_across_and_pushes_along_it() {
    let (mesh, _, fixed) = liver_static();
    let mut model = FemCondensed::new(&mesh, super::tests::liver_material(), &fixed).unwrap();
    let rest = model.rest_surface().to_vec();
    let c = random_constraints(&rest, &fixed, 5, 2e-3, &mut Rng::new(7));
    check_held_along(&mut model, &c, &every_other_direction(5, 7));
}
