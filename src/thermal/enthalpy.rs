//! Water ↔ ice as a specific enthalpy h(T): sensible heat of ice below the mushy range, the
//! latent heat spread evenly over it, sensible heat of water above. h is increasing, so its
//! integral is convex and a backward-Euler heat step is the minimiser of a convex potential.

/// Heat properties of one phase.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phase {
    /// Thermal conductivity k (W/(m K)).
    pub conductivity: f64,
    /// Specific heat capacity c (J/(kg K)).
    pub heat_capacity: f64,
}

/// Water, ice and the change between them. Temperatures in °C (only differences enter the
/// equations, so K would do as well).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phases {
    /// Ice (solid below the mushy range).
    pub ice: Phase,
    /// Liquid water (above the melting point).
    pub water: Phase,
    /// Latent heat of fusion L (J/kg).
    pub latent_heat: f64,
    /// Melting point T_m (°C): fully liquid above it.
    pub melting_point: f64,
    /// Width ΔT of the mushy range (K): fully solid below T_m − ΔT, the latent heat released
    /// evenly across the range. A numerical regularisation (the physical change is sharp):
    /// see docs/thermal.md for its effect on the front.
    pub mushy_range: f64,
}

impl Phases {
    /// Pure water and ice near 0 °C: ice k = 2.22 W/(m K), c = 2050 J/(kg K); water
    /// k = 0.561 W/(m K), c = 4217 J/(kg K); L = 334 kJ/kg; T_m = 0 °C; a mushy range of
    /// 0.1 K (sources in docs/thermal.md).
    pub const WATER_ICE: Phases = Phases {
        ice: Phase {
            conductivity: 2.22,
            heat_capacity: 2050.0,
        },
        water: Phase {
            conductivity: 0.561,
            heat_capacity: 4217.0,
        },
        latent_heat: 334e3,
        melting_point: 0.0,
        mushy_range: 0.1,
    };

    /// Lower end of the mushy range, T_s = T_m − ΔT (°C), where h = 0.
    fn solidus(&self) -> f64 {
        self.melting_point - self.mushy_range
    }

    /// The slope of h in the mushy range (J/(kg K)): ice's sensible heat plus L / ΔT.
    fn mushy_capacity(&self) -> f64 {
        self.ice.heat_capacity + self.latent_heat / self.mushy_range
    }

    /// Specific enthalpy h(T) (J/kg), 0 at T_s.
    pub fn enthalpy(&self, t: f64) -> f64 {
        let ts = self.solidus();
        if t <= ts {
            self.ice.heat_capacity * (t - ts)
        } else if t <= self.melting_point {
            self.mushy_capacity() * (t - ts)
        } else {
            self.mushy_capacity() * self.mushy_range
                + self.water.heat_capacity * (t - self.melting_point)
        }
    }

    /// dh/dT (J/(kg K)) on the segment that holds T (the upper one at a kink).
    pub fn capacity(&self, t: f64) -> f64 {
        if t < self.solidus() {
            self.ice.heat_capacity
        } else if t < self.melting_point {
            self.mushy_capacity()
        } else {
            self.water.heat_capacity
        }
    }

    /// ∫_{T_s}^{T} h dτ (J K/kg): the convex function whose derivative is h.
    pub fn enthalpy_integral(&self, t: f64) -> f64 {
        let ts = self.solidus();
        if t <= ts {
            0.5 * self.ice.heat_capacity * (t - ts).powi(2)
        } else if t <= self.melting_point {
            0.5 * self.mushy_capacity() * (t - ts).powi(2)
        } else {
            let dt = t - self.melting_point;
            0.5 * self.mushy_capacity() * self.mushy_range.powi(2)
                + self.enthalpy(self.melting_point) * dt
                + 0.5 * self.water.heat_capacity * dt * dt
        }
    }

    /// Ice fraction at T: 1 below T_s, 0 above T_m, linear between.
    pub fn ice_fraction(&self, t: f64) -> f64 {
        ((self.melting_point - t) / self.mushy_range).clamp(0.0, 1.0)
    }

    /// Conductivity of a mixture with ice fraction `f` (W/(m K)): the volume-weighted mean.
    pub fn conductivity(&self, f: f64) -> f64 {
        // Written so that equal conductivities give exactly that value whatever f.
        self.water.conductivity + f * (self.ice.conductivity - self.water.conductivity)
    }

    /// Whether the properties are physical: positive conductivities, capacities and mushy
    /// range, non-negative latent heat; the reason otherwise.
    pub fn check(&self) -> Result<(), String> {
        let positive = [
            ("ice conductivity", self.ice.conductivity),
            ("ice heat capacity", self.ice.heat_capacity),
            ("water conductivity", self.water.conductivity),
            ("water heat capacity", self.water.heat_capacity),
            ("mushy range", self.mushy_range),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be > 0, got {v}"));
            }
        }
        if !(self.latent_heat.is_finite() && self.latent_heat >= 0.0) {
            return Err(format!("latent heat must be ≥ 0, got {}", self.latent_heat));
        }
        if !self.melting_point.is_finite() {
            return Err("melting point must be finite".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enthalpy_is_continuous_and_holds_the_latent_heat() {
        let p = Phases::WATER_ICE;
        let h = |t| p.enthalpy(t);
        let eps = 1e-9;
        for t in [p.solidus(), p.melting_point] {
            // No jump: the difference is the steepest slope (3.3e6 J/(kg K)) times 2 eps.
            assert!((h(t + eps) - h(t - eps)).abs() < 1e-2, "jump at {t}");
        }
        // Across the range: L plus ice's sensible heat over ΔT.
        let across = h(0.0) - h(-0.1);
        assert!((across - (334e3 + 2050.0 * 0.1)).abs() < 1e-6, "{across}");
        // Derivatives: h' = capacity, Ĥ' = h (central differences).
        for t in [-5.0, -0.05, 3.0] {
            let d = (h(t + 1e-6) - h(t - 1e-6)) / 2e-6;
            assert!((d - p.capacity(t)).abs() < 1e-6 * d, "h' at {t}");
            let di = (p.enthalpy_integral(t + 1e-6) - p.enthalpy_integral(t - 1e-6)) / 2e-6;
            assert!(
                (di - h(t)).abs() < 1e-5 * h(t).abs().max(1.0),
                "Ĥ' at {t}: {di} vs {}",
                h(t)
            );
        }
        assert_eq!(p.ice_fraction(-1.0), 1.0);
        assert_eq!(p.ice_fraction(1.0), 0.0);
        assert!((p.ice_fraction(-0.025) - 0.25).abs() < 1e-12);
    }
}
