//! The IMU's own timing errors: a sensor clock with a frequency offset, drift and random walk;
//! sampling jitter; the accelerometers' skew from the gyros; latency from the time of validity
//! to the frame's first byte; late and missing samples. Pure math, seeded like every error term
//! (`docs/timing.md` describes the model and its keys).
//!
//! [`TimingModel`] holds the figures (template `[timing]` table, scene-file `[timing]` table);
//! [`SensorTiming`] turns them into, for each sample, the true instants that bound its
//! integration intervals, its time of validity and its emission time; [`ReadRatio`] says which
//! internal sample of a filtered unit each output sample is.

pub mod read_ratio;
mod sensor;

pub use read_ratio::ReadRatio;

pub use sensor::{SensorTiming, TimedBlock};

use crate::units::{Kind, quantity};

/// Times of the records of one block, relative to the run's t₀ (s).
#[derive(Clone, Copy, Debug)]
pub struct Times<'a> {
    /// The run's t₀ (s): add it for absolute times.
    pub t0: f64,
    /// Time of validity (end of the gyro interval) of each record.
    pub tov: &'a [f64],
    /// Time of validity of each record's accelerometers.
    pub tov_accel: &'a [f64],
    /// Emission time of each record's frame (its first byte).
    pub emit: &'a [f64],
    /// Samples the sensor skipped just before each record.
    pub gaps: &'a [u32],
}

/// The timing figures of an IMU, in SI. All zero (the default): samples on the nominal grid,
/// each frame sent at the end of its interval.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TimingModel {
    /// Fractional frequency offset of the sensor clock (positive: the clock runs fast, so
    /// samples come more often than the nominal rate in true time).
    pub clock_offset: f64,
    /// Linear change of the fractional frequency with time (1/s), as a crystal ages or warms.
    pub clock_drift: f64,
    /// Density of the random walk of the fractional frequency (1/√s).
    pub clock_random_walk: f64,
    /// Standard deviation of each sample instant about the sensor clock's tick (s), drawn
    /// independently for the gyros and the accelerometers.
    pub jitter: f64,
    /// The accelerometers sample this long after the gyros (s; negative: before).
    pub skew: f64,
    /// Fixed delay from a sample's time of validity to its frame's first byte (s).
    pub latency: f64,
    /// Half-width of the uniform spread of the latency about `latency` (s).
    pub latency_spread: f64,
    /// Probability that a frame leaves `late_delay` later than its latency says.
    pub late_probability: f64,
    /// Extra delay of a late frame (s).
    pub late_delay: f64,
    /// Probability that the sensor skips a sample: no frame for it, and the next sample's
    /// increments run from the last sample taken.
    pub missing_probability: f64,
}

/// Largest clock frequency offset accepted (1000 ppm: ten times a poor crystal's tolerance).
pub const MAX_CLOCK_OFFSET: f64 = 1e-3;

/// The keys of a `[timing]` table, with the kind of value each takes (`None`: a probability,
/// a plain number in [0, 1)).
const KEYS: [(&str, Option<Kind>); 10] = [
    ("clock_offset", Some(Kind::Ratio)),
    ("clock_drift", Some(Kind::RatioDrift)),
    ("clock_random_walk", Some(Kind::RatioRandomWalk)),
    ("jitter", Some(Kind::Time)),
    ("skew", Some(Kind::Time)),
    ("latency", Some(Kind::Time)),
    ("latency_spread", Some(Kind::Time)),
    ("late_probability", None),
    ("late_delay", Some(Kind::Time)),
    ("missing_probability", None),
];

/// A bad `[timing]` key: the key (without the table's name) and what is wrong.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyError {
    /// The key.
    pub key: String,
    /// What is wrong with its value.
    pub message: String,
}

impl TimingModel {
    /// True when every figure is zero: the nominal sampling grid and emission schedule.
    pub fn is_zero(&self) -> bool {
        *self == TimingModel::default()
    }

    /// True when only the emission is perturbed (latency, its spread, late frames): the
    /// samples stay on the nominal grid and none is skipped.
    pub fn emission_only(&self) -> bool {
        TimingModel {
            latency: 0.0,
            latency_spread: 0.0,
            late_probability: 0.0,
            late_delay: 0.0,
            ..*self
        }
        .is_zero()
    }

    /// Sets the figures a `[timing]` table gives (values are `"number unit"` strings, the
    /// probabilities plain numbers), leaving the others; the whole model is then checked.
    pub fn apply_table(&mut self, table: &toml::Table) -> Result<(), KeyError> {
        for (key, value) in table {
            let err = |message: String| KeyError {
                key: key.clone(),
                message,
            };
            let Some((_, kind)) = KEYS.iter().find(|k| k.0 == key) else {
                let names: Vec<&str> = KEYS.iter().map(|k| k.0).collect();
                return Err(err(format!("unknown key (keys: {})", names.join(", "))));
            };
            let x = match kind {
                Some(kind) => quantity(value, *kind).map_err(err)?,
                None => value
                    .as_float()
                    .or(value.as_integer().map(|i| i as f64))
                    .ok_or_else(|| err("expected a number in [0, 1)".into()))?,
            };
            *self.field(key) = x;
        }
        self.check()
    }

    fn field(&mut self, key: &str) -> &mut f64 {
        match key {
            "clock_offset" => &mut self.clock_offset,
            "clock_drift" => &mut self.clock_drift,
            "clock_random_walk" => &mut self.clock_random_walk,
            "jitter" => &mut self.jitter,
            "skew" => &mut self.skew,
            "latency" => &mut self.latency,
            "latency_spread" => &mut self.latency_spread,
            "late_probability" => &mut self.late_probability,
            "late_delay" => &mut self.late_delay,
            _ => &mut self.missing_probability,
        }
    }

    /// Checks the figures against each other and their ranges (independent of the rate; see
    /// [`SensorTiming::new`] for what the rate adds).
    pub fn check(&self) -> Result<(), KeyError> {
        let bad = |key: &str, message: &str| {
            Err(KeyError {
                key: key.into(),
                message: message.into(),
            })
        };
        if self.clock_offset.abs() > MAX_CLOCK_OFFSET {
            return bad("clock_offset", "expected at most ±1000 ppm");
        }
        for (key, v) in [
            ("clock_random_walk", self.clock_random_walk),
            ("jitter", self.jitter),
            ("latency", self.latency),
            ("latency_spread", self.latency_spread),
            ("late_delay", self.late_delay),
        ] {
            if v < 0.0 {
                return bad(key, "must not be negative (a magnitude)");
            }
        }
        if self.latency_spread > self.latency {
            return bad(
                "latency_spread",
                "must not exceed `latency`: a frame cannot leave before its sample is valid",
            );
        }
        if self.skew.abs() > 1.0 {
            return bad("skew", "expected at most ±1 s");
        }
        for (key, p) in [
            ("late_probability", self.late_probability),
            ("missing_probability", self.missing_probability),
        ] {
            if !(0.0..1.0).contains(&p) {
                return bad(key, "expected a probability in [0, 1)");
            }
        }
        Ok(())
    }

    /// A bound on how far the sensor's sample instants stray from the nominal grid over a run
    /// of `duration` seconds (s): the clock's phase error from its offset and drift, six
    /// standard deviations of the phase its random walk adds (a frequency random walk of
    /// density q integrates to a phase of variance q²D³/3), six of the jitter, and the skew.
    /// The span of the motion must cover the grid widened by this much.
    pub fn margin(&self, duration: f64) -> f64 {
        let d = duration.abs();
        let q = self.clock_random_walk;
        self.clock_offset.abs() * d
            + 0.5 * self.clock_drift.abs() * d * d
            + 6.0 * q * (d * d * d / 3.0).sqrt()
            + 6.0 * self.jitter
            + self.skew.abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> toml::Table {
        text.parse().unwrap()
    }

    /// Every key in its units; the probabilities as numbers; unknown keys, wrong units, a
    /// spread larger than the latency and out-of-range probabilities refused by key.
    #[test]
    fn keys_and_refusals() {
        let mut m = TimingModel::default();
        m.apply_table(&table(
            "clock_offset = \"50 ppm\"\nclock_drift = \"3.6 ppm/h\"\nclock_random_walk = \"1 ppm/sqrt(s)\"\njitter = \"2 us\"\nskew = \"-10 us\"\nlatency = \"400 us\"\nlatency_spread = \"50 us\"\nlate_probability = 0.01\nlate_delay = \"2 ms\"\nmissing_probability = 0.001\n",
        ))
        .unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs();
        assert!(close(m.clock_offset, 50e-6));
        assert!(close(m.clock_drift, 1e-9));
        assert!(close(m.clock_random_walk, 1e-6));
        assert!(close(m.jitter, 2e-6) && close(m.skew, -10e-6));
        assert!(close(m.latency, 400e-6) && close(m.latency_spread, 50e-6));
        assert!(close(m.late_delay, 2e-3));
        assert_eq!((m.late_probability, m.missing_probability), (0.01, 0.001));
        assert!(!m.is_zero() && TimingModel::default().is_zero());
        for (text, key, says) in [
            ("latncy = \"1 ms\"", "latncy", "unknown key"),
            ("jitter = \"2 furlong\"", "jitter", "unknown unit"),
            ("jitter = 2", "jitter", "expected a string"),
            ("jitter = \"-2 us\"", "jitter", "negative"),
            (
                "latency_spread = \"1 s\"",
                "latency_spread",
                "must not exceed",
            ),
            ("missing_probability = 1", "missing_probability", "[0, 1)"),
            (
                "late_probability = \"x\"",
                "late_probability",
                "expected a number",
            ),
            ("clock_offset = \"2000 ppm\"", "clock_offset", "1000 ppm"),
        ] {
            let e = TimingModel::default()
                .apply_table(&table(text))
                .unwrap_err();
            assert_eq!(e.key, key, "{text}");
            assert!(e.message.contains(says), "{text}: {}", e.message);
        }
    }

    /// The margin of a clock 50 ppm off over 60 s is its phase error, 3 ms; the random walk
    /// adds 6·q·√(D³/3).
    #[test]
    fn margin_bounds_the_phase() {
        let m = TimingModel {
            clock_offset: -50e-6,
            ..Default::default()
        };
        assert!((m.margin(60.0) - 3e-3).abs() < 1e-15);
        let rw = TimingModel {
            clock_random_walk: 1e-6,
            ..Default::default()
        };
        assert!((rw.margin(3.0) - 6e-6 * 3.0).abs() < 1e-18);
    }
}
