//! A frictionless contact that only pushes: decided at the end of every (sub)step by the
//! explicit schemes (`push_only`, the mechanics of `Hold::contact`, written once for the
//! integrator and for `fem-explicit`'s central difference, `model::fem::dynamic`), or held
//! inside an implicit step's solve (`HeldContacts`, `filtered_share`: implicit Euler and
//! `fem-corotational`).
//!
//! A particle past the plane through `target` with outward normal n (toward the particle's
//! side: n·(x − t) < 0) is put back on it and its inward velocity along n removed, an
//! inelastic contact with a still plane. A particle short of the plane keeps at most the
//! inward velocity that reaches it in one more (sub)step: explicit Euler moves by the old
//! velocity, and a particle resting on the plane would otherwise be let go and caught every
//! other step. A particle that stays out and does not reach the plane is left free. The
//! active set is so settled at every (sub)step, and the push (the momentum the contact gave,
//! `dv` per unit mass) is never negative: the contact cannot pull.

use crate::math::{Real, Vec3};

/// What a push-only contact did to its particle at the end of a (sub)step of length h.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push {
    /// The position, on the plane if the particle went past it.
    pub position: Vec3,
    /// The velocity with its inward part along n cut.
    pub velocity: Vec3,
    /// The change of the velocity along n, ≥ 0: the push's momentum per unit mass.
    pub dv: Real,
}

/// The contact of a particle at `x` moving at `v` with the plane through `target` of unit
/// outward normal `n`, at the end of a (sub)step of length `h`; `None` when it is free.
pub fn push_only(x: Vec3, v: Vec3, target: Vec3, n: Vec3, h: Real) -> Option<Push> {
    let gap = n.dot(x - target);
    let inside = gap < 0.0;
    let position = if inside { x - n * gap } else { x };
    let vn = n.dot(v);
    let kept = vn.max(-gap.max(0.0) / h);
    if !inside && kept == vn {
        return None;
    }
    Some(Push {
        position,
        velocity: v + n * (kept - vn),
        dv: kept - vn,
    })
}

/// Solves of one step's held contacts before the step stops unsettled (and says so).
pub const MAX_CONTACT_SOLVES: usize = 25;

/// The push-only contacts held inside an implicit step's solve, by the filter of the
/// modified CG (Baraff & Witkin 1998: a held contact's velocity change along its normal is
/// known, its tangent part free): which are held, and which this step let go. Shared by the
/// integrator's implicit Euler and `fem-corotational`'s step.
///
/// The set is settled within the step by solving again: a held contact whose push pulls is
/// let go, for the rest of the step, so that the loop ends (a contact let go cannot come
/// back and be let go again); a free one that ends the step past its plane is held.
#[derive(Clone, Debug, Default)]
pub struct HeldContacts {
    /// Per contact: held in the next solve.
    pub active: Vec<bool>,
    released: Vec<bool>,
}

impl HeldContacts {
    /// A step's first guess, per contact (typically: it pushed in the last step, or it
    /// starts past its plane).
    pub fn start(&mut self, first: impl Iterator<Item = bool>) {
        self.active.clear();
        self.active.extend(first);
        self.released.clear();
        self.released.resize(self.active.len(), false);
    }

    /// After a solve: `pushes` per contact (N, the held ones' reactions along n; anything
    /// for the free ones), `end_gap(j)` the free contact j's distance out of its plane at
    /// the step's end (negative: past it), `depth` the penetration below which a free one
    /// stays free (round-off of the motion). Pulls smaller than 1e-9 of the pushes' sum
    /// are round-off too. Returns whether the set changed (solve again).
    pub fn update(
        &mut self,
        pushes: &[Real],
        end_gap: impl Fn(usize) -> Real,
        depth: Real,
    ) -> bool {
        let scale: Real = pushes
            .iter()
            .zip(&self.active)
            .filter(|(_, a)| **a)
            .map(|(p, _)| p.abs())
            .sum();
        let mut changed = false;
        for (j, (active, released)) in self.active.iter_mut().zip(&mut self.released).enumerate() {
            let push = pushes.get(j).copied().unwrap_or(0.0);
            if *active && push < -1e-9 * scale {
                *active = false;
                *released = true;
                changed = true;
            } else if !*active && !*released && end_gap(j) < -depth {
                *active = true;
                changed = true;
            }
        }
        changed
    }
}

/// The share of a step's load that a modified CG's filter S keeps: ‖S b‖ / ‖b‖, with
/// `load` = ‖b‖ over the unknowns not held in full and `filtered` = ‖S b‖ (1 without a
/// filtered load). The CG's tolerance is relative to S b; divided by this share it is
/// relative to the whole load, the contacts' normal loads included. Once held contacts
/// carry the motion (a probe held still on the tissue), S b alone is round-off, and a
/// tolerance relative to it stops every step at the iteration cap.
pub fn filtered_share(load: Real, filtered: Real) -> Real {
    if filtered > 0.0 && load > filtered {
        filtered / load
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Past the plane: back on it, inward velocity gone, the push its momentum; short of
    /// it and slow: free; short of it and fast: slowed to reach it in one more step; moving
    /// away from inside: put back without a pull (dv = 0).
    #[test]
    fn a_push_only_contact_puts_back_slows_and_never_pulls() {
        let (t, n, h) = (Vec3::ZERO, Vec3::Z, 0.01);
        let p = push_only(
            Vec3::new(1.0, 0.0, -0.02),
            Vec3::new(1.0, 0.0, -3.0),
            t,
            n,
            h,
        );
        let p = p.unwrap();
        assert_eq!(p.position, Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(p.velocity, Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(p.dv, 3.0);
        assert_eq!(push_only(Vec3::Z * 0.1, -Vec3::Z, t, n, h), None);
        let p = push_only(Vec3::Z * 0.01, -Vec3::Z * 5.0, t, n, h).unwrap();
        assert!((p.velocity.z + 1.0).abs() < 1e-12 && (p.dv - 4.0).abs() < 1e-12);
        assert_eq!(p.position, Vec3::Z * 0.01);
        let p = push_only(-Vec3::Z * 0.01, Vec3::Z, t, n, h).unwrap();
        assert_eq!((p.position, p.velocity, p.dv), (Vec3::ZERO, Vec3::Z, 0.0));
    }
}
