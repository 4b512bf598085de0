//! Transients in a static record: a knock on the bench, a cable tug, a spike — a few samples
//! whose step from the one before is far beyond the channel's noise. They are not the unit's
//! noise, and one knock is enough to show as a white floor in the PSD and an excess at short
//! τ (SMAC-Group/imudata `adis_16405_imu4`: a knock of 0.8 s at t = 4045 s, up to 0.5 g on
//! accel z, read by `fit` as a post-filter floor of 3.5 % that the rest of the record does
//! not have). Pure: the reader feeds samples, [`super::passes`] runs the reads and decides.
//!
//! Two passes over the record, both streaming in bounded memory:
//! 1. [`StepScale`]: each channel's step d_k = x_k − x_{k−1} into a histogram of |d| by
//!    binary exponent (1/4 octave), with the exact Σd² per bin. Its scale is the RMS of the
//!    steps inside the threshold, iterated from the Gaussian scale of the median |d| (from
//!    the RMS of all steps when half of them are zero): outliers do not set their own bar,
//!    even when they are many, and a unit whose values sit on a coarse LSB (steps of a few
//!    values only) gets its exact RMS, where the median alone would be off by up to 1.4×.
//! 2. [`Scanner`]: a step beyond z·scale flags the two samples it joins; flags within
//!    2·pad samples merge into one transient.
//!
//! The threshold z is the Gaussian two-sided point for [`FALSE_ALARM`] per record over all the
//! steps of all the channels (6.4 for 10⁶ samples of six channels), and never less than
//! [`MIN_LSBS`] LSBs of the channel's lattice: a unit whose noise is below its LSB steps by
//! one LSB now and then, which is quantization, not a knock.

/// Expected false transients per record of Gaussian noise.
pub const FALSE_ALARM: f64 = 1e-3;

/// Samples left out on each side of a transient, in seconds of record: a bench's ring-down
/// after a knock lasts a fraction of a second.
pub const PAD_S: f64 = 1.0;

/// Beyond this fraction of the record left out, the flags are not rare events but the noise's
/// own tails (a heavy-tailed record): they are reported and kept.
pub const MAX_LEFT_OUT: f64 = 0.01;

/// The bar never sits below this many step RMS: the steps of real units at rest have tails
/// heavier than Gaussian noise — on the ADIS16405 runs of SMAC-Group/imudata (10⁶ samples
/// each) the accelerometers' steps have a kurtosis of 3.2–3.9 and single steps of 7–12 RMS,
/// in records that close everywhere without leaving anything out — while the knock of run 4
/// steps by 24–129 RMS on five channels. (The Gaussian point alone, 6.4 at 10⁶ samples, took
/// 11–21 transients in every run.)
pub const MIN_Z: f64 = 20.0;

/// A step of fewer LSBs than this is quantization, whatever the noise.
pub const MIN_LSBS: f64 = 3.0;

/// The median of |Z| for a standard normal Z (Φ⁻¹(0.75)).
const MEDIAN_ABS_GAUSS: f64 = 0.674_489_750_196_081_7;

/// Histogram bins of |d|: the top 14 bits of a non-negative f64 (11 of exponent, 2 of
/// mantissa), so a bin spans a quarter octave.
const BINS: usize = 1 << 14;
const SHIFT: u32 = 50;

/// Streaming step statistics of six channels (pass 1).
#[derive(Clone, Debug)]
pub struct StepScale {
    prev: [f64; 6],
    n: u64,
    count: Vec<u64>,
    sum_sq: Vec<f64>,
}

impl Default for StepScale {
    fn default() -> Self {
        StepScale {
            prev: [0.0; 6],
            n: 0,
            count: vec![0; 6 * BINS],
            sum_sq: vec![0.0; 6 * BINS],
        }
    }
}

impl StepScale {
    /// Adds one sample of the six channels.
    #[inline]
    pub fn push(&mut self, v: &[f64; 6]) {
        if self.n > 0 {
            for (ch, (x, p)) in v.iter().zip(&self.prev).enumerate() {
                let d = (x - p).abs();
                let b = ch * BINS + (d.to_bits() >> SHIFT) as usize;
                self.count[b] += 1;
                self.sum_sq[b] += d * d;
            }
        }
        self.prev = *v;
        self.n += 1;
    }

    /// Samples pushed.
    pub fn samples(&self) -> u64 {
        self.n
    }

    /// The RMS step of channel `ch` over the steps below `z` times itself: iterated from the
    /// median's Gaussian scale until the set of bins kept no longer changes. 0 for a constant
    /// channel.
    pub fn scale(&self, ch: usize, z: f64) -> f64 {
        let count = &self.count[ch * BINS..(ch + 1) * BINS];
        let sum_sq = &self.sum_sq[ch * BINS..(ch + 1) * BINS];
        // Bins whose lower edge is below the bar are kept whole: a bin spans a quarter
        // octave, so the bar is z within 19 %, which moves a Gaussian's RMS by < 1e-7.
        let rms_below = |top: usize| {
            let (n, s) = (0..top).fold((0u64, 0.0), |(n, s), b| (n + count[b], s + sum_sq[b]));
            if n == 0 { 0.0 } else { (s / n as f64).sqrt() }
        };
        // The start: the median |d| of Gaussian steps is 0.6745 σ — robust where outliers are
        // many enough to lift the RMS of all steps past a twentieth of their size (spikes of
        // 40σ in 1 sample of 500 double it); the RMS of all where half the steps are zero (a
        // coarse LSB).
        let total: u64 = count.iter().sum();
        let mut seen = 0;
        let median_bin = count.iter().position(|&c| {
            seen += c;
            2 * seen >= total
        });
        // usize::MAX: the first pass always recomputes s as an RMS.
        let mut top = usize::MAX;
        let mut s = match median_bin {
            Some(b) if b > 0 && total > 0 => {
                let (lo, hi) = (
                    f64::from_bits((b as u64) << SHIFT),
                    f64::from_bits((b as u64 + 1) << SHIFT),
                );
                (lo * hi).sqrt() / MEDIAN_ABS_GAUSS
            }
            _ => rms_below(BINS),
        };
        for _ in 0..64 {
            let bar = z * s;
            let next = (0..BINS)
                .take_while(|&b| f64::from_bits((b as u64) << SHIFT) < bar)
                .count();
            if next == top {
                break;
            }
            top = next;
            s = rms_below(top);
        }
        s
    }
}

/// The Gaussian two-sided point z for one false alarm in 1/[`FALSE_ALARM`] records of `steps`
/// steps in all.
pub fn threshold(steps: u64) -> f64 {
    let p = FALSE_ALARM / (steps.max(1) as f64);
    crate::analysis::confidence::chi2_quantile(1.0 - p, 1.0).sqrt()
}

/// One transient: the samples whose steps were beyond the bar, before padding.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transient {
    /// First flagged sample (0-based).
    pub first: u64,
    /// Last flagged sample (0-based).
    pub last: u64,
    /// The channel of the largest step (gyro x y z, accel x y z).
    pub channel: usize,
    /// That step (unit of the channel, SI).
    pub step: f64,
    /// That step in units of its channel's step scale.
    pub z: f64,
}

/// Pass 2: flags steps beyond each channel's bar.
#[derive(Clone, Debug)]
pub struct Scanner {
    bar: [f64; 6],
    scale: [f64; 6],
    merge: u64,
    prev: [f64; 6],
    k: u64,
    found: Vec<Transient>,
}

impl Scanner {
    /// Bars per channel (∞ for a channel to leave alone), the scales they were made from, and
    /// the gap below which two flags are one transient (samples).
    pub fn new(bar: [f64; 6], scale: [f64; 6], merge: u64) -> Scanner {
        Scanner {
            bar,
            scale,
            merge,
            prev: [0.0; 6],
            k: 0,
            found: Vec::new(),
        }
    }

    /// Counts a dropped sample's stand-in ([`super::passes`]): not a step; the next step
    /// spans it.
    pub fn skip(&mut self) {
        self.k += 1;
    }

    /// Adds one sample of the six channels.
    #[inline]
    pub fn push(&mut self, v: &[f64; 6]) {
        if self.k > 0 {
            for (ch, (x, p)) in v.iter().zip(self.prev).enumerate() {
                let d = x - p;
                if d.abs() > self.bar[ch] {
                    self.flag(ch, d);
                }
            }
        }
        self.prev = *v;
        self.k += 1;
    }

    fn flag(&mut self, ch: usize, d: f64) {
        let k = self.k;
        let z = d.abs() / self.scale[ch];
        match self.found.last_mut() {
            Some(t) if k - 1 <= t.last + self.merge => {
                t.last = k;
                if z > t.z {
                    (t.channel, t.step, t.z) = (ch, d, z);
                }
            }
            _ => self.found.push(Transient {
                first: k - 1,
                last: k,
                channel: ch,
                step: d,
                z,
            }),
        }
    }

    /// The transients found.
    pub fn finish(self) -> Vec<Transient> {
        self.found
    }
}

/// What was done with the transients of a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Handling {
    /// Left out of every statistic (with [`PAD_S`] on each side).
    LeftOut,
    /// Kept: the user asked for it (`--keep-transients`).
    Kept,
    /// Kept: so many that they are the noise's own tails ([`MAX_LEFT_OUT`]).
    HeavyTailed,
}

/// The transients of a record and what was done with them.
#[derive(Clone, Debug, PartialEq)]
pub struct Transients {
    /// The transients, in time order.
    pub list: Vec<Transient>,
    /// The threshold, in units of each channel's step scale.
    pub z: f64,
    /// Samples left out on each side of a transient.
    pub pad: u64,
    /// What was done.
    pub handling: Handling,
    /// The sample ranges left out (inclusive, merged; empty unless [`Handling::LeftOut`]).
    pub gaps: Vec<(u64, u64)>,
}

impl Transients {
    /// Samples left out.
    pub fn left_out(&self) -> u64 {
        self.gaps.iter().map(|(a, b)| b - a + 1).sum()
    }
}

/// The padded, merged ranges of `list` in a record of `samples` samples.
pub fn gaps(list: &[Transient], pad: u64, samples: u64) -> Vec<(u64, u64)> {
    let mut out: Vec<(u64, u64)> = Vec::new();
    for t in list {
        let (a, b) = (
            t.first.saturating_sub(pad),
            (t.last + pad).min(samples.saturating_sub(1)),
        );
        match out.last_mut() {
            Some(g) if a <= g.1 + 1 => g.1 = g.1.max(b),
            _ => out.push((a, b)),
        }
    }
    out
}

/// A streaming cursor over sorted, disjoint inclusive ranges: is sample k (asked in
/// increasing order) inside one?
#[derive(Clone, Debug, Default)]
pub struct GapCursor {
    gaps: Vec<(u64, u64)>,
    next: usize,
}

impl GapCursor {
    /// A cursor over `gaps` (sorted, disjoint).
    pub fn new(gaps: Vec<(u64, u64)>) -> GapCursor {
        GapCursor { gaps, next: 0 }
    }

    /// Whether sample `k` is in a gap; `k` must not decrease between calls.
    #[inline]
    pub fn contains(&mut self, k: u64) -> bool {
        while let Some(&(_, b)) = self.gaps.get(self.next) {
            if k <= b {
                return k >= self.gaps[self.next].0;
            }
            self.next += 1;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::NormalStream;

    /// The scale of Gaussian steps is their σ within the estimator's scatter, with 1 % of the
    /// steps replaced by outliers 100σ tall as without them; on steps of a coarse lattice
    /// ({−1, 0, 1} LSB) it is their exact RMS.
    ///
    /// Tolerance: the RMS of n = 10⁵ Gaussian steps scatters by σ/√(2n) = 0.22 %; 4σ ≈ 0.9 %,
    /// and the trimming at z ≈ 6 moves it by < 1e-7.
    #[test]
    fn the_scale_ignores_outliers_and_is_exact_on_a_lattice() {
        let n = 100_000;
        let mut s = NormalStream::new(3, "transients/scale");
        let mut clean = StepScale::default();
        let mut dirty = StepScale::default();
        let mut x = 0.0;
        for k in 0..n {
            // Steps of σ = 2 on channel 0: a random walk x.
            x += 2.0 * s.draw();
            clean.push(&[x, 0.0, 0.0, 0.0, 0.0, 0.0]);
            // Outliers: a step up and back every 100 samples, on top of the same walk.
            let spike = if k % 100 == 50 { 200.0 } else { 0.0 };
            dirty.push(&[x + spike, 0.0, 0.0, 0.0, 0.0, 0.0]);
        }
        // At the Gaussian point and at the bar `fit` uses: 2 % of the steps at 100σ lift the
        // RMS of all steps to 14σ, so from there a bar of 20 would not trim them.
        for z in [threshold(n), MIN_Z] {
            for (what, a) in [("clean", &clean), ("dirty", &dirty)] {
                let sc = a.scale(0, z);
                assert!((sc / 2.0 - 1.0).abs() < 0.009, "{what} at z = {z}: {sc}");
            }
        }
        assert_eq!(clean.scale(1, MIN_Z), 0.0);
        // Steps of −1, 0, 1 LSB, one each in 8 samples: of the 79 999 steps (the first
        // sample has none) 19 999 are ±1 LSB.
        let mut q = StepScale::default();
        let mut v = 0.0;
        for k in 0..80_000u64 {
            v += match k % 8 {
                0 => 1.0,
                4 => -1.0,
                _ => 0.0,
            } * 0.05;
            q.push(&[v, 0.0, 0.0, 0.0, 0.0, 0.0]);
        }
        let r = q.scale(0, 6.0);
        let want = 0.05 * (19_999.0f64 / 79_999.0).sqrt();
        assert!((r / want - 1.0).abs() < 1e-9, "{r}");
    }

    /// The threshold is the Gaussian point: P(|Z| > z) = 1e-3/steps.
    #[test]
    fn the_threshold_is_the_gaussian_point() {
        // Φ^{-1}(1 − 0.5e-9) = 6.10941 (1e-9 two-sided): steps = 1e6.
        let z = threshold(1_000_000);
        assert!((z - 6.109_410_204_869_5).abs() < 1e-6, "{z}");
    }

    /// Flags merge within the merge gap and split beyond it; each transient keeps its largest
    /// step; the gaps pad and clip at the record's ends.
    #[test]
    fn flags_merge_into_transients_and_pad_into_gaps() {
        let mut sc = Scanner::new([1.0; 6], [0.25; 6], 10);
        let mut v = [0.0; 6];
        for k in 0..200u64 {
            v[3] = match k {
                5 => 3.0,
                12 => -5.0,
                100 => 2.0,
                _ => 0.0,
            };
            sc.push(&v);
        }
        let t = sc.finish();
        assert_eq!(t.len(), 2, "{t:?}");
        // Sample 5 steps up (4→5) and down (5→6); 12 likewise: one transient 4…13.
        assert_eq!((t[0].first, t[0].last, t[0].channel), (4, 13, 3));
        assert_eq!((t[0].step, t[0].z), (-5.0, 20.0));
        assert_eq!((t[1].first, t[1].last), (99, 101));
        assert_eq!(gaps(&t, 5, 200), vec![(0, 18), (94, 106)]);
        assert_eq!(gaps(&t, 100, 200), vec![(0, 199)]);
        let mut c = GapCursor::new(vec![(3, 4), (8, 8)]);
        let inside: Vec<u64> = (0..10).filter(|&k| c.contains(k)).collect();
        assert_eq!(inside, vec![3, 4, 8]);
    }
}
