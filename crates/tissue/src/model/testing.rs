//! Checks shared by the tests of several model families.

use crate::interact::Constraints;
use crate::math::Vec3;

use super::Deformable;

/// The summed reactions of the first `entries` prescribed entries of `c` after a step with
/// their targets moved by `shift`: an instrument's force, to difference against
/// `Deformable::prescribed_stiffness`.
pub fn shifted_entries_force(
    m: &mut dyn Deformable,
    c: &Constraints,
    entries: usize,
    shift: Vec3,
) -> Vec3 {
    let mut moved = c.clone();
    for p in &mut moved.prescribed[..entries] {
        p.position += shift;
    }
    m.set_constraints(&moved).unwrap();
    m.step(0.01).unwrap();
    m.reactions().prescribed[..entries].iter().copied().sum()
}
