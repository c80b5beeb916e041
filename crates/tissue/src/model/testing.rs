//! Checks shared by the tests of several model families.

use crate::interact::Constraints;
use crate::math::{Real, Vec3};

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

/// (σ, ω_d): the decay rate and damped frequency of the oscillation in `z`, from its
/// extrema after `skip` samples: consecutive extrema are half a damped period apart and
/// their differences shrink by e^{−σ T/2}.
pub fn decay(z: &[Real], dt: Real, skip: usize) -> (Real, Real) {
    let mut ext = Vec::new();
    for k in skip.max(1)..z.len() - 1 {
        if (z[k] - z[k - 1]) * (z[k + 1] - z[k]) < 0.0 {
            // Parabolic refinement of the extremum's time and value.
            let (a, b, c) = (z[k - 1], z[k], z[k + 1]);
            let den = a - 2.0 * b + c;
            let s = if den != 0.0 { 0.5 * (a - c) / den } else { 0.0 };
            ext.push(((k as Real + s) * dt, b - 0.25 * (a - c) * s));
        }
    }
    assert!(ext.len() >= 5, "too few extrema: {ext:?}");
    let swings: Vec<(Real, Real)> = ext
        .windows(2)
        .map(|w| (0.5 * (w[0].0 + w[1].0), (w[1].1 - w[0].1).abs()))
        .collect();
    let (first, last) = (swings[0], swings[swings.len() - 1]);
    let sigma = (first.1 / last.1).ln() / (last.0 - first.0);
    let half = (ext[ext.len() - 1].0 - ext[0].0) / (ext.len() - 1) as Real;
    (sigma, std::f64::consts::PI / half)
}
