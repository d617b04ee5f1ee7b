//! Material constants of an isotropic linear-elastic solid and Hooke's law.

use nalgebra::Matrix3;

/// Isotropic linear-elastic material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// First Lamé constant λ (Pa).
    pub lambda: f64,
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// Density ρ (kg/m³).
    pub density: f64,
}

impl Material {
    /// Lamé constants from Young's modulus E (Pa) and Poisson's ratio ν (−1 < ν < 0.5).
    pub fn from_young_poisson(e: f64, nu: f64, density: f64) -> Self {
        Material {
            lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            mu: e / (2.0 * (1.0 + nu)),
            density,
        }
    }
    /// Young's modulus E (Pa).
    pub fn young(&self) -> f64 {
        self.mu * (3.0 * self.lambda + 2.0 * self.mu) / (self.lambda + self.mu)
    }
    /// Poisson's ratio ν.
    pub fn poisson(&self) -> f64 {
        self.lambda / (2.0 * (self.lambda + self.mu))
    }
    /// Bulk modulus K = λ + 2μ/3 (Pa).
    #[inline]
    pub fn bulk(&self) -> f64 {
        self.lambda + 2.0 * self.mu / 3.0
    }
    /// P-wave speed √((λ + 2μ)/ρ) (m/s).
    pub fn p_wave_speed(&self) -> f64 {
        ((self.lambda + 2.0 * self.mu) / self.density).sqrt()
    }
    /// Hooke's law σ = 2με + λ tr(ε) I (Pa) for a symmetric strain ε.
    #[inline]
    pub fn hooke(&self, eps: &Matrix3<f64>) -> Matrix3<f64> {
        2.0 * self.mu * eps + Matrix3::identity() * (self.lambda * eps.trace())
    }
}
