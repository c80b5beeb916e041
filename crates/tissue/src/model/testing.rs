//! Checks shared by the tests of several model families.

use crate::interact::{Constraints, Prescribed};
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

/// Unit directions, pseudo-random from `seed`, for every other entry of `count` (the others
/// `None`: held in full).
pub fn every_other_direction(count: usize, seed: u64) -> Vec<Option<Vec3>> {
    let mut state = seed;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as Real / (1u64 << 53) as Real - 0.5
    };
    (0..count)
        .map(|k| {
            let d = Vec3::new(next(), next(), next());
            (k % 2 == 0).then(|| d.normalize())
        })
        .collect()
}

/// `c`'s prescribed entries held along `normals` (`Deformable::set_constraints_along`, which
/// must say it did so): an equilibrium where each entry with a direction n sits on its
/// plane nᵀ(x − t) = 0, has slid across it, and is pushed along n only (|r × n| < 1e-9 of
/// the largest reaction); the others reach their targets. Holding every entry in full where
/// that solution put it must then give the same reactions (1e-8) and surface (1e-12 m):
/// the same equilibrium, reached by the plain three-direction solve. Returns the reactions
/// and the surface of the solve along the normals.
pub fn check_held_along(
    model: &mut dyn Deformable,
    c: &Constraints,
    normals: &[Option<Vec3>],
) -> (Vec<Vec3>, Vec<Vec3>) {
    assert!(model.set_constraints_along(c, normals).unwrap());
    model.step(0.01).unwrap();
    let along: Vec<Vec3> = model.reactions().prescribed.to_vec();
    let reached: Vec<Vec3> = model.surface().positions.to_vec();
    let scale = along.iter().map(|r| r.length()).fold(0.0, Real::max);
    assert!(scale > 0.0);
    let (mut slid, mut off, mut sideways): (Real, Real, Real) = (0.0, 0.0, 0.0);
    for ((p, n), r) in c.prescribed.iter().zip(normals).zip(&along) {
        let x = reached[p.vertex as usize];
        match n {
            Some(n) => {
                off = off.max((x - p.position).dot(*n).abs());
                sideways = sideways.max(r.cross(*n).length() / scale);
                slid = slid.max((x - p.position).length());
            }
            None => off = off.max((x - p.position).length()),
        }
    }
    assert!(off < 1e-12, "off its plane by {off:e} m");
    assert!(
        sideways < 1e-9,
        "sideways reaction {sideways:e} of the largest"
    );
    assert!(slid > 1e-5, "{slid}");
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
    let gap = |a: &[Vec3], b: &[Vec3]| {
        a.iter()
            .zip(b)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, Real::max)
    };
    let reactions = gap(&along, model.reactions().prescribed) / scale;
    let surface = gap(&reached, model.surface().positions);
    eprintln!(
        "{}: held along normals: off the planes {off:.1e} m, sideways {sideways:.1e} of the \
         largest reaction, slid {slid:.1e} m; the full hold there: reactions {reactions:.1e} \
         relative, surface {surface:.1e} m",
        model.kind()
    );
    assert!(reactions < 1e-8, "{reactions:e}");
    assert!(surface < 1e-12, "{surface:e} m");
    (along, reached)
}
