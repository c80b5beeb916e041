//! The largest stable explicit step of a particle system, estimated from its forces alone,
//! and the `substeps` setting that uses it.
//!
//! An explicit scheme is stable while every mode of the linearised system stays inside its
//! stability region. For one mode ẍ = −ω²x − c ẋ, symplectic Euler's update matrix has
//! determinant 1 − hc and trace 2 − h²ω² − hc, and the Jury conditions reduce to
//! h²ω² + 2hc ≤ 4, i.e.
//!
//!   h ≤ 4 / (c + √(c² + 4ω²)),
//!
//! (2/ω without damping; 2/c when damping dominates). Velocity Verlet has the same undamped
//! limit; classical RK4 reaches about 2.8/ω on the imaginary axis and 2.8/c on the real one,
//! so it gets 1.3 times the step. The bound is applied with ω² the largest eigenvalue of
//! M⁻¹K and c the largest of M⁻¹C (K = −∂f/∂x, C = −∂f/∂v), exact for Rayleigh damping
//! where K and C share their modes and a close estimate otherwise.
//!
//! Both eigenvalues are found by power iteration on products K·u and C·u taken as central
//! differences of the system's own forces around the current state, so every family gets
//! the same estimate without writing its matrices, and a non-linear system is measured in
//! the state it is in (a stretched spring network or a compressed St Venant–Kirchhoff body
//! is stiffer than at rest). The Rayleigh quotient (u·Ku)/(u·Mu) approaches ω²_max from
//! below, so the step is taken at `SAFETY` = 0.8 of the bound (room for a quotient 1.5×
//! below the true value). Held particles are excluded: holding only lowers ω_max.
//!
//! How it stays safe when the state stiffens: the integrator re-measures every
//! `RECHECK_STEPS` steps at the current state (a few warm-started iterations, never below the
//! rest estimate), and a step the divergence guard refuses is re-measured at once and
//! retried with four times the stiffness margin, twice the substeps (up to three times),
//! before the refusal reaches the caller.

use serde::Deserialize;

use crate::math::{Real, Vec3};

use super::{ParticleSystem, Scheme, eval_forces};

/// Fraction of the stability bound an automatic substep uses.
pub const SAFETY: Real = 0.8;
/// Power iterations for the stiffness at build (and after a cut or a refused step).
pub const ITERATIONS: usize = 30;
/// Power iterations, warm-started, of the periodic re-check.
pub const RECHECK_ITERATIONS: usize = 5;
/// Steps between two re-checks of a stiffness that may have grown with the deformation.
pub const RECHECK_STEPS: u64 = 50;
/// The most substeps a step may take before the model refuses the time step instead.
pub const MAX_SUBSTEPS: u32 = 100_000;

/// `[model] substeps`: `"auto"` (default: as many as the stability limit needs) or a count.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Substeps {
    #[default]
    Auto,
    Fixed(u32),
}

impl Substeps {
    /// The scene spelling.
    pub fn describe(self) -> String {
        match self {
            Substeps::Auto => "auto".into(),
            Substeps::Fixed(n) => n.to_string(),
        }
    }
}

impl<'de> Deserialize<'de> for Substeps {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Count(i64),
            Word(String),
        }
        use serde::de::Error;
        match Raw::deserialize(d)? {
            Raw::Word(w) if w == "auto" => Ok(Substeps::Auto),
            Raw::Count(n) if (1..=i64::from(MAX_SUBSTEPS)).contains(&n) => {
                Ok(Substeps::Fixed(n as u32))
            }
            Raw::Count(n) => Err(D::Error::custom(format!(
                "substeps = {n}: a count must be in 1..={MAX_SUBSTEPS}"
            ))),
            Raw::Word(w) => Err(D::Error::custom(format!(
                "substeps = \"{w}\": expected \"auto\" or a count such as 4"
            ))),
        }
    }
}

/// The undamped-free stability bound h ≤ 4 / (c + √(c² + 4ω²)) of one mode, for `scheme`
/// (infinite for implicit Euler, which has none).
pub fn stable_step(scheme: Scheme, omega_sq: Real, c: Real) -> Real {
    let factor = match scheme {
        Scheme::ImplicitEuler => return Real::INFINITY,
        Scheme::Rk4 => 1.3,
        Scheme::ExplicitEuler | Scheme::SymplecticEuler | Scheme::VelocityVerlet => 1.0,
    };
    let (w, c) = (omega_sq.max(0.0), c.max(0.0));
    let denom = c + (c * c + 4.0 * w).sqrt();
    if denom > 0.0 {
        factor * 4.0 / denom
    } else {
        Real::INFINITY
    }
}

/// Substeps of length ≤ `stable` covering `dt` (at least 1), or None above `MAX_SUBSTEPS`.
pub fn substeps_for(dt: Real, stable: Real) -> Option<u32> {
    if stable.is_nan() || stable <= 0.0 {
        return None;
    }
    let n = (dt / stable * (1.0 - 1e-12)).ceil().max(1.0);
    (n <= Real::from(MAX_SUBSTEPS)).then_some(n as u32)
}

/// Power-iteration estimates of the largest eigenvalues of M⁻¹K and M⁻¹C, kept with their
/// vectors for warm starts.
#[derive(Clone, Debug, Default)]
pub struct RateEstimate {
    /// ω²_max, 1/s².
    pub omega_sq: Real,
    /// Largest eigenvalue of M⁻¹C, 1/s.
    pub damping_rate: Real,
    /// The estimate at rest (or right after the last cut): re-checks never go below it.
    pub rest_omega_sq: Real,
    pub rest_damping_rate: Real,
    stiff_vec: Vec<Vec3>,
    damp_vec: Vec<Vec3>,
    xp: Vec<Vec3>,
    xm: Vec<Vec3>,
    fp: Vec<Vec3>,
    fm: Vec<Vec3>,
}

impl RateEstimate {
    /// Forgets the vectors (a cut changed the particle set or its stiffness).
    pub fn reset(&mut self) {
        self.stiff_vec.clear();
        self.damp_vec.clear();
        self.omega_sq = 0.0;
        self.damping_rate = 0.0;
        self.rest_omega_sq = 0.0;
        self.rest_damping_rate = 0.0;
    }

    /// Measures at (x, v) with `iterations` power iterations (warm-started when vectors are
    /// kept). `inv_mass` is zero on held particles, which are left out. With `as_rest`, the
    /// result becomes the floor of later re-checks.
    pub fn measure<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        x: &[Vec3],
        v: &[Vec3],
        inv_mass: &[Real],
        iterations: usize,
        as_rest: bool,
    ) {
        let omega_sq = self.stiffness_rate(system, x, v, inv_mass, iterations);
        if self.damp_vec.len() != x.len() || is_dead(&self.damp_vec) {
            self.damp_vec.clone_from(&self.stiff_vec);
        }
        let mut vec = std::mem::take(&mut self.damp_vec);
        let damping = self.power(
            system,
            x,
            v,
            inv_mass,
            &mut vec,
            iterations.div_ceil(2),
            1e-3,
            true,
        );
        self.damp_vec = vec;
        if as_rest {
            self.rest_omega_sq = omega_sq;
            self.rest_damping_rate = damping;
        }
        self.omega_sq = omega_sq.max(self.rest_omega_sq);
        self.damping_rate = damping.max(self.rest_damping_rate);
    }

    /// `measure` of the stiffness rate alone (the damping rate kept), warm-started from
    /// the kept vector and never below the rest estimate: for a change of external
    /// stiffness that leaves the damping as it was (the `hybrid` model's contact set on its
    /// rest, which adds or removes a low-rank stiffness at the interface nodes).
    pub fn measure_stiffness<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        x: &[Vec3],
        v: &[Vec3],
        inv_mass: &[Real],
        iterations: usize,
    ) {
        let omega_sq = self.stiffness_rate(system, x, v, inv_mass, iterations);
        self.omega_sq = omega_sq.max(self.rest_omega_sq);
    }

    /// ω² by `iterations` power iterations from the kept stiffness vector (afresh when there
    /// is none of this size, or it died: all zero because the system had no such rate when
    /// it was last measured, e.g. no damping, and so cannot find one that appeared since).
    fn stiffness_rate<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        x: &[Vec3],
        v: &[Vec3],
        inv_mass: &[Real],
        iterations: usize,
    ) -> Real {
        let n = x.len();
        for buf in [&mut self.xp, &mut self.xm, &mut self.fp, &mut self.fm] {
            buf.resize(n, Vec3::ZERO);
        }
        if self.stiff_vec.len() != n || is_dead(&self.stiff_vec) {
            self.stiff_vec = start_vector(n);
        }
        let eps_x = difference_step(x);
        let mut vec = std::mem::take(&mut self.stiff_vec);
        let omega_sq = self.power(system, x, v, inv_mass, &mut vec, iterations, eps_x, false);
        self.stiff_vec = vec;
        omega_sq
    }

    /// Power iteration on M⁻¹A (A = K, or C with `velocity`); returns the last Rayleigh
    /// quotient (u·Au)/(u·Mu), 0 when there is nothing free to move.
    #[allow(clippy::too_many_arguments)]
    fn power<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        x: &[Vec3],
        v: &[Vec3],
        inv_mass: &[Real],
        u: &mut [Vec3],
        iterations: usize,
        eps: Real,
        velocity: bool,
    ) -> Real {
        let mut quotient: Real = 0.0;
        for _ in 0..iterations {
            let mut peak: Real = 0.0;
            for (ui, &inv) in u.iter_mut().zip(inv_mass) {
                if inv == 0.0 {
                    *ui = Vec3::ZERO;
                }
                peak = peak.max(ui.abs().max_element());
            }
            if !(peak > 0.0 && peak.is_finite()) {
                return quotient;
            }
            u.iter_mut().for_each(|ui| *ui /= peak);
            // A·u ≈ −(f(+εu) − f(−εu)) / 2ε, into fp.
            let (xp, xm, fp, fm) = (&mut self.xp, &mut self.xm, &mut self.fp, &mut self.fm);
            let base = if velocity { v } else { x };
            for i in 0..u.len() {
                xp[i] = base[i] + eps * u[i];
                xm[i] = base[i] - eps * u[i];
            }
            if velocity {
                eval_forces(system, x, xp, fp);
                eval_forces(system, x, xm, fm);
            } else {
                eval_forces(system, xp, v, fp);
                eval_forces(system, xm, v, fm);
            }
            let (mut num, mut den) = (0.0, 0.0);
            for i in 0..u.len() {
                if inv_mass[i] == 0.0 {
                    continue;
                }
                let au = (fm[i] - fp[i]) / (2.0 * eps);
                num += u[i].dot(au);
                den += u[i].length_squared() / inv_mass[i];
                u[i] = au * inv_mass[i];
            }
            if den.is_nan() || den <= 0.0 || !num.is_finite() {
                return quotient;
            }
            quotient = num / den;
        }
        quotient.max(0.0)
    }
}

/// A kept vector with no finite non-zero entry.
fn is_dead(u: &[Vec3]) -> bool {
    !u.iter().any(|u| u.is_finite() && *u != Vec3::ZERO)
}

/// The difference step of the stiffness products: a millionth of the body's size (forces
/// are smooth, so the central difference is accurate to ε² while far above rounding).
fn difference_step(x: &[Vec3]) -> Real {
    let (lo, hi) = x.iter().fold(
        (Vec3::splat(Real::INFINITY), Vec3::splat(Real::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let size = (hi - lo).length();
    if size.is_finite() && size > 0.0 {
        1e-6 * size
    } else {
        1e-6
    }
}

/// A start vector with every sign pattern represented (the top modes alternate).
fn start_vector(n: usize) -> Vec<Vec3> {
    let hash = |i: u64| {
        let h = i.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
        let v = 1.0 + (h % 89) as Real / 89.0;
        if h & 1 == 0 { v } else { -v }
    };
    (0..n as u64)
        .map(|i| Vec3::new(hash(3 * i), hash(3 * i + 1), hash(3 * i + 2)))
        .collect()
}
