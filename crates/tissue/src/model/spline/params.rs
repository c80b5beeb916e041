//! The `[model]` settings of `spline`, as scenes give them.

use serde::Deserialize;

use crate::integrate::Scheme;
use crate::math::Real;

/// The `[model]` settings of `spline`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SplineParams {
    /// Shell thickness h, m (default 1 mm).
    #[serde(default = "default_thickness")]
    pub thickness: Real,
    /// Control points [along u, along v] of the fitted net (default [16, 16]); for a tube u
    /// runs around (periodic) and v along.
    #[serde(default = "default_control")]
    pub control: [usize; 2],
    /// Segments of the rendered surface per knot span and direction (default 3).
    #[serde(default = "default_subdivisions")]
    pub subdivisions: usize,
    /// Weight of the smoothing term of the fit (default 1e-6).
    #[serde(default = "default_smoothing")]
    pub smoothing: Real,
    /// Time integration scheme (default `implicit-euler`: the scheme under which the spline
    /// holds a frictionless contact as a push, settled within its step; under an explicit
    /// scheme a frictionless probe slides by the relaxation of full holds, which read 0 N on
    /// the shipped tube at 1 ms with the probe 1 mm into its wall).
    #[serde(default = "default_integrator")]
    pub integrator: Scheme,
    /// Penalty stiffness holding fixed and prescribed surface vertices, N/m (default 100 E h).
    pub hold_stiffness: Option<Real>,
    /// Hold the first two and last two control rows along v exactly (default false).
    #[serde(default)]
    pub clamp_ends: bool,
    /// Implicit Euler: CG iteration cap and relative tolerance (integrator defaults if unset).
    pub cg_iterations: Option<usize>,
    pub cg_tolerance: Option<Real>,
    /// `"auto"` (default: as many integrator steps per step as the measured stability limit
    /// needs) or a forced count.
    #[serde(default)]
    pub substeps: crate::integrate::Substeps,
}

fn default_thickness() -> Real {
    1e-3
}
fn default_control() -> [usize; 2] {
    [16, 16]
}
fn default_subdivisions() -> usize {
    3
}
fn default_smoothing() -> Real {
    1e-6
}
fn default_integrator() -> Scheme {
    Scheme::ImplicitEuler
}

impl Default for SplineParams {
    fn default() -> Self {
        Self {
            thickness: default_thickness(),
            control: default_control(),
            subdivisions: default_subdivisions(),
            smoothing: default_smoothing(),
            integrator: default_integrator(),
            hold_stiffness: None,
            clamp_ends: false,
            cg_iterations: None,
            cg_tolerance: None,
            substeps: crate::integrate::Substeps::Auto,
        }
    }
}
