//! The unit's output stage as the Allan-variance fit takes it ([`super::gmwm`]): what an LSB
//! found on the value lattice, an output filter read from the PSD and the spectral lines fix
//! in each axis's model — known parts of σ² that are added, not fitted, and the filtered
//! white-noise basis. Pure math.

use super::vibration_avar::KnownVibration;
use crate::errors::filter_allan::WhiteAllan;

/// What the unit's output stage fixes for the fit of an axis. Its filter (when the PSD shows
/// one, [`super::filter`]) shapes the white noise: its basis is r(m)/τ
/// ([`WhiteAllan::ratio`]) instead of 1/τ, exact for white noise generated at the internal
/// rate and filtered; the slower components are taken unfiltered (their curves change by the
/// filter's length over τ, where they hold a small share). Its LSB: a unit that rounds each
/// rate sample to its LSB q adds white rate noise of variance q²/12 per sample (density²
/// q²Δt/12, Allan variance q²Δt/(12τ)) — known from the value lattice, so it is not fitted
/// but added, and the fitted white noise N is the noise before the rounding, as the
/// generator's `quantization_mode = "round"` needs it. The carry-mode term Q (3Q²/τ²) is then
/// not a candidate: a template has one quantization mode.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputStage {
    /// Rounding noise density² q²Δt/12 (0: no LSB seen).
    pub rounding: f64,
    /// Whether the carry-mode quantization Q may be fitted.
    pub carry: bool,
    /// Q² of a carry-mode quantizer known from the lattice ((qΔt)²/12 for a rate grid q),
    /// adding 3Q²/τ².
    pub carried: f64,
    /// The output filter's white-noise Allan variance, when there is one.
    pub white: Option<WhiteAllan>,
    /// P²/N²: the white noise added after the filter (`post_filter_noise`) over the filtered
    /// one's density, read from the PSD's floor ([`super::filter::floors`]); 0: none.
    pub post_filter: f64,
    /// Spectral lines of the axis, known from its PSD ([`super::lines`]): (amplitude B of
    /// the recorded samples, frequency f), each adding [`sine_avar`].
    pub sines: Vec<(f64, f64)>,
    /// Broad resonances of the axis, known from its PSD ([`super::resonance`]): a random
    /// vibration whose Allan variance is added.
    pub vibration: Option<KnownVibration>,
}

/// The Allan variance at cluster size m of the samples y_k = B sin(2πf kΔt + φ), averaged
/// over φ: adjacent m-sample means differ by 2 sin(πfτ)·sin(πfτ)/(m sin(πfΔt)) times the
/// amplitude, so σ² = B² sin⁴(πfτ)/(m² sin²(πfΔt)) — for the interval means of a sine of
/// amplitude A (B = A·sinc(πfΔt)) the continuous A² sin⁴(πfτ)/(πfτ)² (IEEE Std 952-1997,
/// Annex C, sinusoidal noise).
pub fn sine_avar(b: f64, f: f64, m: usize, dt: f64) -> f64 {
    let x = std::f64::consts::PI * f * dt;
    let s = (x * m as f64).sin();
    let d = m as f64 * x.sin();
    b * b * s.powi(4) / (d * d)
}

impl Default for OutputStage {
    fn default() -> Self {
        OutputStage {
            rounding: 0.0,
            carry: true,
            carried: 0.0,
            white: None,
            post_filter: 0.0,
            sines: Vec::new(),
            vibration: None,
        }
    }
}

impl OutputStage {
    /// Rounding to a rate LSB `q` at interval Δt.
    pub fn rounded(q: f64, dt: f64) -> OutputStage {
        OutputStage {
            rounding: q * q * dt / 12.0,
            carry: false,
            carried: 0.0,
            white: None,
            post_filter: 0.0,
            sines: Vec::new(),
            vibration: None,
        }
    }
    /// A carry-mode quantizer whose outputs sit on the rate grid `q` at interval Δt: the
    /// increments are multiples of qΔt and the residual carried, so the angle error is uniform
    /// over an increment LSB, Q = qΔt/√12, known.
    pub fn carried(q: f64, dt: f64) -> OutputStage {
        OutputStage {
            carry: false,
            carried: (q * dt).powi(2) / 12.0,
            ..OutputStage::default()
        }
    }
    /// The white-noise basis's factor at cluster size m: r(m) through the filter plus the
    /// post-filter noise's P²/N², which the filter leaves white (1 without a filter).
    pub fn white_ratio(&self, m: usize) -> f64 {
        self.white.as_ref().map_or(1.0, |w| w.ratio(m)) + self.post_filter
    }
    /// The known part of σ² at cluster size m (interval Δt): rounding noise, lines and
    /// resonances.
    pub fn known(&self, m: usize, dt: f64) -> f64 {
        let tau = m as f64 * dt;
        self.rounding / tau
            + 3.0 * self.carried / (tau * tau)
            + self
                .sines
                .iter()
                .map(|&(b, f)| sine_avar(b, f, m, dt))
                .sum::<f64>()
            + self.vibration.as_ref().map_or(0.0, |v| v.avar(m))
    }
    /// The quantization's one-sided PSD at frequency `f` (interval Δt): rounding is white,
    /// 2·q²Δt/12; a carried angle error e_k − e_{k−1} over Δt has |1 − e^{−i2πfΔt}|² of it,
    /// 8Q²/Δt·sin²(πfΔt) (its Allan variance is the 3Q²/τ² of [`Self::known`]).
    pub fn quantization_psd(&self, f: f64, dt: f64) -> f64 {
        let s = (std::f64::consts::PI * f * dt).sin();
        2.0 * self.rounding + 8.0 * self.carried / dt * s * s
    }
    /// Its limit at long τ (the white density's aliasing gain, squared, and the post-filter
    /// noise's share).
    pub fn white_long(&self) -> f64 {
        self.white.as_ref().map_or(1.0, WhiteAllan::long_tau) + self.post_filter
    }
    /// The white-noise PSD's factor at f over 2N²: the filter's folded |H|² at its DC level
    /// r_∞, plus the post-filter noise's flat P²/N².
    pub fn white_psd(&self, f: f64, dt: f64) -> f64 {
        self.white
            .as_ref()
            .map_or(1.0, |w| w.long_tau() * w.psd_ratio(f, dt))
            + self.post_filter
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// ∫₀^{1/(2Δt)} of a one-sided PSD times the discrete Allan-variance transfer
    /// 2 sin⁴(πfmΔt)/(m² sin²(πfΔt)) (m = 0: times 1, the covariance), by the midpoint rule:
    /// the integrands are cosine polynomials in 2πfΔt of degree at most 2m + 2, which the
    /// rule with n = 4096 points takes exactly for the m tested.
    fn integrate(psd: impl Fn(f64) -> f64, m: usize, dt: f64) -> f64 {
        let n = 4096;
        let df = 0.5 / dt / n as f64;
        (0..n)
            .map(|j| {
                let f = (j as f64 + 0.5) * df;
                let x = PI * f * dt;
                let h = if m == 0 {
                    1.0
                } else {
                    2.0 * (x * m as f64).sin().powi(4) / ((m * m) as f64 * x.sin().powi(2))
                };
                psd(f) * h * df
            })
            .sum()
    }

    /// The quantization PSD holds the sample variance (q²/12 rounded, 2Q²/Δt² carried), the
    /// carried error's lag-one covariance −Q²/Δt², and at every m the Allan variance
    /// [`OutputStage::known`] adds for it.
    #[test]
    fn quantization_psd_matches_its_variance_and_allan_variance() {
        let (q, dt) = (0.05_f64.to_radians(), 0.01);
        let (r, c) = (OutputStage::rounded(q, dt), OutputStage::carried(q, dt));
        let close = |a: f64, b: f64| assert!((a / b - 1.0).abs() < 1e-12, "{a} vs {b}");
        close(
            integrate(|f| r.quantization_psd(f, dt), 0, dt),
            q * q / 12.0,
        );
        let big_q = c.carried;
        close(
            integrate(|f| c.quantization_psd(f, dt), 0, dt),
            2.0 * big_q / (dt * dt),
        );
        let lag1 = integrate(
            |f| c.quantization_psd(f, dt) * (2.0 * PI * f * dt).cos(),
            0,
            dt,
        );
        close(lag1, -big_q / (dt * dt));
        for m in [1, 2, 3, 16, 100] {
            for s in [&r, &c] {
                close(
                    integrate(|f| s.quantization_psd(f, dt), m, dt),
                    s.known(m, dt),
                );
            }
        }
    }
}
