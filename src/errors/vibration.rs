//! Vibration on the sensed angular rate and specific force: sinusoids, and stationary Gaussian
//! random vibration given as a one-sided PSD table, to be added to each record's interval-mean
//! rates (DESIGN §2–4).
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
//! Streams (DESIGN §4): random vibration of sensor s, axis a draws from
//! `vibration/{gyro|accel}/{x|y|z}/random`, so adding or removing any other term leaves it
//! bit-identical. One random vibration per sensor axis: a table expresses any shape.

use crate::math::Vec3;
use crate::rng::NormalStream;
use std::f64::consts::{PI, TAU};
use std::fmt;

/// Smallest FIR length.
pub const MIN_TAPS: usize = 1023;
/// Largest FIR length (FFT blocks of 32768).
pub const MAX_TAPS: usize = 16383;
/// The design spacing fs/N is at most this fraction of a table's lowest frequency and width.
pub const RESOLUTION_BINS: f64 = 64.0;

const AXES: [&str; 3] = ["x", "y", "z"];

/// The triad a vibration acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sensor {
    /// Angular rate (rad/s).
    Gyro,
    /// Specific force (m/s²).
    Accel,
}

impl Sensor {
    /// The name used in stream names: `gyro` or `accel`.
    pub fn name(self) -> &'static str {
        match self {
            Sensor::Gyro => "gyro",
            Sensor::Accel => "accel",
        }
    }
    fn slot(self, axis: usize) -> usize {
        3 * (self as usize) + axis
    }
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
    #[error("vibration: the step Δt = {dt} s must be finite and positive")]
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
    #[error("vibration {entry}: {what} = {value} is not finite")]
    NotFinite {
        /// Entry.
        entry: Entry,
        /// Which number.
        what: &'static str,
        /// Value given.
        value: f64,
    },
    /// A negative sinusoid amplitude.
    #[error("vibration {entry}: amplitude {value} must be ≥ 0 (use the phase for the sign)")]
    Amplitude {
        /// Entry.
        entry: Entry,
        /// Value given.
        value: f64,
    },
    /// A frequency ≤ 0.
    #[error("vibration {entry}: frequency {freq_hz} Hz must be positive")]
    Frequency {
        /// Entry.
        entry: Entry,
        /// Value given (Hz).
        freq_hz: f64,
    },
    /// A PSD value ≤ 0.
    #[error(
        "vibration {entry}: PSD {value} must be positive (the table is interpolated log-log; \
         end the table instead of writing 0)"
    )]
    Psd {
        /// Entry.
        entry: Entry,
        /// Value given (unit²/Hz).
        value: f64,
    },
    /// Table frequencies not strictly increasing.
    #[error("vibration {entry}: {freq_hz} Hz does not exceed the previous row's {previous_hz} Hz")]
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
        "vibration {entry}: {freq_hz} Hz is above the Nyquist frequency {nyquist_hz} Hz of the \
         record rate"
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
            let slot = r.sensor.slot(r.axis);
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
        })
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
        (Vec3([v[0], v[1], v[2]]), Vec3([v[3], v[4], v[5]]))
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

/// Dekker's split of a into a high half and the rest (a = hi + lo exactly).
#[inline]
fn split(a: f64) -> (f64, f64) {
    let t = 134_217_729.0 * a;
    let hi = t - (t - a);
    (hi, a - hi)
}

/// The rounding error of p = fl(a·b): a·b = p + err exactly (Dekker; b given split).
#[inline]
fn product_error(a: f64, (bh, bl): (f64, f64), p: f64) -> f64 {
    let (ah, al) = split(a);
    ((ah * bh - p) + ah * bl + al * bh) + al * bl
}

/// Nearest integer for 0 ≤ x < 2⁵¹ without a libm call (as in `process.rs`).
#[inline]
fn round_small(x: f64) -> f64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    if x.abs() < 2_251_799_813_685_248.0 {
        (x + MAGIC) - MAGIC
    } else {
        x.round()
    }
}

/// One sinusoid, as its interval mean.
#[derive(Clone, Debug)]
struct SineTerm {
    slot: usize,
    /// A·sinc(πfΔt).
    mean_amplitude: f64,
    /// Cycles per record f·Δt = c_hi + c_lo (double-double).
    c_hi: f64,
    c_hi_split: (f64, f64),
    c_lo: f64,
    phase: f64,
}

impl SineTerm {
    fn new(s: &Sine, dt: f64) -> SineTerm {
        let c_hi = s.freq_hz * dt;
        let c_lo = product_error(s.freq_hz, split(dt), c_hi);
        SineTerm {
            slot: s.sensor.slot(s.axis),
            mean_amplitude: s.amplitude * sinc(PI * s.freq_hz * dt),
            c_hi,
            c_hi_split: split(c_hi),
            c_lo,
            phase: s.phase_rad,
        }
    }
    /// Record k's value: the mean over ((k − 1)Δt, kΔt] = A·sinc·sin(2πf(k − ½)Δt + φ).
    #[inline]
    fn at(&self, k: u64) -> f64 {
        let m = k as f64 - 0.5; // exact for k < 2⁵²
        let p = m * self.c_hi;
        let tail = product_error(m, self.c_hi_split, p) + m * self.c_lo;
        let cycles = (p - round_small(p)) + tail;
        self.mean_amplitude * (TAU * cycles + self.phase).sin()
    }
}

/// The FIR of a random vibration (N odd, linear phase) and where its table was cut.
struct Design {
    h: Vec<f64>,
    truncated_at_hz: Option<f64>,
}

/// Frequency-sampling design of |H| = √(S/(2Δt))·sinc(πfΔt) (module doc), with the table's
/// ends moved out so that Σh² keeps the target variance.
fn design(r: &Random, dt: f64) -> Design {
    let fs = 1.0 / dt;
    let nyquist = 0.5 * fs;
    let (f_first, f_last) = (r.psd[0].0, r.psd[r.psd.len() - 1].0);
    let top = f_last.min(nyquist);
    let feature = f_first.min(top - f_first);
    let wanted = RESOLUTION_BINS * fs / feature;
    let taps = if wanted >= MAX_TAPS as f64 {
        MAX_TAPS
    } else {
        ((wanted as usize) + 1).next_power_of_two() - 1
    }
    .max(MIN_TAPS);
    let fft = Fft::new(8 * (taps + 1));
    // A table's end at Nyquist is no edge: the two-sided target is continuous there.
    let cut_top = f_last < nyquist;
    let fir_with = |delta: f64| {
        let lo = (f_first - delta).max(0.0);
        let hi = (f_last + delta).min(nyquist);
        fir(r, dt, taps, &fft, lo, cut_top.then_some(hi))
    };
    // The window spreads each end (a jump of the amplitude to 0) symmetrically, which loses
    // power: ∫(a⊛K)² < ∫a² across the jump, half a design bin of the end's level per end
    // (0.46 % of a 200-bin band). Moving each end out by δ = lost power / Σ(end levels) gives
    // it back and changes only the spread-out zone itself; a second step takes up what the
    // levels' slopes near the ends and the rounding of kinks leave (measured: Σh² within 1e-5 of
    // the target, 6e-5 for tables finer than the FIR resolves).
    let target = band_variance(r, dt, top);
    let level = |f: f64| r.psd_at(f) * sinc(PI * f * dt).powi(2);
    let ends = level(f_first) + if cut_top { level(f_last) } else { 0.0 };
    let max_shift = 2.0 * fs / taps as f64;
    let mut delta = 0.0;
    let mut h = fir_with(delta);
    for _ in 0..2 {
        let lost = target - h.iter().map(|v| v * v).sum::<f64>();
        delta = (delta + lost / ends).clamp(-max_shift, max_shift);
        h = fir_with(delta);
    }
    Design {
        h,
        truncated_at_hz: (f_last > nyquist).then_some(nyquist),
    }
}

/// The windowed FIR for the table with its ends placed at lo and hi (None: up to Nyquist),
/// holding the end values beyond the table. The target is area-sampled (each grid cell
/// weighted by the part of it inside [lo, hi]) so the ends' positions act continuously.
fn fir(r: &Random, dt: f64, taps: usize, fft: &Fft, lo: f64, hi: Option<f64>) -> Vec<f64> {
    let g = fft.len();
    let fs = 1.0 / dt;
    let cell = fs / g as f64;
    let (f_first, f_last) = (r.psd[0].0, r.psd[r.psd.len() - 1].0);
    let (mut re, mut im) = (vec![0.0; g], vec![0.0; g]);
    // The part of a cell inside the band, counting its mirror images about 0 and fs, which
    // reach the cells at 0 Hz and at Nyquist. Up to Nyquist the band on the circle of period
    // fs is the single interval [lo, fs − lo], its own image about fs.
    let overlap = |f: f64, a: f64, b: f64| {
        ((f + 0.5 * cell).min(b) - (f - 0.5 * cell).max(a)).max(0.0) / cell
    };
    let band = |f: f64| match hi {
        Some(hi) => overlap(f, lo, hi) + overlap(f, -hi, -lo) + overlap(f, fs - hi, fs - lo),
        None => overlap(f, lo, fs - lo) + overlap(f, lo - fs, -lo),
    };
    for k in 0..=g / 2 {
        let f = k as f64 * cell;
        let inside = band(f);
        if inside > 0.0 {
            let s = r.psd_at(f.clamp(f_first, f_last));
            let d = inside * (0.5 * s * fs).sqrt() * sinc(PI * f * dt);
            re[k] = d;
            if k > 0 && k < g / 2 {
                re[g - k] = d;
            }
        }
    }
    // Real and even: the transform's direction does not matter.
    fft.forward(&mut re, &mut im);
    let mid = (taps - 1) / 2;
    let w = TAU / (taps - 1) as f64;
    (0..taps)
        .map(|n| {
            let blackman = 0.42 - 0.5 * (w * n as f64).cos() + 0.08 * (2.0 * w * n as f64).cos();
            re[(n + g - mid) % g] / g as f64 * blackman
        })
        .collect()
}

/// ∫ S(f)·sinc²(πfΔt) df from the table's start to `top` (Hz): the variance of the interval
/// means of the vibration as specified. Simpson on each segment, where S is a power law:
/// 256 intervals leave < 1e-9 relative error.
fn band_variance(r: &Random, dt: f64, top: f64) -> f64 {
    let f = |x: f64| r.psd_at(x) * sinc(PI * x * dt).powi(2);
    r.psd
        .windows(2)
        .map(|w| {
            let (a, b) = (w[0].0, w[1].0.min(top));
            if b <= a {
                return 0.0;
            }
            let n = 256;
            let h = (b - a) / n as f64;
            let inner: f64 = (1..n)
                .map(|i| f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 })
                .sum();
            (f(a) + f(b) + inner) * h / 3.0
        })
        .sum()
}

/// One random vibration: overlap-save FFT convolution of its white-noise stream with h.
#[derive(Clone)]
struct RandomChannel {
    slot: usize,
    /// N − 1: samples of history a block needs.
    keep: usize,
    /// B = L − N + 1: outputs per block.
    block: usize,
    fft: Fft,
    /// Spectrum of h zero-padded to L, divided by L (the inverse transform's scale).
    h_re: Vec<f64>,
    h_im: Vec<f64>,
    /// N − 1 samples of history, then the 2B draws of the current block pair.
    seq: Vec<f64>,
    /// After a refill: block 1's outputs at re[keep..], block 2's at im[keep..].
    re: Vec<f64>,
    im: Vec<f64>,
    pos: usize,
    rng: NormalStream,
    summary: RandomSummary,
}

impl fmt::Debug for RandomChannel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("RandomChannel")
            .field("summary", &self.summary)
            .field("pos", &self.pos)
            .finish_non_exhaustive()
    }
}

impl RandomChannel {
    fn stream_name(r: &Random) -> String {
        format!("vibration/{}/{}/random", r.sensor.name(), AXES[r.axis])
    }

    fn new(r: &Random, dt: f64, seed: u64) -> RandomChannel {
        let Design { h, truncated_at_hz } = design(r, dt);
        let taps = h.len();
        let l = 2 * (taps + 1);
        let (keep, block) = (taps - 1, l - taps + 1);
        let fft = Fft::new(l);
        let (mut h_re, mut h_im) = (vec![0.0; l], vec![0.0; l]);
        let scale = 1.0 / l as f64;
        for (d, &v) in h_re.iter_mut().zip(&h) {
            *d = v * scale;
        }
        fft.forward(&mut h_re, &mut h_im);
        let mut rng = NormalStream::new(seed, &Self::stream_name(r));
        let mut seq = vec![0.0; keep + 2 * block];
        // The history before record 1, so the output is stationary from the start.
        for v in &mut seq[..keep] {
            *v = rng.draw();
        }
        let summary = RandomSummary {
            sensor: r.sensor,
            axis: r.axis,
            taps,
            resolution_hz: 1.0 / (dt * taps as f64),
            rms: h.iter().map(|v| v * v).sum::<f64>().sqrt(),
            rms_spec: r.variance_up_to(f64::INFINITY).sqrt(),
            truncated_at_hz,
        };
        RandomChannel {
            slot: r.sensor.slot(r.axis),
            keep,
            block,
            fft,
            h_re,
            h_im,
            seq,
            re: vec![0.0; l],
            im: vec![0.0; l],
            pos: 2 * block,
            rng,
            summary,
        }
    }

    /// Draws the next 2B samples and filters them: two blocks in one complex FFT pair (the
    /// filter is real, so the real and imaginary parts do not mix).
    #[cold]
    fn refill(&mut self) {
        let (keep, b, l) = (self.keep, self.block, self.re.len());
        for v in &mut self.seq[keep..] {
            *v = self.rng.draw();
        }
        self.re.copy_from_slice(&self.seq[..l]);
        self.im.copy_from_slice(&self.seq[b..b + l]);
        self.fft.forward(&mut self.re, &mut self.im);
        for (((r, i), hr), hi) in self
            .re
            .iter_mut()
            .zip(self.im.iter_mut())
            .zip(&self.h_re)
            .zip(&self.h_im)
        {
            let (a, c) = (*r, *i);
            *r = a * hr - c * hi;
            *i = a * hi + c * hr;
        }
        // Inverse transform as the forward one with real and imaginary parts swapped.
        self.fft.forward(&mut self.im, &mut self.re);
        self.seq.copy_within(2 * b.., 0);
        self.pos = 0;
    }

    #[inline]
    fn sample(&mut self) -> f64 {
        if self.pos == 2 * self.block {
            self.refill();
        }
        let p = self.pos;
        self.pos += 1;
        if p < self.block {
            self.re[self.keep + p]
        } else {
            self.im[self.keep + p - self.block]
        }
    }
}

/// In-place iterative radix-2 complex FFT of a power-of-two size (forward, e^{−2πijk/n},
/// unnormalised); the inverse is the forward transform with re and im swapped.
#[derive(Clone)]
struct Fft {
    /// Twiddles e^{−iπj/h} of the stage of half-length h at [h, 2h).
    tw_re: Vec<f64>,
    tw_im: Vec<f64>,
    rev: Vec<u32>,
}

impl Fft {
    fn new(n: usize) -> Fft {
        assert!(n.is_power_of_two() && (2..=1 << 31).contains(&n));
        let bits = n.trailing_zeros();
        let (mut tw_re, mut tw_im) = (vec![0.0; n], vec![0.0; n]);
        let mut h = 1;
        while h < n {
            for j in 0..h {
                let (s, c) = (-PI * j as f64 / h as f64).sin_cos();
                tw_re[h + j] = c;
                tw_im[h + j] = s;
            }
            h *= 2;
        }
        let rev = (0..n)
            .map(|i| (i.reverse_bits() >> (usize::BITS - bits)) as u32)
            .collect();
        Fft { tw_re, tw_im, rev }
    }

    fn len(&self) -> usize {
        self.rev.len()
    }

    fn forward(&self, re: &mut [f64], im: &mut [f64]) {
        let n = self.rev.len();
        assert!(re.len() == n && im.len() == n);
        for (i, &j) in self.rev.iter().enumerate() {
            let j = j as usize;
            if j > i {
                re.swap(i, j);
                im.swap(i, j);
            }
        }
        let mut h = 1;
        while h < n {
            let (wr, wi) = (&self.tw_re[h..2 * h], &self.tw_im[h..2 * h]);
            for (cr, ci) in re.chunks_exact_mut(2 * h).zip(im.chunks_exact_mut(2 * h)) {
                let (ar, br) = cr.split_at_mut(h);
                let (ai, bi) = ci.split_at_mut(h);
                for j in 0..h {
                    let tr = br[j] * wr[j] - bi[j] * wi[j];
                    let ti = br[j] * wi[j] + bi[j] * wr[j];
                    br[j] = ar[j] - tr;
                    bi[j] = ai[j] - ti;
                    ar[j] += tr;
                    ai[j] += ti;
                }
            }
            h *= 2;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const G0: f64 = 9.806_65;

    fn random(sensor: Sensor, axis: usize, psd: &[(f64, f64)]) -> Random {
        Random {
            sensor,
            axis,
            psd: psd.to_vec(),
        }
    }

    fn spec_of(randoms: Vec<Random>) -> VibrationSpec {
        VibrationSpec {
            sines: Vec::new(),
            randoms,
        }
    }

    /// n records of the slot's component.
    fn run(v: &mut Vibration, slot: usize, n: usize) -> Vec<f64> {
        (0..n)
            .map(|_| {
                let (g, a) = v.next();
                if slot < 3 { g.0[slot] } else { a.0[slot - 3] }
            })
            .collect()
    }

    /// Welch one-sided PSD estimate: Hann segments of m samples, 50 % overlap;
    /// P_j = 2Δt/Σw² · mean |Σ w x e^{−2πijn/m}|² at f_j = j/(mΔt).
    fn welch(x: &[f64], dt: f64, m: usize) -> Vec<f64> {
        let fft = Fft::new(m);
        let w: Vec<f64> = (0..m)
            .map(|n| 0.5 - 0.5 * (TAU * n as f64 / m as f64).cos())
            .collect();
        let w2: f64 = w.iter().map(|v| v * v).sum();
        let mut acc = vec![0.0; m / 2 + 1];
        let mut segments = 0;
        let mut start = 0;
        while start + m <= x.len() {
            let mut re: Vec<f64> = (0..m).map(|n| x[start + n] * w[n]).collect();
            let mut im = vec![0.0; m];
            fft.forward(&mut re, &mut im);
            for (j, a) in acc.iter_mut().enumerate() {
                *a += re[j] * re[j] + im[j] * im[j];
            }
            segments += 1;
            start += m / 2;
        }
        acc.iter()
            .map(|a| 2.0 * dt / w2 * a / segments as f64)
            .collect()
    }

    /// Two-sided Σ_l ρ(l)² of the process with FIR h: the variance factor of sample
    /// correlations (sd of a sample correlation over n samples ≈ √(Σρ²/n)).
    fn sum_rho2(h: &[f64]) -> f64 {
        let var: f64 = h.iter().map(|v| v * v).sum();
        let n = h.len();
        let mut s = 1.0;
        for lag in 1..n {
            let c: f64 = (0..n - lag).map(|i| h[i] * h[i + lag]).sum::<f64>() / var;
            s += 2.0 * c * c;
        }
        s
    }

    /// Normalised sample correlation of x[i] and y[i + lag] (zero-mean processes).
    fn corr(x: &[f64], y: &[f64], lag: usize) -> f64 {
        let n = x.len().min(y.len() - lag);
        let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
        for i in 0..n {
            sxy += x[i] * y[i + lag];
            sxx += x[i] * x[i];
            syy += y[i + lag] * y[i + lag];
        }
        sxy / (sxx * syy).sqrt()
    }

    #[test]
    fn fft_matches_the_direct_dft() {
        for n in [2usize, 8, 64, 512] {
            let mut s = NormalStream::new(1, "vibration/test/fft");
            let x: Vec<(f64, f64)> = (0..n).map(|_| (s.draw(), s.draw())).collect();
            let (mut re, mut im): (Vec<f64>, Vec<f64>) = x.iter().copied().unzip();
            Fft::new(n).forward(&mut re, &mut im);
            for k in 0..n {
                let (mut dr, mut di) = (0.0, 0.0);
                for (j, &(a, b)) in x.iter().enumerate() {
                    let (sn, cs) = (-TAU * ((j * k) % n) as f64 / n as f64).sin_cos();
                    dr += a * cs - b * sn;
                    di += a * sn + b * cs;
                }
                assert!((re[k] - dr).abs() < 1e-12 * n as f64, "n {n} k {k}");
                assert!((im[k] - di).abs() < 1e-12 * n as f64, "n {n} k {k}");
            }
            // Inverse by swapping parts, then 1/n.
            Fft::new(n).forward(&mut im, &mut re);
            for (k, &(a, b)) in x.iter().enumerate() {
                assert!(
                    (re[k] / n as f64 - a).abs() < 1e-13 && (im[k] / n as f64 - b).abs() < 1e-13
                );
            }
        }
    }

    #[test]
    fn psd_table_interpolates_log_log() {
        // +3 dB/oct (PSD ∝ f) from 20 to 80 Hz, then flat to 400 Hz.
        let r = random(
            Sensor::Accel,
            2,
            &[(20.0, 1e-3), (80.0, 4e-3), (400.0, 4e-3)],
        );
        assert!((r.psd_at(40.0) / 2e-3 - 1.0).abs() < 1e-14);
        assert_eq!(r.psd_at(20.0), 1e-3);
        assert_eq!(r.psd_at(400.0), 4e-3);
        assert_eq!(r.psd_at(200.0), 4e-3);
        assert_eq!(r.psd_at(19.999), 0.0);
        assert_eq!(r.psd_at(400.001), 0.0);
        // ∫ 1e-3 f/20 df over [20, 80] = 0.15, then 4e-3 × 320 = 1.28.
        assert!((r.variance_up_to(f64::INFINITY) - 1.43).abs() < 1e-13);
        assert!((r.variance_up_to(200.0) - 0.63).abs() < 1e-13);
        assert_eq!(r.variance_up_to(10.0), 0.0);
        // The numerical band variance (with sinc² → 1 for a tiny step) agrees.
        assert!((band_variance(&r, 1e-9, f64::INFINITY) / 1.43 - 1.0).abs() < 1e-9);
        // S ∝ 1/f uses the logarithmic form: ∫ = S_a f_a ln(f_b/f_a).
        let s = random(Sensor::Gyro, 0, &[(10.0, 1e-2), (100.0, 1e-3)]);
        assert!((s.variance_up_to(f64::INFINITY) - 0.1 * 10f64.ln()).abs() < 1e-15);
    }

    /// The closed form is the interval mean of A sin(ωt + φ) (checked against Simpson), and
    /// each record equals A/(ωΔt)·[cos(ωt_{k−1} + φ) − cos(ωt_k + φ)]; other axes stay 0.
    /// Tolerance 1e-12·A: the reference's arguments ωt ≤ 315 rad carry an ulp of 6e-14, which
    /// the difference of cosines amplifies by 1/(ωΔt) = 6.4.
    #[test]
    fn sine_interval_mean_is_exact() {
        let (a, f, phi, dt) = (0.3, 25.0, 0.7, 1e-3);
        let spec = VibrationSpec {
            sines: vec![Sine {
                sensor: Sensor::Gyro,
                axis: 1,
                amplitude: a,
                freq_hz: f,
                phase_rad: phi,
            }],
            randoms: Vec::new(),
        };
        let mut v = Vibration::new(&spec, dt, 1).unwrap();
        let w = TAU * f;
        for k in 1..=2000u64 {
            let (g, acc) = v.next();
            assert_eq!((g.0[0], g.0[2], acc), (0.0, 0.0, Vec3::ZERO));
            let (t0, t1) = ((k - 1) as f64 * dt, k as f64 * dt);
            let closed = a / (w * dt) * ((w * t0 + phi).cos() - (w * t1 + phi).cos());
            assert!((g.0[1] - closed).abs() < 1e-12 * a, "k {k}");
            if k % 97 == 0 {
                let n = 200;
                let h = dt / n as f64;
                let y = |i: usize| a * (w * (t0 + i as f64 * h) + phi).sin();
                let inner: f64 = (1..n)
                    .map(|i| y(i) * if i % 2 == 1 { 4.0 } else { 2.0 })
                    .sum();
                let simpson = (y(0) + y(n) + inner) * h / 3.0 / dt;
                assert!((g.0[1] - simpson).abs() < 1e-12 * a, "k {k}");
            }
        }
    }

    /// 25 Hz at 1 kHz: 40 records per period. Over 50 whole periods the mean is 0 and the RMS
    /// is A·sinc(π/40)/√2 exactly (Σ sin² over whole periods is n/2), up to rounding.
    #[test]
    fn sine_whole_periods_mean_zero_rms_amplitude_over_sqrt2() {
        let (a, dt) = (0.5 * G0, 1e-3);
        let spec = VibrationSpec {
            sines: vec![Sine {
                sensor: Sensor::Accel,
                axis: 0,
                amplitude: a,
                freq_hz: 25.0,
                phase_rad: -1.1,
            }],
            randoms: Vec::new(),
        };
        let mut v = Vibration::new(&spec, dt, 1).unwrap();
        let x = run(&mut v, 3, 2000);
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        let expect = a * sinc(PI * 0.025) / 2f64.sqrt();
        assert!(mean.abs() < 1e-13 * a, "mean {mean:e}");
        assert!(
            (rms / expect - 1.0).abs() < 1e-13,
            "rms {rms} expected {expect}"
        );
        // The interval mean's attenuation is visible: 0.1 % below A/√2.
        assert!((rms / (a / 2f64.sqrt()) - 1.0 + 1.028e-3).abs() < 1e-5);
    }

    /// Record 8.64e7 (24 h at 1 kHz) of a 25 Hz sinusoid against the integer-exact phase
    /// 2π((2k − 1) mod 80)/80. The f64 inputs f·Δt differ from 1/40 by 5e-19, which after 2.16e6
    /// cycles is 3e-10 rad; a plain f64 product k·f·Δt would add up to ulp(2.16e6)/2 cycles
    /// = 1.5e-9 rad. 1e-9 of the amplitude therefore shows that no phase is lost.
    #[test]
    fn sine_phase_does_not_drift_over_24_h() {
        let s = Sine {
            sensor: Sensor::Gyro,
            axis: 0,
            amplitude: 1.0,
            freq_hz: 25.0,
            phase_rad: 0.3,
        };
        let term = SineTerm::new(&s, 1e-3);
        for k in [1u64, 12_345, 86_400_000 - 7, 86_400_000] {
            let cycles = ((2 * k - 1) % 80) as f64 / 80.0;
            let exact = sinc(PI * 0.025) * (TAU * cycles + 0.3).sin();
            assert!(
                (term.at(k) - exact).abs() < 1e-9,
                "k {k}: {:e}",
                term.at(k) - exact
            );
        }
    }

    /// Deterministic check of the designed filter: the PSD it imposes, 2Δt|H(f)|² (from the
    /// zero-padded FFT of h), equals the table × sinc² within 1e-3 more than 4 design bins
    /// from the table's ends and 8 from its breakpoints and Nyquist, within 1e-2 nearer to
    /// those (the rounding of a kink: the slope of √S changes there, and at Nyquist the
    /// periodic response is reflected), and leaks < 1e-5 of the end level more than 4 bins
    /// outside; a table cut at Nyquist has no end to spread. Σh² equals ∫S·sinc² within 1e-5.
    #[test]
    fn filter_response_matches_the_table() {
        let dt = 1e-3;
        for table in [
            vec![(50.0, 1e-3), (250.0, 1e-3)],
            vec![(20.0, 1e-3), (80.0, 4e-3), (400.0, 4e-3)],
            vec![(100.0, 1e-3), (200.0, 1e-4), (800.0, 1e-4)],
        ] {
            let r = random(Sensor::Accel, 2, &table);
            let h = design(&r, dt).h;
            let res = 1.0 / (dt * h.len() as f64);
            let m = 16 * (h.len() + 1);
            let (mut re, mut im) = (vec![0.0; m], vec![0.0; m]);
            re[..h.len()].copy_from_slice(&h);
            Fft::new(m).forward(&mut re, &mut im);
            let (lo, hi) = (table[0].0, table[table.len() - 1].0);
            let kinks = &table[1..table.len() - 1];
            let (mut worst_in, mut worst_kink, mut worst_out) = (0.0f64, 0.0f64, 0.0f64);
            for j in 0..=m / 2 {
                let f = j as f64 / (m as f64 * dt);
                let p = 2.0 * dt * (re[j] * re[j] + im[j] * im[j]);
                if f > lo + 4.0 * res && (f < hi - 4.0 * res || hi > 0.5 / dt) {
                    let err = (p / (r.psd_at(f) * sinc(PI * f * dt).powi(2)) - 1.0).abs();
                    let near = |k: f64| (f - k).abs() < 8.0 * res;
                    if kinks.iter().any(|k| near(k.0)) || near(0.5 / dt) {
                        worst_kink = worst_kink.max(err);
                    } else {
                        worst_in = worst_in.max(err);
                    }
                } else if f < lo - 4.0 * res || f > hi + 4.0 * res {
                    worst_out = worst_out.max(p / r.psd_at(f.clamp(lo, hi)));
                }
            }
            let var: f64 = h.iter().map(|v| v * v).sum();
            let target = band_variance(&r, dt, 0.5 / dt);
            eprintln!(
                "{table:?}: N {} res {res:.3} Hz, max rel err: in band {worst_in:.1e}, near \
                 breakpoints and Nyquist {worst_kink:.1e}; outside {worst_out:.1e} of the level; \
                 Σh²/target − 1 = {:.1e}",
                h.len(),
                var / target - 1.0
            );
            assert!(worst_in < 1e-3, "in band {worst_in:e}");
            assert!(worst_kink < 1e-2, "at breakpoints {worst_kink:e}");
            assert!(worst_out < 1e-5, "out of band {worst_out:e}");
            assert!(
                (var / target - 1.0).abs() < 1e-5,
                "variance {var} vs {target}"
            );
        }
    }

    /// The overlap-save blocks are the linear convolution of the stream with h, across block
    /// boundaries and refills, to rounding.
    #[test]
    fn blocks_equal_the_direct_convolution() {
        let r = random(Sensor::Accel, 2, &[(100.0, 1e-2), (400.0, 1e-2)]);
        let dt = 1e-3;
        let mut v = Vibration::new(&spec_of(vec![r.clone()]), dt, 9).unwrap();
        let h = design(&r, dt).h;
        let n_out = 5 * v.randoms[0].block + 17;
        let y = run(&mut v, 5, n_out);
        let mut s = NormalStream::new(9, "vibration/accel/z/random");
        let z: Vec<f64> = (0..h.len() - 1 + n_out).map(|_| s.draw()).collect();
        let rms = v.randoms[0].summary.rms;
        for (j, &yj) in y.iter().enumerate() {
            let direct: f64 = h
                .iter()
                .enumerate()
                .map(|(i, hi)| hi * z[h.len() - 1 + j - i])
                .sum();
            assert!((yj - direct).abs() < 1e-12 * rms, "sample {j}");
        }
    }

    /// Flat S = 0.01 g²/Hz over [50, 250] Hz at 1 kHz, 2¹⁹ records (524 s).
    /// Variance: the estimate's relative sd is √(2Σρ²/n), Σρ² = fs/(2W) = 2.5 → 0.31 %
    /// (calibrated: over 40 seeds the normalised errors had mean −0.04 and sd 1.06); checked
    /// at 4 sd against Σh², which itself equals S·∫sinc² within 1e-5 (previous test), i.e.
    /// against S·(f₂ − f₁) times the band's mean sinc² (0.919 here: the interval mean).
    /// PSD: Welch with 1024-sample Hann segments, 50 % overlap (1023 segments): relative sd
    /// per bin ≈ √(1.06/1023) = 3.2 %; bins are averaged in groups of 10 (adjacent Hann bins
    /// correlate, ≈ 6 independent) → ≈ 1.4 %; each group must be within 6 % (> 4 sd).
    /// Outside the table, more than 10 Hz from its ends, the estimate must be < 1e-4 of S
    /// (Hann leakage at 10 bins and the FIR's sidelobes are both far below).
    #[test]
    fn flat_band_variance_and_psd() {
        let (s, f1, f2, dt) = (0.01 * G0 * G0, 50.0, 250.0, 1e-3);
        let r = random(Sensor::Accel, 2, &[(f1, s), (f2, s)]);
        let mut v = Vibration::new(&spec_of(vec![r.clone()]), dt, 3).unwrap();
        let n = 1 << 19;
        let x = run(&mut v, 5, n);
        let sum = v.random_summaries().next().copied().unwrap();
        assert_eq!(sum.truncated_at_hz, None);
        assert!((sum.rms_spec - (s * (f2 - f1)).sqrt()).abs() < 1e-12 * sum.rms_spec);
        let var = x.iter().map(|v| v * v).sum::<f64>() / n as f64;
        let mean = x.iter().sum::<f64>() / n as f64;
        let sd = (2.0 * 2.5 / n as f64).sqrt();
        let mean_sinc2 = band_variance(&r, dt, f64::INFINITY) / (s * (f2 - f1));
        eprintln!(
            "flat: var/Σh² − 1 = {:.2e} (sd {sd:.1e}), var/(S(f2−f1)·{mean_sinc2:.4}) − 1 = \
             {:.2e}, mean {mean:.1e} (rms {:.3})",
            var / (sum.rms * sum.rms) - 1.0,
            var / (s * (f2 - f1) * mean_sinc2) - 1.0,
            sum.rms
        );
        assert!((var / (sum.rms * sum.rms) - 1.0).abs() < 4.0 * sd);
        assert!((var / (s * (f2 - f1) * mean_sinc2) - 1.0).abs() < 4.0 * sd + 1e-5);
        // No power at 0 Hz: over T = 524 s the mean is of order rms/(2πf₁T) ≈ 6e-6 rms.
        assert!(mean.abs() < 1e-4 * sum.rms);

        let m = 1024;
        let p = welch(&x, dt, m);
        let df = 1.0 / (m as f64 * dt);
        let inside: Vec<usize> = (0..p.len())
            .filter(|&j| j as f64 * df > f1 + 8.0 && (j as f64 * df) < f2 - 8.0)
            .collect();
        let (mut worst, mut ss, mut groups) = (0.0f64, 0.0, 0);
        for g in inside.chunks_exact(10) {
            let est = g.iter().map(|&j| p[j]).sum::<f64>() / 10.0;
            let tgt = g
                .iter()
                .map(|&j| s * sinc(PI * j as f64 * df * dt).powi(2))
                .sum::<f64>()
                / 10.0;
            worst = worst.max((est / tgt - 1.0).abs());
            ss += (est / tgt - 1.0).powi(2);
            groups += 1;
        }
        let outside = (0..p.len())
            .filter(|&j| {
                let f = j as f64 * df;
                f < f1 - 10.0 || f > f2 + 10.0
            })
            .map(|j| p[j] / s)
            .fold(0.0f64, f64::max);
        let rms_dev = (ss / groups as f64).sqrt();
        eprintln!(
            "flat Welch: {groups} groups, rms {rms_dev:.2e}, worst {worst:.2e}; outside max \
             {outside:.2e} of S"
        );
        assert!(worst < 0.06, "in band {worst}");
        assert!(outside < 1e-4, "out of band {outside:e}");
    }

    /// +3 dB/oct from 20 to 80 Hz then flat to 400 Hz, on a gyro axis at 1 kHz, 2¹⁹ records.
    /// Groups of 10 Welch bins within 6 % (≈ 4 sd, see above) of S·sinc² on both parts; the
    /// fitted log-log slope over 25–75 Hz is 1 (3.01 dB/oct) within 0.1: over a 1.6-octave
    /// span with ~50 bins of 3.2 % scatter each, the slope's sd is ≈ 0.02.
    #[test]
    fn two_level_table_has_its_shape() {
        let dt = 1e-3;
        let r = random(
            Sensor::Gyro,
            0,
            &[(20.0, 1e-8), (80.0, 4e-8), (400.0, 4e-8)],
        );
        let mut v = Vibration::new(&spec_of(vec![r.clone()]), dt, 4).unwrap();
        let x = run(&mut v, 0, 1 << 19);
        let m = 1024;
        let p = welch(&x, dt, m);
        let df = 1.0 / (m as f64 * dt);
        let mut worst = 0.0f64;
        for (lo, hi) in [(24.0, 76.0), (84.0, 392.0)] {
            let bins: Vec<usize> = (0..p.len())
                .filter(|&j| j as f64 * df > lo && (j as f64 * df) < hi)
                .collect();
            for g in bins.chunks_exact(10) {
                let est = g.iter().map(|&j| p[j]).sum::<f64>() / 10.0;
                let tgt = g
                    .iter()
                    .map(|&j| {
                        let f = j as f64 * df;
                        r.psd_at(f) * sinc(PI * f * dt).powi(2)
                    })
                    .sum::<f64>()
                    / 10.0;
                worst = worst.max((est / tgt - 1.0).abs());
            }
        }
        // Least-squares slope of ln P against ln f (sinc² removed) over 25–75 Hz.
        let pts: Vec<(f64, f64)> = (0..p.len())
            .map(|j| (j as f64 * df, j))
            .filter(|&(f, _)| (25.0..=75.0).contains(&f))
            .map(|(f, j)| (f.ln(), (p[j] / sinc(PI * f * dt).powi(2)).ln()))
            .collect();
        let n = pts.len() as f64;
        let (mx, my) = (
            pts.iter().map(|p| p.0).sum::<f64>() / n,
            pts.iter().map(|p| p.1).sum::<f64>() / n,
        );
        let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>()
            / pts.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
        eprintln!("two-level Welch: worst group {worst:.2e}, slope {slope:.3} (1 = +3 dB/oct)");
        assert!(worst < 0.06, "shape {worst}");
        assert!((slope - 1.0).abs() < 0.1, "slope {slope}");
    }

    /// No repetition: the sample autocorrelation at lags of one and two FFT blocks, the FFT
    /// size, and 10 and 100 FIR lengths is 0 within 5 sd (sd = √(Σρ²/n), ≈ 0.002 here — a
    /// repeating buffer would give ≈ 1 at its period); windows of 2¹⁵ records 2¹⁸ records
    /// apart are uncorrelated within 5 sd (≈ 0.009) at a few relative shifts.
    #[test]
    fn no_repetition() {
        let (s, dt) = (1e-3, 1e-3);
        let r = random(Sensor::Accel, 0, &[(50.0, s), (250.0, s)]);
        let mut v = Vibration::new(&spec_of(vec![r.clone()]), dt, 5).unwrap();
        let n = 1 << 19;
        let x = run(&mut v, 3, n);
        let ch = &v.randoms[0];
        let (taps, b) = (ch.summary.taps, ch.block);
        let rho2 = sum_rho2(&design(&r, dt).h);
        let mut worst = 0.0f64;
        for lag in [b, 2 * b, 2 * (taps + 1), 10 * taps, 100 * taps] {
            let c = corr(&x, &x, lag);
            let sd = (rho2 / (n - lag) as f64).sqrt();
            worst = worst.max(c.abs() / sd);
            assert!(c.abs() < 5.0 * sd, "lag {lag}: {c}");
        }
        let w = 1 << 15;
        let sd = (rho2 / w as f64).sqrt();
        let (a, later) = (&x[..w], &x[1 << 18..]);
        for shift in [0, 1, 7, b] {
            let c = corr(a, later, shift);
            worst = worst.max(c.abs() / sd);
            assert!(c.abs() < 5.0 * sd, "shift {shift}: {c}");
        }
        eprintln!("no repetition: N {taps}, B {b}, Σρ² {rho2:.2}, worst |r|/sd {worst:.2}");
    }

    /// Two vibrated axes with overlapping bands are uncorrelated (5 sd, sd from
    /// Cauchy–Schwarz ≤ (Σρ₁²Σρ₂²)^{1/4}/√n); adding another term or reordering leaves an
    /// axis bit-identical (own stream, DESIGN §4); a seed reproduces exactly.
    #[test]
    fn streams_are_independent_and_deterministic() {
        let dt = 1e-3;
        let az = random(Sensor::Accel, 2, &[(50.0, 1e-3), (250.0, 1e-3)]);
        let gy = random(Sensor::Gyro, 1, &[(30.0, 1e-6), (300.0, 1e-6)]);
        let sine = Sine {
            sensor: Sensor::Accel,
            axis: 1,
            amplitude: 1.0,
            freq_hz: 13.0,
            phase_rad: 0.0,
        };
        let both = VibrationSpec {
            sines: vec![sine.clone()],
            randoms: vec![gy.clone(), az.clone()],
        };
        let n = 1 << 18;
        let mut v = Vibration::new(&both, dt, 11).unwrap();
        let recs: Vec<(Vec3, Vec3)> = (0..n).map(|_| v.next()).collect();
        let x: Vec<f64> = recs.iter().map(|r| r.1.0[2]).collect();
        let y: Vec<f64> = recs.iter().map(|r| r.0.0[1]).collect();
        let sd = (sum_rho2(&design(&az, dt).h) * sum_rho2(&design(&gy, dt).h))
            .sqrt()
            .sqrt()
            / (n as f64).sqrt();
        for lag in [0, 1, 5, 100] {
            assert!(corr(&x, &y, lag).abs() < 5.0 * sd, "lag {lag}");
            assert!(corr(&y, &x, lag).abs() < 5.0 * sd, "lag −{lag}");
        }
        // Alone, first in the list, or with other terms: the same accel z values.
        let mut alone = Vibration::new(&spec_of(vec![az.clone()]), dt, 11).unwrap();
        assert_eq!(run(&mut alone, 5, 5000), x[..5000]);
        let reordered = VibrationSpec {
            sines: vec![sine],
            randoms: vec![az.clone(), gy],
        };
        let mut again = Vibration::new(&reordered, dt, 11).unwrap();
        let recs2: Vec<(Vec3, Vec3)> = (0..5000).map(|_| again.next()).collect();
        assert_eq!(recs2, recs[..5000]);
        let mut other = Vibration::new(&spec_of(vec![az]), dt, 12).unwrap();
        assert_ne!(run(&mut other, 5, 10), x[..10]);
    }

    #[test]
    fn table_past_nyquist_is_cut() {
        let s = 1e-3;
        let r = random(Sensor::Accel, 0, &[(100.0, s), (800.0, s)]);
        let v = Vibration::new(&spec_of(vec![r.clone()]), 1e-3, 1).unwrap();
        let sum = *v.random_summaries().next().unwrap();
        assert_eq!(sum.truncated_at_hz, Some(500.0));
        assert!((sum.rms_spec - (s * 700.0).sqrt()).abs() < 1e-12);
        let target = band_variance(&r, 1e-3, 500.0).sqrt();
        assert!(
            (sum.rms / target - 1.0).abs() < 1e-5,
            "{} vs {target}",
            sum.rms
        );
    }

    /// Tables finer than the largest FIR resolves (fs/N = 0.06 Hz at 1 kHz): starting at
    /// 0.01 Hz, a 1 Hz band, a band across Nyquist. The shape is smoothed over a few bins, but
    /// the filter is finite and keeps the target variance (measured within 6e-5).
    #[test]
    fn extreme_tables_keep_their_variance() {
        let dt = 1e-3;
        for table in [
            vec![(0.01, 1e-3), (10.0, 1e-3)],
            vec![(100.0, 1e-3), (101.0, 1e-3)],
            vec![(499.0, 1e-3), (501.0, 1e-3)],
        ] {
            let r = random(Sensor::Accel, 0, &table);
            let h = design(&r, dt).h;
            assert_eq!(h.len(), MAX_TAPS);
            assert!(h.iter().all(|v| v.is_finite()));
            let var: f64 = h.iter().map(|v| v * v).sum();
            let target = band_variance(&r, dt, 0.5 / dt);
            assert!(
                (var / target - 1.0).abs() < 2e-4,
                "{table:?}: {var} vs {target}"
            );
        }
    }

    #[test]
    fn bad_specs_name_the_entry() {
        let dt = 1e-3;
        let ok = random(Sensor::Accel, 0, &[(10.0, 1e-3), (100.0, 1e-3)]);
        let with = |r: Random| spec_of(vec![ok.clone(), r]);
        let err = |spec: VibrationSpec| Vibration::new(&spec, dt, 1).unwrap_err();
        let e = err(with(random(Sensor::Gyro, 3, &[(1.0, 1.0), (2.0, 1.0)])));
        assert_eq!(
            e,
            VibrationError::Axis {
                entry: Entry::Random(1),
                axis: 3
            }
        );
        let e = err(with(random(Sensor::Gyro, 0, &[(1.0, 1.0), (2.0, 0.0)])));
        assert!(matches!(
            e,
            VibrationError::Psd {
                entry: Entry::Row(1, 1),
                ..
            }
        ));
        assert!(e.to_string().contains("random[1].psd[1]"), "{e}");
        let e = err(with(random(Sensor::Gyro, 0, &[(1.0, -1.0), (2.0, 1.0)])));
        assert!(matches!(
            e,
            VibrationError::Psd {
                entry: Entry::Row(1, 0),
                ..
            }
        ));
        let e = err(with(random(Sensor::Gyro, 0, &[(5.0, 1.0), (5.0, 1.0)])));
        assert!(matches!(
            e,
            VibrationError::NotIncreasing {
                entry: Entry::Row(1, 1),
                ..
            }
        ));
        let e = err(with(random(Sensor::Gyro, 0, &[(0.0, 1.0), (5.0, 1.0)])));
        assert!(matches!(
            e,
            VibrationError::Frequency {
                entry: Entry::Row(1, 0),
                ..
            }
        ));
        let e = err(with(random(
            Sensor::Gyro,
            0,
            &[(1.0, f64::NAN), (5.0, 1.0)],
        )));
        assert!(matches!(
            e,
            VibrationError::NotFinite {
                entry: Entry::Row(1, 0),
                what: "PSD",
                ..
            }
        ));
        let e = err(with(random(Sensor::Gyro, 0, &[(500.0, 1.0), (900.0, 1.0)])));
        assert!(matches!(
            e,
            VibrationError::AboveNyquist {
                entry: Entry::Random(1),
                ..
            }
        ));
        assert!(e.to_string().contains("Nyquist frequency 500 Hz"), "{e}");
        let e = err(with(random(Sensor::Gyro, 0, &[(5.0, 1.0)])));
        assert_eq!(
            e,
            VibrationError::TooFewRows {
                entry: Entry::Random(1),
                rows: 1
            }
        );
        let e = err(with(random(Sensor::Accel, 0, &[(5.0, 1.0), (9.0, 1.0)])));
        assert!(matches!(
            e,
            VibrationError::Duplicate {
                entry: Entry::Random(1),
                first: 0,
                ..
            }
        ));
        let sine = |amplitude: f64, freq_hz: f64, axis: usize| VibrationSpec {
            sines: vec![Sine {
                sensor: Sensor::Gyro,
                axis,
                amplitude,
                freq_hz,
                phase_rad: 0.0,
            }],
            randoms: Vec::new(),
        };
        assert!(matches!(
            err(sine(1.0, 501.0, 0)),
            VibrationError::AboveNyquist {
                entry: Entry::Sine(0),
                ..
            }
        ));
        assert!(matches!(
            err(sine(1.0, 0.0, 0)),
            VibrationError::Frequency {
                entry: Entry::Sine(0),
                ..
            }
        ));
        assert!(matches!(
            err(sine(-1.0, 5.0, 0)),
            VibrationError::Amplitude { .. }
        ));
        assert!(matches!(
            err(sine(f64::INFINITY, 5.0, 0)),
            VibrationError::NotFinite {
                what: "amplitude",
                ..
            }
        ));
        assert!(matches!(
            err(sine(1.0, 5.0, 7)),
            VibrationError::Axis {
                entry: Entry::Sine(0),
                axis: 7
            }
        ));
        assert!(Vibration::new(&sine(1.0, 500.0, 0), dt, 1).is_ok());
        assert!(matches!(
            Vibration::new(&sine(1.0, 5.0, 0), 0.0, 1),
            Err(VibrationError::Step { .. })
        ));
        let empty = Vibration::new(&VibrationSpec::default(), dt, 1).unwrap();
        assert!(empty.is_empty() && VibrationSpec::default().is_empty());
    }
}
