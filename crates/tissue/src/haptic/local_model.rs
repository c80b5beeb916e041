//! The local linear contact model the haptic loop evaluates between full simulation updates.
//!
//! A full update (one `Simulation::step`, 10-100 ms for the slower models) gives the force at
//! one instrument position. Between updates the 1 kHz loop needs the force at the device's
//! current position: it uses `f(x) = f0 + K (x - x0)` around the last update `(x0, f0)`,
//! where `K = df/dx` is the contact stiffness of the touched region as seen by the
//! instrument (the condensed stiffness of the touched vertices). `K` is estimated from
//! successive full updates by the symmetric (Powell) Broyden secant update: the stiffness of
//! an elastic body is symmetric, and the symmetric update reproduces the last secant exactly
//! (a plain Broyden update made symmetric afterwards does not). Its eigenvalues are capped in
//! magnitude. Early estimates are indefinite (one secant says nothing about the other
//! directions), so passivity is guarded where it matters, per evaluation: a displacement
//! along which `K` would add energy (`dx·K dx > 0`, the force growing as the hand moves with
//! it) gets the anchored force only, so the display never pushes the hand further on.

use crate::math::{Mat3, Real, Vec3};

/// Moves smaller than this (m) carry no stiffness information (noise, a resting hand).
const MIN_STEP: Real = 1e-7;

/// Force model around the last full update.
#[derive(Clone, Debug, PartialEq)]
pub struct LocalContact {
    anchor: Vec3,
    force: Vec3,
    /// The secant estimate as it stands (uncapped, so that secants keep refining it).
    raw: Mat3,
    /// `raw` with its eigenvalues capped in magnitude: what `force_at` uses.
    stiffness: Mat3,
    in_contact: bool,
    /// Largest stiffness eigenvalue magnitude allowed, in N/m.
    max_stiffness: Real,
    /// Largest force returned, in N.
    max_force: Real,
    updates: u64,
}

impl LocalContact {
    /// No contact yet; stiffness magnitudes capped at `max_stiffness` N/m, forces at
    /// `max_force` N.
    pub fn new(max_stiffness: Real, max_force: Real) -> Self {
        Self {
            anchor: Vec3::ZERO,
            force: Vec3::ZERO,
            raw: Mat3::ZERO,
            stiffness: Mat3::ZERO,
            in_contact: false,
            max_stiffness: max_stiffness.abs(),
            max_force: max_force.abs(),
            updates: 0,
        }
    }

    /// The stiffness estimate `df/dx`, in N/m (symmetric, negative semi-definite).
    pub fn stiffness(&self) -> Mat3 {
        self.stiffness
    }

    pub fn max_stiffness(&self) -> Real {
        self.max_stiffness
    }

    pub fn max_force(&self) -> Real {
        self.max_force
    }

    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// Replaces the stiffness with a known one (a model that provides its condensed
    /// compliance), clamped like an estimate.
    pub fn set_stiffness(&mut self, k: Mat3) {
        self.raw = k;
        self.stiffness = project_passive(k, self.max_stiffness);
    }

    /// Takes a full update: the instrument was at `position` and felt `force`;
    /// `in_contact` says whether it touched anything.
    pub fn update(&mut self, position: Vec3, force: Vec3, in_contact: bool) {
        self.update_with_stiffness(position, force, in_contact, None);
    }

    /// `update` with the model's own tangent stiffness at that state, where it has one
    /// (`Simulation::instrument_stiffness`): it replaces the secant estimate, which a jump
    /// of the model's force between updates (a contact vertex gained or lost, a model
    /// refining its contact rule) turns into a spurious stiffness up to the cap, felt as a
    /// kick when the hand moves on.
    pub fn update_with_stiffness(
        &mut self,
        position: Vec3,
        force: Vec3,
        in_contact: bool,
        known: Option<Mat3>,
    ) {
        if !(crate::math::is_finite_vec(position) && crate::math::is_finite_vec(force)) {
            return;
        }
        if let Some(k) = known.filter(|k| in_contact && k.is_finite()) {
            self.set_stiffness(k);
        } else if in_contact && self.in_contact {
            let dx = position - self.anchor;
            let df = force - self.force;
            let dx2 = dx.length_squared();
            if dx2 > MIN_STEP * MIN_STEP {
                // Powell-symmetric-Broyden: the smallest symmetric change of K with
                // K dx = df afterwards.
                let r = df - self.raw * dx;
                self.raw +=
                    (outer(r, dx) + outer(dx, r)) / dx2 - outer(dx, dx) * (r.dot(dx) / (dx2 * dx2));
                self.stiffness = project_passive(self.raw, self.max_stiffness);
            }
        } else if !in_contact {
            // Contact lost: the next contact may be elsewhere with another stiffness.
            self.raw = Mat3::ZERO;
            self.stiffness = Mat3::ZERO;
        }
        self.anchor = position;
        self.force = force;
        self.in_contact = in_contact;
        self.updates += 1;
    }

    /// The force at `position`, in N.
    pub fn force_at(&self, position: Vec3) -> Vec3 {
        if !self.in_contact || !crate::math::is_finite_vec(position) {
            return Vec3::ZERO;
        }
        let dx = position - self.anchor;
        let kdx = self.stiffness * dx;
        // Energy guard: no force that grows along the motion (see the module doc).
        let f = if dx.dot(kdx) > 0.0 {
            self.force
        } else {
            self.force + kdx
        };
        // Contact pushes: once the linear model would reverse the last force, the tool has
        // left the surface.
        if self.force.length_squared() > 0.0 && f.dot(self.force) <= 0.0 {
            return Vec3::ZERO;
        }
        let n = f.length();
        if n > self.max_force {
            f * (self.max_force / n)
        } else {
            f
        }
    }
}

fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Symmetric part with its eigenvalues clamped to `[-cap, cap]`.
fn project_passive(k: Mat3, cap: Real) -> Mat3 {
    let s = (k + k.transpose()) * 0.5;
    let (values, vectors) = symmetric_eigen(s);
    let mut out = Mat3::ZERO;
    for (i, value) in values.iter().enumerate() {
        let v = vectors.col(i);
        out += outer(v, v) * value.clamp(-cap, cap);
    }
    out
}

/// Eigenvalues and eigenvectors (columns) of a symmetric 3x3 matrix by cyclic Jacobi
/// rotations; 3x3 converges to machine precision in a handful of sweeps.
fn symmetric_eigen(m: Mat3) -> ([Real; 3], Mat3) {
    let mut a = [[0.0; 3]; 3];
    for (j, row) in a.iter_mut().enumerate() {
        for (i, x) in row.iter_mut().enumerate() {
            *x = m.col(i)[j];
        }
    }
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..32 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        let scale = a[0][0].abs() + a[1][1].abs() + a[2][2].abs();
        if off <= 1e-15 * scale.max(Real::MIN_POSITIVE) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in &mut a {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
            a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
            for row in &mut v {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
        }
    }
    let col = |i: usize| Vec3::new(v[0][i], v[1][i], v[2][i]);
    (
        [a[0][0], a[1][1], a[2][2]],
        Mat3::from_cols(col(0), col(1), col(2)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Mat3, b: Mat3, tol: Real) -> bool {
        (0..3).all(|i| (a.col(i) - b.col(i)).length() <= tol)
    }

    /// A spring wall: f = -K (x - c) with K symmetric positive definite.
    fn spring_k() -> Mat3 {
        Mat3::from_cols(
            Vec3::new(300.0, 20.0, -10.0),
            Vec3::new(20.0, 150.0, 5.0),
            Vec3::new(-10.0, 5.0, 80.0),
        )
    }

    #[test]
    fn one_secant_is_reproduced_exactly() {
        // The symmetric update keeps K dx = df: a prediction along the last move is exact
        // for a linear force, whatever the off-diagonal coupling.
        let k = spring_k();
        let f = |x: Vec3| -(k * x) + Vec3::new(0.0, 2.0, 0.0);
        let mut m = LocalContact::new(1e6, 1e3);
        m.update(Vec3::ZERO, f(Vec3::ZERO), true);
        let x1 = Vec3::new(0.0, -1e-3, 0.0);
        m.update(x1, f(x1), true);
        let x2 = Vec3::new(0.0, -3e-3, 0.0);
        assert!((m.force_at(x2) - f(x2)).length() < 1e-12);
    }

    #[test]
    fn three_orthogonal_moves_recover_a_symmetric_stiffness_exactly() {
        let k = spring_k();
        let c = Vec3::new(0.01, 0.02, -0.03);
        let f = |x: Vec3| -(k * (x - c));
        let mut m = LocalContact::new(1e6, 1e3);
        let mut x = Vec3::new(0.0, 0.0, 0.0);
        m.update(x, f(x), true);
        for d in [Vec3::X, Vec3::Y, Vec3::Z] {
            x += 1e-3 * d;
            m.update(x, f(x), true);
        }
        // The symmetric update with orthogonal steps fixes one row and column per step and
        // keeps the earlier ones; the exact answer is within the cap, so it is kept.
        assert!(close(m.stiffness(), -k, 1e-9), "{:?}", m.stiffness());
        let probe = x + Vec3::new(2e-4, -1e-4, 3e-4);
        assert!((m.force_at(probe) - f(probe)).length() < 1e-12);
    }

    #[test]
    fn estimate_is_passive_and_capped() {
        // Force grows as the tool moves out: a "pulling" secant that would be active. The
        // estimate keeps it (capped at 500 N/m), the evaluation does not use it.
        let mut m = LocalContact::new(500.0, 2.0);
        m.update(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0), true);
        m.update(Vec3::new(0.0, 1e-3, 0.0), Vec3::new(0.0, 1.8, 0.0), true);
        assert!((m.stiffness().y_axis.y - 500.0).abs() < 1e-9);
        assert_eq!(
            m.force_at(Vec3::new(0.0, 2e-3, 0.0)),
            Vec3::new(0.0, 1.8, 0.0)
        );
        // Moving back along the secant is dissipative-looking (dx.K dx > 0 too): held.
        assert_eq!(m.force_at(Vec3::ZERO), Vec3::new(0.0, 1.8, 0.0));
        // A very stiff secant is capped at 500 N/m.
        let mut m = LocalContact::new(500.0, 2.0);
        m.update(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0), true);
        m.update(Vec3::new(0.0, -1e-3, 0.0), Vec3::new(0.0, 11.0, 0.0), true);
        let (values, _) = symmetric_eigen(m.stiffness());
        let min = values.iter().copied().fold(Real::INFINITY, Real::min);
        assert!((min + 500.0).abs() < 1e-9, "{values:?}");
        // Force capped at 2 N.
        let f = m.force_at(Vec3::new(0.0, -1.0, 0.0));
        assert!((f.length() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn a_known_stiffness_replaces_the_secant_through_a_force_jump() {
        // The true stiffness is -20 N/m; between two updates 0.1 mm apart the model's force
        // jumps by 0.02 N (a contact vertex gained). The secant reads that as 200 N/m more
        // and the next 0.1 mm of hand motion would feel 0.02 N too much; the known one
        // gives the model's own tangent.
        let k = Mat3::from_diagonal(Vec3::splat(-20.0));
        let (x0, x1) = (Vec3::ZERO, Vec3::new(0.0, -1e-4, 0.0));
        let (f0, f1) = (Vec3::new(0.0, 0.05, 0.0), Vec3::new(0.0, 0.072, 0.0));
        let mut secant = LocalContact::new(5000.0, 10.0);
        secant.update(x0, f0, true);
        secant.update(x1, f1, true);
        assert!((secant.stiffness().y_axis.y + 220.0).abs() < 1e-9);
        let mut known = LocalContact::new(5000.0, 10.0);
        known.update_with_stiffness(x0, f0, true, Some(k));
        known.update_with_stiffness(x1, f1, true, Some(k));
        assert_eq!(known.stiffness(), k);
        let x2 = Vec3::new(0.0, -2e-4, 0.0);
        assert!((known.force_at(x2).y - 0.074).abs() < 1e-12);
        assert!((secant.force_at(x2).y - 0.094).abs() < 1e-12);
        // A stiffness that is not finite is not taken: the secant goes on.
        known.update_with_stiffness(x2, f1, true, Some(Mat3::from_diagonal(Vec3::NAN)));
        assert!(known.stiffness().is_finite());
    }

    #[test]
    fn no_force_without_contact_or_when_leaving() {
        let mut m = LocalContact::new(1e4, 10.0);
        assert_eq!(m.force_at(Vec3::ZERO), Vec3::ZERO);
        m.update(Vec3::ZERO, Vec3::new(0.0, 0.5, 0.0), true);
        m.set_stiffness(Mat3::from_diagonal(Vec3::splat(-100.0)));
        // 6 mm out along +y: 0.5 - 100 * 0.006 < 0: the tool has left.
        assert_eq!(m.force_at(Vec3::new(0.0, 0.006, 0.0)), Vec3::ZERO);
        let f = m.force_at(Vec3::new(0.0, -0.001, 0.0));
        assert!((f.y - 0.6).abs() < 1e-12);
        m.update(Vec3::new(0.0, 0.01, 0.0), Vec3::ZERO, false);
        assert_eq!(m.stiffness(), Mat3::ZERO);
        assert_eq!(m.force_at(Vec3::ZERO), Vec3::ZERO);
        // Non-finite input is ignored.
        m.update(Vec3::splat(Real::NAN), Vec3::ZERO, true);
        assert_eq!(m.updates(), 2);
    }

    #[test]
    fn jacobi_eigen_reconstructs() {
        let k = spring_k();
        let (l, v) = symmetric_eigen(k);
        let mut r = Mat3::ZERO;
        for (i, li) in l.iter().enumerate() {
            r += outer(v.col(i), v.col(i)) * *li;
        }
        assert!(close(r, k, 1e-10));
        let tr: Real = l.iter().sum();
        assert!((tr - 530.0).abs() < 1e-10);
    }
}
