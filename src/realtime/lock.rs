//! Phase lock of the output schedule to external edges (a PPS): the schedule that maps the
//! frames' nominal instants to the wall clock, and a proportional–integral loop that slews its
//! rate so that the whole seconds of the run fall on the edges. Pure arithmetic: the edges come
//! from [`super::pps`], the pacer applies the schedule.
//!
//! The loop is the usual second-order one of software PLLs (as in NTP's clock discipline, RFC
//! 5905 §11.3): at each edge the phase error φ (our whole second minus the edge) first updates
//! the integral I += Ki·φ, which learns the frequency offset, then gives the rate correction
//! u = (Kp·φ + I)/P over the next period P. Per edge the error then follows
//! φₙ₊₁ = (1 − Kp − Ki)·φₙ − Iₙ + d (d: the frequency offset × P), Iₙ₊₁ = Iₙ + Ki·φₙ, whose
//! characteristic polynomial is λ² − (2 − Kp − Ki)·λ + (1 − Kp). Kp = 0.84 and Ki = 0.36 put
//! a double root at 0.4 (critical damping): an error decays as (1 + n)·0.4ⁿ, so 3 ms falls to
//! about 5 µs in 10 edges.
//! Only the rate changes, continuously, so no frame is skipped or sent twice.

/// Proportional gain per edge.
pub const KP: f64 = 0.84;
/// Integral gain per edge.
pub const KI: f64 = 0.36;
/// Largest rate correction (fraction): 1 %, so a link sized for the nominal rate keeps up.
pub const MAX_SLEW: f64 = 0.01;

/// Maps a frame's nominal instant (ns after the start, at the run's speed) to the
/// CLOCK_MONOTONIC instant it is due: `start + n` until a lock changes the rate, then a
/// line through an anchor point, continuous at every change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schedule {
    anchor_wall: i128,
    anchor_nominal: i128,
    /// Wall-clock ns per nominal ns.
    rate: f64,
}

impl Schedule {
    /// The nominal schedule from `start`.
    pub fn new(start: i128) -> Schedule {
        Schedule {
            anchor_wall: start,
            anchor_nominal: 0,
            rate: 1.0,
        }
    }

    /// The wall-clock instant of nominal offset `n`.
    pub fn at(&self, n: i128) -> i128 {
        let d = n - self.anchor_nominal;
        if self.rate == 1.0 {
            // Integer arithmetic: nothing accumulates over a long unlocked run.
            self.anchor_wall + d
        } else {
            self.anchor_wall + (d as f64 * self.rate).round() as i128
        }
    }

    /// The nominal offset due at wall-clock instant `wall` (inverse of [`Schedule::at`]).
    pub fn nominal(&self, wall: i128) -> i128 {
        self.anchor_nominal + ((wall - self.anchor_wall) as f64 / self.rate).round() as i128
    }

    /// Changes the rate from wall-clock instant `now` on, keeping the schedule continuous.
    pub fn set_rate(&mut self, now: i128, rate: f64) {
        let n = self.nominal(now);
        self.anchor_wall = self.at(n);
        self.anchor_nominal = n;
        self.rate = rate;
    }

    /// Wall-clock ns per nominal ns.
    pub fn rate(&self) -> f64 {
        self.rate
    }
}

/// What the lock reports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LockState {
    /// Edges used so far.
    pub edges: u64,
    /// Phase error at the last edge (ns): the run's whole second minus the edge; + late.
    pub phase_error_ns: f64,
    /// Frequency of the edges against the host clock, as the integral learned it (ppm);
    /// + the edges come faster than the host's seconds.
    pub freq_offset_ppm: f64,
}

/// The proportional–integral phase lock.
#[derive(Clone, Debug)]
pub struct PhaseLock {
    /// Nominal ns between edges (1 s at speed 1).
    period_ns: i128,
    integral_ns: f64,
    /// What the lock reports.
    pub state: LockState,
}

impl PhaseLock {
    /// A lock to edges every `period_ns` nominal ns, which fall on multiples of it.
    pub fn new(period_ns: i128) -> PhaseLock {
        PhaseLock {
            period_ns,
            integral_ns: 0.0,
            state: LockState::default(),
        }
    }

    /// An edge at wall-clock instant `edge`, seen at `now`: measures the phase error against
    /// `sched` and slews its rate from `now` on.
    pub fn edge(&mut self, sched: &mut Schedule, edge: i128, now: i128) {
        let n = sched.nominal(edge);
        let second = (n as f64 / self.period_ns as f64).round() as i128 * self.period_ns;
        let phi = (sched.at(second) - edge) as f64;
        self.integral_ns += KI * phi;
        let p = self.period_ns as f64;
        let u = ((KP * phi + self.integral_ns) / p).clamp(-MAX_SLEW, MAX_SLEW);
        sched.set_rate(now, 1.0 - u);
        self.state = LockState {
            edges: self.state.edges + 1,
            phase_error_ns: phi,
            freq_offset_ppm: self.integral_ns / p * 1e6,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unlocked schedule is start + n exactly; a rate change keeps it continuous and
    /// scales what follows.
    #[test]
    fn schedule_is_continuous() {
        let mut s = Schedule::new(1_000);
        assert_eq!(s.at(5_000_000_000_123), 5_000_000_001_123);
        s.set_rate(1_000 + 2_000_000_000, 0.999);
        assert_eq!(s.at(2_000_000_000), 1_000 + 2_000_000_000);
        // One second later in nominal time is 0.999 s later on the wall.
        assert_eq!(s.at(3_000_000_000), 1_000 + 2_000_000_000 + 999_000_000);
        assert_eq!(
            s.nominal(1_000 + 2_000_000_000 + 999_000_000),
            3_000_000_000
        );
    }

    /// One edge 3 ms before our whole second: φ = +3 ms exactly, and the rate is 1 − (Kp + Ki)·φ/P.
    #[test]
    fn first_edge_closed_form() {
        let start = 10_000_000_000;
        let mut s = Schedule::new(start);
        let mut l = PhaseLock::new(1_000_000_000);
        let edge = start + 1_000_000_000 - 3_000_000;
        l.edge(&mut s, edge, edge);
        assert_eq!(l.state.phase_error_ns, 3e6);
        let expect = 1.0 - (KP + KI) * 3e6 / 1e9;
        assert!((s.rate() - expect).abs() < 1e-15, "{}", s.rate());
        assert!((l.state.freq_offset_ppm - KI * 3e6 / 1e9 * 1e6).abs() < 1e-9);
    }

    /// Edges from a reference 3 ms ahead of the start and 20 ppm fast: at the 11th edge the
    /// phase error is under 20 µs (11·0.4¹⁰·3 ms ≈ 3.5 µs by the loop's double root, plus the
    /// frequency step's share, 4 µs in a simulation of the recurrence), and after 60 the
    /// learned frequency is 20 ppm to 0.01 ppm and the phase error under 1 ns. A loop with the
    /// sign of φ reversed diverges instead; Kp = 0.6, Ki = 0.1 (roots 0.8 and 0.5) leaves
    /// 0.2 ms at the 11th edge.
    #[test]
    fn pulls_in_phase_and_frequency() {
        let start = 0i128;
        let mut s = Schedule::new(start);
        let mut l = PhaseLock::new(1_000_000_000);
        let y = 20e-6;
        let mut errs = Vec::new();
        for k in 1..=60i128 {
            let edge = start - 3_000_000 + (k as f64 * 1e9 * (1.0 - y)).round() as i128;
            l.edge(&mut s, edge, edge + 200_000);
            errs.push(l.state.phase_error_ns);
        }
        assert!(errs[0] > 2.9e6, "{}", errs[0]);
        assert!(errs[10].abs() < 2e4, "{errs:?}");
        assert!(errs[59].abs() < 1.0, "{}", errs[59]);
        assert!(
            (l.state.freq_offset_ppm - 20.0).abs() < 0.01,
            "{}",
            l.state.freq_offset_ppm
        );
    }
}
