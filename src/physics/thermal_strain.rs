//! Thermal strain of ice: ice contracts as it cools and expands as it warms, by the linear
//! expansion coefficient α(T) (1/K). Its isotropic strain from the temperature T_ref at which
//! it is stress-free to T is
//!
//! ε_th(T) = ∫_{T_ref}^{T} α(θ) dθ,
//!
//! exact for α constant or piecewise linear in T (a table, linear between its points and
//! constant beyond its ends). It is a strain offset beside the freezing expansion: an element
//! whose ice fraction is s carries s (e_max + ε_th) (see `Freezing::apply`), water none.
//! Adding the two strains rather than composing them, (1 + e_max)(1 + ε_th) − 1, leaves out
//! e_max ε_th: 3 % of ε_th, below 1.5e-5 for the 50 K below melting that ice meets in a
//! freezer.
//!
//! Ice is stress-free where it was born: at the melting point for ice that freezes during the
//! run, at its initial temperature for ice present at the start (an element holding ice at
//! the start takes its initial temperature as reference; its ice fraction then is 1 unless
//! it starts within the mushy range, where both readings agree to the range's width).

/// The linear thermal expansion coefficient of ice.
#[derive(Clone, Debug, PartialEq)]
pub enum Expansion {
    /// One value (1/K) at every temperature.
    Constant(f64),
    /// (temperature °C, α 1/K) points with increasing temperatures, at least two: linear
    /// between them, constant beyond the ends.
    Table(Vec<(f64, f64)>),
}

impl Expansion {
    /// α(T) (1/K) at temperature `t` (°C).
    pub fn at(&self, t: f64) -> f64 {
        match self {
            Expansion::Constant(alpha) => *alpha,
            Expansion::Table(points) => {
                let (first, last) = (points[0], points[points.len() - 1]);
                if t <= first.0 {
                    return first.1;
                }
                if t >= last.0 {
                    return last.1;
                }
                let k = points.partition_point(|p| p.0 <= t);
                let ((t0, a0), (t1, a1)) = (points[k - 1], points[k]);
                a0 + (a1 - a0) * (t - t0) / (t1 - t0)
            }
        }
    }

    /// ∫₀^t α(θ) dθ (dimensionless) from 0 °C to `t` (°C): the strain between two temperatures
    /// is the difference of two of these.
    fn primitive(&self, t: f64) -> f64 {
        match self {
            Expansion::Constant(alpha) => alpha * t,
            Expansion::Table(points) => {
                // ∫₀ᵗ of the piecewise-linear α by the trapezoid rule on each piece between
                // the table's points (exact: α is linear there).
                let (lo, hi, sign) = if t >= 0.0 {
                    (0.0, t, 1.0)
                } else {
                    (t, 0.0, -1.0)
                };
                let (mut x, mut sum) = (lo, 0.0);
                for &(knot, _) in points.iter().filter(|p| p.0 > lo && p.0 < hi) {
                    sum += 0.5 * (knot - x) * (self.at(x) + self.at(knot));
                    x = knot;
                }
                sum += 0.5 * (hi - x) * (self.at(x) + self.at(hi));
                sign * sum
            }
        }
    }

    /// ε_th = ∫_{reference}^{t} α(θ) dθ (dimensionless) for temperatures in °C.
    pub fn strain(&self, reference: f64, t: f64) -> f64 {
        self.primitive(t) - self.primitive(reference)
    }
}

/// The thermal strain of a heat-driven run's elements: the coefficient and each element's
/// stress-free temperature.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalStrain {
    /// α(T).
    pub expansion: Expansion,
    /// Temperature (°C) at which each element's ice is stress-free.
    pub reference: Vec<f64>,
}

impl ThermalStrain {
    /// The thermal strain of elements whose initial ice fractions are `fractions` and initial
    /// temperatures `initial` (°C): ice present at the start is stress-free at its initial
    /// temperature, ice that forms later at `melting_point` (°C).
    pub fn new(
        expansion: Expansion,
        fractions: &[f64],
        initial: &[f64],
        melting_point: f64,
    ) -> Self {
        let reference = fractions
            .iter()
            .zip(initial)
            .map(|(&s, &t)| if s > 0.0 { t } else { melting_point })
            .collect();
        ThermalStrain {
            expansion,
            reference,
        }
    }

    /// Thermal strain (dimensionless) of element `e`'s ice at temperature `t` (°C).
    pub fn strain(&self, e: usize, t: f64) -> f64 {
        self.expansion.strain(self.reference[e], t)
    }

    /// The thermal strain on a split mesh whose element `e` came from element `parent[e]`.
    pub fn inherit(&self, parent: &[usize]) -> Self {
        ThermalStrain {
            expansion: self.expansion.clone(),
            reference: parent.iter().map(|&p| self.reference[p]).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_constant_coefficient_gives_alpha_times_the_temperature_change() {
        let e = Expansion::Constant(5e-5);
        assert_eq!(e.strain(0.0, -10.0), -5e-4);
        // Round-off of the two primitives: a few ulps of 5e-4.
        assert!((e.strain(-5.0, -15.0) + 5e-4).abs() < 1e-18);
    }

    #[test]
    fn a_table_is_integrated_exactly_across_its_points_and_beyond_its_ends() {
        // α from 4e-5 at −40 °C to 5e-5 at 0 °C, linear between.
        let e = Expansion::Table(vec![(-40.0, 4e-5), (0.0, 5e-5)]);
        assert_eq!(e.at(-20.0), 4.5e-5);
        // ∫_{-20}^{0} α = 20 × (4.5e-5 + 5e-5) / 2 = 9.5e-4 (the strain from 0 down to −20).
        let s = e.strain(0.0, -20.0);
        assert!((s + 9.5e-4).abs() < 1e-17, "{s}");
        // Below the table α stays 4e-5: from −40 to −50 adds 10 × 4e-5 = 4e-4 more.
        let below = e.strain(-40.0, -50.0);
        assert!((below + 4e-4).abs() < 1e-17, "{below}");
        // A table of two equal values is a constant.
        let flat = Expansion::Table(vec![(-10.0, 5e-5), (10.0, 5e-5)]);
        assert!(
            (flat.strain(3.0, -7.0) - Expansion::Constant(5e-5).strain(3.0, -7.0)).abs() < 1e-18
        );
        // Strains add along a path and change sign with it.
        let (a, b, c) = (
            e.strain(2.0, -30.0),
            e.strain(-30.0, -45.0),
            e.strain(2.0, -45.0),
        );
        assert!((a + b - c).abs() < 1e-17);
        assert_eq!(e.strain(-45.0, 2.0), -c);
    }

    #[test]
    fn ice_present_at_the_start_is_stress_free_at_its_initial_temperature() {
        let t = ThermalStrain::new(
            Expansion::Constant(5e-5),
            &[1.0, 0.0, 0.5],
            &[-18.0, 5.0, -0.05],
            0.0,
        );
        assert_eq!(t.reference, vec![-18.0, 0.0, -0.05]);
        assert_eq!(t.strain(0, -18.0), 0.0);
        assert!((t.strain(1, -10.0) + 5e-4).abs() < 1e-18);
        assert_eq!(t.inherit(&[1, 1, 0]).reference, vec![0.0, 0.0, -18.0]);
    }
}
