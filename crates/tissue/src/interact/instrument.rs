//! Instruments: a probe (sphere tip that pushes), a capsule (a tool shaft), a plane or a box
//! (a retractor, a table), a grasper (grabs the surface vertices within its radius at a given
//! time and carries them rigidly), a scalpel (a blade segment swept along its path that
//! cuts). Each follows a scripted path unless a live position overrides it. The pushing ones
//! slide over the tissue: frictionless by default, Coulomb with `friction` μ.

use crate::error::SimError;
use crate::interact::contact::Contact;
use crate::interact::fine_points::{FinePoint, PlaneRelaxation};
use crate::interact::shape::Shape;
use crate::interact::sliding::Slider;
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
    /// Pushes out of a capsule of the instrument's radius around the segment from the path
    /// point (tip) `length` m along `axis`.
    Capsule { axis: Vec3, length: Real },
    /// Pushes out of the half-space `normal · (x − position) ≤ 0` (`normal` toward the tissue).
    Plane { normal: Vec3 },
    /// Pushes out of the axis-aligned box of half extents `half` centred at the path point.
    Box { half: Vec3 },
}

impl InstrumentKind {
    pub fn name(&self) -> &'static str {
        match self {
            InstrumentKind::Probe => "probe",
            InstrumentKind::Grasper { .. } => "grasper",
            InstrumentKind::Scalpel { .. } => "scalpel",
            InstrumentKind::Capsule { .. } => "capsule",
            InstrumentKind::Plane { .. } => "plane",
            InstrumentKind::Box { .. } => "box",
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
    /// `Some(μ)`: sliding contact with Coulomb friction μ (0: frictionless, the default of
    /// the pushing kinds; `with_friction`, scene key `friction`); `None`: sticking contact
    /// (a touched vertex is held at its point of the instrument within a step: `sticking`,
    /// scene key `contact = "sticking"`; graspers and scalpels).
    friction: Option<Real>,
    pub(crate) slider: Slider,
    /// The fine surface's points held exactly against this instrument
    /// (`interact::fine_points`), and the push on each after the last solve, in N.
    pub(crate) points: Vec<FinePoint>,
    pub(crate) point_pushes: Vec<Real>,
    /// A static loop's acceleration of the points' planes within a step.
    pub(crate) relaxation: PlaneRelaxation,
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
        let unit = |v: Vec3, name: &'static str| {
            if crate::math::is_finite_vec(v) && v.length() > 0.0 {
                Ok(())
            } else {
                Err(bad(
                    name,
                    format!("{v:?}"),
                    "must be a finite non-zero vector",
                ))
            }
        };
        let kind = match kind {
            InstrumentKind::Capsule { axis, length } => InstrumentKind::Capsule {
                axis: axis.normalize_or_zero(),
                length,
            },
            InstrumentKind::Plane { normal } => InstrumentKind::Plane {
                normal: normal.normalize_or_zero(),
            },
            other => other,
        };
        match &kind {
            InstrumentKind::Probe => {}
            InstrumentKind::Capsule { axis, length } => {
                unit(*axis, "axis")?;
                if !(length.is_finite() && *length >= 0.0) {
                    return Err(bad(
                        "length",
                        length.to_string(),
                        "must be finite and >= 0 m",
                    ));
                }
            }
            InstrumentKind::Plane { normal } => unit(*normal, "normal")?,
            InstrumentKind::Box { half } => {
                if !(crate::math::is_finite_vec(*half) && half.min_element() > 0.0) {
                    return Err(bad(
                        "size",
                        format!("{}", *half * 2.0),
                        "must be three finite lengths > 0 m",
                    ));
                }
            }
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
            friction: None,
            slider: Slider::default(),
            points: Vec::new(),
            relaxation: PlaneRelaxation::default(),
            point_pushes: Vec::new(),
        }
        .frictionless())
    }

    /// The default contact of a pushing instrument (probe, capsule, plane, box): sliding
    /// and frictionless (issue 20). Graspers hold what they grasp and scalpels cut.
    fn frictionless(mut self) -> Self {
        if self.shape().is_some() {
            self.friction = Some(0.0);
        }
        self
    }

    /// Makes a pushing instrument's contact sticking: a touched vertex is held at its point
    /// of the instrument within a step and moves with it (the default before frictionless
    /// sliding was; `tissue compare`'s sticking scenarios). Graspers and scalpels are left
    /// as they are.
    pub fn sticking(mut self) -> Self {
        self.friction = None;
        self
    }

    /// Makes a pushing instrument's contact sliding, with Coulomb friction coefficient μ
    /// (finite, ≥ 0; 0 is frictionless): its contacts stick while their tangential force is
    /// below μ times the normal one and slide at that bound. Graspers hold what they grasp
    /// and scalpels cut: refused there. Without it a pushing instrument is frictionless.
    pub fn with_friction(mut self, friction: Real) -> Result<Self, SimError> {
        let bad = |reason: &str| SimError::BadParameter {
            name: "friction",
            value: friction.to_string(),
            reason: reason.to_string(),
        };
        if !(friction.is_finite() && friction >= 0.0) {
            return Err(bad("must be finite and >= 0"));
        }
        if self.shape().is_none() {
            return Err(bad(&format!(
                "a {} does not slide (only probe, capsule, plane, box)",
                self.kind.name()
            )));
        }
        self.friction = Some(friction);
        Ok(self)
    }

    /// The Coulomb friction coefficient of a sliding contact (0: frictionless, the default);
    /// `None` for sticking contact (`sticking`) and for graspers and scalpels.
    pub fn friction(&self) -> Option<Real> {
        self.friction
    }

    /// The solid a pushing instrument keeps the tissue out of; `None` for graspers and
    /// scalpels.
    pub fn shape(&self) -> Option<Shape> {
        match self.kind {
            InstrumentKind::Probe => Some(Shape::Sphere {
                radius: self.radius,
            }),
            InstrumentKind::Capsule { axis, length } => Some(Shape::Capsule {
                radius: self.radius,
                axis,
                length,
            }),
            InstrumentKind::Plane { normal } => Some(Shape::Plane { normal }),
            InstrumentKind::Box { half } => Some(Shape::Box { half }),
            InstrumentKind::Grasper { .. } | InstrumentKind::Scalpel { .. } => None,
        }
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

    /// The fine surface's points held exactly against this instrument
    /// (`interact::fine_points`; empty where its contacts are on vertices).
    pub fn fine_points(&self) -> &[FinePoint] {
        &self.points
    }

    /// The push on each of `fine_points` after the last step (along its normal), in N.
    pub fn point_pushes(&self) -> &[Real] {
        &self.point_pushes
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
