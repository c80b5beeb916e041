//! Scripted instrument paths: keyframes `{ t, position }`, linear between keys, held at the
//! first and last key outside their time range.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::math::{Real, Vec3};

/// One key of a path: where the instrument is at time `t` (s), in m.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    pub t: Real,
    pub position: [Real; 3],
}

/// Why a list of keyframes is not a path; keys are numbered from 0.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum TrajectoryError {
    #[error("a path needs at least one keyframe")]
    Empty,
    #[error("keyframe {key} has a non-finite time or position")]
    NonFinite { key: usize },
    #[error("keyframe {key} has time {t} s, not after the previous key's {previous} s")]
    Unsorted { key: usize, t: Real, previous: Real },
}

/// A validated path: finite keys with strictly increasing times.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    keys: Vec<Keyframe>,
}

impl Trajectory {
    pub fn new(keys: Vec<Keyframe>) -> Result<Self, TrajectoryError> {
        if keys.is_empty() {
            return Err(TrajectoryError::Empty);
        }
        for (i, k) in keys.iter().enumerate() {
            if !(k.t.is_finite() && k.position.iter().all(|c| c.is_finite())) {
                return Err(TrajectoryError::NonFinite { key: i });
            }
            if i > 0 && k.t <= keys[i - 1].t {
                return Err(TrajectoryError::Unsorted {
                    key: i,
                    t: k.t,
                    previous: keys[i - 1].t,
                });
            }
        }
        Ok(Self { keys })
    }

    /// A path that stays at one point.
    pub fn fixed(position: Vec3) -> Self {
        Self {
            keys: vec![Keyframe {
                t: 0.0,
                position: position.to_array(),
            }],
        }
    }

    pub fn keys(&self) -> &[Keyframe] {
        &self.keys
    }

    /// The position at time `t`: linear between the two keys around it, clamped outside.
    pub fn position(&self, t: Real) -> Vec3 {
        // `new` guarantees at least one key; `fixed` too.
        let (first, last) = match (self.keys.first(), self.keys.last()) {
            (Some(f), Some(l)) => (f, l),
            _ => return Vec3::ZERO,
        };
        if t.is_nan() || t <= first.t {
            return Vec3::from(first.position);
        }
        if t >= last.t {
            return Vec3::from(last.position);
        }
        // First key strictly after t; it exists and is not the first (t > first.t, t < last.t).
        let i = self.keys.partition_point(|k| k.t <= t);
        let (a, b) = (&self.keys[i - 1], &self.keys[i]);
        let s = (t - a.t) / (b.t - a.t);
        Vec3::from(a.position).lerp(Vec3::from(b.position), s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(t: Real, x: Real) -> Keyframe {
        Keyframe {
            t,
            position: [x, 2.0 * x, -x],
        }
    }

    #[test]
    fn interpolates_linearly_and_clamps() {
        let p = Trajectory::new(vec![key(0.0, 0.0), key(1.0, 1.0), key(3.0, -1.0)]).unwrap();
        assert_eq!(p.position(-5.0), Vec3::ZERO);
        assert_eq!(p.position(0.25), Vec3::new(0.25, 0.5, -0.25));
        assert_eq!(p.position(1.0), Vec3::new(1.0, 2.0, -1.0));
        // Halfway between keys 1 and 2: x = 0.
        assert!(p.position(2.0).length() < 1e-15);
        assert_eq!(p.position(10.0), Vec3::new(-1.0, -2.0, 1.0));
    }

    #[test]
    fn bad_keys_are_named() {
        assert_eq!(Trajectory::new(vec![]), Err(TrajectoryError::Empty));
        let e = Trajectory::new(vec![key(0.0, 0.0), key(0.0, 1.0)]).unwrap_err();
        assert_eq!(
            e,
            TrajectoryError::Unsorted {
                key: 1,
                t: 0.0,
                previous: 0.0
            }
        );
        let e = Trajectory::new(vec![key(0.0, 0.0), key(1.0, Real::NAN)]).unwrap_err();
        assert_eq!(e, TrajectoryError::NonFinite { key: 1 });
    }
}
