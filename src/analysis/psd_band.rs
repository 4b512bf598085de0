//! Confidence band of a Welch PSD ([`super::psd`]) averaged over log-spaced frequency bands.
//!
//! The averaged periodogram of a Gaussian signal whose spectrum is flat across the averaged
//! bins is distributed as P·χ²_ν/ν, with ν the equivalent degrees of freedom
//! ν = 2·E[P̂]²/Var(P̂) (Blackman & Tukey 1958; Percival & Walden, *Spectral Analysis for
//! Physical Applications*, 1993, §6.17 on WOSA). The two-sided interval of confidence c is
//!
//! P ∈ [P̂·ν/χ²_{(1+c)/2}(ν), P̂·ν/χ²_{(1−c)/2}(ν)].
//!
//! ν is computed exactly for white noise: with window w of length L, hop L/2 and
//! X_{s,k} = Σ_i w_i y_{i+sL/2} e^{−2πiki/L}, the complex covariance of two bins is
//! σ²·e^{iφ}·V_{Δs}(k − k′), V_{Δs} the DFT of the product window v_i = w_i·w_{i+Δs·L/2}
//! (segments two hops apart do not overlap). For circular Gaussian X,
//! Cov(|X|², |X′|²) = |E[X X′*]|², so K segments and M adjacent bins give
//!
//! Var / E² = (K·S_0(M) + 2(K − 1)·S_1(M)) / (K·M·V_0(0))², S_j(M) = Σ_{|d|<M} (M − |d|)·|V_j(d)|².
//!
//! With M = 1 this is Welch's (1967) 2K/(1 + 2ρ²(K−1)/K), ρ = 1/6 for a Hann window at 50 %
//! overlap; the Hann window also correlates adjacent bins (|V_0(1)/V_0(0)|² = 4/9), so a band of
//! M bins carries fewer than 2KM degrees of freedom. Left out: the non-circular term
//! |E[X X′]|², which matters only within a few bins of 0 and of the Nyquist frequency.

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::confidence::chi2_quantile;
use super::psd::{Psd, hann};

/// Equivalent degrees of freedom of a Welch estimate averaged over adjacent bins.
pub struct WelchEdf {
    segments: f64,
    /// |V_0(d)|² / V_0(0)², d = 0 … L/2.
    same: Vec<f64>,
    /// |V_1(d)|² / V_0(0)², d = 0 … L/2.
    next: Vec<f64>,
}

impl WelchEdf {
    /// For `segments` Hann segments of length `len` (a power of two, ≥ 8) at 50 % overlap.
    pub fn new(len: usize, segments: u64) -> WelchEdf {
        let w = hann(len);
        let half = len / 2;
        let fft = FftPlanner::new().plan_fft_forward(len);
        let power = |v: &mut [Complex<f64>]| {
            fft.process(v);
            v[..=half]
                .iter()
                .map(|c| c.norm_sqr())
                .collect::<Vec<f64>>()
        };
        let mut same: Vec<Complex<f64>> = w.iter().map(|x| Complex::new(x * x, 0.0)).collect();
        let mut next: Vec<Complex<f64>> = (0..len)
            .map(|i| Complex::new(if i < half { w[i] * w[i + half] } else { 0.0 }, 0.0))
            .collect();
        let (same, next) = (power(&mut same), power(&mut next));
        let v00 = same[0];
        WelchEdf {
            segments: segments as f64,
            same: same.iter().map(|p| p / v00).collect(),
            next: next.iter().map(|p| p / v00).collect(),
        }
    }

    /// ν of the mean of `bins` adjacent bins (1 ≤ bins ≤ L/2).
    pub fn edf(&self, bins: usize) -> f64 {
        let m = bins.clamp(1, self.same.len() - 1);
        let s =
            |v: &[f64]| v[0] * m as f64 + 2.0 * (1..m).map(|d| (m - d) as f64 * v[d]).sum::<f64>();
        let k = self.segments;
        let rel = (k * s(&self.same) + 2.0 * (k - 1.0) * s(&self.next)) / (k * m as f64).powi(2);
        2.0 / rel
    }
}

/// Interval [lo, hi] of a density estimate `p` with `edf` degrees of freedom at confidence `c`.
pub fn psd_interval(p: f64, edf: f64, c: f64) -> (f64, f64) {
    (
        p * edf / chi2_quantile((1.0 + c) / 2.0, edf),
        p * edf / chi2_quantile((1.0 - c) / 2.0, edf),
    )
}

/// A PSD averaged over log-spaced bands, with each band's interval.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BandedPsd {
    /// Mean frequency of each band (Hz).
    pub freq: Vec<f64>,
    /// Mean density of each band.
    pub density: Vec<f64>,
    /// Lower edge of the interval.
    pub lo: Vec<f64>,
    /// Upper edge of the interval.
    pub hi: Vec<f64>,
    /// Bins averaged in each band.
    pub bins: Vec<usize>,
}

/// Groups consecutive (f, P) into bands of 1/`per_decade` decade (f ≤ 0 left out): per band
/// (mean f, mean P, number of bins).
pub fn log_groups(freq: &[f64], density: &[f64], per_decade: f64) -> Vec<(f64, f64, usize)> {
    let mut out: Vec<(f64, f64, usize)> = Vec::new();
    let mut last = None;
    for (&f, &p) in freq.iter().zip(density) {
        if f <= 0.0 {
            continue;
        }
        let band = (f.log10() * per_decade).floor() as i64;
        match out.last_mut() {
            Some(g) if last == Some(band) => {
                g.0 += f;
                g.1 += p;
                g.2 += 1;
            }
            _ => out.push((f, p, 1)),
        }
        last = Some(band);
    }
    for g in &mut out {
        g.0 /= g.2 as f64;
        g.1 /= g.2 as f64;
    }
    out
}

/// `psd` without its Nyquist bin (its one-sided density has no mirror image) averaged over
/// bands of 1/`per_decade` decade, each with its interval of confidence `c`. Empty when no
/// segment was averaged.
pub fn banded(psd: &Psd, per_decade: f64, c: f64) -> BandedPsd {
    if psd.segments == 0 || psd.freq.len() < 3 {
        return BandedPsd::default();
    }
    let end = psd.freq.len() - 1;
    let edf = WelchEdf::new(2 * end, psd.segments);
    let mut out = BandedPsd::default();
    for (f, p, m) in log_groups(&psd.freq[..end], &psd.density[..end], per_decade) {
        let (lo, hi) = psd_interval(p, edf.edf(m), c);
        out.freq.push(f);
        out.density.push(p);
        out.lo.push(lo);
        out.hi.push(hi);
        out.bins.push(m);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed forms: one segment, one bin: ν = 2 (a χ²₂ periodogram); K segments of one bin:
    /// Welch's 2K/(1 + 2ρ²(K − 1)/K) with ρ = 1/6; one segment, two adjacent bins:
    /// Var/E² = (2 + 2·4/9)/4, ν = 36/13.
    #[test]
    fn edf_closed_forms() {
        let one = WelchEdf::new(256, 1);
        assert!((one.edf(1) - 2.0).abs() < 1e-12, "{}", one.edf(1));
        assert!((one.edf(2) - 36.0 / 13.0).abs() < 1e-12, "{}", one.edf(2));
        for k in [2u64, 7, 100] {
            let e = WelchEdf::new(1024, k).edf(1);
            let kf = k as f64;
            let welch = 2.0 * kf / (1.0 + 2.0 / 36.0 * (kf - 1.0) / kf);
            assert!((e / welch - 1.0).abs() < 1e-12, "K = {k}: {e} vs {welch}");
        }
    }

    /// Many bins: the Hann bin correlations 4/9 and 1/36 at lags 1, 2 (the only non-zero
    /// lags of V_0) bring ν per bin towards 2/(1 + 2·4/9 + 2/36) for one segment.
    #[test]
    fn edf_of_many_bins_per_segment() {
        let m = 100;
        let e = WelchEdf::new(4096, 1).edf(m);
        let mf = m as f64;
        let exact = 2.0 * mf * mf / (mf + 2.0 * ((mf - 1.0) * 4.0 / 9.0 + (mf - 2.0) / 36.0));
        assert!((e / exact - 1.0).abs() < 1e-12, "{e} vs {exact}");
    }

    #[test]
    fn groups_match_their_bands() {
        let f: Vec<f64> = (0..=20).map(|k| k as f64).collect();
        let p = vec![1.0; f.len()];
        let g = log_groups(&f, &p, 10.0);
        assert_eq!(g.iter().map(|x| x.2).sum::<usize>(), 20);
        assert_eq!(g[0], (1.0, 1.0, 1));
        assert!(banded(&Psd::default(), 10.0, 0.68).freq.is_empty());
    }
}
