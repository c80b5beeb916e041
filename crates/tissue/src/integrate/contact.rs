//! A frictionless contact that only pushes, decided at the end of every (sub)step: the
//! mechanics of `Hold::contact`, written once for the integrator and for `fem-explicit`'s
//! central difference (`model::fem::dynamic`).
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
