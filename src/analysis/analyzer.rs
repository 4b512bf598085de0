//! One pass over six-channel IMU data (gyro x y z, accel x y z): statistics, octave Allan
//! deviation, Welch PSD and the IEEE term fit of every channel, in memory independent of the
//! record length.

use super::blocks::BlockMeans;
use super::confidence::NoiseType;
use super::fit::{Fit, fit};
use super::lattice::{Lattice, LatticeScan};
use super::octave_adev::{AdevPoint, OctaveAdev};
use super::psd::{Psd, Welch};
use super::stats::Stats;
use super::transients::{GapCursor, Transients};
use crate::record::Record;

/// Channel names, in the order of the six values.
pub const CHANNELS: [&str; 6] = [
    "gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z",
];

/// Default Welch segment length (samples).
pub const DEFAULT_SEGMENT: usize = 1 << 14;

/// Longest Welch segment (samples): 2²⁰, 17 min at 1 kHz, a frequency resolution of 1 mHz,
/// below which the Allan deviation is the better estimator. Each channel holds a segment's
/// samples, window and FFT scratch (40 bytes a sample): 2²⁰ is 250 MB over six channels,
/// where 2²⁸ once asked for 60 GB before reading a byte.
pub const MAX_SEGMENT: usize = 1 << 20;

pub use crate::units::bounds::MAX_RATE_HZ;

/// Refuses a Welch segment length that is not a power of two in 8..=[`MAX_SEGMENT`], naming
/// the limit.
pub fn check_segment(segment: usize) -> Result<(), String> {
    if segment.is_power_of_two() && (8..=MAX_SEGMENT).contains(&segment) {
        Ok(())
    } else {
        Err(format!(
            "segment: {segment} samples; expected a power of two from 8 to {MAX_SEGMENT} (2^20)"
        ))
    }
}

/// Refuses a sampling rate that is not in (0, [`MAX_RATE_HZ`]] Hz, the bound of every rate
/// the program takes, naming it (`--rate 1e300` made Δt 1e-300 s and every τ and frequency
/// meaningless).
pub fn check_rate(rate: f64) -> Result<(), String> {
    if rate > 0.0 && rate <= MAX_RATE_HZ {
        Ok(())
    } else {
        Err(format!(
            "rate: {} Hz; expected a sampling rate in (0, {}] Hz",
            crate::csvio::num(rate),
            crate::csvio::num(MAX_RATE_HZ)
        ))
    }
}

/// Streaming analysis of six channels.
pub struct Analyzer {
    stats: [Stats; 6],
    adev: [OctaveAdev; 6],
    psd: [Welch; 6],
    lattice: [LatticeScan; 6],
    blocks: BlockMeans,
    n: u64,
    t_first: f64,
    t_prev: f64,
    step_min: f64,
    step_max: f64,
    /// Sample index (0-based, the later sample of the step) and time of the smallest and
    /// largest step.
    step_min_at: (u64, f64),
    step_max_at: (u64, f64),
    /// Samples to leave out of the statistics, the Allan deviation and the PSD.
    gaps: GapCursor,
    /// The last sample given (a dropped sample's stand-in in the Allan deviation and PSD).
    last: [f64; 6],
    /// The record's first step (s), which no earlier step can call long.
    first_step: f64,
    /// Steps over [`LONG_STEP`] times the smallest before them: (index of the step's later
    /// sample, the step), at most [`MAX_LONG_STEPS`] — where samples may have been dropped.
    long_steps: Vec<(u64, f64)>,
    /// More long steps than are kept.
    long_overflow: bool,
}

/// A step this many times the smallest so far is kept as a possible drop.
const LONG_STEP: f64 = 1.5;

/// Long steps kept; a record with more is not one with a few dropped samples.
pub const MAX_LONG_STEPS: usize = 4096;

/// What one channel showed.
#[derive(Clone, Debug)]
pub struct ChannelAnalysis {
    /// Mean, std, min, max (SI).
    pub stats: Stats,
    /// Octave Allan deviation with 68 % intervals (edf from the fit's dominant noise).
    pub adev: Vec<AdevPoint>,
    /// One-sided Welch PSD (SI²/Hz).
    pub psd: Psd,
    /// The fitted IEEE terms.
    pub fit: Fit,
    /// The record's linear trend (None without a time series, e.g. a published table).
    pub trend: Option<Trend>,
    /// The grid the values sit on, when they sit on one (a unit's output LSB).
    pub lattice: Option<Lattice>,
}

impl ChannelAnalysis {
    /// A channel the input does not have (a table of one sensor, a CSV of some axes): no
    /// points, no PSD, no statistics, nothing fitted.
    pub fn missing() -> ChannelAnalysis {
        ChannelAnalysis {
            stats: Stats::default(),
            adev: Vec::new(),
            psd: Psd {
                freq: Vec::new(),
                density: Vec::new(),
                segments: 0,
            },
            fit: fit(&[], 0),
            trend: None,
            lattice: None,
        }
    }
}

/// The least-squares line of a channel and the Allan deviation of what is left around it.
#[derive(Clone, Debug)]
pub struct Trend {
    /// Least-squares slope of the rate (unit of the rate per second).
    pub slope: f64,
    /// The octave Allan deviation of the record minus that line (68 % intervals as `adev`).
    pub detrended: Vec<AdevPoint>,
}

/// The samples a record dropped.
#[derive(Clone, Debug, PartialEq)]
pub struct Dropped {
    /// Where: (index of the sample after the drop among those read, 0-based; its time from
    /// the record's start on the grid (s); samples missing before it).
    pub at: Vec<(u64, f64, u64)>,
    /// The record's sampling interval, counting the missing samples (s).
    pub dt: f64,
}

impl Dropped {
    /// Samples missing in all.
    pub fn samples(&self) -> u64 {
        self.at.iter().map(|a| a.2).sum()
    }
}

/// The analysis of a record.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// Samples per channel.
    pub samples: u64,
    /// Sampling interval used (s).
    pub dt: f64,
    /// Smallest and largest time step seen (s; NaN without a time column).
    pub step_range: (f64, f64),
    /// Where they were seen: (0-based index of the step's later sample, its time).
    pub step_at: [(u64, f64); 2],
    /// Block means of the six channels (None without a time series).
    pub blocks: Option<BlockMeans>,
    /// Time of the first sample (s).
    pub t_first: f64,
    /// The six channels in [`CHANNELS`] order.
    pub channels: Vec<ChannelAnalysis>,
    /// The record's transients and what was done with them (None: not looked for — a table,
    /// a simulated record).
    pub transients: Option<Transients>,
    /// The samples the record dropped, put back on its time grid and left out of every
    /// statistic ([`super::passes`]; None: none, or not looked for).
    pub dropped: Option<Dropped>,
}

impl Analysis {
    /// This analysis with the channels flagged in `missing` (gyro x y z, accel x y z) emptied.
    pub fn without(mut self, missing: [bool; 6]) -> Analysis {
        for (c, _) in self.channels.iter_mut().zip(missing).filter(|(_, m)| *m) {
            *c = ChannelAnalysis::missing();
        }
        self
    }
}

impl Analyzer {
    /// An analyzer with Welch segments of `segment` samples.
    pub fn new(segment: usize) -> Analyzer {
        Analyzer {
            stats: Default::default(),
            adev: Default::default(),
            psd: std::array::from_fn(|_| Welch::new(segment)),
            lattice: Default::default(),
            blocks: BlockMeans::default(),
            n: 0,
            t_first: f64::NAN,
            t_prev: f64::NAN,
            step_min: f64::INFINITY,
            step_max: f64::NEG_INFINITY,
            step_min_at: (0, f64::NAN),
            step_max_at: (0, f64::NAN),
            gaps: GapCursor::default(),
            last: [0.0; 6],
            first_step: f64::NAN,
            long_steps: Vec::new(),
            long_overflow: false,
        }
    }

    /// [`Analyzer::new`] leaving the samples in `gaps` (sorted, disjoint, inclusive 0-based
    /// ranges: a record's transients) out of every statistic: every Allan-variance difference
    /// and Welch segment that holds one, and the mean and scatter. The lattice and the block
    /// means (the static check) still see them.
    pub fn with_gaps(segment: usize, gaps: Vec<(u64, u64)>) -> Analyzer {
        Analyzer {
            gaps: GapCursor::new(gaps),
            ..Analyzer::new(segment)
        }
    }

    /// Adds one sample of the six channels at time t (NaN if the data have no time).
    #[inline]
    pub fn push(&mut self, t: f64, v: &[f64; 6]) {
        self.step_to(t);
        self.last = *v;
        let bad = self.gaps.contains(self.n);
        self.n += 1;
        for (i, &x) in v.iter().enumerate() {
            if bad {
                self.adev[i].push_flagged(x);
                self.psd[i].push_flagged(x);
            } else {
                self.stats[i].push(x);
                self.adev[i].push(x);
                self.psd[i].push(x);
            }
            self.lattice[i].push(x);
        }
        self.blocks.push(v);
    }

    /// Stands in at time t for a sample the record dropped ([`super::passes`] puts them back):
    /// it keeps the time grid, and every statistic leaves it out as a transient's samples
    /// (the Allan deviation and the PSD take the last sample's value, which no difference or
    /// segment they keep holds).
    pub fn push_dropped(&mut self, t: f64) {
        self.step_to(t);
        self.n += 1;
        for (i, &x) in self.last.iter().enumerate() {
            self.adev[i].push_flagged(x);
            self.psd[i].push_flagged(x);
        }
    }

    /// The time bookkeeping of a sample at t: first time, smallest, largest and long steps.
    #[inline]
    fn step_to(&mut self, t: f64) {
        if self.n == 0 {
            self.t_first = t;
        } else {
            let step = t - self.t_prev;
            if self.n == 1 {
                self.first_step = step;
            }
            if step < self.step_min {
                self.step_min = step;
                self.step_min_at = (self.n, t);
            }
            if step > self.step_max {
                self.step_max = step;
                self.step_max_at = (self.n, t);
            }
            if step > LONG_STEP * self.step_min {
                if self.long_steps.len() < MAX_LONG_STEPS {
                    self.long_steps.push((self.n, step));
                } else {
                    self.long_overflow = true;
                }
            }
        }
        self.t_prev = t;
    }

    /// Adds one output record (its interval-mean rates).
    pub fn push_record(&mut self, r: &Record) {
        let (g, a) = (r.gyro, r.accel);
        self.push(r.t, &[g[0], g[1], g[2], a[0], a[1], a[2]]);
    }

    /// Samples so far.
    pub fn samples(&self) -> u64 {
        self.n
    }

    /// The steps of the record that are long against the smallest (the first step whatever it
    /// is, then each over 1.5 times the smallest before it: index of its later sample, step);
    /// None when there are more than [`MAX_LONG_STEPS`].
    pub fn long_steps(&self) -> Option<Vec<(u64, f64)>> {
        if self.long_overflow {
            return None;
        }
        let mut all = Vec::with_capacity(self.long_steps.len() + 1);
        if self.first_step > LONG_STEP * self.step_min {
            all.push((1, self.first_step));
        }
        all.extend(self.long_steps.iter().copied());
        Some(all)
    }

    /// The smallest time step (s; +∞ before two samples).
    pub fn step_min(&self) -> f64 {
        self.step_min
    }

    /// The time of the first sample (s).
    pub fn t_first(&self) -> f64 {
        self.t_first
    }

    /// The time of the last sample (s).
    pub fn t_last(&self) -> f64 {
        self.t_prev
    }

    /// The sampling interval from the time column: (t_last − t_first)/(n − 1).
    pub fn measured_dt(&self) -> Option<f64> {
        let dt = (self.t_prev - self.t_first) / (self.n as f64 - 1.0);
        (self.n >= 2 && dt.is_finite() && dt > 0.0).then_some(dt)
    }

    /// Finishes at sampling interval `dt`.
    pub fn finish(&self, dt: f64) -> Analysis {
        let n = self.n as usize;
        let channels = (0..6)
            .map(|i| {
                let first = self.adev[i].points(dt, |_| NoiseType::WhiteRate);
                let fit = fit(&first, n);
                ChannelAnalysis {
                    stats: self.stats[i],
                    adev: self.adev[i].points(dt, |tau| fit.dominant(tau)),
                    psd: self.psd[i].finish(dt),
                    trend: Some(Trend {
                        slope: self.adev[i].slope() / dt,
                        detrended: self.adev[i].detrended_points(dt, |tau| fit.dominant(tau)),
                    }),
                    fit,
                    lattice: self.lattice[i].finish(),
                }
            })
            .collect();
        Analysis {
            samples: self.n,
            dt,
            step_at: [self.step_min_at, self.step_max_at],
            blocks: Some(self.blocks.clone()),
            step_range: if self.n >= 2 {
                (self.step_min, self.step_max)
            } else {
                (f64::NAN, f64::NAN)
            },
            t_first: self.t_first,
            channels,
            transients: None,
            dropped: None,
        }
    }
}
