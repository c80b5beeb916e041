//! Linear elastic material constants and the Lamé parameters derived from them.

use serde::{Deserialize, Serialize};

use crate::error::MaterialError;
use crate::math::Real;

pub mod regions;

pub use regions::{ElementMaterials, RegionMaterial};

/// An isotropic, linear elastic material with mass and Rayleigh damping.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Young's modulus E, in Pa (force per unit area). Soft liver tissue: a few kPa.
    pub young_modulus: Real,
    /// Poisson's ratio ν, dimensionless, in (-1, 0.5). Soft tissue: 0.3 to 0.49.
    pub poisson_ratio: Real,
    /// Mass density ρ, in kg/m³ (default: 1000, water-like tissue).
    #[serde(default = "default_density")]
    pub density: Real,
    /// Rayleigh mass-proportional damping α, in 1/s (default: `0.0`, undamped).
    #[serde(default)]
    pub damping: Real,
    /// Rayleigh stiffness-proportional damping β, in s (default: `0.0`).
    #[serde(default)]
    pub stiffness_damping: Real,
}

fn default_density() -> Real {
    1000.0
}

impl Material {
    /// A material from E (Pa) and ν, with density 1000 kg/m³ and no damping; checked.
    pub fn new(young_modulus: Real, poisson_ratio: Real) -> Result<Self, MaterialError> {
        Self {
            young_modulus,
            poisson_ratio,
            density: default_density(),
            damping: 0.0,
            stiffness_damping: 0.0,
        }
        .validated()
    }

    /// Returns the same material with density ρ (kg/m³), checked.
    pub fn with_density(mut self, density: Real) -> Result<Self, MaterialError> {
        self.density = density;
        self.validated()
    }

    /// Checks every constant, naming the first one that is out of its physical range.
    pub fn validated(self) -> Result<Self, MaterialError> {
        let bad = |name: &'static str, value: Real, reason: &'static str| {
            Err(MaterialError::OutOfRange {
                name,
                value,
                reason,
            })
        };
        if !(self.young_modulus.is_finite() && self.young_modulus > 0.0) {
            return bad(
                "young_modulus",
                self.young_modulus,
                "must be a finite value > 0 Pa",
            );
        }
        if !(self.poisson_ratio.is_finite()
            && self.poisson_ratio > -1.0
            && self.poisson_ratio < 0.5)
        {
            return bad(
                "poisson_ratio",
                self.poisson_ratio,
                "must lie in (-1, 0.5); 0.5 (incompressible) makes λ infinite",
            );
        }
        if !(self.density.is_finite() && self.density > 0.0) {
            return bad("density", self.density, "must be a finite value > 0 kg/m^3");
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return bad("damping", self.damping, "must be a finite value >= 0 1/s");
        }
        if !(self.stiffness_damping.is_finite() && self.stiffness_damping >= 0.0) {
            return bad(
                "stiffness_damping",
                self.stiffness_damping,
                "must be a finite value >= 0 s",
            );
        }
        Ok(self)
    }

    /// Lamé's first parameter λ = Eν / ((1+ν)(1-2ν)), in Pa.
    pub fn lambda(&self) -> Real {
        let (e, nu) = (self.young_modulus, self.poisson_ratio);
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    }

    /// Shear modulus μ = E / (2(1+ν)), in Pa.
    pub fn mu(&self) -> Real {
        self.young_modulus / (2.0 * (1.0 + self.poisson_ratio))
    }

    /// Bulk modulus K = E / (3(1-2ν)), in Pa.
    pub fn bulk_modulus(&self) -> Real {
        self.young_modulus / (3.0 * (1.0 - 2.0 * self.poisson_ratio))
    }

    /// Speed of the pressure (P) wave, in m/s: sets the explicit stable time step.
    pub fn p_wave_speed(&self) -> Real {
        ((self.lambda() + 2.0 * self.mu()) / self.density).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lame_parameters_reproduce_young_and_poisson() {
        let m = Material::new(3000.0, 0.3).unwrap();
        let (l, mu) = (m.lambda(), m.mu());
        // E = μ(3λ+2μ)/(λ+μ), ν = λ/(2(λ+μ)).
        assert!((mu * (3.0 * l + 2.0 * mu) / (l + mu) - 3000.0).abs() < 1e-9);
        assert!((l / (2.0 * (l + mu)) - 0.3).abs() < 1e-14);
    }

    #[test]
    fn invalid_constants_are_named() {
        let e = Material::new(3000.0, 0.5).unwrap_err();
        assert!(e.to_string().contains("poisson_ratio"), "{e}");
        let e = Material::new(-1.0, 0.3).unwrap_err();
        assert!(e.to_string().contains("young_modulus"), "{e}");
        let e = Material::new(f64::NAN, 0.3).unwrap_err();
        assert!(e.to_string().contains("young_modulus"), "{e}");
        assert!(Material::new(1e3, 0.3).unwrap().with_density(0.0).is_err());
    }
}
