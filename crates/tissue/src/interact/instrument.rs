//! Instruments: a probe (sphere tip that pushes), a grasper (grabs the surface vertices within
//! its radius at a given time and carries them rigidly), a scalpel (a blade segment swept
//! along its path that cuts). Each follows a scripted path unless a live position overrides it.

use crate::error::SimError;
use crate::interact::contact::Contact;
use crate::interact::trajectory::Trajectory;
use crate::math::{Real, Vec3};
use crate::model::CutPath;

/// What an instrument does.
#[derive(Clone, Debug, PartialEq)]
pub enum InstrumentKind {
    /// Pushes surface vertices out of its ball.
    Probe,
    /// At `grasp_at` (s) takes the surface vertices within its radius and moves them with
    /// itself until `release_at` (s), if given.
    Grasper {
        grasp_at: Real,
        release_at: Option<Real>,
    },
    /// A blade from the path point (tip) `length` m along `direction` (heel), cutting the
    /// ruled surface it sweeps each step.
    Scalpel { direction: Vec3, length: Real },
}

impl InstrumentKind {
    pub fn name(&self) -> &'static str {
        match self {
            InstrumentKind::Probe => "probe",
            InstrumentKind::Grasper { .. } => "grasper",
            InstrumentKind::Scalpel { .. } => "scalpel",
        }
    }
}

/// An instrument and its state: where it is, what it holds, the force it feels.
#[derive(Clone, Debug, PartialEq)]
pub struct Instrument {
    pub name: String,
    kind: InstrumentKind,
    radius: Real,
    trajectory: Trajectory,
    live: Option<Vec3>,
    pub(crate) position: Vec3,
    pub(crate) contacts: Vec<Contact>,
    /// Force of the tissue on the instrument at each contact after the last solve.
    pub(crate) reactions: Vec<Vec3>,
    /// Grasped vertices and their offsets from the instrument position.
    pub(crate) grasped: Vec<(u32, Vec3)>,
    pub(crate) grasp_done: bool,
    pub(crate) force: Vec3,
}

impl Instrument {
    /// Checks the radius (finite, > 0) and the kind's own numbers.
    pub fn new(
        name: impl Into<String>,
        kind: InstrumentKind,
        radius: Real,
        trajectory: Trajectory,
    ) -> Result<Self, SimError> {
        let bad = |name: &'static str, value: String, reason: &str| SimError::BadParameter {
            name,
            value,
            reason: reason.to_string(),
        };
        if !(radius.is_finite() && radius > 0.0) {
            return Err(bad(
                "radius",
                radius.to_string(),
                "must be finite and > 0 m",
            ));
        }
        match &kind {
            InstrumentKind::Probe => {}
            InstrumentKind::Grasper {
                grasp_at,
                release_at,
            } => {
                if !grasp_at.is_finite() {
                    return Err(bad("grasp_at", grasp_at.to_string(), "must be finite"));
                }
                if let Some(r) = release_at
                    && !(r.is_finite() && r > grasp_at)
                {
                    return Err(bad("release_at", r.to_string(), "must be after grasp_at"));
                }
            }
            InstrumentKind::Scalpel { direction, length } => {
                if !(crate::math::is_finite_vec(*direction) && direction.length() > 0.0) {
                    return Err(bad(
                        "direction",
                        format!("{direction:?}"),
                        "must be a finite non-zero vector",
                    ));
                }
                if !(length.is_finite() && *length > 0.0) {
                    return Err(bad(
                        "length",
                        length.to_string(),
                        "must be finite and > 0 m",
                    ));
                }
            }
        }
        let position = trajectory.position(0.0);
        Ok(Self {
            name: name.into(),
            kind,
            radius,
            trajectory,
            live: None,
            position,
            contacts: Vec::new(),
            reactions: Vec::new(),
            grasped: Vec::new(),
            grasp_done: false,
            force: Vec3::ZERO,
        })
    }

    pub fn kind(&self) -> &InstrumentKind {
        &self.kind
    }

    pub fn radius(&self) -> Real {
        self.radius
    }

    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }

    /// Where the instrument is now (after the last step), in m.
    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// The force the tissue exerts on the instrument after the last step, in N.
    pub fn force(&self) -> Vec3 {
        self.force
    }

    /// The vertices it holds now (contact or grasp) and their targets.
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// The force at each contact after the last step (same order as `contacts`), in N.
    pub fn contact_reactions(&self) -> &[Vec3] {
        &self.reactions
    }

    /// The live position that overrides the path (viewer, haptic device), if any.
    pub fn live_position(&self) -> Option<Vec3> {
        self.live
    }

    pub(crate) fn set_live_position(&mut self, p: Option<Vec3>) {
        self.live = p;
    }

    /// Where the instrument should be at time `t`.
    pub fn position_at(&self, t: Real) -> Vec3 {
        self.live.unwrap_or_else(|| self.trajectory.position(t))
    }

    /// The scalpel blade (tip, heel) with the tip at `tip`; `None` for other instruments.
    pub fn blade_at(&self, tip: Vec3) -> Option<[Vec3; 2]> {
        match self.kind {
            InstrumentKind::Scalpel { direction, length } => {
                Some([tip, tip + length * direction.normalize()])
            }
            _ => None,
        }
    }

    /// The cut swept from `previous` to this instrument's position; `None` when it did not
    /// move or is no scalpel.
    pub(crate) fn sweep(&self, previous: Vec3) -> Option<CutPath> {
        if previous == self.position {
            return None;
        }
        Some(CutPath {
            start: self.blade_at(previous)?,
            end: self.blade_at(self.position)?,
        })
    }
}
