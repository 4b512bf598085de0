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
//!
//! A host's polled read (output k reads internal sample n_k = ⌊k·p/q⌋,
//! [`crate::timing::ReadRatio`], p/q = f_in/f_out in lowest terms) makes the output
//! cyclostationary: the covariance of outputs k and k + l is R^in at internal lag
//! n_{k+l} − n_k (R^in_j = Σ_i h_i h_{i+j}), which is a = ⌊lp/q⌋ or a + 1. The overlapping
//! Allan variance averages over every start k, so its expectation is that of a stationary
//! sequence with the covariance averaged over the q phases of k. As k runs over a period,
//! kp mod q runs over 0 … q − 1 (p and q coprime), and the lag is a + 1 exactly when
//! kp mod q ≥ q − c, c = lp mod q: for c of the q phases. Hence
//!
//! R_l = ((q − c)·R^in_a + c·R^in_{a+1})/q,
//!
//! R^in linearly interpolated at the fractional lag l·f_in/f_out, and the formulas above hold
//! with D = p/q. A decimation is the case q = 1.

use super::output_filter::{FilterKind, FilterSpec};
use crate::timing::ReadRatio;

/// The filtered white-noise Allan variance of each sensor's filter (one for both unless the
/// template gives the accelerometers their own, `[output_filter.accel]`).
#[derive(Clone, Debug, PartialEq)]
pub struct SensorAllan {
    gyro: WhiteAllan,
    accel: WhiteAllan,
}

impl SensorAllan {
    /// Both sensors' filters of `spec`, with outputs reading the internal samples `read` names.
    pub fn new(spec: &FilterSpec, read: ReadRatio) -> SensorAllan {
        let gyro = WhiteAllan::new(&spec.sensor(false), read);
        let accel = match spec.accel {
            Some(_) => WhiteAllan::new(&spec.sensor(true), read),
            None => gyro.clone(),
        };
        SensorAllan { gyro, accel }
    }

    /// One sensor's (`accel` false: the gyros').
    pub fn sensor(&self, accel: bool) -> &WhiteAllan {
        if accel { &self.accel } else { &self.gyro }
    }

    /// Channel `ch`'s (0–2 gyro, 3–5 accel).
    pub fn channel(&self, ch: usize) -> &WhiteAllan {
        self.sensor(ch >= 3)
    }
}

/// Longest impulse response kept for an IIR filter (internal samples).
const MAX_TAPS: usize = 1 << 16;

/// The filtered white-noise Allan variance of one filter at one read ratio.
#[derive(Clone, Debug, PartialEq)]
pub struct WhiteAllan {
    /// R_0 … R_L at output lags (unit internal variance; phase-averaged under a polled read).
    r: Vec<f64>,
    /// f_in/f_out: D for a decimation.
    decimation: f64,
}

impl WhiteAllan {
    /// The filter of `spec` (the gyros' when the accelerometers have their own,
    /// [`SensorAllan`]) with outputs reading the internal samples `read` names.
    pub fn new(spec: &FilterSpec, read: ReadRatio) -> WhiteAllan {
        let h = spec.impulse_response(response_len(spec));
        let internal = |j: u64| -> f64 {
            let j = j as usize;
            if j >= h.len() {
                return 0.0;
            }
            h.iter().zip(&h[j..]).map(|(a, b)| a * b).sum()
        };
        let (p, q) = (read.internal_per_period(), read.period());
        let mut r = Vec::new();
        for l in 0u64.. {
            let (a, c) = (l * p / q, l * p % q);
            if a as usize >= h.len() {
                break;
            }
            let mut v = internal(a);
            if c > 0 {
                v = ((q - c) as f64 * v + c as f64 * internal(a + 1)) / q as f64;
            }
            r.push(v);
        }
        WhiteAllan {
            r,
            decimation: read.value(),
        }
    }

    /// R_0 … R_L: the output's covariance at output lags 0 … L for unit-variance internal
    /// white noise (phase-averaged under a polled read; zero beyond).
    pub fn covariance(&self) -> &[f64] {
        &self.r
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
            accel: None,
        }
    }

    /// A moving average of D taps decimated by D is exact block averaging: no mark at all.
    #[test]
    fn moving_average_of_d_is_unfiltered() {
        let w = WhiteAllan::new(
            &spec(FilterKind::MovingAverage { taps: 4 }),
            ReadRatio::integer(4),
        );
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
        let w = WhiteAllan::new(
            &spec(FilterKind::Cic { order: 2, taps: 4 }),
            ReadRatio::integer(4),
        );
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
        let flat = WhiteAllan::new(
            &spec(FilterKind::MovingAverage { taps: 4 }),
            ReadRatio::integer(4),
        );
        for f in [0.0, 10.0, 50.0] {
            assert!((flat.psd_ratio(f, dt) - 1.0).abs() < 1e-15);
        }
    }

    /// The Bartlett window (CIC 2 × 4) at D = 4: h = (1 2 3 4 3 2 1)/16, R_0 = 44/256,
    /// R_1 = 10/256, so r(1) = 4·34/256 = 17/32 and r(m) = 1 − 15/(32 m) beyond lag 1.
    #[test]
    fn bartlett_window_closed_form() {
        let w = WhiteAllan::new(
            &spec(FilterKind::Cic { order: 2, taps: 4 }),
            ReadRatio::integer(4),
        );
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
        let w = WhiteAllan::new(&s, ReadRatio::integer(d as u64));
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

    /// A polled read (a Bartlett window of 2 × 16 taps at 819.2 Hz read at 100 Hz, outputs 8
    /// or 9 internal samples apart): the interpolated covariance gives the Allan variance
    /// averaged over the 125 start phases, each computed directly as Σ c_i c_j R^in(n_i − n_j)
    /// over the cluster pair's outputs (c = ∓1), to 1e-13. Taking the lag as ⌊l·R⌋ only, or
    /// the decimation by 8 at 800 Hz the fit used to approximate it with, fails by more than
    /// 1e-3.
    #[test]
    fn polled_read_is_the_phase_average() {
        let s = FilterSpec {
            internal_rate_hz: 819.2,
            kind: FilterKind::Cic { order: 2, taps: 16 },
            accel: None,
        };
        let read = ReadRatio::from_rates(819.2, 100.0).unwrap();
        let w = WhiteAllan::new(&s, read);
        let h = s.impulse_response(31);
        let rin = |j: u64| -> f64 {
            let j = j as usize;
            h.iter()
                .zip(h.get(j..).unwrap_or(&[]))
                .map(|(a, b)| a * b)
                .sum()
        };
        let q = read.period();
        for m in [1u64, 2, 3, 5, 16, 64] {
            let mut sum = 0.0;
            for k in 0..q {
                let n: Vec<u64> = (0..2 * m).map(|i| read.index(k + i)).collect();
                let c = |i: usize| if (i as u64) < m { -1.0 } else { 1.0 };
                let mut v = 0.0;
                for i in 0..n.len() {
                    for j in 0..n.len() {
                        v += c(i) * c(j) * rin(n[i].abs_diff(n[j]));
                    }
                }
                // σ² = E(Δ²)/2 of cluster means; the ratio to N²/τ, τ = m·R·Δt_in.
                sum += v / (2.0 * (m * m) as f64) * m as f64 * read.value();
            }
            let want = sum / q as f64;
            let got = w.ratio(m as usize);
            assert!((got - want).abs() < 1e-13, "{m}: {got} vs {want}");
            let decimated = WhiteAllan::new(
                &FilterSpec {
                    internal_rate_hz: 800.0,
                    ..s.clone()
                },
                ReadRatio::integer(8),
            );
            if m <= 5 {
                assert!((decimated.ratio(m as usize) - want).abs() > 1e-3, "{m}");
            }
        }
    }
}
