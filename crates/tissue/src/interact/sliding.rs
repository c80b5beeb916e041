//! Sliding contact for every model through the prescribed-position interface.
//!
//! A touched vertex is held at a target on the instrument's surface; the model returns the
//! force it needs there. Split along the instrument's normal, that force has a normal part N
//! (the push) and a tangential part f_t. Signorini–Coulomb contact asks |f_t| ≤ μN: a vertex
//! whose tangential reaction is larger slides. Here it slides by moving its target along the
//! instrument's surface, against the excess e = f_t (1 − μN/|f_t|), by e / k, where k is the
//! contact's tangential stiffness, and the model solves again. With μ = 0 (frictionless, the
//! default for pushing instruments) the targets move until the tangential reactions vanish.
//!
//! k is a secant estimate (Barzilai–Borwein) over the instrument's contacts from the last two
//! relaxations of this step; the first relaxation of a step takes the model's own tangent
//! stiffness where it gives one (`Deformable::prescribed_stiffness`, the compliance models),
//! else the ratio of the normal reactions to the normal displacements from rest. Static
//! models relax inside the step's contact loop until the excess is below `SLIDE_TOLERANCE`
//! of the normal force; dynamic models relax once per step, so their contacts settle over a
//! few steps as their inertia does.

use crate::interact::contact::Contact;
use crate::interact::shape::Shape;
use crate::math::{Mat3, Real, Vec3};

/// The sliding loop stops when the summed tangential excess is below this fraction of the
/// summed normal force: the tangential force of a frictionless contact is then below 0.1%
/// of the normal one.
pub const SLIDE_TOLERANCE: Real = 1e-3;

/// The largest move of a target in one relaxation, as a fraction of the shape's size: a
/// poor first stiffness estimate cannot throw a contact across the instrument.
const MAX_MOVE: Real = 0.25;

/// The normal push N (positive when the tissue pushes the instrument away) and the
/// tangential part of a contact reaction, for an instrument surface with outward `normal`.
pub fn split(reaction: Vec3, normal: Vec3) -> (Real, Vec3) {
    let push = -reaction.dot(normal);
    (push, reaction + push * normal)
}

/// The tangential reaction beyond the Coulomb bound μN (zero while the contact sticks).
pub fn excess(tangential: Vec3, push: Real, friction: Real) -> Vec3 {
    let bound = friction * push.max(0.0);
    let m = tangential.length();
    if m <= bound || m == 0.0 {
        Vec3::ZERO
    } else {
        tangential * (1.0 - bound / m)
    }
}

/// How far one relaxation left the contacts from Coulomb's law.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SlideResidual {
    /// Σ |tangential excess| over the contacts, in N.
    pub excess: Real,
    /// Σ N over the contacts, in N.
    pub push: Real,
    /// Contacts held along their normals only: the largest move of a target to where its
    /// vertex slid, relative to the instrument's size.
    pub moved: Real,
}

/// Contacts held along their normals only have settled when no target moved by more than
/// this fraction of the instrument's size.
pub const SETTLED_MOVE: Real = 1e-6;

impl SlideResidual {
    pub fn converged(&self) -> bool {
        self.excess <= SLIDE_TOLERANCE * self.push.max(0.0) && self.moved <= SETTLED_MOVE
    }

    /// Keeps the worse of two instruments' residuals: the larger relative excess, the
    /// larger move.
    pub fn merge(&mut self, other: SlideResidual) {
        if other.relative() >= self.relative() {
            self.excess = other.excess;
            self.push = other.push;
        }
        self.moved = self.moved.max(other.moved);
    }

    /// The excess relative to the push (0 without contact).
    pub fn relative(&self) -> Real {
        if self.push > 0.0 {
            self.excess / self.push
        } else {
            0.0
        }
    }
}

/// An instrument's sliding state within a step: the stiffness estimate and what the last
/// relaxation saw, for the secant.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Slider {
    /// Tangential stiffness per contact, N/m (0: not estimated yet this step).
    stiffness: Real,
    /// (vertex, target, excess) at the last relaxation of this step.
    last: Vec<(u32, Vec3, Vec3)>,
    /// (vertex, target) at the step's first relaxation: the slip of this step is measured
    /// from there.
    start: Vec<(u32, Vec3)>,
}

impl Slider {
    /// Forgets the last step: the instrument has moved, so a secant across steps would mix
    /// the tissue's response with the instrument's motion.
    pub fn begin_step(&mut self) {
        self.stiffness = 0.0;
        self.last.clear();
        self.start.clear();
    }

    /// One relaxation: moves the targets of sliding contacts along the instrument's surface
    /// (`shape` placed at `at`) and returns the residual the reactions showed before the move.
    /// `rest` are the surface's rest positions (for the first stiffness estimate) and
    /// `model_stiffness` the model's tangent stiffness of this instrument's contacts together,
    /// if it gives one.
    #[allow(clippy::too_many_arguments)]
    pub fn relax(
        &mut self,
        contacts: &mut [Contact],
        reactions: &[Vec3],
        shape: &Shape,
        at: Vec3,
        friction: Real,
        rest: &[Vec3],
        model_stiffness: impl FnOnce() -> Option<Mat3>,
    ) -> SlideResidual {
        let mut residual = SlideResidual::default();
        let mut excesses = Vec::with_capacity(contacts.len());
        let mut normals = Vec::with_capacity(contacts.len());
        let mut pushes = Vec::with_capacity(contacts.len());
        if self.start.is_empty() {
            self.start
                .extend(contacts.iter().map(|k| (k.vertex, k.target)));
        }
        let mut backs = Vec::with_capacity(contacts.len());
        for (k, f) in contacts.iter().zip(reactions) {
            let n = k.normal(shape, at);
            let (push, tangential) = split(*f, n);
            // Coulomb in a step: a contact that has slipped by s since the step began has
            // the tangential force μN along s (maximal dissipation); one that has not may
            // hold anything up to μN. Jacobi moves of coupled contacts can leave a slipped
            // contact inside the cone or turned: it moves on toward f_t = μN ŝ, and back
            // at most to where the step began it (then it sticks).
            let slip = self
                .start
                .iter()
                .find(|(v, _)| *v == k.vertex)
                .map_or(Vec3::ZERO, |(_, x0)| k.target - *x0);
            let slip = slip - slip.dot(n) * n;
            let mut back = Real::INFINITY;
            let e = if friction > 0.0 && slip.length() > 1e-12 * shape.size() {
                let e = tangential - friction * push.max(0.0) * slip.normalize();
                if e.dot(slip) < 0.0 {
                    back = slip.length();
                }
                e
            } else {
                excess(tangential, push, friction)
            };
            backs.push(back);
            residual.excess += e.length();
            residual.push += push.max(0.0);
            excesses.push(e);
            normals.push(n);
            pushes.push(push);
        }
        if contacts.is_empty() || residual.converged() {
            self.last.clear();
            return residual;
        }
        self.update_stiffness(
            contacts,
            &excesses,
            &normals,
            &pushes,
            rest,
            model_stiffness,
        );
        self.last.clear();
        let k = self.stiffness;
        if !(k.is_finite() && k > 0.0) {
            return residual;
        }
        let max_move = MAX_MOVE * shape.size();
        for (((c, e), n), back) in contacts.iter_mut().zip(&excesses).zip(&normals).zip(&backs) {
            self.last.push((c.vertex, c.target, *e));
            if *e == Vec3::ZERO {
                continue;
            }
            let mut step = *e / k;
            let len = step.length();
            let cap = max_move.min(*back);
            if len > cap {
                step *= cap / len;
            }
            c.target = match c.face {
                // A face contact slides in the face's tangent plane; the face hold puts the
                // face back on the instrument at the next round.
                Some(_) => c.target + step - step.dot(*n) * *n,
                None => shape.closest(at, c.target + step, *n).point,
            };
        }
        residual
    }

    fn update_stiffness(
        &mut self,
        contacts: &[Contact],
        excesses: &[Vec3],
        normals: &[Vec3],
        pushes: &[Real],
        rest: &[Vec3],
        model_stiffness: impl FnOnce() -> Option<Mat3>,
    ) {
        // Secant over the contacts seen at both relaxations: the excess falls by k per metre
        // a target moves against it.
        let (mut num, mut den) = (0.0, 0.0);
        for (c, e) in contacts.iter().zip(excesses) {
            if let Some((_, x0, e0)) = self.last.iter().find(|(v, _, _)| *v == c.vertex) {
                let dx = c.target - *x0;
                num -= (*e - *e0).dot(dx);
                den += dx.length_squared();
            }
        }
        let previous = self.stiffness;
        if den > 0.0 && num > 0.0 && previous > 0.0 {
            // Bounded: one pair of solves where the contact set also changed is a poor
            // secant, and a tenfold change is never the tissue's.
            self.stiffness = (num / den).clamp(0.1 * previous, 10.0 * previous);
            return;
        }
        if previous > 0.0 {
            return;
        }
        let count = contacts.len() as Real;
        if let Some(m) = model_stiffness() {
            // The collective tangent stiffness: its mean over directions, per contact.
            let k = (m.x_axis.x + m.y_axis.y + m.z_axis.z).abs() / 3.0 / count;
            if k.is_finite() && k > 0.0 {
                self.stiffness = k;
                return;
            }
        }
        // The normal response's secant: N over the normal displacement from rest, summed
        // over the contacts. A contact patch on a half-space is 2(1 − ν)/(2 − ν) times as
        // stiff sideways as normally (Mindlin; 0.82 at ν = 0.3): a first step a little short,
        // which the secant then lengthens.
        let (mut push, mut depth) = (0.0, 0.0);
        for (c, n) in contacts.iter().zip(normals) {
            if let Some(r) = rest.get(c.vertex as usize) {
                depth += (c.target - *r).dot(*n).abs();
            }
        }
        for p in pushes {
            push += p.max(0.0);
        }
        if depth > 0.0 && push > 0.0 {
            self.stiffness = push / depth;
        }
    }
}
