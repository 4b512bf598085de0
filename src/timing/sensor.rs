//! The sensor's sample instants in true time, block by block.
//!
//! Sample k is taken when the sensor clock reads τ_k = k·Δt (Δt the nominal interval). The clock
//! reads τ(t) = t + y₀t + ½dt² + φ(t) at true time t after the run's start: y₀ the frequency
//! offset, d the drift, φ the phase its frequency random walk accumulates. With no random walk
//! the instant solves ½dt² + (1+y₀)t − τ = 0 in closed form, from the integer k:
//! t = 2τ/(A + S), A = 1 + y₀, S = √(A² + 2dτ), written below as τ plus a deviation computed
//! without cancellation. The random walk's phase is summed per sample to first order in the
//! frequency (its error is of order y·q√Δt·Δt, below 10⁻¹⁵ s per sample for any accepted
//! figure). Each triad's sample instant then moves by its own jitter, and the accelerometers'
//! by the skew; the interval of sample k runs from sample k−1's instant to sample k's, so
//! consecutive intervals share their bounds and nothing is integrated twice or skipped.

use super::TimingModel;
use crate::rng::{NormalStream, fnv1a64, splitmix64};
use crate::timing::ReadRatio;

/// The sensor's instants of one block of samples, relative to the run's t₀ (s).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TimedBlock {
    /// Gyro interval bounds: sample i of the block integrates over (gyro[i], gyro[i+1]].
    pub gyro: Vec<f64>,
    /// Accelerometer interval bounds, likewise.
    pub accel: Vec<f64>,
    /// Emission time of each sample's frame (its first byte).
    pub emit: Vec<f64>,
    /// Whether the sensor skipped each sample.
    pub missing: Vec<bool>,
    /// A unit with an output filter: the bounds of its internal samples' intervals (gyro,
    /// accelerometers), from the last sample the previous output read to the one the last
    /// output reads ([`crate::timing::ReadRatio`]); the bound of the internal sample
    /// output k reads is output k's (empty without a filter, or when the samples are nominal).
    pub internal: (Vec<f64>, Vec<f64>),
}

impl TimedBlock {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.emit.len()
    }

    /// True when the block holds no sample.
    pub fn is_empty(&self) -> bool {
        self.emit.is_empty()
    }

    /// Time of validity of sample i: the end of its gyro interval.
    pub fn tov(&self, i: usize) -> f64 {
        self.gyro[i + 1]
    }

    /// Time of validity of sample i's accelerometers.
    pub fn tov_accel(&self, i: usize) -> f64 {
        self.accel[i + 1]
    }
}

/// The timing of one IMU's samples over a run: its clock's phase and its random streams.
#[derive(Clone, Debug)]
pub struct SensorTiming {
    model: TimingModel,
    /// The interval of the sampler's ticks (the internal one under an output filter).
    dt: f64,
    /// The tick each output sample is taken at: every D-th under a decimating filter, the
    /// newest under a polled read, every one without a filter.
    read: ReadRatio,
    /// The output interval.
    dt_out: f64,
    /// The random walk's frequency step per tick, q·√Δt (from the model and Δt).
    rw_step: f64,
    /// Frequency and phase of the clock's random walk.
    rw_freq: f64,
    rw_phase: f64,
    rw: NormalStream,
    jitter: [NormalStream; 2],
    /// Seeds of the per-sample uniform draws: latency spread, late frames, missing samples.
    uniform: [u64; 3],
    /// Next sample index (1-based) and the bounds and emission of the last one.
    next: u64,
    last: (f64, f64, f64),
    /// The motion's span relative to t₀: instants are kept inside it.
    span: (f64, f64),
}

impl SensorTiming {
    /// The timing of `model` for samples at `rate_hz` over `duration` s, seeded from `seed`;
    /// `span` is the motion's span relative to t₀ (instants are clamped into it, which
    /// [`TimingModel::margin`] makes a formality). Refuses jitter too large for the interval
    /// and a drift that would move the frequency by more than 10 % within the run.
    pub fn new(
        model: TimingModel,
        rate_hz: f64,
        duration: f64,
        seed: u64,
        span: (f64, f64),
    ) -> Result<SensorTiming, String> {
        SensorTiming::decimated(model, rate_hz, ReadRatio::integer(1), duration, seed, span)
    }

    /// [`SensorTiming::new`] for a unit with an output filter whose outputs at `rate_hz` read
    /// the internal samples `read` names: its clock ticks at the internal rate, and each
    /// tick's instant moves by its own jitter (the internal sampler's, checked against the
    /// internal interval); output sample k is taken at internal tick n_k (k·D for a
    /// decimation), and its emission, latency, late frame and skipping are drawn per output
    /// sample. With a decimation of 1 this is [`SensorTiming::new`], draw for draw.
    pub fn decimated(
        model: TimingModel,
        rate_hz: f64,
        read: ReadRatio,
        duration: f64,
        seed: u64,
        span: (f64, f64),
    ) -> Result<SensorTiming, String> {
        let dt = 1.0 / (rate_hz * read.value());
        // Sample intervals differ from Δt by the difference of two jitters (σ√2); at Δt/20,
        // an interval shrinks to zero only beyond 7σ.
        if model.jitter > dt / 20.0 {
            let what = if read != ReadRatio::integer(1) {
                "internal "
            } else {
                ""
            };
            // In µs rounded to 1e-6 µs: "100 us" reads back as 9.999…e-5 s.
            let us = |x: f64| (x * 1e12).round() / 1e6;
            return Err(format!(
                "`jitter` = {} µs: at most 1/20 of the {what}sample interval {} µs",
                us(model.jitter),
                us(dt)
            ));
        }
        if model.clock_drift.abs() * duration > 0.1 {
            return Err(format!(
                "`clock_drift` = {} /s moves the clock's frequency by more than 10 % in {} s",
                model.clock_drift, duration
            ));
        }
        // The accelerometers' first interval starts at the skew: a negative one reaches before
        // t₀, where the motion may not be defined. Clamping it would silently shorten that
        // interval, so it is refused.
        if model.skew < span.0 {
            return Err(format!(
                "`skew` = {} s: the accelerometers' first interval would begin {} s before t₀, before the motion starts ({} s before t₀); start the run at least that much later (--start) or give a skew ≥ {} s",
                model.skew, -model.skew, -span.0, span.0
            ));
        }
        let stream = |name: &str| NormalStream::new(seed, name);
        let uniform = |name: &str| splitmix64(seed ^ fnv1a64(name));
        Ok(SensorTiming {
            model,
            dt,
            read,
            dt_out: 1.0 / rate_hz,
            rw_step: model.clock_random_walk * dt.sqrt(),
            rw_freq: 0.0,
            rw_phase: 0.0,
            rw: stream("timing/clock/random_walk"),
            jitter: [stream("timing/gyro/jitter"), stream("timing/accel/jitter")],
            uniform: [
                uniform("timing/latency"),
                uniform("timing/late"),
                uniform("timing/missing"),
            ],
            next: 1,
            last: (0.0, model.skew.min(span.1), f64::NEG_INFINITY),
            span,
        })
    }

    /// The model.
    pub fn model(&self) -> &TimingModel {
        &self.model
    }

    /// The deviation of the clock's k-th tick from k·Δt from its offset and drift (s); ticks
    /// are the internal sampler's under an output filter.
    pub fn deterministic_phase(&self, k: u64) -> f64 {
        let tau = self.nominal(k);
        let (y, d) = (self.model.clock_offset, self.model.clock_drift);
        let a = 1.0 + y;
        let s = (a * a + 2.0 * d * tau).sqrt();
        // t − τ = τ(2 − A − S)/(A + S), with 1 − S = (1 − S²)/(1 + S) to avoid cancellation.
        tau * (-y - (2.0 * y + y * y + 2.0 * d * tau) / (1.0 + s)) / (a + s)
    }

    /// The nominal instant of tick j, jΔt; under a decimation every D-th the output's k·Δt_out
    /// to the bit, as a run without a filter has it.
    fn nominal(&self, j: u64) -> f64 {
        match self.read.as_integer() {
            // No division per sample on the common path.
            Some(1) => j as f64 * self.dt_out,
            Some(d) => (j / d) as f64 * self.dt_out + (j % d) as f64 * self.dt,
            None => j as f64 * self.dt,
        }
    }

    /// How long after the internal sample it reads output k is read: 0 for a decimation;
    /// under a polled read, k·Δt_out − n_k·Δt_in (nominal; less than one internal interval).
    fn wait(&self, k: u64) -> f64 {
        match self.read.as_integer() {
            Some(_) => 0.0,
            None => k as f64 * self.dt_out - self.read.index(k) as f64 * self.dt,
        }
    }

    /// Whether the samples fall on the nominal grid (only the emission is perturbed): the
    /// internal bounds are then not filled, and a filtered run takes its nominal intervals.
    pub fn is_nominal(&self) -> bool {
        self.model.emission_only()
    }

    /// Fills `out` with samples `k_first .. k_first + n` (k_first must follow the last block);
    /// under a filter, with the internal samples' bounds too unless they are nominal.
    pub fn fill(&mut self, k_first: u64, n: usize, out: &mut TimedBlock) {
        assert_eq!(k_first, self.next, "timing blocks must be consecutive");
        let m = self.model;
        let internal = self.read != ReadRatio::integer(1) && !self.is_nominal();
        out.gyro.clear();
        out.accel.clear();
        out.emit.clear();
        out.missing.clear();
        out.internal.0.clear();
        out.internal.1.clear();
        out.gyro.push(self.last.0);
        out.accel.push(self.last.1);
        if internal {
            out.internal.0.push(self.last.0);
            out.internal.1.push(self.last.1);
        }
        for i in 0..n as u64 {
            let k = k_first + i;
            let (mut g, mut a) = (self.last.0, self.last.1);
            for j in self.read.index(k - 1) + 1..=self.read.index(k) {
                (g, a) = self.tick(j, (g, a));
                if internal {
                    out.internal.0.push(g);
                    out.internal.1.push(a);
                }
            }
            let u = |s: usize| uniform(self.uniform[s], k);
            let missing = m.missing_probability > 0.0 && u(2) < m.missing_probability;
            let mut e = g + m.latency + m.latency_spread * (2.0 * u(0) - 1.0) + self.wait(k);
            if m.late_probability > 0.0 && u(1) < m.late_probability {
                e += m.late_delay;
            }
            // A serial line sends frames in order: none leaves before the previous one.
            let e = e.max(self.last.2);
            out.gyro.push(g);
            out.accel.push(a);
            out.emit.push(e);
            out.missing.push(missing);
            self.last = (g, a, if missing { self.last.2 } else { e });
        }
        self.next = k_first + n as u64;
    }

    /// The gyro's and accelerometers' instants of tick j, after the previous tick's `last`.
    fn tick(&mut self, j: u64, last: (f64, f64)) -> (f64, f64) {
        let m = self.model;
        if self.rw_step > 0.0 {
            self.rw_freq += self.rw_step * self.rw.draw();
            self.rw_phase -= self.dt * self.rw_freq;
        }
        let tick = self.nominal(j) + self.deterministic_phase(j) + self.rw_phase;
        let (mut g, mut a) = (tick, tick + m.skew);
        if m.jitter > 0.0 {
            g += m.jitter * self.jitter[0].draw();
            a += m.jitter * self.jitter[1].draw();
        }
        // Bounds never run backwards (a 7σ jitter pair) nor leave the motion.
        let (lo, hi) = self.span;
        (g.clamp(lo, hi).max(last.0), a.clamp(lo, hi).max(last.1))
    }
}

/// A uniform draw in [0, 1) for sample k of the stream seeded `seed`: counter-based, so the
/// draws do not depend on the block size.
fn uniform(seed: u64, k: u64) -> f64 {
    (splitmix64(seed ^ splitmix64(k)) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn timing(model: TimingModel, rate: f64) -> SensorTiming {
        SensorTiming::new(model, rate, 100.0, 7, (-1e9, 1e9)).unwrap()
    }

    /// The closed-form phase: a constant offset y gives t_k = k·Δt/(1+y) to round-off; with a
    /// drift d the instants solve ½dt² + (1+y)t = τ (checked by putting them back).
    #[test]
    fn phase_is_the_clock_equation() {
        let y = 50e-6;
        let s = timing(
            TimingModel {
                clock_offset: y,
                ..Default::default()
            },
            1000.0,
        );
        for k in [1u64, 1000, 60_000, 1_000_000] {
            let tau = k as f64 / 1000.0;
            let t = tau + s.deterministic_phase(k);
            assert!(
                (t - tau / (1.0 + y)).abs() <= 4.0 * f64::EPSILON * tau,
                "{k}"
            );
        }
        let d = 2e-7;
        let s = timing(
            TimingModel {
                clock_offset: -30e-6,
                clock_drift: d,
                ..Default::default()
            },
            400.0,
        );
        for k in [1u64, 400, 40_000] {
            let tau = k as f64 / 400.0;
            let t = tau + s.deterministic_phase(k);
            let back = 0.5 * d * t * t + (1.0 - 30e-6) * t;
            assert!((back - tau).abs() <= 8.0 * f64::EPSILON * tau, "{k}");
        }
    }

    /// Blocks of any size give the same instants (the streams advance per sample); the
    /// interval bounds are shared between consecutive samples; latency lies in its band.
    #[test]
    fn blocks_do_not_matter() {
        let m = TimingModel {
            clock_offset: 20e-6,
            clock_random_walk: 1e-6,
            jitter: 1e-6,
            skew: 5e-6,
            latency: 400e-6,
            latency_spread: 50e-6,
            late_probability: 0.01,
            late_delay: 1e-3,
            missing_probability: 0.01,
            ..Default::default()
        };
        let mut whole = TimedBlock::default();
        timing(m, 1000.0).fill(1, 100, &mut whole);
        let mut s = timing(m, 1000.0);
        let (mut b, mut k) = (TimedBlock::default(), 1);
        for n in [7, 1, 50, 42] {
            s.fill(k, n, &mut b);
            let i = (k - 1) as usize;
            assert_eq!(b.gyro[..], whole.gyro[i..=i + n]);
            assert_eq!(b.accel[..], whole.accel[i..=i + n]);
            assert_eq!(b.emit[..], whole.emit[i..i + n]);
            assert_eq!(b.missing[..], whole.missing[i..i + n]);
            k += n as u64;
        }
        assert_eq!(whole.gyro[0], 0.0);
        assert_eq!(whole.accel[0], 5e-6);
        for i in 0..100 {
            let lat = whole.emit[i] - whole.tov(i);
            assert!(lat >= 350e-6 - 1e-12, "{i}: {lat}");
            assert!(whole.gyro[i + 1] > whole.gyro[i]);
        }
    }

    /// Jitter above Δt/20 and a drift that moves the frequency 10 % are refused.
    #[test]
    fn refusals() {
        let j = TimingModel {
            jitter: 60e-6,
            ..Default::default()
        };
        let e = SensorTiming::new(j, 1000.0, 1.0, 1, (0.0, 1.0)).unwrap_err();
        assert!(e.contains("1/20"), "{e}");
        let d = TimingModel {
            clock_drift: 1e-3,
            ..Default::default()
        };
        let e = SensorTiming::new(d, 1000.0, 200.0, 1, (0.0, 1.0)).unwrap_err();
        assert!(e.contains("10 %"), "{e}");
        // A negative skew is refused when the motion starts at t₀, taken when it starts earlier.
        let s = TimingModel {
            skew: -20e-6,
            ..Default::default()
        };
        let e = SensorTiming::new(s, 1000.0, 1.0, 1, (0.0, 1.0)).unwrap_err();
        assert!(e.contains("`skew`") && e.contains("--start"), "{e}");
        let ok = SensorTiming::new(s, 1000.0, 1.0, 1, (-1.0, 1.0)).unwrap();
        assert_eq!(ok.last.1, -20e-6);
    }
}
