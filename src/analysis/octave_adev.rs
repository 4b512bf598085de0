//! Allan deviation on octave τ from a stream of rate samples, in constant memory.
//!
//! What is computed: the overlapping estimator of [`super::allan`] with the second
//! differences θ_{k+2m} − 2θ_{k+m} + θ_k taken at every k that is a multiple of a stride
//! s = max(1, m/[`STRIDE_DIVISOR`]). For m ≤ 16 (s = 1) this is exactly the fully overlapping
//! estimator; for larger m consecutive differences still overlap by 15/16 of their span, so
//! the estimate keeps nearly all the degrees of freedom of the fully overlapping one (its edf
//! is taken from the fully overlapping formulas, an approximation that errs by a few per cent
//! at most on the optimistic side).
//!
//! Why: the phase θ (the running sum of the rate) decimated by s is exact, so octave m only
//! needs the last 2·16 + 1 phase values at its stride. Memory is O(octaves) whatever the record
//! length, and the work per sample is a handful of operations (octave m is visited once every
//! s samples), so a 24 h, 100 Hz record streams through at memory speed.
//!
//! The phase is accumulated in units of rate × samples (Δt enters only in [`OctaveAdev::points`],
//! so the sampling interval may be measured from the time column after the pass), after
//! subtracting the first sample (σ(τ) ignores a constant offset; without it θ grows with the
//! bias and the second differences lose digits), by compensated (Neumaier) summation.

use super::confidence::{NoiseType, adev_interval, edf};

/// Stride of octave m is m / STRIDE_DIVISOR (at least 1).
pub const STRIDE_DIVISOR: usize = 16;

/// Octaves kept: m = 1 … 2^(OCTAVES−1).
const OCTAVES: usize = 48;

/// One point of a measured Allan deviation curve with its confidence interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdevPoint {
    /// Cluster size m (samples).
    pub m: usize,
    /// τ = m·Δt (s).
    pub tau: f64,
    /// Allan deviation, unit of the rate.
    pub adev: f64,
    /// Number of second differences averaged.
    pub terms: u64,
    /// Equivalent degrees of freedom used for the interval.
    pub edf: f64,
    /// Lower end of the 68.3 % (1σ-equivalent) χ² interval.
    pub lo: f64,
    /// Upper end of the 68.3 % χ² interval.
    pub hi: f64,
}

/// Confidence of the intervals stored in [`AdevPoint`] (the 1σ-equivalent 68.27 %).
pub const CONFIDENCE: f64 = 0.682_689_492_137_085_9;

#[derive(Clone, Debug)]
struct Octave {
    m: usize,
    stride: usize,
    /// Phase values at the stride, newest at `head`.
    ring: Vec<f64>,
    head: usize,
    filled: usize,
    sum_sq: f64,
    /// Σ of the second differences: with Σd² it gives the curve of the record with any
    /// linear trend removed ([`OctaveAdev::detrended_points`]).
    sum_d: f64,
    terms: u64,
    /// Second differences left out because their span held a flagged sample.
    skipped: u64,
}

/// Streaming accumulator of the octave Allan deviation of one rate channel.
#[derive(Clone, Debug)]
pub struct OctaveAdev {
    octaves: Vec<Octave>,
    offset: Option<f64>,
    sum: f64,
    comp: f64,
    /// Phase index of the next phase point (= samples pushed).
    k: u64,
    /// Running mean of the (offset) rate and its co-moment with the sample index, for the
    /// least-squares slope (Welford's update, stable whatever the bias).
    mean_x: f64,
    co_kx: f64,
    /// Phase index of the latest flagged sample (0: none): a second difference at phase k
    /// spans samples k − 2m + 1 … k, and is left out when that holds it.
    last_bad: u64,
}

impl Default for OctaveAdev {
    fn default() -> Self {
        OctaveAdev::new()
    }
}

impl OctaveAdev {
    /// An empty accumulator.
    pub fn new() -> OctaveAdev {
        let octaves = (0..OCTAVES)
            .map(|j| {
                let m = 1usize << j;
                let stride = (m / STRIDE_DIVISOR).max(1);
                Octave {
                    m,
                    stride,
                    ring: vec![0.0; 2 * m / stride + 1],
                    head: 0,
                    filled: 0,
                    sum_sq: 0.0,
                    sum_d: 0.0,
                    terms: 0,
                    skipped: 0,
                }
            })
            .collect();
        let mut a = OctaveAdev {
            octaves,
            offset: None,
            sum: 0.0,
            comp: 0.0,
            k: 0,
            mean_x: 0.0,
            co_kx: 0.0,
            last_bad: 0,
        };
        a.visit(0.0); // θ_0 = 0
        a
    }

    /// Adds one rate sample that every second difference spanning it must leave out (a
    /// transient's: [`super::transients`]). Its value still enters the phase, which the
    /// differences that do not span it never see.
    #[inline]
    pub fn push_flagged(&mut self, y: f64) {
        self.last_bad = self.k + 1;
        self.push(y);
    }

    /// Adds one rate sample.
    #[inline]
    pub fn push(&mut self, y: f64) {
        let off = *self.offset.get_or_insert(y);
        let x = y - off;
        let t = self.sum + x;
        self.comp += if self.sum.abs() >= x.abs() {
            (self.sum - t) + x
        } else {
            (x - t) + self.sum
        };
        self.sum = t;
        // Index k joins: the index mean moves from (k−1)/2 to k/2, so k − mean_old = (k+1)/2.
        let dx = x - self.mean_x;
        self.mean_x += dx / (self.k + 1) as f64;
        self.co_kx += 0.5 * (self.k + 1) as f64 * (x - self.mean_x);
        self.k += 1;
        self.visit(self.sum + self.comp);
    }

    /// Samples pushed so far.
    pub fn len(&self) -> u64 {
        self.k
    }

    /// True before the first sample.
    pub fn is_empty(&self) -> bool {
        self.k == 0
    }

    /// Feeds phase point θ_k to every octave whose stride divides k.
    #[inline]
    fn visit(&mut self, theta: f64) {
        let k = self.k;
        for o in self.octaves.iter_mut() {
            // Strides are non-decreasing powers of two: once one does not divide k, none after.
            if k & (o.stride as u64 - 1) != 0 {
                break;
            }
            let len = o.ring.len();
            o.head = if o.head + 1 == len { 0 } else { o.head + 1 };
            o.ring[o.head] = theta;
            if o.filled < len {
                o.filled += 1;
            }
            if o.filled == len {
                let lag = o.m / o.stride;
                let mid = o.ring[(o.head + len - lag) % len];
                let old = o.ring[(o.head + 1) % len];
                if self.last_bad > 0 && k < self.last_bad + 2 * o.m as u64 {
                    o.skipped += 1;
                    continue;
                }
                let d = theta - 2.0 * mid + old;
                o.sum_sq += d * d;
                o.sum_d += d;
                o.terms += 1;
            }
        }
    }

    /// Least-squares slope of the rate against the sample index (rate per sample; 0 for
    /// fewer than two samples): Σ(k − k̄)x_k / Σ(k − k̄)², the denominator n(n² − 1)/12.
    pub fn slope(&self) -> f64 {
        let n = self.k as f64;
        if self.k < 2 {
            return 0.0;
        }
        self.co_kx / (n * (n * n - 1.0) / 12.0)
    }

    /// The curve at sampling interval `dt`, one point per octave with at least one second
    /// difference; `noise(τ)` names the noise type that dominates at τ (it sets the edf).
    pub fn points(&self, dt: f64, noise: impl Fn(f64) -> NoiseType) -> Vec<AdevPoint> {
        self.points_less(0.0, dt, noise)
    }

    /// [`OctaveAdev::points`] of the record with its least-squares line removed. Why exact:
    /// the phase of a rate b·k is b·k(k − 1)/2, whose second difference at lag m is b·m²
    /// for every k, so each difference d becomes d − b·m² and Σ(d − bm²)² = Σd² − 2bm²Σd +
    /// terms·b²m⁴ needs only the running Σd.
    pub fn detrended_points(&self, dt: f64, noise: impl Fn(f64) -> NoiseType) -> Vec<AdevPoint> {
        self.points_less(self.slope(), dt, noise)
    }

    fn points_less(&self, slope: f64, dt: f64, noise: impl Fn(f64) -> NoiseType) -> Vec<AdevPoint> {
        self.octaves
            .iter()
            .filter(|o| o.terms > 0)
            .map(|o| {
                // Left-out differences shorten the record the edf formulas see.
                let phases = (self.k as usize + 1).saturating_sub(o.skipped as usize * o.stride);
                let m = o.m as f64;
                let bm2 = slope * m * m;
                let terms = o.terms as f64;
                let sum_sq = o.sum_sq - 2.0 * bm2 * o.sum_d + terms * bm2 * bm2;
                let adev = (sum_sq.max(0.0) / (2.0 * m * m * terms)).sqrt();
                let tau = m * dt;
                let edf = edf(noise(tau), phases, o.m);
                let (lo, hi) = adev_interval(adev, edf, CONFIDENCE);
                AdevPoint {
                    m: o.m,
                    tau,
                    adev,
                    terms: o.terms,
                    edf,
                    lo,
                    hi,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::NormalStream;

    /// A flagged sample leaves out exactly the second differences whose span holds it: for
    /// m ≤ 16 the curve equals the overlapping estimator summed over the differences that do
    /// not span sample j, to round-off, whatever value the flagged sample has (a 10⁶σ spike
    /// gives the same curve as a zero); the edf sees the shorter record.
    #[test]
    fn a_flagged_sample_leaves_out_the_differences_that_span_it() {
        let mut s = NormalStream::new(5, "octave/gap");
        let n = 20_000usize;
        let j = 7_000usize; // 0-based index of the flagged sample
        let y: Vec<f64> = (0..n).map(|_| s.draw()).collect();
        let run = |spike: f64| {
            let mut acc = OctaveAdev::new();
            for (k, &v) in y.iter().enumerate() {
                if k == j {
                    acc.push_flagged(v + spike);
                } else {
                    acc.push(v);
                }
            }
            acc.points(1.0, |_| NoiseType::WhiteRate)
        };
        let (spiked, zeroed) = (run(1e6), run(-y[j]));
        // The batch sum: phase θ_k = Σ_{i<k} y_i, so the difference at phase k spans
        // y[k − 2m … k − 1].
        let mut theta = vec![0.0; n + 1];
        for k in 0..n {
            theta[k + 1] = theta[k] + y[k];
        }
        for (p, q) in spiked.iter().zip(&zeroed) {
            // Round-off only: the spike enters the phase, which the kept differences cancel.
            assert!((p.adev / q.adev - 1.0).abs() < 1e-9, "m {}", p.m);
            if p.m > STRIDE_DIVISOR {
                continue;
            }
            let m = p.m;
            let (mut sum, mut terms) = (0.0, 0u64);
            for k in 2 * m..=n {
                if k - 2 * m <= j && j < k {
                    continue;
                }
                let d = theta[k] - 2.0 * theta[k - m] + theta[k - 2 * m];
                sum += d * d;
                terms += 1;
            }
            let want = (sum / (2.0 * (m * m) as f64 * terms as f64)).sqrt();
            assert_eq!(p.terms, terms, "m {m}");
            assert!(
                (p.adev / want - 1.0).abs() < 1e-9,
                "m {m}: {} vs {want}",
                p.adev
            );
            // 2m differences left out: the edf is that of a record 2m samples shorter.
            let full = edf(NoiseType::WhiteRate, n + 1, m);
            let short = edf(NoiseType::WhiteRate, n + 1 - 2 * m, m);
            assert_eq!(p.edf, short);
            assert!(p.edf < full);
        }
    }

    /// For m ≤ 16 the stream is the fully overlapping estimator: it equals `allan` to
    /// round-off; beyond, the strided estimate stays within the 1σ interval of the full one.
    #[test]
    fn matches_the_batch_overlapping_estimator() {
        let mut s = NormalStream::new(11, "octave/white");
        let y: Vec<f64> = (0..50_000).map(|_| 3.0 + s.draw()).collect();
        let mut acc = OctaveAdev::new();
        y.iter().for_each(|&v| acc.push(v));
        let dt = 0.01;
        let batch = super::super::allan::overlapping(&y, dt);
        let stream = acc.points(dt, |_| NoiseType::WhiteRate);
        assert_eq!(batch.len(), stream.len());
        for (b, p) in batch.iter().zip(&stream) {
            assert_eq!(b.m, p.m);
            assert!((p.tau - b.tau).abs() < 1e-12);
            if p.m <= STRIDE_DIVISOR {
                assert!((p.adev / b.adev - 1.0).abs() < 1e-9, "m {}", p.m);
                assert_eq!(p.terms as usize, 50_001 - 2 * p.m);
            } else {
                assert!((p.adev - b.adev).abs() < (p.hi - p.lo) / 2.0, "m {}", p.m);
            }
        }
    }

    /// The streamed slope is the batch least-squares slope, and the detrended curve equals the
    /// batch overlapping estimator of the record minus that line (m ≤ 16, where the stream is
    /// fully overlapping), to round-off, on a record with a bias and a trend 10⁴× its noise
    /// at the end. Without the Σd term the m = 16 point would carry the trend (b·m²/√2 = 23× the noise there).
    #[test]
    fn detrended_curve_is_the_curve_of_the_residual() {
        let mut s = NormalStream::new(12, "octave/trend");
        let n = 20_000usize;
        let y: Vec<f64> = (0..n).map(|k| 9.8 + 0.5 * k as f64 + s.draw()).collect();
        let mut acc = OctaveAdev::new();
        y.iter().for_each(|&v| acc.push(v));
        let kbar = (n as f64 - 1.0) / 2.0;
        let ybar = y.iter().sum::<f64>() / n as f64;
        let num: f64 = y
            .iter()
            .enumerate()
            .map(|(k, v)| (k as f64 - kbar) * (v - ybar))
            .sum();
        let den: f64 = (0..n).map(|k| (k as f64 - kbar).powi(2)).sum();
        let b = num / den;
        assert!(
            (acc.slope() / b - 1.0).abs() < 1e-12,
            "{} vs {b}",
            acc.slope()
        );
        let r: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(k, v)| v - b * k as f64)
            .collect();
        let dt = 0.01;
        let batch = super::super::allan::overlapping(&r, dt);
        let stream = acc.detrended_points(dt, |_| NoiseType::WhiteRate);
        for (bp, p) in batch
            .iter()
            .zip(&stream)
            .filter(|(b, _)| b.m <= STRIDE_DIVISOR)
        {
            assert!(
                (p.adev / bp.adev - 1.0).abs() < 1e-7,
                "m {}: {} vs {}",
                p.m,
                p.adev,
                bp.adev
            );
        }
        let raw = acc.points(dt, |_| NoiseType::WhiteRate);
        assert!(raw[4].adev > 10.0 * stream[4].adev);
    }

    /// Memory does not grow with the record: the rings are fixed at construction.
    #[test]
    fn rings_are_bounded() {
        let acc = OctaveAdev::new();
        let total: usize = acc.octaves.iter().map(|o| o.ring.len()).sum();
        assert!(total <= OCTAVES * (2 * STRIDE_DIVISOR + 1));
    }
}
