//! Vibration on the sensed angular rate and specific force: sinusoids, and stationary Gaussian
//! random vibration given as a one-sided PSD table, to be added to each record's interval-mean
//! rates (the `vibration` stage of the error chain, `errors/stages/vibration.rs`).
//!
//! **Sinusoids.** A record carries the mean over (t_{k−1}, t_k], so a sinusoid
//! A sin(2πft + φ) (t from the run's first sample time t₀) enters as its exact interval mean
//! A·sinc(πfΔt)·sin(2πf(k − ½)Δt + φ), sinc x = sin x / x — the attenuation an integrating
//! sensor really shows (0.1 % at fs/40, 36 % at Nyquist). The phase is formed from the integer
//! k at every record, never accumulated: the product f·Δt·(k − ½) is taken in double-double
//! arithmetic (Dekker's split, no FMA needed) and reduced to a fraction of a cycle before the
//! sine, so record 8.64·10⁷ (24 h at 1 kHz) is as exact as record 1 (test
//! `sine_phase_does_not_drift_over_24_h`: < 10⁻⁹ of the amplitude against an integer-exact
//! phase). Frequencies above Nyquist are refused: the closed form would alias them correctly,
//! but a spec asking for them is more likely a unit mistake than a wish to study aliasing.
//!
//! **Random vibration.** Specs are tables of (f, PSD) interpolated linearly in log-log axes (a
//! constant dB/octave slope between breakpoints, as g²/Hz test profiles are written), zero
//! outside the table. A fixed sum of sinusoids or an inverse FFT of one random-phase buffer
//! repeats with the buffer's period and has a deterministic periodogram; instead unit white
//! noise from the axis's own stream is filtered, without end, by a linear-phase FIR h. The
//! output is then exactly Gaussian (a weighted sum of Gaussians), stationary from the first
//! record (the filter's history is drawn at construction), and never repeats: every record
//! uses fresh draws and its correlation with anything more than N samples away is exactly 0.
//! Its one-sided PSD is 2Δt|H(f)|² and its variance is exactly Σh² (reported as
//! [`RandomSummary::rms`]).
//!
//! *Target.* The physical vibration has the table's PSD S(f); the record is its interval mean,
//! whose PSD is S(f)·sinc²(πfΔt) (no aliasing, because the content is cut at Nyquist), so the
//! FIR is designed for |H(f)| = √(S(f)/(2Δt))·sinc(πfΔt). A flat S over [f₁, f₂] therefore
//! gives the variance S·∫sinc² df, which is S·(f₂ − f₁) to within (πf₂Δt)²/3 (1 % for
//! f₂ = fs/18). A table reaching past Nyquist is cut there (what lies above is dropped, and
//! [`RandomSummary::truncated_at_hz`] says so); a table lying entirely above is refused.
//!
//! *Design.* Frequency sampling: the target amplitude is area-sampled on a grid 8× finer than
//! the FIR length, inverse-transformed to the zero-phase response, cut to N = 2^p − 1 taps
//! around its centre and Blackman-windowed. The window makes H the target convolved with a
//! kernel of unit area, so H equals the target wherever the target is smooth on the scale of
//! the kernel; a table's end (a jump to zero) is spread over about ±3 fs/N, and the sidelobes
//! (−58 dB, falling fast) keep what leaks further out negligible. Spreading a jump loses power
//! (about half a design bin of the end's level per end), so the ends are moved out by the
//! fraction of a bin that gives it back: Σh² then equals the target variance, not just the
//! in-band level. N is the smallest 2^p − 1 with fs/N at most 1/[`RESOLUTION_BINS`] of the
//! table's lowest frequency and of its width (up to Nyquist), within [`MIN_TAPS`]…[`MAX_TAPS`];
//! [`RandomSummary::resolution_hz`] reports fs/N. Measured (test
//! `filter_response_matches_the_table`, N = 1023…4095 at 1 kHz): 2Δt|H|² is within 5·10⁻⁴
//! (asserted: 10⁻³) of S·sinc² more than 4 bins inside the ends and 8 from breakpoints;
//! within 0.6 % (asserted: 1 %) at a −10 dB/oct-to-flat breakpoint and at Nyquist, where the
//! slope of √S·sinc turns (a kink is rounded over a few bins); below 4·10⁻⁸ of the end level
//! more than 4 bins outside; Σh² within 10⁻⁵ of S·∫sinc². A run's variance and Welch PSD then
//! match to their own statistical scatter (tests `flat_band_variance_and_psd`,
//! `two_level_table_has_its_shape`).
//!
//! *Cost.* The convolution runs as overlap-save FFT blocks: with FFT size L = 2(N + 1) a block
//! yields B = L − N + 1 outputs, and since the input and h are real, two consecutive blocks
//! go through one complex FFT pair (one as the real part, the next as the imaginary part) —
//! about log₂L radix-2 butterflies and one normal draw per output sample, where the direct
//! form would need N multiply-adds. Measured in release on one core (AMD EPYC, shared): 30–50
//! ns per record and vibrated axis for N = 2047…16383 (six axes at N = 16383: 220 ns); a
//! sinusoid costs one `sin`, 12–20 ns. Building costs 3–20 ms per axis; memory is about 8L
//! doubles per axis (2 MB at N = 16383).
//!
//! Streams: random vibration of sensor s, axis a draws from
//! `vibration/{gyro|accel}/{x|y|z}/random`, so adding or removing any other term leaves it
//! bit-identical. One random vibration per sensor axis: a table expresses any shape.

mod design;
mod fft;
mod random;
mod sine;

pub use super::model::Sensor;
use crate::math::{Mat3, Vec3};
use crate::units::bounds::compact;
use random::RandomChannel;
use sine::SineTerm;
use std::fmt;

/// Smallest FIR length.
pub const MIN_TAPS: usize = 1023;
/// Largest FIR length (FFT blocks of 32768).
pub const MAX_TAPS: usize = 16383;
/// The design spacing fs/N is at most this fraction of a table's lowest frequency and width.
pub const RESOLUTION_BINS: f64 = 64.0;

/// Index of a sensor axis in the six values a record's vibration adds (gyro x…z, accel x…z).
fn slot(sensor: Sensor, axis: usize) -> usize {
    3 * (sensor as usize) + axis
}

/// A sinusoidal vibration A sin(2πft + φ) on one axis, t from the run's first sample time.
#[derive(Clone, Debug, PartialEq)]
pub struct Sine {
    /// Triad.
    pub sensor: Sensor,
    /// Axis 0, 1, 2 (x, y, z).
    pub axis: usize,
    /// Peak amplitude A ≥ 0 (rad/s or m/s²).
    pub amplitude: f64,
    /// Frequency f, 0 < f ≤ Nyquist (Hz).
    pub freq_hz: f64,
    /// Phase φ at t = 0 (rad).
    pub phase_rad: f64,
}

/// A stationary Gaussian random vibration on one axis with a one-sided PSD table.
#[derive(Clone, Debug, PartialEq)]
pub struct Random {
    /// Triad.
    pub sensor: Sensor,
    /// Axis 0, 1, 2 (x, y, z).
    pub axis: usize,
    /// Rows (f in Hz, one-sided PSD in unit²/Hz), f strictly increasing, PSD > 0;
    /// interpolated log-log, zero outside.
    pub psd: Vec<(f64, f64)>,
}

impl Random {
    /// The table's PSD at f (unit²/Hz): log-log interpolation, zero outside the table.
    pub fn psd_at(&self, f: f64) -> f64 {
        let t = &self.psd;
        if t.len() < 2 || !(f >= t[0].0 && f <= t[t.len() - 1].0) {
            return 0.0;
        }
        let i = t.partition_point(|r| r.0 <= f);
        if i == t.len() {
            return t[i - 1].1;
        }
        let (a, b) = (t[i - 1], t[i]);
        a.1 * (b.1 / a.1).powf((f / a.0).ln() / (b.0 / a.0).ln())
    }
    /// ∫ PSD df over the table up to f_max (Hz), in closed form: the variance (unit²) as
    /// specified (`f64::INFINITY` for the whole table).
    pub fn variance_up_to(&self, f_max: f64) -> f64 {
        self.psd
            .windows(2)
            .map(|w| {
                let (a, b) = (w[0], w[1]);
                let hi = b.0.min(f_max);
                if hi <= a.0 {
                    return 0.0;
                }
                // S = S_a (f/f_a)^s on the segment: ∫ = S_a f_a (e^{(s+1)l} − 1)/(s + 1).
                let s = (b.1 / a.1).ln() / (b.0 / a.0).ln();
                let l = (hi / a.0).ln();
                let x = (s + 1.0) * l;
                let integral = if x.abs() < 1e-9 {
                    l * (1.0 + 0.5 * x)
                } else {
                    x.exp_m1() / (s + 1.0)
                };
                a.1 * a.0 * integral
            })
            .sum()
    }
}

/// Vibration of a run: sinusoids and random vibrations, SI units.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VibrationSpec {
    /// Sinusoids (any number per axis).
    pub sines: Vec<Sine>,
    /// Random vibrations (at most one per sensor axis).
    pub randoms: Vec<Random>,
}

impl VibrationSpec {
    /// True when there is nothing to add (the stage need not be built).
    pub fn is_empty(&self) -> bool {
        self.sines.is_empty() && self.randoms.is_empty()
    }
}

/// The spec entry an error is about (indices from 0, as in the spec's lists).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entry {
    /// Sinusoid i.
    Sine(usize),
    /// Random vibration i.
    Random(usize),
    /// Row j of random vibration i's PSD table.
    Row(usize, usize),
}

impl fmt::Display for Entry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Entry::Sine(i) => write!(f, "sines[{i}]"),
            Entry::Random(i) => write!(f, "random[{i}]"),
            Entry::Row(i, j) => write!(f, "random[{i}].psd[{j}]"),
        }
    }
}

/// A vibration spec that cannot be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VibrationError {
    /// The record step is not finite and positive.
    #[error("vibration: the step Δt = {} s must be finite and positive", compact(*.dt))]
    Step {
        /// Step (s).
        dt: f64,
    },
    /// Axis outside 0..3.
    #[error("vibration {entry}: axis {axis} is not 0, 1 or 2 (x, y, z)")]
    Axis {
        /// Entry.
        entry: Entry,
        /// Axis given.
        axis: usize,
    },
    /// A NaN or infinite number.
    #[error("vibration {entry}: {what} = {} is not finite", compact(*.value))]
    NotFinite {
        /// Entry.
        entry: Entry,
        /// Which number.
        what: &'static str,
        /// Value given.
        value: f64,
    },
    /// A negative sinusoid amplitude.
    #[error(
        "vibration {entry}: amplitude {} must be ≥ 0 (use the phase for the sign)",
        compact(*.value)
    )]
    Amplitude {
        /// Entry.
        entry: Entry,
        /// Value given.
        value: f64,
    },
    /// A frequency ≤ 0.
    #[error("vibration {entry}: frequency {} Hz must be positive", compact(*.freq_hz))]
    Frequency {
        /// Entry.
        entry: Entry,
        /// Value given (Hz).
        freq_hz: f64,
    },
    /// A PSD value ≤ 0.
    #[error(
        "vibration {entry}: PSD {} must be positive (the table is interpolated log-log; \
         end the table instead of writing 0)",
        compact(*.value)
    )]
    Psd {
        /// Entry.
        entry: Entry,
        /// Value given (unit²/Hz).
        value: f64,
    },
    /// Table frequencies not strictly increasing.
    #[error(
        "vibration {entry}: {} Hz does not exceed the previous row's {} Hz",
        compact(*.freq_hz),
        compact(*.previous_hz)
    )]
    NotIncreasing {
        /// Entry.
        entry: Entry,
        /// Value given (Hz).
        freq_hz: f64,
        /// The previous row's frequency (Hz).
        previous_hz: f64,
    },
    /// A PSD table with fewer than two rows.
    #[error("vibration {entry}: a PSD table needs at least two rows, it has {rows}")]
    TooFewRows {
        /// Entry.
        entry: Entry,
        /// Rows given.
        rows: usize,
    },
    /// A sinusoid above Nyquist, or a PSD table starting at or above it.
    #[error(
        "vibration {entry}: {} Hz is above the Nyquist frequency {} Hz of the record rate",
        compact(*.freq_hz),
        compact(*.nyquist_hz)
    )]
    AboveNyquist {
        /// Entry.
        entry: Entry,
        /// The sinusoid's frequency or the table's first frequency (Hz).
        freq_hz: f64,
        /// 1/(2Δt) (Hz).
        nyquist_hz: f64,
    },
    /// Two random vibrations on the same sensor axis.
    #[error(
        "vibration {entry}: {sensor} axis {axis} already has a random vibration (random[{first}]); \
         merge the tables"
    )]
    Duplicate {
        /// Entry.
        entry: Entry,
        /// Sensor name.
        sensor: &'static str,
        /// Axis.
        axis: usize,
        /// Index of the first random vibration on that axis.
        first: usize,
    },
}

/// What was built for one random vibration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RandomSummary {
    /// Triad.
    pub sensor: Sensor,
    /// Axis.
    pub axis: usize,
    /// FIR length N.
    pub taps: usize,
    /// Design spacing fs/N (Hz); a table's ends are spread over about ±3 of these.
    pub resolution_hz: f64,
    /// RMS of the generated record values, exactly √Σh² (rad/s or m/s²).
    pub rms: f64,
    /// RMS of the table as written, √∫PSD df (before the Nyquist cut and the interval mean).
    pub rms_spec: f64,
    /// Where the table was cut at Nyquist (Hz), when it extends beyond.
    pub truncated_at_hz: Option<f64>,
}

/// Vibration generator: one sample of every term per record.
#[derive(Clone, Debug)]
pub struct Vibration {
    sines: Vec<SineTerm>,
    randoms: Vec<RandomChannel>,
    k: u64,
    /// C: the spec's axes to the sensed axes, when they differ (a rig unit turned on a body
    /// whose vibration the spec gives).
    axes: Option<Mat3>,
}

impl Vibration {
    /// Validates `spec` and builds the generator for records of step Δt, master seed `seed`.
    pub fn new(spec: &VibrationSpec, dt: f64, seed: u64) -> Result<Vibration, VibrationError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(VibrationError::Step { dt });
        }
        let nyquist_hz = 0.5 / dt;
        let sines = spec
            .sines
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let entry = Entry::Sine(i);
                check_axis(entry, s.axis)?;
                for (what, value) in [
                    ("amplitude", s.amplitude),
                    ("frequency", s.freq_hz),
                    ("phase", s.phase_rad),
                ] {
                    check_finite(entry, what, value)?;
                }
                if s.amplitude < 0.0 {
                    return Err(VibrationError::Amplitude {
                        entry,
                        value: s.amplitude,
                    });
                }
                if s.freq_hz <= 0.0 {
                    return Err(VibrationError::Frequency {
                        entry,
                        freq_hz: s.freq_hz,
                    });
                }
                if s.freq_hz > nyquist_hz {
                    return Err(VibrationError::AboveNyquist {
                        entry,
                        freq_hz: s.freq_hz,
                        nyquist_hz,
                    });
                }
                Ok(SineTerm::new(s, dt))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut first_on_slot = [None; 6];
        let mut randoms = Vec::with_capacity(spec.randoms.len());
        for (i, r) in spec.randoms.iter().enumerate() {
            check_table(i, r, nyquist_hz)?;
            let slot = slot(r.sensor, r.axis);
            if let Some(first) = first_on_slot[slot] {
                return Err(VibrationError::Duplicate {
                    entry: Entry::Random(i),
                    sensor: r.sensor.name(),
                    axis: r.axis,
                    first,
                });
            }
            first_on_slot[slot] = Some(i);
            randoms.push(RandomChannel::new(r, dt, seed));
        }
        Ok(Vibration {
            sines,
            randoms,
            k: 0,
            axes: None,
        })
    }

    /// The same vibration sensed in axes turned by `c` from the spec's (C_b^c: the spec
    /// gives the body's vibration, a unit mounted by C_c^b senses C_b^c v): one realization,
    /// rotated, so units on one grid see the same body motion.
    pub fn in_axes(mut self, c: Option<Mat3>) -> Vibration {
        self.axes = c.filter(|c| *c != Mat3::identity());
        self
    }

    /// The vibration to add to the next record's interval-mean gyro (rad/s) and accel (m/s²);
    /// the first call gives record k = 1, over (t₀, t₀ + Δt].
    #[allow(clippy::should_implement_trait)] // an endless generator, not an iterator
    #[inline]
    pub fn next(&mut self) -> (Vec3, Vec3) {
        self.k += 1;
        let mut v = [0.0; 6];
        for s in &self.sines {
            v[s.slot] += s.at(self.k);
        }
        for r in &mut self.randoms {
            v[r.slot] += r.sample();
        }
        let (g, a) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
        match &self.axes {
            Some(c) => (c * g, c * a),
            None => (g, a),
        }
    }

    /// What was built for each random vibration, in spec order.
    pub fn random_summaries(&self) -> impl Iterator<Item = &RandomSummary> {
        self.randoms.iter().map(|r| &r.summary)
    }

    /// True when the spec had no terms.
    pub fn is_empty(&self) -> bool {
        self.sines.is_empty() && self.randoms.is_empty()
    }
}

fn check_axis(entry: Entry, axis: usize) -> Result<(), VibrationError> {
    if axis > 2 {
        return Err(VibrationError::Axis { entry, axis });
    }
    Ok(())
}

fn check_finite(entry: Entry, what: &'static str, value: f64) -> Result<(), VibrationError> {
    if !value.is_finite() {
        return Err(VibrationError::NotFinite { entry, what, value });
    }
    Ok(())
}

fn check_table(i: usize, r: &Random, nyquist_hz: f64) -> Result<(), VibrationError> {
    check_axis(Entry::Random(i), r.axis)?;
    if r.psd.len() < 2 {
        return Err(VibrationError::TooFewRows {
            entry: Entry::Random(i),
            rows: r.psd.len(),
        });
    }
    for (j, &(f, s)) in r.psd.iter().enumerate() {
        let entry = Entry::Row(i, j);
        check_finite(entry, "frequency", f)?;
        check_finite(entry, "PSD", s)?;
        if f <= 0.0 {
            return Err(VibrationError::Frequency { entry, freq_hz: f });
        }
        if s <= 0.0 {
            return Err(VibrationError::Psd { entry, value: s });
        }
        if j > 0 && f <= r.psd[j - 1].0 {
            return Err(VibrationError::NotIncreasing {
                entry,
                freq_hz: f,
                previous_hz: r.psd[j - 1].0,
            });
        }
    }
    if r.psd[0].0 >= nyquist_hz {
        return Err(VibrationError::AboveNyquist {
            entry: Entry::Random(i),
            freq_hz: r.psd[0].0,
            nyquist_hz,
        });
    }
    Ok(())
}

/// sin x / x.
fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-4 {
        1.0 - x * x / 6.0
    } else {
        x.sin() / x
    }
}

#[cfg(test)]
mod tests;
