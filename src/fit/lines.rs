//! Narrow spectral lines in a Welch PSD: bins that stand significantly above the local
//! background, reported as sinusoids (frequency, amplitude).
//!
//! Background: the median of the bins within ±[`HALF_WINDOW`] of the candidate, leaving out
//! its own main lobe (±[`LOBE`] bins: a Hann window spreads a line over its 4-bin main lobe).
//! A Welch bin of true density S is distributed as S·χ²_ν/ν with ν ≈ 2K/(1 + 2ρ²) for K
//! segments of Hann windows overlapping by half, ρ = 0.167 their correlation (Welch, IEEE
//! Trans. Audio Electroacoust. 15 (1967); Harris, Proc. IEEE 66 (1978), Table 1), whose
//! median is ≈ S(1 − 2/(9ν))³ (Wilson–Hilferty), so the background is the median divided by
//! that factor. A bin is a line when it is a local maximum and P(χ²_ν/ν > P/S) is below
//! [`FALSE_ALARM`] divided by the number of bins searched (Bonferroni: at most one false line
//! in 1000 records of pure noise).
//!
//! Amplitude: Σ P_k·Δf over the main lobe, less the background, is the line's variance A²/2
//! (the Welch density sums to the variance, [`crate::analysis::psd`]); the frequency is the
//! power-weighted mean of the lobe's bins.

use crate::analysis::confidence::chi2_quantile;
use crate::analysis::psd::Psd;

/// Bins each side of a candidate that set its background.
pub const HALF_WINDOW: usize = 24;

/// Bins each side of a line's centre that belong to its main lobe.
pub const LOBE: usize = 2;

/// Probability of one or more false lines in a record of pure noise.
pub const FALSE_ALARM: f64 = 1e-3;

/// Correlation of adjacent Hann segments at 50 % overlap.
const OVERLAP_CORRELATION: f64 = 0.167;

/// A spectral line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// Frequency (Hz).
    pub freq: f64,
    /// Peak amplitude A of the sinusoid A·sin(2πft + φ) (unit of the rate).
    pub amplitude: f64,
    /// Peak bin over the background.
    pub ratio: f64,
}

/// The lines of `psd`, strongest first.
pub fn find(psd: &Psd) -> Vec<Line> {
    let n = psd.density.len();
    if psd.segments == 0 || n < 2 * HALF_WINDOW + 2 {
        return Vec::new();
    }
    let nu = 2.0 * psd.segments as f64 / (1.0 + 2.0 * OVERLAP_CORRELATION.powi(2));
    let median_factor = (1.0 - 2.0 / (9.0 * nu)).powi(3);
    // Bins with a full background window on both sides: the first ones carry the random-walk
    // and flicker rise, where a median of neighbours is not the local level.
    let (first, last) = (2 * HALF_WINDOW, n - 1 - HALF_WINDOW);
    let searched = (last - first) as f64;
    let threshold = chi2_quantile(1.0 - FALSE_ALARM / searched, nu) / nu;
    let df = psd.freq[1] - psd.freq[0];
    let p = &psd.density;
    let mut window = Vec::with_capacity(2 * HALF_WINDOW);
    let mut lines = Vec::new();
    let mut k = first;
    while k < last {
        if !(p[k] >= p[k - 1] && p[k] > p[k + 1]) {
            k += 1;
            continue;
        }
        window.clear();
        window.extend(
            (k - HALF_WINDOW..=k + HALF_WINDOW)
                .filter(|&j| j.abs_diff(k) > LOBE)
                .map(|j| p[j]),
        );
        window.sort_by(f64::total_cmp);
        let background = window[window.len() / 2] / median_factor;
        let ratio = p[k] / background;
        if ratio > threshold {
            let lobe = k - LOBE..=k + LOBE;
            let power: f64 = lobe.clone().map(|j| (p[j] - background).max(0.0)).sum();
            let freq = lobe
                .clone()
                .map(|j| psd.freq[j] * (p[j] - background).max(0.0))
                .sum::<f64>()
                / power;
            lines.push(Line {
                freq,
                amplitude: (2.0 * power * df).sqrt(),
                ratio,
            });
            k += LOBE + 1;
        } else {
            k += 1;
        }
    }
    lines.sort_by(|a, b| b.amplitude.total_cmp(&a.amplitude));
    lines
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::psd::Welch;
    use crate::rng::NormalStream;

    /// A 0.5 Hz sine of amplitude A = 0.2 in unit white noise is found at its frequency with
    /// its amplitude; the noise alone gives no line. 2^20 samples at 100 Hz, segments of 2^14
    /// (K = 127): the lobe's density sum is 3.3 against a background of 0.02 per bin, and its
    /// scatter, dominated by the line × noise cross term, is √(2·3.3·0.02/K) = 0.032, 1 % of
    /// the power or 0.5 % of A; ±2 % on A is 4σ. The frequency within ±¼ bin.
    #[test]
    fn finds_a_sine_in_white_noise_and_nothing_in_noise() {
        let (dt, n, a, f0) = (0.01, 1usize << 20, 0.2, 0.5);
        let mut s = NormalStream::new(7, "lines/white");
        let mut with = Welch::new(1 << 14);
        let mut without = Welch::new(1 << 14);
        for k in 0..n {
            let w = s.draw();
            let t = k as f64 * dt;
            with.push(w + a * (2.0 * std::f64::consts::PI * f0 * t + 0.3).sin());
            without.push(w);
        }
        let found = find(&with.finish(dt));
        assert_eq!(found.len(), 1, "{found:?}");
        let l = found[0];
        let bin = 1.0 / ((1 << 14) as f64 * dt);
        assert!((l.freq - f0).abs() < 0.25 * bin, "{l:?}");
        assert!((l.amplitude / a - 1.0).abs() < 0.02, "{l:?}");
        assert!(find(&without.finish(dt)).is_empty());
    }
}
