//! Creep of ice by Glen's flow law (Cuffey & Paterson 2010, §3.4; see docs/ice.md#creep).
//!
//! Ice under a deviatoric stress τ (effective stress τₑ = √(½ τ:τ)) flows at the strain rate
//! ε̇ = A(T) τₑⁿ⁻¹ τ, n = 3: over the hours of freezing it relaxes the stresses the expansion
//! builds, while under loads of seconds it stays elastic and brittle. In Frobenius norms
//! ‖ε̇‖ = B ‖τ‖ⁿ with B = A 2^{(1−n)/2}.
//!
//! A solve integrates the flow over its length h by backward Euler, as a flow rule in the same
//! return mapping as plasticity ([`Flow::Creep`], `fem::solid_response`): the element's energy
//! is the incremental potential of the step's creep at its end stress, so the solve converges
//! to displacements whose stress has crept, with the consistent tangent. After the solve,
//! [`Creep::advance`] adds the step's creep to the element's inelastic strain (the history's
//! plastic strain); the stress output, the fracture criterion and the energies then read the
//! elastic law at the updated strain, which gives the same stress again.
//!
//! The rate factor follows the ice's temperature: each element's, at the solve's end, from a
//! heat solve, or the scene's one temperature without `[thermal]`.

use crate::fem::{creep_stress_norm, Flow, Material};
use nalgebra::Matrix3;

/// Glen's rate factor A* at the reference temperature T* (Pa⁻³ s⁻¹; Cuffey & Paterson 2010,
/// eq. 3.35 and table 3.4).
pub const GLEN_RATE_AT_REFERENCE: f64 = 3.5e-25;
/// The reference temperature T* of the Arrhenius law (K): −10 °C.
pub const GLEN_REFERENCE_TEMPERATURE: f64 = 263.15;
/// Activation energy of creep below T* (J/mol).
pub const GLEN_ACTIVATION_COLD: f64 = 6.0e4;
/// Activation energy of creep above T* (J/mol): grain-boundary processes near the melting
/// point make warm ice softer than the cold law extrapolates.
pub const GLEN_ACTIVATION_WARM: f64 = 1.15e5;
/// The gas constant (J/(mol K)).
const GAS_CONSTANT: f64 = 8.314;
/// Kelvin at 0 °C.
const ZERO_CELSIUS: f64 = 273.15;

/// How the rate factor A depends on temperature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RateFactor {
    /// A fixed A (Pa⁻ⁿ s⁻¹) at every temperature.
    Constant(f64),
    /// Cuffey & Paterson's Arrhenius law for n = 3, A = E A* exp(−Q/R (1/T − 1/T*)), with the
    /// enhancement factor E (dimensionless; 1 for isotropic ice).
    Arrhenius {
        /// Enhancement factor E (dimensionless).
        enhancement: f64,
    },
}

/// Glen creep of an element's ice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Creep {
    /// Stress exponent n (dimensionless): 3 for ice.
    pub exponent: f64,
    /// The rate factor A.
    pub rate: RateFactor,
    /// The ice's temperature (°C) where no heat solve gives one (none: the scene has a heat
    /// solve, or a constant rate factor).
    pub temperature: Option<f64>,
}

/// A solve's creep: each element's compliance h B over it ([`Creep::compliance`]), formed
/// once per solve rather than at every evaluation of the element (an exponential and a power
/// each).
#[derive(Clone, Copy, Debug)]
pub struct CreepStep<'a> {
    /// h B per element (Pa⁻ⁿ).
    pub compliance: &'a [f64],
}

impl Creep {
    /// Glen's rate factor A (Pa⁻ⁿ s⁻¹) of ice at `celsius` (°C). The Arrhenius law reads
    /// ice at most at its melting point: an element that is partly water can be warmer on
    /// average, but its ice is at 0 °C.
    pub fn rate_factor(&self, celsius: f64) -> f64 {
        match self.rate {
            RateFactor::Constant(a) => a,
            RateFactor::Arrhenius { enhancement } => {
                let t = celsius.min(0.0) + ZERO_CELSIUS;
                let q = if t < GLEN_REFERENCE_TEMPERATURE {
                    GLEN_ACTIVATION_COLD
                } else {
                    GLEN_ACTIVATION_WARM
                };
                let since_reference = 1.0 / t - 1.0 / GLEN_REFERENCE_TEMPERATURE;
                enhancement * GLEN_RATE_AT_REFERENCE * (-q / GAS_CONSTANT * since_reference).exp()
            }
        }
    }

    /// The compliance h B (Pa⁻ⁿ) of ice over a solve of length `h` (s) at `celsius` (°C; the
    /// scene's temperature where none is given): B = A 2^{(1−n)/2}, Glen's rate in Frobenius
    /// norms.
    pub fn compliance(&self, h: f64, celsius: Option<f64>) -> f64 {
        let celsius = celsius.or(self.temperature).unwrap_or(0.0);
        let frobenius_rate = self.rate_factor(celsius) * 2f64.powf(0.5 * (1.0 - self.exponent));
        h * frobenius_rate
    }

    /// The flow rule of an element of `compliance` h B over its solve.
    pub fn flow(&self, compliance: f64) -> Flow {
        Flow::Creep {
            compliance,
            exponent: self.exponent,
        }
    }

    /// The inelastic strain after an element of `material` with elastic strain `elastic` (in
    /// its frame, from the inelastic strain `inelastic` of the solve's start) crept by `flow`
    /// over the solve: `inelastic` plus the crept x n, x = r − S/2μ (see
    /// `fem::solid_response`), so that the elastic law at the updated strain gives the
    /// solve's stress.
    pub fn advance(
        material: &Material,
        flow: Flow,
        elastic: &Matrix3<f64>,
        inelastic: &Matrix3<f64>,
    ) -> Matrix3<f64> {
        let Flow::Creep {
            compliance,
            exponent,
        } = flow
        else {
            return *inelastic;
        };
        let deviator = elastic - Matrix3::identity() * (elastic.trace() / 3.0);
        let r = deviator.norm();
        if r == 0.0 || compliance <= 0.0 || material.mu <= 0.0 {
            return *inelastic;
        }
        let (s, _) = creep_stress_norm(r, material.mu, compliance, exponent);
        let delta = (1.0 - s / (2.0 * material.mu * r)) * deviator;
        // Symmetrised against round-off, as plasticity's.
        inelastic + 0.5 * (delta + delta.transpose())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::solid_response;

    fn glen() -> Creep {
        Creep {
            exponent: 3.0,
            rate: RateFactor::Arrhenius { enhancement: 1.0 },
            temperature: None,
        }
    }

    #[test]
    fn rate_factor_follows_cuffey_and_paterson_table() {
        // Cuffey & Paterson (2010), table 3.4 (A in Pa⁻³ s⁻¹, two digits): the law reproduces
        // the rounded table to within its rounding, 3 %.
        let table = [
            (0.0, 2.4e-24),
            (-2.0, 1.7e-24),
            (-5.0, 9.3e-25),
            (-10.0, 3.5e-25),
            (-15.0, 2.1e-25),
            (-20.0, 1.2e-25),
            (-30.0, 3.7e-26),
            (-40.0, 1.0e-26),
            (-50.0, 2.6e-27),
        ];
        for (t, a) in table {
            let law = glen().rate_factor(t);
            assert!((law / a - 1.0).abs() < 0.03, "{t} °C: {law:e} vs {a:e}");
        }
        // Warmer than melting reads as melting; the enhancement scales it.
        assert_eq!(glen().rate_factor(3.0), glen().rate_factor(0.0));
        let soft = Creep {
            rate: RateFactor::Arrhenius { enhancement: 2.0 },
            ..glen()
        };
        assert_eq!(soft.rate_factor(-7.0), 2.0 * glen().rate_factor(-7.0));
    }

    #[test]
    fn uniaxial_rate_is_glen_s() {
        // A uniaxial stress σ: τₑ = σ/√3, so ε̇_xx = A τₑ² (2σ/3) = (2/9) A σ³. One
        // backward-Euler step at a fixed stress is exact: the crept strain of a step of
        // length h under the solve's stress is h ε̇.
        let material = Material::from_young_poisson(9e9, 0.33, 917.0);
        let creep = Creep {
            temperature: Some(-10.0),
            ..glen()
        };
        let h = 50.0;
        let flow = creep.flow(creep.compliance(h, None));
        let a = creep.rate_factor(-10.0);
        // The elastic strain whose crept stress is a uniaxial σ: the trial deviator
        // σ'/2μ + h ε̇ (creep changes only the deviator).
        let sigma: f64 = 1.0e6;
        let rate = 2.0 / 9.0 * a * sigma.powi(3);
        let stress_dev =
            Matrix3::from_diagonal(&nalgebra::Vector3::new(2.0, -1.0, -1.0)) * (sigma / 3.0);
        let crept_dev =
            Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, -0.5, -0.5)) * (h * rate);
        let trial = stress_dev / (2.0 * material.mu) + crept_dev;
        let response = solid_response(&material, Some(flow), &trial);
        let dev = response.sigma - Matrix3::identity() * (response.sigma.trace() / 3.0);
        assert!(
            (dev - stress_dev).norm() <= 1e-12 * sigma,
            "{dev} vs {stress_dev}"
        );
        let crept = Creep::advance(&material, flow, &trial, &Matrix3::zeros());
        assert!((crept[(0, 0)] - h * rate).abs() <= 1e-12 * h * rate);
        assert!(crept.trace().abs() <= 1e-15 * h * rate);
    }
}
