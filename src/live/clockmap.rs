//! The map from simulation time to the host's monotonic clock, estimated from when states
//! arrive.
//!
//! A state's arrival is its send instant plus a delay that is never below the path's
//! minimum and often above it (scheduling, queues, network). The minimum is the stable part:
//! the map's offset tracks the lower envelope of (arrival − time tag) over a sliding window
//! — the minimum-delay filter NTP applies to its samples (RFC 5905 §10) — and moves toward a
//! new minimum at a bounded slew rate, so a drifting sender clock (tens of ppm) is followed
//! while one early or late datagram moves nothing. The spread above the minimum over the
//! window is the jitter; with the time-tag spacing it sets the default output delay.

use std::collections::VecDeque;

/// Window of states the envelope and the jitter are taken over (s of simulation time).
pub const WINDOW_S: f64 = 2.0;

/// Largest rate at which the offset follows the envelope (s per s): 500 ppm, above a
/// crystal's error, far below what would move emission instants visibly within a record.
pub const SLEW: f64 = 500e-6;

/// The map host_ns = offset + t·10⁹ and the input's measured period and jitter.
#[derive(Clone, Debug, Default)]
pub struct ClockMap {
    /// Host ns minus simulation ns at the map's current setting.
    offset: Option<f64>,
    /// Simulation time of the last update (s).
    last_t: f64,
    /// Simulation time of the first state (s).
    first_t: f64,
    /// (time tag s, arrival − time tag ns) of the window's states.
    window: VecDeque<(f64, f64)>,
}

impl ClockMap {
    /// An empty map.
    pub fn new() -> ClockMap {
        ClockMap::default()
    }

    /// Takes a state with time tag `t` (s) that arrived at host instant `arrival_ns`.
    pub fn observe(&mut self, t: f64, arrival_ns: i128) {
        let d = arrival_ns as f64 - t * 1e9;
        self.window.push_back((t, d));
        while self.window.front().is_some_and(|w| w.0 < t - WINDOW_S) {
            self.window.pop_front();
        }
        let floor = self
            .window
            .iter()
            .map(|w| w.1)
            .fold(f64::INFINITY, f64::min);
        match self.offset {
            None => {
                self.offset = Some(floor);
                self.first_t = t;
            }
            // Over the first window the envelope is still forming: take it as it is.
            Some(_) if t < self.first_t + WINDOW_S => self.offset = Some(floor),
            Some(o) => {
                let step = SLEW * (t - self.last_t).max(0.0) * 1e9;
                self.offset = Some(o + (floor - o).clamp(-step, step));
            }
        }
        self.last_t = self.last_t.max(t);
    }

    /// True once a state has been seen.
    pub fn ready(&self) -> bool {
        self.offset.is_some()
    }

    /// Host instant (ns) that simulation time `t` maps to.
    pub fn host_ns(&self, t: f64) -> i128 {
        (self.offset.unwrap_or(f64::NAN) + t * 1e9).round() as i128
    }

    /// Median spacing of the window's time tags (s); NaN with fewer than two.
    pub fn period(&self) -> f64 {
        let mut d: Vec<f64> = (self.window.iter().zip(self.window.iter().skip(1)))
            .map(|(a, b)| b.0 - a.0)
            .collect();
        if d.is_empty() {
            return f64::NAN;
        }
        d.sort_by(f64::total_cmp);
        d[d.len() / 2]
    }

    /// Spread of the arrival delays above their minimum over the window (s).
    pub fn jitter(&self) -> f64 {
        let (lo, hi) = self
            .window
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, w| {
                (a.0.min(w.1), a.1.max(w.1))
            });
        if lo.is_finite() { (hi - lo) / 1e9 } else { 0.0 }
    }

    /// States in the window per second of simulation time.
    pub fn rate(&self) -> f64 {
        match (self.window.front(), self.window.back()) {
            (Some(a), Some(b)) if b.0 > a.0 => (self.window.len() - 1) as f64 / (b.0 - a.0),
            _ => f64::NAN,
        }
    }

    /// The output delay a run defaults to: a state must be in before the records it
    /// completes are due, so the delay covers one input period, the jitter seen, and `margin`
    /// for the emitter's own scheduling (s).
    pub fn default_delay(&self, margin: f64) -> f64 {
        let p = self.period();
        (if p.is_finite() { p } else { 0.0 }) + self.jitter() + margin
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A constant path delay of 3 ms plus jitter of up to 4 ms on some states: the offset is
    /// the minimum (3 ms), the jitter the spread, the period the tag spacing.
    #[test]
    fn lower_envelope_ignores_late_arrivals() {
        let mut m = ClockMap::new();
        let t_host0 = 5_000_000_000i128;
        for i in 0..200 {
            let t = 10.0 + i as f64 * 0.01;
            let extra = if i % 3 == 0 {
                4_000_000
            } else {
                (i % 7) * 100_000
            };
            m.observe(t, t_host0 + (t * 1e9) as i128 + 3_000_000 + extra as i128);
        }
        assert_eq!(m.host_ns(10.0), t_host0 + 10_000_000_000 + 3_000_000);
        assert!((m.jitter() - 0.004).abs() < 1e-9, "{}", m.jitter());
        assert!((m.period() - 0.01).abs() < 1e-12);
        assert!((m.rate() - 100.0).abs() < 1e-6);
        assert!((m.default_delay(0.001) - 0.015).abs() < 1e-9);
    }

    /// Once the first window is past, a step in the path delay is followed at the slew rate,
    /// not at once; a sender clock 100 ppm fast is followed.
    #[test]
    fn follows_drift_at_bounded_slew() {
        let mut m = ClockMap::new();
        for i in 0..300 {
            let t = i as f64 * 0.01;
            m.observe(t, (t * 1e9).round() as i128 + 1_000_000);
        }
        assert_eq!(m.host_ns(0.0), 1_000_000);
        // The path gets 1 ms faster: one step of 10 ms moves the offset by 5 µs only.
        m.observe(3.0, 3_000_000_000);
        assert_eq!(m.host_ns(0.0), 1_000_000 - 5_000);
        let mut m = ClockMap::new();
        for i in 0..1000 {
            let t = i as f64 * 0.01;
            m.observe(t, (t * 1e9 * (1.0 - 100e-6)) as i128);
        }
        // After 10 s the true offset is −1 ms; the envelope lags by up to one window's drift.
        let err = (m.host_ns(10.0) - (10e9 * (1.0 - 100e-6)) as i128).abs();
        assert!(err < 250_000, "{err} ns");
    }
}
