//! How long a run has left, from the pace at which it has recently advanced simulated time.
//!
//! A freezing or cracking run slows down as it goes (the shell stiffens, contacts close,
//! splits re-solve steps), so the average pace since the start promises too little time: a
//! run measured at step 402 with "< 2 s" left took 76 s more. The estimate here divides the
//! simulated time left by the pace over a trailing window — the last quarter of the wall time
//! so far, and at least the last 5 s — so it follows the run's current cost.

use std::collections::VecDeque;

/// Trailing-window estimate of the wall time left in a run.
#[derive(Clone, Debug, Default)]
pub struct Eta {
    /// (wall time since the start, simulated time reached), oldest first (s).
    samples: VecDeque<(f64, f64)>,
}

/// The shortest window the pace is measured over (s of wall time).
const MIN_WINDOW: f64 = 5.0;
/// The window's share of the wall time so far.
const WINDOW_SHARE: f64 = 0.25;

impl Eta {
    /// An estimate with no samples yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records that simulated time `time` (s) was reached `wall` seconds after the start, and
    /// returns the estimated wall seconds left to reach `end` (s of simulated time): `None`
    /// until the window holds two samples with simulated time between them.
    pub fn update(&mut self, wall: f64, time: f64, end: f64) -> Option<f64> {
        self.samples.push_back((wall, time));
        let window = (WINDOW_SHARE * wall).max(MIN_WINDOW);
        // Keep the newest sample older than the window, so the window is always covered.
        while self.samples.len() > 2 && self.samples[1].0 <= wall - window {
            self.samples.pop_front();
        }
        let (&(w0, t0), &(w1, t1)) = (self.samples.front()?, self.samples.back()?);
        let pace = (t1 - t0) / (w1 - w0);
        (pace > 0.0 && pace.is_finite()).then(|| (end - t1).max(0.0) / pace)
    }
}

/// Seconds as `1h02m`, `3m05s` or `42s`.
pub fn format_duration(seconds: f64) -> String {
    let s = seconds.max(0.0).round() as u64;
    match (s / 3600, s % 3600 / 60, s % 60) {
        (0, 0, sec) => format!("{sec}s"),
        (0, min, sec) => format!("{min}m{sec:02}s"),
        (h, min, _) => format!("{h}h{min:02}m"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_estimate_follows_a_run_that_slows_down() {
        // 100 s of wall time at 1 s of simulated time per second, then 10× slower.
        let mut eta = Eta::new();
        let end = 1000.0;
        let mut left = None;
        for w in 1..=100 {
            left = eta.update(w as f64, w as f64, end);
        }
        // At the steady pace: 900 s of simulated time left at 1 per second.
        assert!((left.unwrap() - 900.0).abs() < 1e-9);
        for w in 101..=200 {
            left = eta.update(w as f64, 100.0 + 0.1 * (w - 100) as f64, end);
        }
        // The window is the last 50 s, all at the new pace: 890 s left at 0.1 per second.
        assert!((left.unwrap() - 8900.0).abs() < 1e-6, "{left:?}");
        assert_eq!(Eta::new().update(1.0, 0.5, end), None, "one sample");
    }

    #[test]
    fn durations_read_at_a_glance() {
        assert_eq!(format_duration(42.4), "42s");
        assert_eq!(format_duration(185.0), "3m05s");
        assert_eq!(format_duration(3720.0), "1h02m");
    }
}
