//! Neumann's similarity solution of the two-phase Stefan problem: a half-space of liquid at
//! T₀ > T_m whose face x = 0 is held at T_w < T_m from t = 0 (one density for both phases).
//! The front is at X(t) = 2 λ √(α_s t), λ the root of
//!
//! λ √π = St_s e^{−λ²} / erf λ − (St_l / ν) e^{−ν²λ²} / erfc(ν λ),
//!
//! St_s = c_s (T_m − T_w) / L, St_l = c_l (T₀ − T_m) / L, α = k / (ρ c), ν = √(α_s / α_l)
//! (e.g. Alexiades & Solomon, *Mathematical Modeling of Melting and Freezing Processes*, 1993,
//! §2.2).

use super::Phases;

/// The front of Neumann's solution for `phases` (their mushy range is ignored: the change is
/// sharp at T_m), density `rho` (kg/m³), wall `t_wall` and initial `t_initial` (°C).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Neumann {
    /// λ (dimensionless).
    pub lambda: f64,
    /// The solid's diffusivity α_s (m²/s).
    pub alpha_solid: f64,
}

impl Neumann {
    /// Solves for λ by bisection (the left side minus the right is increasing in λ).
    pub fn new(phases: &Phases, rho: f64, t_wall: f64, t_initial: f64) -> Self {
        let (ice, water) = (phases.ice, phases.water);
        let alpha_s = ice.conductivity / (rho * ice.heat_capacity);
        let alpha_l = water.conductivity / (rho * water.heat_capacity);
        let nu = (alpha_s / alpha_l).sqrt();
        let st_s = ice.heat_capacity * (phases.melting_point - t_wall) / phases.latent_heat;
        let st_l = water.heat_capacity * (t_initial - phases.melting_point) / phases.latent_heat;
        let gap = |l: f64| {
            l * std::f64::consts::PI.sqrt() - st_s * (-l * l).exp() / libm::erf(l)
                + st_l / nu * (-nu * nu * l * l).exp() / libm::erfc(nu * l)
        };
        let (mut lo, mut hi) = (1e-12, 10.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if gap(mid) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Neumann {
            lambda: 0.5 * (lo + hi),
            alpha_solid: alpha_s,
        }
    }

    /// The front's distance from the cooled face at time `t` (m).
    pub fn front(&self, t: f64) -> f64 {
        2.0 * self.lambda * (self.alpha_solid * t).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_phase_limit_and_the_water_ice_numbers() {
        // Liquid at the melting point: λ e^{λ²} erf λ = St/√π; small St: λ ≈ √(St/2).
        let p = Phases::WATER_ICE;
        let n = Neumann::new(&p, 916.0, -0.01, 0.0);
        let st = p.ice.heat_capacity * 0.01 / p.latent_heat;
        assert!(
            (n.lambda / (st / 2.0).sqrt() - 1.0).abs() < 1e-3,
            "{}",
            n.lambda
        );
        // Walls at −10 °C, water at 0 °C: about 9 mm after 10 min, 23 mm after an hour and
        // 55 mm after six hours (ρ = 916 kg/m³), growing as √t.
        let n = Neumann::new(&p, 916.0, -10.0, 0.0);
        let mm = |t: f64| 1e3 * n.front(t);
        assert!((8.5..10.0).contains(&mm(600.0)), "{}", mm(600.0));
        assert!((mm(4.0 * 3600.0) / mm(3600.0) - 2.0).abs() < 1e-12);
        assert!((20.0..25.0).contains(&mm(3600.0)), "{}", mm(3600.0));
        // Warm water slows the front: λ as scipy's brentq finds it for the same equation
        // (0.1640264820987164; validation venv, scipy 1.17).
        let warm = Neumann::new(&p, 916.0, -10.0, 5.0);
        assert!(warm.lambda < n.lambda);
        assert!(
            (warm.lambda - 0.1640264820987164).abs() < 1e-10,
            "{}",
            warm.lambda
        );
    }
}
