//! One-sided power spectral density by Welch's method, streaming: Hann-windowed segments of
//! length L (a power of two), 50 % overlap, each segment's mean removed, periodograms averaged.
//!
//! Scaling: with window w_i = ½(1 − cos 2πi/L) (periodic Hann), sampling rate f_s and
//! X_k = Σ w_i y_i e^{−2πiki/L}, the one-sided density is P_k = c_k·|X_k|²/(f_s·Σw_i²) with
//! c_k = 2 for 0 < k < L/2 and 1 at 0 and L/2, so that Σ_k P_k·f_s/L = the variance:
//! unit²/Hz, white noise of variance σ² at rate f_s has P = 2σ²/f_s.
//!
//! Memory is one segment per channel; f_s enters only when the result is read, so the rate may
//! be measured from the time column after the pass. A record shorter than one segment is
//! analysed at the end with the largest power-of-two segment of at most half its length.

use std::sync::Arc;

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

/// A one-sided PSD estimate.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Psd {
    /// Frequencies k·f_s/L, k = 0 … L/2 (Hz).
    pub freq: Vec<f64>,
    /// Density at each frequency (unit²/Hz).
    pub density: Vec<f64>,
    /// Segments averaged.
    pub segments: u64,
}

/// Streaming Welch accumulator of one channel.
pub struct Welch {
    len: usize,
    fft: Arc<dyn Fft<f64>>,
    window: Vec<f64>,
    buf: Vec<f64>,
    acc: Vec<f64>,
    segments: u64,
    scratch: Vec<Complex<f64>>,
    /// Samples pushed, and 1 + the index of the latest flagged one (0: none): a segment
    /// holding a flagged sample is left out.
    pushed: u64,
    bad_end: u64,
}

impl Welch {
    /// Segment length `len` (rounded down to a power of two, at least 8).
    pub fn new(len: usize) -> Welch {
        let len = prev_pow2(len.max(8));
        let fft = FftPlanner::new().plan_fft_forward(len);
        Welch {
            len,
            window: hann(len),
            buf: Vec::with_capacity(len),
            acc: vec![0.0; len / 2 + 1],
            segments: 0,
            scratch: vec![Complex::default(); len],
            fft,
            pushed: 0,
            bad_end: 0,
        }
    }

    /// Adds one sample that every segment holding it must leave out (a transient's:
    /// [`super::transients`]).
    #[inline]
    pub fn push_flagged(&mut self, y: f64) {
        self.bad_end = self.pushed + 1;
        self.push(y);
    }

    /// Adds one sample.
    #[inline]
    pub fn push(&mut self, y: f64) {
        self.buf.push(y);
        self.pushed += 1;
        if self.buf.len() == self.len {
            // The buffer holds samples pushed − len … pushed − 1.
            if self.bad_end <= self.pushed - self.len as u64 {
                self.segment();
            }
            self.buf.drain(..self.len / 2);
        }
    }

    fn segment(&mut self) {
        add_periodogram(
            &self.buf,
            &self.window,
            self.fft.as_ref(),
            &mut self.scratch,
            &mut self.acc,
        );
        self.segments += 1;
    }

    /// The estimate at sampling interval `dt` (empty if fewer than 16 samples came).
    pub fn finish(&self, dt: f64) -> Psd {
        if self.segments > 0 {
            return scale(&self.acc, self.segments, self.len, &self.window, dt);
        }
        if self.pushed >= self.len as u64 {
            // Every segment held a flagged sample.
            return Psd::default();
        }
        // Short record: everything is still in `buf`; redo it with a smaller segment.
        if self.buf.len() < 16 {
            return Psd::default();
        }
        let mut w = Welch::new(self.buf.len() / 2);
        self.buf.iter().for_each(|&y| w.push(y));
        w.finish(dt)
    }
}

/// Largest power of two ≤ n (n ≥ 1).
fn prev_pow2(n: usize) -> usize {
    1 << (usize::BITS - 1 - n.leading_zeros())
}

/// Periodic Hann window of length n.
pub(crate) fn hann(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| 0.5 * (1.0 - (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos()))
        .collect()
}

fn add_periodogram(
    seg: &[f64],
    window: &[f64],
    fft: &dyn Fft<f64>,
    scratch: &mut [Complex<f64>],
    acc: &mut [f64],
) {
    let mean = seg.iter().sum::<f64>() / seg.len() as f64;
    for ((s, &y), &w) in scratch.iter_mut().zip(seg).zip(window) {
        *s = Complex::new((y - mean) * w, 0.0);
    }
    fft.process(scratch);
    for (a, s) in acc.iter_mut().zip(scratch.iter()) {
        *a += s.norm_sqr();
    }
}

fn scale(acc: &[f64], segments: u64, len: usize, window: &[f64], dt: f64) -> Psd {
    let fs = 1.0 / dt;
    let wss: f64 = window.iter().map(|w| w * w).sum();
    let half = len / 2;
    let (freq, density) = acc
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let c = if k == 0 || k == half { 1.0 } else { 2.0 };
            (
                k as f64 * fs / len as f64,
                c * a / (segments as f64 * fs * wss),
            )
        })
        .unzip();
    Psd {
        freq,
        density,
        segments,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_lengths() {
        assert_eq!(Welch::new(1000).len, 512);
        assert_eq!(Welch::new(3).len, 8);
        assert_eq!(prev_pow2(1), 1);
    }

    /// Parseval: the density integrates to the variance of a zero-mean sinusoid (A²/2)
    /// when its frequency sits on a bin (Hann leakage stays inside the sum).
    #[test]
    fn integrates_to_variance() {
        let (dt, n, a) = (0.01, 1 << 14, 2.0);
        let mut w = Welch::new(1024);
        for k in 0..n {
            w.push(a * (2.0 * std::f64::consts::PI * 12.5 * k as f64 * dt).sin());
        }
        let p = w.finish(dt);
        let df = p.freq[1];
        let total: f64 = p.density.iter().sum::<f64>() * df;
        assert!((total / (a * a / 2.0) - 1.0).abs() < 1e-3, "{total}");
    }

    /// A flagged sample leaves out the segments that hold it (two, with half overlap) and
    /// nothing else: the estimate equals the average over the others — the same whatever the
    /// flagged value, and the same as a Welch over the record with those segments cut out.
    #[test]
    fn a_flagged_sample_leaves_out_its_segments() {
        let len = 64;
        // Segments start at 0, 32, 64, …; sample 100 is in those starting at 64 and 96.
        let y: Vec<f64> = (0..640).map(|k| ((k * 37) % 11) as f64 - 5.0).collect();
        let run = |v100: f64| {
            let mut w = Welch::new(len);
            for (k, &v) in y.iter().enumerate() {
                if k == 100 {
                    w.push_flagged(v100);
                } else {
                    w.push(v);
                }
            }
            w.finish(0.01)
        };
        let (a, b) = (run(1e9), run(0.0));
        assert_eq!(a, b);
        assert_eq!(a.segments, 19 - 2);
        // The same segments, from two records: 0…95 (segments at 0 and 32) and 128…639.
        let mut w = Welch::new(len);
        y[..96].iter().for_each(|&v| w.push(v));
        let mut w2 = Welch::new(len);
        y[128..].iter().for_each(|&v| w2.push(v));
        for (acc, more) in w.acc.iter_mut().zip(&w2.acc) {
            *acc += more;
        }
        w.segments += w2.segments;
        let want = w.finish(0.01);
        assert_eq!(want.segments, a.segments);
        for (p, q) in a.density.iter().zip(&want.density) {
            assert!((p / q - 1.0).abs() < 1e-12, "{p} vs {q}");
        }
    }

    #[test]
    fn short_record_uses_a_shorter_segment() {
        let mut w = Welch::new(4096);
        (0..100).for_each(|k| w.push((k % 7) as f64));
        let p = w.finish(1.0);
        assert_eq!(p.freq.len(), 17); // L = 32, the largest power of two ≤ 100/2
        assert!(p.segments >= 3);
        assert!(Welch::new(64).finish(1.0).freq.is_empty());
    }
}
