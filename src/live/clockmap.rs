//! The map from simulation time to the host's monotonic clock, estimated from when states
//! arrive, or given.
//!
//! A state's arrival is its send instant plus a delay that is never below the path's
//! minimum and often above it (scheduling, queues, network). The minimum is the stable part:
//! the map follows the lower envelope of (arrival − time tag) — the minimum-delay filter NTP
//! applies to its samples (RFC 5905 §10) — in two parts:
//!
//! * **rate**: the sender's clock may run fast or slow against the host's (a crystal's tens
//!   of ppm); the slope of the envelope is fitted by least squares through the minimum delay
//!   of each [`BIN_S`] of states over the last [`RATE_SPAN_S`], a bin whose minimum lies far
//!   above the fit (a stall that delayed all its states) dropped and the fit repeated;
//! * **offset**: the minimum over the last [`WINDOW_S`] of the delays brought to the newest
//!   state along that slope, taken as it is over the first window, then approached at a
//!   bounded slew rate, so one early or late datagram moves nothing.
//!
//! **Re-lock.** A sender that pauses and resumes with continuous time tags (a simulation
//! stopped in a debugger, a suspended process) steps the delay up by the pause, and the slew
//! would take hours to follow it. When every state for [`RELOCK_AFTER_S`] of host time arrives
//! more than [`RELOCK_STEP_S`] later than the map says, the map is estimated afresh from those
//! states (the offset taken as it is, the rate fit restarted, the rate fitted before the step
//! kept meanwhile). A stall that the sender catches up with a burst (tags on schedule) does not
//! re-lock: the burst's states come in at once and the next ones on time.
//!
//! The spread above the envelope over the window is the jitter; with the time-tag spacing it
//! sets the default output delay. When sender and host share a time scale (both GPS time),
//! the map is given instead ([`ClockMap::given`]) and only the input's figures are measured.
//!
//! Tags are taken relative to the first one, and arrivals relative to the first arrival, so a
//! GPS-seconds tag (≈ 1.4e9 s) keeps the resolution of its own double in the map.

use std::collections::VecDeque;

/// Window of states the offset and the jitter are taken over (s of simulation time).
pub const WINDOW_S: f64 = 2.0;

/// Largest rate at which the offset follows the envelope (s per s): 500 ppm, above a
/// crystal's error, far below what would move emission instants visibly within a record.
pub const SLEW: f64 = 500e-6;

/// Length of the bins whose minimum delays the rate is fitted through (s of simulation time).
pub const BIN_S: f64 = 0.5;

/// Span of bins the rate is fitted over (s of simulation time).
pub const RATE_SPAN_S: f64 = 30.0;

/// Completed bins before the rate is fitted (a shorter span fits the jitter, not the clock).
pub const RATE_MIN_BINS: usize = 8;

/// Largest clock rate difference the fit may report (s per s): beyond a crystal's error,
/// what the fit sees is the path changing, which the offset's slew follows instead.
pub const MAX_RATE: f64 = 1e-3;

/// A state later than the map by more than this (s) starts or continues a streak of late
/// states: far above any jitter the default output delay absorbs.
pub const RELOCK_STEP_S: f64 = 0.1;

/// Host time (s) a streak of late states must last before the map is estimated afresh: long
/// enough that a burst after a stall (its states arriving at once) is never one.
pub const RELOCK_AFTER_S: f64 = 0.2;

/// States of a streak kept for the new estimate (the last ones).
const STREAK_KEEP: usize = 4096;

/// A map fixed by the caller: host_ns = host0 + (t − t0)·10⁹·(1 + rate).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GivenMap {
    /// A simulation time (s).
    pub t0: f64,
    /// The host instant it falls on (CLOCK_MONOTONIC ns).
    pub host0_ns: i128,
    /// Host seconds per simulation second, minus 1.
    pub rate: f64,
}

/// The map host_ns(t) and the input's measured period and jitter.
#[derive(Clone, Debug, Default)]
pub struct ClockMap {
    /// First time tag (s) and first arrival (ns): the origins of τ and of the delays.
    origin: Option<(f64, i128)>,
    /// The map given by the caller, if any.
    given: Option<GivenMap>,
    /// Delay (ns, against the origins) the map has at τ = `last_tau`.
    offset: f64,
    /// Fitted clock rate: ns of delay per ns of simulation time.
    drift: f64,
    /// Newest τ seen (s).
    last_tau: f64,
    /// (τ s, delay ns) of the window's states.
    window: VecDeque<(f64, f64)>,
    /// (bin index, τ s, delay ns) of each bin's least-delayed state; the last is filling.
    bins: VecDeque<(i64, f64, f64)>,
    /// The current streak of late states: (τ s, delay ns) of each, the first one's arrival
    /// (ns) and the rate fitted before it.
    streak: VecDeque<(f64, f64)>,
    streak_since: i128,
    streak_drift: f64,
    /// τ (s) at which the map was last estimated afresh (the first window runs from it).
    since_tau: f64,
    /// How many times the map was estimated afresh after a step.
    relocks: u64,
}

impl ClockMap {
    /// An empty map, estimated from the states it observes.
    pub fn new() -> ClockMap {
        ClockMap::default()
    }

    /// A map fixed to `given`; states observed only measure the input's period and jitter.
    pub fn given(given: GivenMap) -> ClockMap {
        ClockMap {
            given: Some(given),
            ..ClockMap::default()
        }
    }

    /// Takes a state with time tag `t` (s) that arrived at host instant `arrival_ns`.
    pub fn observe(&mut self, t: f64, arrival_ns: i128) {
        let (t0, a0) = *self.origin.get_or_insert((t, arrival_ns));
        let first = self.window.is_empty() && self.bins.is_empty();
        let tau = t - t0;
        let d = (arrival_ns - a0) as f64 - tau * 1e9;
        if self.given.is_none() && !first && self.late(tau, d, arrival_ns) {
            return;
        }
        self.window.push_back((tau, d));
        while self.window.front().is_some_and(|w| w.0 < tau - WINDOW_S) {
            self.window.pop_front();
        }
        self.bin(tau, d);
        let floor = self
            .window
            .iter()
            .map(|w| w.1 + self.drift * (tau - w.0) * 1e9)
            .fold(f64::INFINITY, f64::min);
        if first || tau < self.since_tau + WINDOW_S {
            // Over the first window the envelope is still forming: take it as it is.
            self.offset = floor;
        } else if tau > self.last_tau {
            let step = (tau - self.last_tau) * 1e9;
            let predicted = self.offset + self.drift * step;
            self.offset = predicted + (floor - predicted).clamp(-SLEW * step, SLEW * step);
        }
        self.last_tau = self.last_tau.max(tau);
    }

    /// Follows the streak of states later than the map by more than [`RELOCK_STEP_S`]; once it
    /// has lasted [`RELOCK_AFTER_S`] of host time, estimates the map afresh from its states and
    /// returns true (the state is taken).
    fn late(&mut self, tau: f64, d: f64, arrival_ns: i128) -> bool {
        let map_d = self.offset + self.drift * (tau - self.last_tau) * 1e9;
        if d - map_d <= RELOCK_STEP_S * 1e9 {
            self.streak.clear();
            return false;
        }
        if self.streak.is_empty() {
            self.streak_since = arrival_ns;
            self.streak_drift = self.drift;
        }
        self.streak.push_back((tau, d));
        if self.streak.len() > STREAK_KEEP {
            self.streak.pop_front();
        }
        if ((arrival_ns - self.streak_since) as f64) < RELOCK_AFTER_S * 1e9 {
            return false;
        }
        // A step, not a stall: start over from the streak, keeping the rate fitted before it.
        self.drift = self.streak_drift;
        self.window = std::mem::take(&mut self.streak);
        self.bins.clear();
        for &(tau, d) in self.window.clone().iter() {
            self.bin(tau, d);
        }
        self.offset = self
            .window
            .iter()
            .map(|w| w.1 + self.drift * (tau - w.0) * 1e9)
            .fold(f64::INFINITY, f64::min);
        self.last_tau = self.last_tau.max(tau);
        self.since_tau = self.window.front().map_or(tau, |w| w.0);
        self.relocks += 1;
        true
    }

    /// How many times a step in the delay made the map be estimated afresh.
    pub fn relocks(&self) -> u64 {
        self.relocks
    }

    /// Files (τ, d) in its bin; when a bin completes, refits the rate.
    fn bin(&mut self, tau: f64, d: f64) {
        let i = (tau / BIN_S).floor() as i64;
        match self.bins.back_mut() {
            Some(b) if b.0 == i => {
                if d < b.2 {
                    *b = (i, tau, d);
                }
                return;
            }
            // A reordered state of an earlier bin: its bin has been fitted already.
            Some(b) if b.0 > i => return,
            _ => self.bins.push_back((i, tau, d)),
        }
        while self
            .bins
            .front()
            .is_some_and(|b| b.1 < tau - RATE_SPAN_S - BIN_S)
        {
            self.bins.pop_front();
        }
        let done = self.bins.len() - 1;
        if done >= RATE_MIN_BINS {
            let pts: Vec<(f64, f64)> = self.bins.iter().take(done).map(|b| (b.1, b.2)).collect();
            self.drift = robust_slope(&pts).clamp(-MAX_RATE, MAX_RATE);
        }
    }

    /// True once a state has been seen (always, for a given map).
    pub fn ready(&self) -> bool {
        self.given.is_some() || self.origin.is_some()
    }

    /// Host instant (ns) that simulation time `t` maps to; 0 before any state.
    pub fn host_ns(&self, t: f64) -> i128 {
        if let Some(g) = self.given {
            let dt = t - g.t0;
            return g.host0_ns + (dt * 1e9 * (1.0 + g.rate)).round() as i128;
        }
        let Some((t0, a0)) = self.origin else {
            return 0;
        };
        let tau = t - t0;
        let d = self.offset + self.drift * (tau - self.last_tau) * 1e9;
        a0 + (d + tau * 1e9).round() as i128
    }

    /// The simulation time that host instant `host_ns` maps to: the inverse of
    /// [`ClockMap::host_ns`]; 0 before any state.
    pub fn sim_at(&self, host_ns: i128) -> f64 {
        if let Some(g) = self.given {
            return g.t0 + (host_ns - g.host0_ns) as f64 / (1e9 * (1.0 + g.rate));
        }
        let Some((t0, a0)) = self.origin else {
            return 0.0;
        };
        // host − a0 = offset + drift·(τ − τ_last)·10⁹ + τ·10⁹, solved for τ.
        let x = (host_ns - a0) as f64 - self.offset + self.drift * self.last_tau * 1e9;
        t0 + x / (1e9 * (1.0 + self.drift))
    }

    /// The sender's clock against the host's: host seconds per simulation second, minus 1
    /// (fitted, or given); negative for a sender clock running fast.
    pub fn clock_rate(&self) -> f64 {
        self.given.map_or(self.drift, |g| g.rate)
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

    /// (least, largest) arrival over the window relative to the map's instant for each
    /// state's tag (ns).
    fn lateness(&self) -> (f64, f64) {
        let Some((t0, a0)) = self.origin else {
            return (0.0, 0.0);
        };
        self.window
            .iter()
            .map(|&(tau, d)| {
                let arrival = a0 as f64 + d + tau * 1e9;
                arrival - self.host_ns(t0 + tau) as f64
            })
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, x| {
                (a.0.min(x), a.1.max(x))
            })
    }

    /// Spread of the arrival delays above their envelope over the window (s).
    pub fn jitter(&self) -> f64 {
        let (lo, hi) = self.lateness();
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
    /// completes are due, so the delay covers one input period, the latest arrival seen
    /// against the map (the jitter, for an estimated map; the path's latency as well, for a
    /// given one), and `margin` for the emitter's own scheduling (s).
    pub fn default_delay(&self, margin: f64) -> f64 {
        let p = self.period();
        let (lo, hi) = self.lateness();
        let late = if lo.is_finite() {
            hi.max(0.0) / 1e9
        } else {
            0.0
        };
        (if p.is_finite() { p } else { 0.0 }) + late + margin
    }
}

/// Least-squares slope of `pts`, refitted without the points that lie more than four robust
/// standard deviations (1.4826 × the median absolute residual) above the first fit: the
/// envelope's outliers are late, never early.
fn robust_slope(pts: &[(f64, f64)]) -> f64 {
    let fit = |pts: &mut dyn Iterator<Item = (f64, f64)>| {
        let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (x, y) in pts {
            n += 1.0;
            sx += x;
            sy += y;
            sxx += x * x;
            sxy += x * y;
        }
        let den = n * sxx - sx * sx;
        if n < 2.0 || den <= 0.0 {
            return (0.0, 0.0);
        }
        let b = (n * sxy - sx * sy) / den;
        (b, (sy - b * sx) / n)
    };
    let (b, a) = fit(&mut pts.iter().copied());
    let mut res: Vec<f64> = pts.iter().map(|&(x, y)| (y - a - b * x).abs()).collect();
    res.sort_by(f64::total_cmp);
    let cut = 4.0 * 1.4826 * res[res.len() / 2];
    let (b2, _) = fit(&mut pts.iter().copied().filter(|&(x, y)| y - a - b * x <= cut));
    // x is in s and y in ns: the slope in ns per s, i.e. 1e9 × the dimensionless rate.
    b2 / 1e9
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::splitmix64;

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
    /// not at once; a sender clock 100 ppm fast without jitter is followed exactly.
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
        let host = |t: f64| (t * 1e9 / (1.0 + 100e-6)).round() as i128;
        for i in 0..1000 {
            let t = i as f64 * 0.01;
            m.observe(t, host(t));
        }
        // Only the arrivals' whole-ns rounding is left.
        assert!((m.clock_rate() - (1.0 / (1.0 + 100e-6) - 1.0)).abs() < 1e-11);
        assert!((m.host_ns(10.6) - host(10.6)).abs() <= 2);
    }

    /// A sender clock 100 ppm fast (its tags advance 1.0001 s per host second), 40 s of
    /// states at 100 Hz, each delayed by 3 ± 3 ms (uniform, fixed seed).
    ///
    /// Rate: each 0.5 s bin's minimum over its 50 delays lies above the true envelope by the
    /// minimum of 50 uniforms on [0, 6 ms]: mean 6/51 ms = 118 µs, standard deviation
    /// 6 ms·√(50/(51²·52)) = 115 µs. The least-squares slope through the 60 bins of the last
    /// 30 s (tags spread evenly: Σ(τ−τ̄)² = 60·30²/12 = 4500 s²) scatters by
    /// 115 µs/√4500 s² = 1.7e-6; the bound is 4σ, 7e-6. (Dropping the few late bins only
    /// narrows the scatter.) An offset-only map has no rate: it fails by 1e-4.
    ///
    /// Prediction: 0.6 s past the newest state, the map's step from the newest state is off by
    /// at most the rate bound × 0.6 s = 4.2 µs (+ 1 ns rounding); without the rate term it is
    /// off by 60 µs. The offset itself lies above the true envelope by the least of the
    /// window's 200 excesses (mean 6 ms/201 = 30 µs, an exponential tail: above 200 µs with
    /// probability e^(−200/30) ≈ 0.1 %), and below it by at most the rate bound over the 2 s
    /// window, 14 µs.
    #[test]
    fn recovers_a_100_ppm_sender_clock_through_jitter() {
        let fast = 100e-6;
        let truth = |t: f64| 7e9 + t * 1e9 / (1.0 + fast);
        let mut m = ClockMap::new();
        let mut seed = 20261202u64;
        let mut t = 0.0;
        for i in 0..4000 {
            t = i as f64 * 0.01;
            seed = splitmix64(seed);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
            m.observe(t, (truth(t) + 6e6 * u).round() as i128);
        }
        let rate = m.clock_rate();
        let want = 1.0 / (1.0 + fast) - 1.0;
        eprintln!("rate {rate:e}, want {want:e}");
        assert!((rate - want).abs() <= 7e-6, "rate {rate:e}, want {want:e}");
        let step = (m.host_ns(t + 0.6) - m.host_ns(t)) as f64;
        let true_step = truth(t + 0.6) - truth(t);
        let off = m.host_ns(t) as f64 - truth(t);
        eprintln!(
            "0.6 s step off by {} ns, offset by {off} ns",
            step - true_step
        );
        assert!(
            (step - true_step).abs() <= 4.2e3 + 1.0,
            "0.6 s step off by {} ns",
            step - true_step
        );
        assert!((-14e3..=200e3).contains(&off), "offset off by {off} ns");
    }

    /// A map given (GPS time on both sides) is used as it is, whatever the arrivals say; the
    /// default delay then covers the path's latency as well as the period and the jitter.
    #[test]
    fn a_given_map_is_not_estimated() {
        let t0 = 1_400_000_000.25;
        let mut m = ClockMap::given(GivenMap {
            t0,
            host0_ns: 1_000_000_000,
            rate: 0.0,
        });
        assert!(m.ready());
        for i in 0..100 {
            let t = t0 + i as f64 * 0.01;
            // Each state arrives 5 ms after its instant, 2 ms more every other one.
            let late = 5_000_000 + (i % 2) * 2_000_000;
            m.observe(t, 1_000_000_000 + i as i128 * 10_000_000 + late as i128);
        }
        // GPS-seconds tags keep their resolution (2.4e-7 s at 1.4e9 s) in the map.
        assert_eq!(m.host_ns(t0 + 0.5), 1_500_000_000);
        assert_eq!(m.clock_rate(), 0.0);
        assert!((m.jitter() - 0.002).abs() < 1e-6, "{}", m.jitter());
        assert!((m.default_delay(0.003) - 0.020).abs() < 1e-6);
    }

    /// `sim_at` inverts `host_ns` for an estimated map with a fitted drift and for a given
    /// one with a rate: t → host → t comes back within the ns rounding of host_ns (≤ 0.5 ns,
    /// so ≤ 5e-10 s plus the f64 ulp of t).
    #[test]
    fn sim_at_inverts_host_ns() {
        let mut m = ClockMap::new();
        // A sender 200 ppm slow against the host, arrivals 3 ms behind, 100 Hz for 60 s.
        for k in 0..6000 {
            let t = 1000.0 + k as f64 * 0.01;
            let arrival =
                5_000_000_000i128 + ((t - 1000.0) * 1e9 * (1.0 + 2e-4)) as i128 + 3_000_000;
            m.observe(t, arrival);
        }
        assert!(
            m.clock_rate() > 1e-4,
            "the drift was fitted: {}",
            m.clock_rate()
        );
        for t in [1000.0, 1012.345, 1059.99, 1075.5] {
            let back = m.sim_at(m.host_ns(t));
            assert!((back - t).abs() <= 6e-10, "{t}: {back}");
        }
        let g = ClockMap::given(GivenMap {
            t0: 3.0,
            host0_ns: 7_000_000_000,
            rate: -5e-5,
        });
        for t in [3.0, 4.25, 1e5] {
            let back = g.sim_at(g.host_ns(t));
            assert!((back - t).abs() <= 6e-10 + t * 1e-15, "{t}: {back}");
        }
        assert_eq!(ClockMap::new().sim_at(123), 0.0);
    }

    /// A sender at 100 Hz pauses 3 s at 5 s and resumes with continuous tags (its state of
    /// 5.01 s arrives 3 s late, and every one after it): within [`RELOCK_AFTER_S`] of host time
    /// plus one period the map puts the tags 3 s later, exactly (no jitter here), and keeps its
    /// rate. Without the re-lock the offset would have moved 500 ppm × 0.3 s = 150 µs.
    #[test]
    fn a_pause_with_continuous_tags_relocks() {
        let mut m = ClockMap::new();
        let delay = 2_000_000i128;
        let arrival = |t: f64, pause: i128| (t * 1e9).round() as i128 + delay + pause;
        for i in 0..=500 {
            let t = i as f64 * 0.01;
            m.observe(t, arrival(t, 0));
        }
        let pause = 3_000_000_000i128;
        let mut relocked_at = None;
        for i in 501..=1000 {
            let t = i as f64 * 0.01;
            m.observe(t, arrival(t, pause));
            if m.relocks() == 1 && relocked_at.is_none() {
                relocked_at = Some(t);
            }
        }
        assert_eq!(m.relocks(), 1);
        let at = relocked_at.unwrap();
        assert!(
            at <= 5.01 + RELOCK_AFTER_S + 0.01 + 1e-9,
            "re-locked at {at}"
        );
        assert_eq!(m.host_ns(10.5), arrival(10.5, pause));
        // The rate kept from before the step: zero but for the fit's round-off.
        assert!(m.clock_rate().abs() < 1e-12, "{}", m.clock_rate());
    }

    /// A sender that stalls 3 s and then sends the states it owes at once (tags on schedule,
    /// then on time again) does not re-lock: the map stays within [`RELOCK_STEP_S`] of where
    /// it was (the stall's late bins tilt the rate fit for a while: 4.5 ms at 10 s here), where
    /// a re-lock on the burst would have moved it by seconds.
    #[test]
    fn a_stall_caught_up_by_a_burst_does_not_relock() {
        let mut m = ClockMap::new();
        let delay = 2_000_000i128;
        for i in 0..=1000 {
            let t = i as f64 * 0.01;
            let mut a = (t * 1e9).round() as i128 + delay;
            if (5.0..8.0).contains(&t) {
                // Sent together at 8 s, 10 µs apart.
                a = 8_000_000_000 + delay + (i - 500) as i128 * 10_000;
            }
            m.observe(t, a);
        }
        assert_eq!(m.relocks(), 0);
        let off = m.host_ns(10.0) - (10_000_000_000 + delay);
        assert!((off.abs() as f64) < RELOCK_STEP_S * 1e9, "{off} ns");
    }
}
