//! Time functions: a dimensionless factor of time, piecewise linear between given points,
//! that scales a load, a prescribed displacement or gravity.

/// A piecewise-linear function of time a(t) (dimensionless) through points (tᵢ, aᵢ) with
/// non-decreasing times; constant before the first point and after the last. Two points at
/// the same time make a jump, and a(t) at that time is the later value (so a traction
/// "switched off at 0.5 s" is off in the step that ends at 0.5 s). With no points a(t) = 1.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Amplitude {
    points: Vec<(f64, f64)>,
}

impl Amplitude {
    /// The function through `points` (s, dimensionless); an error says what is wrong with
    /// them: times must be finite and non-decreasing, at most two points share a time, and
    /// values must be finite.
    pub fn new(points: Vec<(f64, f64)>) -> Result<Self, String> {
        if points.is_empty() {
            return Err("needs at least one [time, value] point".into());
        }
        for (k, &(t, a)) in points.iter().enumerate() {
            if !t.is_finite() || !a.is_finite() {
                return Err(format!("point {k} [{t}, {a}] is not finite"));
            }
            if k > 0 && t < points[k - 1].0 {
                return Err(format!(
                    "times must not decrease: point {k} at {t} s comes after {} s",
                    points[k - 1].0
                ));
            }
            if k > 1 && t == points[k - 2].0 {
                return Err(format!(
                    "three points at {t} s; a jump takes two (before and after)"
                ));
            }
        }
        Ok(Amplitude { points })
    }

    /// Whether a(t) = 1 at all times (no points given).
    pub fn is_one(&self) -> bool {
        self.points.is_empty()
    }

    /// a(t) at time `t` (s).
    pub fn at(&self, t: f64) -> f64 {
        let Some(&(first_t, first_a)) = self.points.first() else {
            return 1.0;
        };
        // The last point at or before t: at a jump the later of its two values.
        let after = self.points.partition_point(|&(ti, _)| ti <= t);
        if after == 0 {
            return first_a;
        }
        let (t0, a0) = self.points[after - 1];
        match self.points.get(after) {
            None => a0,
            Some(&(t1, a1)) => {
                debug_assert!(t1 > t0 && t >= first_t);
                a0 + (a1 - a0) * (t - t0) / (t1 - t0)
            }
        }
    }

    /// The largest |a(t)| over all times.
    pub fn max_abs(&self) -> f64 {
        if self.points.is_empty() {
            return 1.0;
        }
        self.points.iter().fold(0.0, |m, &(_, a)| m.max(a.abs()))
    }

    /// ∫₀ᵗ a(s) ds (s): exact for the piecewise-linear a (t may be negative: −∫ₜ⁰).
    pub fn integral(&self, t: f64) -> f64 {
        if self.points.is_empty() {
            return t;
        }
        self.antiderivative(t) - self.antiderivative(0.0)
    }

    /// An antiderivative of a: zero at the first point's time.
    fn antiderivative(&self, t: f64) -> f64 {
        let (t0, a0) = self.points[0];
        if t <= t0 {
            return a0 * (t - t0);
        }
        let mut sum = 0.0;
        for w in self.points.windows(2) {
            let ((ta, aa), (tb, ab)) = (w[0], w[1]);
            if tb == ta {
                continue;
            }
            if t <= tb {
                let at = aa + (ab - aa) * (t - ta) / (tb - ta);
                return sum + 0.5 * (aa + at) * (t - ta);
            }
            sum += 0.5 * (aa + ab) * (tb - ta);
        }
        let &(tn, an) = self.points.last().unwrap_or(&(t0, a0));
        sum + an * (t - tn)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_holds_its_ends_and_jumps_to_the_later_value() {
        let a = Amplitude::new(vec![(0.0, 0.0), (1.0, 2.0), (2.0, 2.0), (2.0, 0.0)]).unwrap();
        assert_eq!(a.at(-1.0), 0.0);
        assert_eq!(a.at(0.25), 0.5);
        assert_eq!(a.at(1.0), 2.0);
        assert_eq!(a.at(1.999), 2.0);
        assert_eq!(a.at(2.0), 0.0);
        assert_eq!(a.at(7.0), 0.0);
        assert_eq!(Amplitude::default().at(3.0), 1.0);
        assert_eq!(Amplitude::new(vec![(1.0, 0.3)]).unwrap().at(0.0), 0.3);
    }

    #[test]
    fn integrals_are_exact_for_the_piecewise_linear_function() {
        let a = Amplitude::new(vec![(1.0, 0.0), (2.0, 2.0), (3.0, 2.0), (3.0, -1.0)]).unwrap();
        // 0 until 1 s (a = 0), a triangle of area 1 to 2 s, 2 from 2 s to 3 s, then −1.
        assert_eq!(a.integral(1.0), 0.0);
        assert_eq!(a.integral(1.5), 0.25);
        assert_eq!(a.integral(2.0), 1.0);
        assert_eq!(a.integral(3.0), 3.0);
        assert_eq!(a.integral(5.0), 1.0);
        assert_eq!(Amplitude::default().integral(2.5), 2.5);
        let b = Amplitude::new(vec![(0.5, 3.0)]).unwrap();
        assert_eq!(b.integral(2.0), 6.0);
        assert_eq!(b.integral(-1.0), -3.0);
    }

    #[test]
    fn bad_tables_say_what_is_wrong() {
        let err = |p: Vec<(f64, f64)>| Amplitude::new(p).unwrap_err();
        assert!(err(vec![]).contains("at least one"));
        assert!(err(vec![(0.0, 1.0), (-1.0, 1.0)]).contains("must not decrease"));
        assert!(err(vec![(0.0, 1.0), (0.0, 2.0), (0.0, 3.0)]).contains("three points"));
        assert!(err(vec![(0.0, f64::NAN)]).contains("not finite"));
    }
}
