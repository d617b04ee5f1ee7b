//! `[creep]`: Glen's flow law for the ice (see `physics::creep` and docs/ice.md#creep).

use super::{SceneError, Validator};
use crate::physics::creep::{Creep, RateFactor};
use serde::Deserialize;

/// `[creep]`: ice creeps by Glen's law, ε̇ = A(T) τₑⁿ⁻¹ τ.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CreepSection {
    /// Stress exponent n, in [1, 5]. Default 3 (Glen).
    pub exponent: Option<f64>,
    /// Rate factor A (Pa⁻ⁿ s⁻¹), the same at every temperature. Default: Cuffey &
    /// Paterson's (2010) Arrhenius law in the ice's temperature (n = 3 only).
    pub rate_factor: Option<f64>,
    /// Enhancement factor E of the Arrhenius law, in (0, 100]. Default 1.
    pub enhancement: Option<f64>,
    /// The ice's temperature (°C) for the Arrhenius law in a scene without `[thermal]`,
    /// in [−100, 0].
    pub temperature: Option<f64>,
}

/// The coldest temperature the Arrhenius law is taken to (°C): Cuffey & Paterson's table
/// reaches −50 °C; the law is an extrapolation beyond it.
const COLDEST: f64 = -100.0;

impl Validator<'_> {
    /// The creep of `[creep]`, in a scene with a heat solve if `thermal` (which then gives
    /// the ice's temperatures).
    pub(super) fn creep(&self, c: &CreepSection, thermal: bool) -> Result<Creep, SceneError> {
        let exponent = c.exponent.unwrap_or(3.0);
        if !(1.0..=5.0).contains(&exponent) {
            return Err(self.invalid(
                "creep.exponent",
                format!("must be in [1, 5] (ice: 3), got {exponent}"),
            ));
        }
        if let Some(a) = c.rate_factor {
            let a = self.positive("creep.rate_factor", a)?;
            for (key, given) in [
                ("enhancement", c.enhancement.is_some()),
                ("temperature", c.temperature.is_some()),
            ] {
                if given {
                    return Err(self.invalid(
                        &format!("creep.{key}"),
                        "belongs to the Arrhenius law; with `rate_factor` the rate is the same at every temperature (remove one of the keys)",
                    ));
                }
            }
            return Ok(Creep {
                exponent,
                rate: RateFactor::Constant(a),
                temperature: None,
            });
        }
        if exponent != 3.0 {
            return Err(self.invalid(
                "creep.exponent",
                format!("the Arrhenius rate factor is Glen's for n = 3; with n = {exponent} give `rate_factor` (Pa⁻ⁿ s⁻¹)"),
            ));
        }
        let enhancement = c.enhancement.unwrap_or(1.0);
        if !(enhancement > 0.0 && enhancement <= 100.0) {
            return Err(self.invalid(
                "creep.enhancement",
                format!("must be in (0, 100] (isotropic ice: 1), got {enhancement}"),
            ));
        }
        let temperature = match (c.temperature, thermal) {
            (Some(_), true) => {
                return Err(self.invalid(
                    "creep.temperature",
                    "the scene's [thermal] gives the ice's temperatures (remove the key)",
                ))
            }
            (None, false) => {
                return Err(self.invalid(
                    "creep.temperature",
                    "the creep rate needs the ice's temperature (°C): give `temperature`, or a [thermal] section",
                ))
            }
            (Some(t), false) if !(COLDEST..=0.0).contains(&t) => {
                return Err(self.invalid(
                    "creep.temperature",
                    format!("must be in [{COLDEST}, 0] °C, got {t}"),
                ))
            }
            (t, _) => t,
        };
        Ok(Creep {
            exponent,
            rate: RateFactor::Arrhenius { enhancement },
            temperature,
        })
    }
}
