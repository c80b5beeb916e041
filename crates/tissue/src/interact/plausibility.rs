//! The run-level backstop against absurd results. The integrators guard their own stability
//! (blow-up and energy checks inside the models); this module judges what a finished step
//! hands out: where the surface is and what the instruments feel. A state is plausible when
//!
//! - every surface coordinate and every instrument force is finite;
//! - no surface vertex has moved farther from rest than `DISPLACEMENT_FACTOR` times the
//!   body's size (the diagonal of its rest bounding box): tissue torn twice across itself
//!   is a diverged solve, not surgery;
//! - no instrument feels more than `FORCE_FACTOR · E · L²` (E the material's Young's
//!   modulus, L the body's size): the force that would squash the whole body flat over its
//!   whole cross-section, ten times over. Liver (E = 3 kPa, L = 0.15 m): about 700 N, where
//!   probes measure below 1 N and the absurd runs of issue 21 reached 1e4 to 1e102 N. An
//!   instrument wider than the body is refused when the scene is built
//!   (`check_instrument_size`), so the instrument's size never sets a larger bound.
//!
//! `Simulation::step` calls `check` before it accepts a step; a failed check is
//! `SimError::Implausible` and the step is not accepted (time, instruments and the outputs
//! written so far stay at the last plausible step).

use crate::error::SimError;
use crate::interact::instrument::Instrument;
use crate::material::Material;
use crate::math::{Real, Vec3, is_finite_vec};
use crate::model::Deformable;

/// Largest plausible displacement, in body sizes.
pub const DISPLACEMENT_FACTOR: Real = 2.0;
/// Largest plausible instrument force, in units of E · L².
pub const FORCE_FACTOR: Real = 10.0;

/// The bounds of one body.
#[derive(Clone, Debug, PartialEq)]
pub struct Plausibility {
    /// The body's size: the diagonal of its rest surface's bounding box, in m.
    pub size: Real,
    /// Largest displacement of a surface vertex from rest, in m.
    pub max_displacement: Real,
    /// Largest instrument force, in N (infinite when no material is known).
    pub max_force: Real,
}

/// The diagonal of the bounding box of the finite points (0 if none).
pub fn body_size(points: &[Vec3]) -> Real {
    let mut it = points.iter().copied().filter(|p| is_finite_vec(*p));
    let Some(first) = it.next() else { return 0.0 };
    let (lo, hi) = it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p)));
    (hi - lo).length()
}

impl Plausibility {
    /// Bounds from the body's rest surface alone (no force bound).
    pub fn for_body(rest_surface: &[Vec3]) -> Self {
        let size = body_size(rest_surface);
        Self {
            size,
            max_displacement: DISPLACEMENT_FACTOR * size,
            max_force: Real::INFINITY,
        }
    }

    /// Adds the force bound from the body's material.
    #[must_use]
    pub fn with_material(self, material: &Material) -> Self {
        self.with_young_modulus(material.young_modulus)
    }

    /// Adds the force bound from the material's Young's modulus, in Pa.
    #[must_use]
    pub fn with_young_modulus(mut self, young_modulus: Real) -> Self {
        self.max_force = FORCE_FACTOR * young_modulus * self.size * self.size;
        self
    }

    /// Whether the model's state after step `step`, and the instruments' forces, are
    /// plausible; the first violation otherwise.
    pub fn check(
        &self,
        model: &dyn Deformable,
        instruments: &[Instrument],
        step: u64,
    ) -> Result<(), SimError> {
        let fail = |quantity: String, value: Real, bound: Real, reason: &str| {
            Err(SimError::Implausible {
                step,
                quantity,
                value,
                bound,
                reason: reason.to_string(),
            })
        };
        // A model that computed only part of its surface for the contact search bounds
        // the rest: when every vertex is surely within the displacement bound, the check
        // passes without the whole surface; otherwise it reads it.
        let near = model.contact_surface();
        let surely_within = !near.slack.is_empty()
            && near
                .positions
                .iter()
                .zip(near.slack)
                .zip(model.rest_surface())
                .all(|((p, s), q)| {
                    is_finite_vec(*p) && p.distance(*q) + s <= self.max_displacement
                });
        if !surely_within {
            let surface = model.surface();
            let mut worst = (0.0, 0);
            for (v, (p, q)) in surface
                .positions
                .iter()
                .zip(model.rest_surface())
                .enumerate()
            {
                if !is_finite_vec(*p) {
                    return fail(
                        format!("surface vertex {v}"),
                        Real::NAN,
                        self.max_displacement,
                        "its position is not finite",
                    );
                }
                let d = p.distance(*q);
                if d > worst.0 {
                    worst = (d, v);
                }
            }
            if worst.0 > self.max_displacement {
                return fail(
                    format!("displacement of surface vertex {}", worst.1),
                    worst.0,
                    self.max_displacement,
                    &format!(
                        "{DISPLACEMENT_FACTOR} × the body's size {:.3e} m",
                        self.size
                    ),
                );
            }
        }
        for inst in instruments {
            let f = inst.force();
            if !is_finite_vec(f) || f.length() > self.max_force {
                return fail(
                    format!("force on instrument `{}`", inst.name),
                    f.length(),
                    self.max_force,
                    &format!("{FORCE_FACTOR} × E × size², size {:.3e} m", self.size),
                );
            }
        }
        Ok(())
    }
}

/// Refuses an instrument wider than the body: its contact would be the whole body, and no
/// force or displacement bound means anything for it.
pub fn check_instrument_size(instrument: &Instrument, body_size: Real) -> Result<(), String> {
    let width = 2.0 * instrument.radius();
    if body_size > 0.0 && width > body_size {
        return Err(format!(
            "radius {} m: the instrument ({width:.3e} m across) is wider than the body \
             ({body_size:.3e} m across its bounding box)",
            instrument.radius()
        ));
    }
    Ok(())
}
