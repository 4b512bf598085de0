//! Sensor failures scheduled in time, per channel: what a fault-detection and isolation test
//! must find. Pure math on a record's channel values, no I/O.
//!
//! A failure acts on the records whose time tag t_k lies in [start, end) and replaces the
//! channel's reading m by:
//!
//! | kind | reading | magnitude |
//! |---|---|---|
//! | `stuck` | the channel's last reading before the start, held | — |
//! | `null` | 0 | — |
//! | `bias-step` | m + a | a (rad/s or m/s²) |
//! | `bias-ramp` | m + a·(t_k − start) | a (rad/s² or m/s³) |
//! | `scale-factor-jump` | (1 + a)·m | a (ratio) |
//! | `noise-burst` | m + a·n, n ~ N(0, 1) per record | a (σ, rad/s or m/s²) |
//! | `saturation` | m clipped to [−a, a] | a (rad/s or m/s²) |
//! | `intermittent` | 0 with probability a per record, else m | a (probability) |
//!
//! Random alternatives (which sensor, when, how large) are drawn once, when the schedule is
//! resolved, from the failure seed and the failure's index, so a seed gives the same schedule
//! whatever else changes.

use crate::rng::{NormalStream, fnv1a64, splitmix64};

/// What a failure does to its channel (see the module's table).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FailureKind {
    /// Holds the last reading before the failure.
    Stuck,
    /// Reads zero.
    Null,
    /// Adds a constant.
    BiasStep,
    /// Adds a constant rate times the time since the start.
    BiasRamp,
    /// Multiplies by (1 + a).
    ScaleFactorJump,
    /// Adds white noise of σ = a.
    NoiseBurst,
    /// Clips to ±a.
    Saturation,
    /// Drops records (reads zero) with probability a each.
    Intermittent,
}

impl FailureKind {
    /// Every kind, in the order of the module's table.
    pub const ALL: [FailureKind; 8] = [
        FailureKind::Stuck,
        FailureKind::Null,
        FailureKind::BiasStep,
        FailureKind::BiasRamp,
        FailureKind::ScaleFactorJump,
        FailureKind::NoiseBurst,
        FailureKind::Saturation,
        FailureKind::Intermittent,
    ];

    /// The name in scene files and the failures file.
    pub fn name(self) -> &'static str {
        match self {
            FailureKind::Stuck => "stuck",
            FailureKind::Null => "null",
            FailureKind::BiasStep => "bias-step",
            FailureKind::BiasRamp => "bias-ramp",
            FailureKind::ScaleFactorJump => "scale-factor-jump",
            FailureKind::NoiseBurst => "noise-burst",
            FailureKind::Saturation => "saturation",
            FailureKind::Intermittent => "intermittent",
        }
    }

    /// The kind named `s`.
    pub fn from_name(s: &str) -> Option<FailureKind> {
        FailureKind::ALL.into_iter().find(|k| k.name() == s)
    }

    /// Whether the kind takes a magnitude.
    pub fn needs_magnitude(self) -> bool {
        !matches!(self, FailureKind::Stuck | FailureKind::Null)
    }

    /// The magnitude's accepted range, for [`FailureSpec::resolve`]'s check.
    fn magnitude_ok(self, a: f64) -> Result<(), &'static str> {
        match self {
            _ if !a.is_finite() => Err("a finite number"),
            FailureKind::NoiseBurst | FailureKind::Saturation if a <= 0.0 => {
                Err("a positive number")
            }
            FailureKind::ScaleFactorJump if a <= -1.0 => Err("a ratio above −1"),
            FailureKind::Intermittent if !(0.0..=1.0).contains(&a) => {
                Err("a probability in [0, 1]")
            }
            _ => Ok(()),
        }
    }
}

/// A value given outright or drawn uniformly from [lo, hi] when the schedule is resolved.
#[derive(Clone, Debug, PartialEq)]
pub enum Pick<T> {
    /// This value.
    Fixed(T),
    /// One of these, each as likely (for channels), or uniform in [lo, hi] (numbers).
    Random(Vec<T>),
}

/// A failure as the user gives it (before the random choices are drawn).
#[derive(Clone, Debug, PartialEq)]
pub struct FailureSpec {
    /// What it does.
    pub kind: FailureKind,
    /// The channel (index into the unit's channels), or channels to draw one from.
    pub channel: Pick<usize>,
    /// Start time (s), or [lo, hi] to draw it from.
    pub start_s: Pick<f64>,
    /// How long it lasts (s); `None`: to the end of the run.
    pub duration_s: Option<f64>,
    /// The magnitude (see the module's table), or [lo, hi] to draw it from.
    pub magnitude: Pick<f64>,
}

/// A failure with its random choices made: what the failures file lists.
#[derive(Clone, Debug, PartialEq)]
pub struct Failure {
    /// What it does.
    pub kind: FailureKind,
    /// The channel.
    pub channel: usize,
    /// First time (s) it acts on (records with t_k ≥ start).
    pub start_s: f64,
    /// Time (s) from which it no longer acts (∞: never ends).
    pub end_s: f64,
    /// The magnitude (see the module's table).
    pub magnitude: f64,
}

/// Uniform draws in [0, 1) from a counter: a SplitMix64 sequence (Steele, Lea & Flood,
/// "Fast splittable pseudorandom number generators", OOPSLA 2014) keyed by seed and name.
#[derive(Clone, Debug)]
struct Uniform(u64);

impl Uniform {
    fn new(seed: u64, name: &str) -> Uniform {
        Uniform(splitmix64(seed ^ fnv1a64(name)))
    }
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        // The top 53 bits, as a multiple of 2⁻⁵³.
        (splitmix64(self.0) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

impl FailureSpec {
    /// Draws the random choices (stream `failure/INDEX` of `seed`) and checks the result:
    /// a channel below `channels`, a finite start, a positive duration, a magnitude the kind
    /// accepts. The error names the field.
    pub fn resolve(
        &self,
        index: usize,
        seed: u64,
        channels: usize,
    ) -> Result<Failure, (&'static str, String)> {
        let mut u = Uniform::new(seed, &format!("failure/{index}"));
        let mut number = |p: &Pick<f64>, field: &'static str| match p {
            Pick::Fixed(x) => Ok(*x),
            Pick::Random(r) if r.len() == 2 && r[0].is_finite() && r[1] >= r[0] => {
                Ok(r[0] + (r[1] - r[0]) * u.next())
            }
            Pick::Random(r) => Err((field, format!("{r:?}: expected [lo, hi] with lo ≤ hi"))),
        };
        let start_s = number(&self.start_s, "at_s")?;
        let magnitude = number(&self.magnitude, "magnitude")?;
        let channel = match &self.channel {
            Pick::Fixed(c) => *c,
            Pick::Random(cs) if !cs.is_empty() => {
                cs[((u.next() * cs.len() as f64) as usize).min(cs.len() - 1)]
            }
            Pick::Random(_) => return Err(("sensor", "no sensor to draw from".into())),
        };
        if channel >= channels {
            return Err((
                "sensor",
                format!("channel {channel}: the unit has {channels}"),
            ));
        }
        if !start_s.is_finite() {
            return Err(("at_s", format!("{start_s}: expected a finite time")));
        }
        let end_s = match self.duration_s {
            Some(d) if d.is_finite() && d > 0.0 => start_s + d,
            Some(d) => return Err(("duration_s", format!("{d}: expected a positive duration"))),
            None => f64::INFINITY,
        };
        self.kind
            .magnitude_ok(magnitude)
            .map_err(|e| ("magnitude", format!("{magnitude}: expected {e}")))?;
        Ok(Failure {
            kind: self.kind,
            channel,
            start_s,
            end_s,
            magnitude,
        })
    }
}

/// The failures of one unit, with what they need from record to record.
#[derive(Clone, Debug)]
pub struct FailureSet {
    failures: Vec<Failure>,
    /// Per failure: the held value (stuck), the noise stream (noise burst), the draws
    /// (intermittent).
    held: Vec<Option<f64>>,
    noise: Vec<NormalStream>,
    draws: Vec<Uniform>,
    /// Each channel's last reading (for `stuck`).
    last: Vec<f64>,
}

impl FailureSet {
    /// The set of `failures` on a unit of `channels` channels; random processes on streams
    /// of `seed`.
    pub fn new(failures: Vec<Failure>, channels: usize, seed: u64) -> FailureSet {
        let name = |i: usize, what: &str| format!("failure/{i}/{what}");
        FailureSet {
            held: vec![None; failures.len()],
            noise: (0..failures.len())
                .map(|i| NormalStream::new(seed, &name(i, "noise")))
                .collect(),
            draws: (0..failures.len())
                .map(|i| Uniform::new(seed, &name(i, "drops")))
                .collect(),
            failures,
            last: vec![f64::NAN; channels],
        }
    }

    /// The resolved failures.
    pub fn failures(&self) -> &[Failure] {
        &self.failures
    }

    /// Whether there is no failure.
    pub fn is_empty(&self) -> bool {
        self.failures.is_empty()
    }

    /// Applies the failures active at `t` to one record's `values` (one per channel), in
    /// the order given; returns the mask of channels with an active failure (bit i:
    /// channel i, up to 64 channels).
    pub fn apply(&mut self, t: f64, values: &mut [f64]) -> u64 {
        let mut mask = 0;
        for (i, f) in self.failures.iter().enumerate() {
            if !(t >= f.start_s && t < f.end_s) {
                continue;
            }
            mask |= 1u64 << f.channel.min(63);
            let v = &mut values[f.channel];
            let a = f.magnitude;
            match f.kind {
                FailureKind::Stuck => {
                    let last = self.last[f.channel];
                    *v = *self.held[i].get_or_insert(if last.is_nan() { *v } else { last });
                }
                FailureKind::Null => *v = 0.0,
                FailureKind::BiasStep => *v += a,
                FailureKind::BiasRamp => *v += a * (t - f.start_s),
                FailureKind::ScaleFactorJump => *v *= 1.0 + a,
                FailureKind::NoiseBurst => *v += a * self.noise[i].draw(),
                FailureKind::Saturation => *v = v.clamp(-a, a),
                FailureKind::Intermittent => {
                    if self.draws[i].next() < a {
                        *v = 0.0;
                    }
                }
            }
        }
        if !self.failures.is_empty() {
            self.last.copy_from_slice(values);
        }
        mask
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one(kind: FailureKind, magnitude: f64) -> FailureSet {
        let f = Failure {
            kind,
            channel: 1,
            start_s: 1.0,
            end_s: 2.0,
            magnitude,
        };
        FailureSet::new(vec![f], 3, 7)
    }

    /// Each deterministic kind changes its channel exactly as the table says inside
    /// [start, end), and nothing outside it or on other channels.
    #[test]
    fn each_kind_acts_inside_its_window_only() {
        // (kind, magnitude, the reading m at time t becomes).
        type Case = (FailureKind, f64, fn(f64, f64) -> f64);
        let cases: [Case; 6] = [
            (FailureKind::Null, 0.0, |_, _| 0.0),
            (FailureKind::BiasStep, 0.5, |m, _| m + 0.5),
            (FailureKind::BiasRamp, 0.5, |m, t| m + 0.5 * (t - 1.0)),
            (FailureKind::ScaleFactorJump, 0.1, |m, _| 1.1 * m),
            (FailureKind::Saturation, 2.5, |m, _| m.clamp(-2.5, 2.5)),
            (FailureKind::Stuck, 0.0, |_, _| 3.0 * 0.9),
        ];
        for (kind, a, expect) in cases {
            let mut s = one(kind, a);
            for k in 0..30 {
                let t = k as f64 * 0.1;
                let m = 3.0 * t;
                let mut v = [1.0, m, -1.0];
                let mask = s.apply(t, &mut v);
                let inside = (1.0..2.0).contains(&t);
                let want = if inside { expect(m, t) } else { m };
                assert!(
                    (v[1] - want).abs() < 1e-12,
                    "{kind:?} t={t}: {} vs {want}",
                    v[1]
                );
                assert_eq!((v[0], v[2]), (1.0, -1.0));
                assert_eq!(mask, if inside { 2 } else { 0 }, "{kind:?} t={t}");
            }
        }
    }

    /// The noise burst adds N(0, a²): over 40 000 draws the sample σ is a within 4 × its
    /// standard error a/√(2n) ≈ 0.0035a. Intermittent drops a fraction p of records: the
    /// count of n draws is within 4√(np(1−p)).
    #[test]
    fn random_kinds_have_their_statistics() {
        let n = 40_000;
        let mut s = one(FailureKind::NoiseBurst, 0.2);
        let mut sum2 = 0.0;
        for k in 0..n {
            let mut v = [0.0; 3];
            s.apply(1.0 + k as f64 * 1e-5, &mut v);
            sum2 += v[1] * v[1];
        }
        let sigma = (sum2 / n as f64).sqrt();
        assert!(
            (sigma / 0.2 - 1.0).abs() < 4.0 / (2.0 * n as f64).sqrt(),
            "{sigma}"
        );
        let mut s = one(FailureKind::Intermittent, 0.3);
        let mut dropped = 0;
        for k in 0..n {
            let mut v = [1.0; 3];
            s.apply(1.0 + k as f64 * 1e-5, &mut v);
            dropped += (v[1] == 0.0) as usize;
        }
        let expect = 0.3 * n as f64;
        assert!(
            (dropped as f64 - expect).abs() < 4.0 * (expect * 0.7).sqrt(),
            "{dropped}"
        );
    }

    /// Random choices are reproducible from the seed, lie in their ranges, and differ
    /// between failures of the same spec (the stream carries the index).
    #[test]
    fn random_choices_are_seeded_and_in_range() {
        let spec = FailureSpec {
            kind: FailureKind::BiasStep,
            channel: Pick::Random(vec![0, 2, 4]),
            start_s: Pick::Random(vec![10.0, 20.0]),
            duration_s: Some(5.0),
            magnitude: Pick::Random(vec![-1.0, 1.0]),
        };
        let a = spec.resolve(0, 99, 6).unwrap();
        assert_eq!(a, spec.resolve(0, 99, 6).unwrap());
        assert_ne!(a, spec.resolve(1, 99, 6).unwrap());
        for i in 0..50 {
            let f = spec.resolve(i, 99, 6).unwrap();
            assert!([0, 2, 4].contains(&f.channel));
            assert!((10.0..=20.0).contains(&f.start_s) && (-1.0..=1.0).contains(&f.magnitude));
            assert_eq!(f.end_s, f.start_s + 5.0);
        }
        let bad = FailureSpec {
            channel: Pick::Fixed(6),
            ..spec.clone()
        };
        assert_eq!(bad.resolve(0, 1, 6).unwrap_err().0, "sensor");
        let bad = FailureSpec {
            kind: FailureKind::Intermittent,
            magnitude: Pick::Fixed(1.5),
            ..spec
        };
        assert_eq!(bad.resolve(0, 1, 6).unwrap_err().0, "magnitude");
    }
}
