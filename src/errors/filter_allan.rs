//! The Allan variance of white noise after a unit's output filter and decimation: what
//! `validate` and `analyze --imu` expect of a filtered template's white-noise term, and from
//! which cluster size on the IEEE 1/τ law holds again. Pure math.
//!
//! White noise of density N sampled at the internal interval Δt_in has per-sample variance
//! N²/Δt_in. Filtered by h and decimated by D, the output sequence has autocovariance
//! (N²/Δt_in)·R_l at output lag l, R_l = Σ_i h_i h_{i+lD}. The Allan variance of a cluster of
//! m outputs is Var(block mean) − Cov(adjacent block means) (e.g. NIST SP 1065, §5.2.2):
//!
//! m²·A(m) = m R_0 + 2 Σ_{l=1}^{m−1} (m − l) R_l − Σ_{j=1}^{2m−1} (m − |j − m|) R_j,
//!
//! and σ²(m) = (N²/Δt_in)·A(m). Against the unfiltered N²/τ (τ = m·D·Δt_in) the ratio is
//! r(m) = m·D·A(m); at m = 1 it is D·Σ h_i (h_i − h_{i+D}). Once m exceeds the last lag L
//! where R is non-zero, r(m) = r_∞ − 3D Σ_j j R_j / m, so the filter's mark fades as 1/τ.
//! The limit r_∞ = D Σ_l R_l equals Σ_{k=0}^{D−1} |H(k·f_out)|² (Poisson summation): the
//! noise the filter lets through at the output rate's multiples aliases onto DC. It is 1 for
//! a moving average or CIC of D taps (nulls there) and slightly above 1 for a Butterworth.

use super::output_filter::{FilterKind, FilterSpec};

/// Longest impulse response kept for an IIR filter (internal samples).
const MAX_TAPS: usize = 1 << 16;

/// The filtered white-noise Allan variance of one filter at one decimation.
#[derive(Clone, Debug, PartialEq)]
pub struct WhiteAllan {
    /// R_0 … R_L at output lags (unit internal variance).
    r: Vec<f64>,
    decimation: f64,
}

impl WhiteAllan {
    /// The filter of `spec` decimated by `decimation` (≥ 1).
    pub fn new(spec: &FilterSpec, decimation: usize) -> WhiteAllan {
        let h = spec.impulse_response(response_len(spec));
        let d = decimation.max(1);
        let r = (0..=(h.len() - 1) / d)
            .map(|l| h.iter().zip(&h[l * d..]).map(|(a, b)| a * b).sum())
            .collect();
        WhiteAllan {
            r,
            decimation: d as f64,
        }
    }

    /// r(m): the filtered Allan variance at m output samples over the unfiltered N²/τ.
    pub fn ratio(&self, m: usize) -> f64 {
        let r = |l: usize| self.r.get(l).copied().unwrap_or(0.0);
        let mf = m as f64;
        let var: f64 = mf * r(0)
            + 2.0
                * (1..m.min(self.r.len()))
                    .map(|l| (mf - l as f64) * r(l))
                    .sum::<f64>();
        let cov: f64 = (1..(2 * m).min(self.r.len()))
            .map(|j| (mf - (j as f64 - mf).abs()) * r(j))
            .sum();
        self.decimation * (var - cov) / mf
    }

    /// r_∞: the ratio at long τ (the aliasing gain of the white-noise density, squared).
    pub fn long_tau(&self) -> f64 {
        self.decimation * (self.r[0] + 2.0 * self.r[1..].iter().sum::<f64>())
    }

    /// The output's white-noise PSD at frequency `f` over its value at f → 0, for output
    /// interval `dt`: the Wiener–Khinchin sum of the output autocorrelation,
    /// (R_0 + 2 Σ R_l cos 2πf l Δt)/(R_0 + 2 Σ R_l) — the filter's |H|² with the bands above
    /// the output Nyquist folded back by the decimation.
    pub fn psd_ratio(&self, f: f64, dt: f64) -> f64 {
        let w = 2.0 * std::f64::consts::PI * f * dt;
        let folded: f64 = self.r[0]
            + 2.0
                * self.r[1..]
                    .iter()
                    .enumerate()
                    .map(|(l, r)| r * (w * (l + 1) as f64).cos())
                    .sum::<f64>();
        folded * self.decimation / self.long_tau()
    }

    /// The smallest m (of `ms`, ascending) from which on every r(m) is within `tolerance`
    /// (relative) of r_∞; None when none is.
    pub fn settled_from(&self, ms: &[usize], tolerance: f64) -> Option<usize> {
        let long = self.long_tau();
        let off = |m: usize| (self.ratio(m) / long - 1.0).abs() > tolerance;
        let last_off = ms.iter().rposition(|&m| off(m));
        let first = last_off.map_or(0, |i| i + 1);
        ms.get(first).copied()
    }
}

/// Samples of impulse response that hold the whole filter: exact for FIR; for a Butterworth
/// long enough that its slowest pole, decaying as exp(−2π f_c sin(π/2n) t), is below 1e−12.
fn response_len(spec: &FilterSpec) -> usize {
    match &spec.kind {
        FilterKind::MovingAverage { taps } => *taps,
        FilterKind::Cic { order, taps } => order * (taps - 1) + 1,
        FilterKind::Fir { coefficients } => coefficients.len(),
        FilterKind::Butterworth { order, cutoff_hz } => {
            let rate = 2.0
                * std::f64::consts::PI
                * cutoff_hz
                * (std::f64::consts::PI / (2 * order) as f64).sin()
                / spec.internal_rate_hz;
            ((28.0 / rate).ceil() as usize).clamp(64, MAX_TAPS)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(kind: FilterKind) -> FilterSpec {
        FilterSpec {
            internal_rate_hz: 800.0,
            kind,
        }
    }

    /// A moving average of D taps decimated by D is exact block averaging: no mark at all.
    #[test]
    fn moving_average_of_d_is_unfiltered() {
        let w = WhiteAllan::new(&spec(FilterKind::MovingAverage { taps: 4 }), 4);
        for m in [1, 2, 3, 7, 64] {
            assert!((w.ratio(m) - 1.0).abs() < 1e-15, "{m}: {}", w.ratio(m));
        }
        assert_eq!(w.settled_from(&[1, 2, 4], 1e-9), Some(1));
    }

    /// The folded PSD shape: the Bartlett window at D = 4 has R_0 = 44/256, R_1 = 10/256 and
    /// nothing beyond, so S(f)/S(0) = (44 + 20 cos 2πfΔt)/64: 3/8 at the output Nyquist (100 Hz),
    /// 11/16 at a quarter of the output rate. A moving average of D decimated by D is flat. Lags
    /// counted from 0 in the cosine (an off-by-one) or the unfolded |H|² (lags at the internal
    /// rate) fail it.
    #[test]
    fn psd_ratio_closed_form() {
        let w = WhiteAllan::new(&spec(FilterKind::Cic { order: 2, taps: 4 }), 4);
        let dt = 4.0 / 800.0;
        for (f, want) in [
            (0.0, 1.0),
            (50.0, 11.0 / 16.0),
            (100.0, 3.0 / 8.0),
            (100.0 / 3.0, 27.0 / 32.0),
        ] {
            let got = w.psd_ratio(f, dt);
            assert!((got - want).abs() < 1e-14, "{f} Hz: {got} vs {want}");
        }
        let flat = WhiteAllan::new(&spec(FilterKind::MovingAverage { taps: 4 }), 4);
        for f in [0.0, 10.0, 50.0] {
            assert!((flat.psd_ratio(f, dt) - 1.0).abs() < 1e-15);
        }
    }

    /// The Bartlett window (CIC 2 × 4) at D = 4: h = (1 2 3 4 3 2 1)/16, R_0 = 44/256,
    /// R_1 = 10/256, so r(1) = 4·34/256 = 17/32 and r(m) = 1 − 15/(32 m) beyond lag 1.
    #[test]
    fn bartlett_window_closed_form() {
        let w = WhiteAllan::new(&spec(FilterKind::Cic { order: 2, taps: 4 }), 4);
        assert!((w.ratio(1) - 17.0 / 32.0).abs() < 1e-15);
        for m in [2usize, 5, 64, 1 << 20] {
            let want = 1.0 - 15.0 / (32.0 * m as f64);
            assert!((w.ratio(m) - want).abs() < 1e-14, "{m}: {}", w.ratio(m));
        }
        assert!((w.long_tau() - 1.0).abs() < 1e-15);
        // 15/(32 m) ≤ 1 % from m = 47: the first octave is 64.
        let ms: Vec<usize> = (0..12).map(|j| 1 << j).collect();
        assert_eq!(w.settled_from(&ms, 0.01), Some(64));
    }

    /// r_∞ of a Butterworth equals Σ_k |H(k f_out)|², from the filter's own response: the
    /// aliased noise. Wrong lag spacing (internal instead of output lags) fails it.
    #[test]
    fn long_tau_is_the_aliasing_sum() {
        let s = spec(FilterKind::Butterworth {
            order: 3,
            cutoff_hz: 150.0,
        });
        let d = 4;
        let w = WhiteAllan::new(&s, d);
        let f_out = s.internal_rate_hz / d as f64;
        let alias: f64 = (0..d).map(|k| s.magnitude(k as f64 * f_out).powi(2)).sum();
        assert!(alias > 1.0 + 1e-4, "{alias}");
        assert!(
            (w.long_tau() / alias - 1.0).abs() < 1e-9,
            "{} vs {alias}",
            w.long_tau()
        );
        // At long τ the ratio tends to r_∞.
        assert!((w.ratio(1 << 20) / alias - 1.0).abs() < 1e-5);
    }
}
