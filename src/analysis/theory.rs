//! Theoretical Allan variance and PSD of what the error model generates for one axis of an
//! IMU template at a given rate (static input: scale factor, misalignment and constant biases
//! do not move the ADEV or the PSD above f = 0).
//!
//! | term (template key) | Allan variance at τ = mΔt | one-sided PSD (unit²/Hz) |
//! | --- | --- | --- |
//! | white noise N (`noise`), per-sample σ = N/√Δt | N²/τ (exact for the discrete sequence) | 2N² |
//! | random walk K (`random_walk`), b⁺ = b + K√Δt n | K²τ/3·(1 + 1/(2m²)) (exact, discrete) | K²Δt²/(2 sin²πfΔt) |
//! | Gauss–Markov σ, T (`bias_gm`, and each bias-instability component) | σ²·s(Δt/T, m), the sampled sequence's exact curve ([`gm_avar_sampled`]; → σ²·g(τ/T) of the continuous process, g(u) = (2u − 3 + 4e^{−u} − e^{−2u})/u², as Δt/T → 0) | 4σ²T/(1 + (2πfT)²) |
//! | quantization q, carry mode | 3Q²/τ², Q = q_angle/√12 | (8Q²/Δt)·sin²(πfΔt) |
//! | white angle noise Q (`quantization_noise`), rate error (w_k − w_{k−1})/Δt | 3Q²/τ² (exact) | (8Q²/Δt)·sin²(πfΔt) |
//! | quantization q, round / truncate | white rate noise of variance (q_rate)²/12 | 2·(q_rate²/12)·Δt |
//!
//! The generator adds the Gauss–Markov state once per sample (b⁺ = φb + σ√(1 − φ²)n,
//! φ = e^{−Δt/T}): an AR(1) sequence, whose Allan variance [`gm_avar_sampled`] is exact for every
//! Δt/T — white noise of variance σ² per sample when T ≪ Δt, where the continuous curve
//! σ²g(τ/T) would say 2σ²T/τ, off by the factor Δt/(2T).
//!
//! Bias instability is the bank of Gauss–Markov processes of
//! [`crate::errors::process::flicker_bank`]; its curve here is the sum of its components'
//! sampled curves, with the variances the generator uses. Two approximations, both far below
//! the other terms where they act: a slow component is advanced every P samples and held in
//! between (P ≤ T/(16Δt)), taken here as if stepped every sample — the hold changes its curve
//! by O(PΔt/T) ≤ 6 % of that component at τ ≲ PΔt, where it holds a share of σ² of order
//! τ/T; and quantization is treated as an independent uniform error, true when the noise
//! spans an LSB or more (for Gaussian noise of σ ≥ q the error's deviation from uniform is of
//! order e^{−2π²σ²/q²} ≤ 3e−9, Widrow & Kollár, *Quantization Noise*, 2008, ch. 4). The nominal IEEE floor 0.664·B is given separately
//! ([`AxisTheory::nominal_avar`]).

use std::f64::consts::PI;

use super::fit::{FLICKER_FLOOR, Term};
use crate::errors::process::{QuantMode, flicker_bank};
use crate::errors::template::TriadModel;
use crate::units::Lsb;

/// The stochastic terms of one axis, in SI.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AxisTheory {
    /// White-noise density N (rad/√s or m/s/√s), with the post-filter noise's.
    pub white: f64,
    /// The part of `white` added after the output filter (`post_filter_noise`): left
    /// unfiltered by [`crate::analysis::conformance::filtered_avar`].
    pub post_filter: f64,
    /// Extra white rate noise from per-sample rounding (same unit as `white`).
    pub rounding_white: f64,
    /// Angle (velocity) quantization Q = q/√12 in carry mode (rad or m/s).
    pub quantization: f64,
    /// Random-walk density K.
    pub random_walk: f64,
    /// Gauss–Markov bias (σ, T) of the template's `bias_gm`.
    pub gauss_markov: Vec<(f64, f64)>,
    /// The bias-instability bank's components (σ, T).
    pub flicker: Vec<(f64, f64)>,
    /// The template's bias-instability coefficient B.
    pub bias_instability: f64,
}

impl AxisTheory {
    /// Allan variance at cluster size m, sampling interval Δt.
    pub fn avar(&self, m: usize, dt: f64) -> f64 {
        let tau = m as f64 * dt;
        let mf = m as f64;
        let white = self.white.powi(2) + self.rounding_white.powi(2);
        let gm: f64 = self
            .gauss_markov
            .iter()
            .chain(&self.flicker)
            .map(|&(s, t)| s * s * gm_avar_sampled(dt / t, m))
            .sum();
        white / tau
            + 3.0 * self.quantization.powi(2) / (tau * tau)
            + self.random_walk.powi(2) * tau / 3.0 * (1.0 + 1.0 / (2.0 * mf * mf))
            + gm
    }

    /// The IEEE 952 closed form with the template's nominal coefficients (flat 0.664·B floor).
    pub fn nominal_avar(&self, tau: f64) -> f64 {
        let white = self.white.powi(2) + self.rounding_white.powi(2);
        3.0 * self.quantization.powi(2) / (tau * tau)
            + white / tau
            + FLICKER_FLOOR * self.bias_instability.powi(2)
            + self.random_walk.powi(2) * tau / 3.0
    }

    /// One-sided PSD at frequency f (Hz) for sampling interval Δt.
    pub fn psd(&self, f: f64, dt: f64) -> f64 {
        let white = self.white.powi(2) + self.rounding_white.powi(2);
        let s = (PI * f * dt).sin();
        let rw = if s == 0.0 {
            f64::INFINITY
        } else {
            self.random_walk.powi(2) * dt * dt / (2.0 * s * s)
        };
        let gm: f64 = self
            .gauss_markov
            .iter()
            .chain(&self.flicker)
            .map(|&(sg, t)| 4.0 * sg * sg * t / (1.0 + (2.0 * PI * f * t).powi(2)))
            .sum();
        2.0 * white
            + 8.0 * self.quantization.powi(2) / dt * s * s
            + if self.random_walk > 0.0 { rw } else { 0.0 }
            + gm
    }

    /// The bank's Allan variance at τ per unit B² — the exact shape of what the generator
    /// makes of the flat (2 ln 2/π)·B² floor (None without bias instability).
    pub fn flicker_shape(&self, tau: f64) -> Option<f64> {
        (self.bias_instability > 0.0).then(|| {
            self.flicker
                .iter()
                .map(|&(s, t)| s * s * gm_shape(tau / t))
                .sum::<f64>()
                / self.bias_instability.powi(2)
        })
    }

    /// The template's value of an IEEE term (0 when it does not set it; R is never set).
    pub fn specified(&self, t: Term) -> f64 {
        match t {
            Term::Quantization => self.quantization,
            Term::WhiteNoise => (self.white.powi(2) + self.rounding_white.powi(2)).sqrt(),
            Term::BiasInstability => self.bias_instability,
            Term::RandomWalk => self.random_walk,
            Term::Ramp => 0.0,
        }
    }

    /// The share of term `t` in the theoretical σ² at cluster size m (the Gauss–Markov
    /// components count as bias instability).
    pub fn share(&self, t: Term, m: usize, dt: f64) -> f64 {
        let tau = m as f64 * dt;
        let total = self.avar(m, dt);
        if total <= 0.0 {
            return 0.0;
        }
        let part = match t {
            Term::Quantization => 3.0 * self.quantization.powi(2) / (tau * tau),
            Term::WhiteNoise => (self.white.powi(2) + self.rounding_white.powi(2)) / tau,
            Term::BiasInstability => self
                .gauss_markov
                .iter()
                .chain(&self.flicker)
                .map(|&(s, t)| s * s * gm_avar_sampled(dt / t, m))
                .sum(),
            Term::RandomWalk => {
                let mf = m as f64;
                self.random_walk.powi(2) * tau / 3.0 * (1.0 + 1.0 / (2.0 * mf * mf))
            }
            Term::Ramp => 0.0,
        };
        part / total
    }
}

/// g(u) = (2u − 3 + 4e^{−u} − e^{−2u})/u²: the Allan variance of a unit-variance continuous
/// Gauss–Markov process at τ = uT (→ 2/(3)·u for small u, 2/u for large u). Below u = 0.5 the
/// series Σ_{k≥3} (−1)^k (4 − 2^k) u^{k−2}/k! avoids the cancellation.
pub fn gm_shape(u: f64) -> f64 {
    if u < 0.5 {
        let mut sum = 0.0;
        let mut uk = u; // u^{k−2}
        let mut fact = 6.0; // k!
        let mut pow2 = 8.0; // 2^k
        for k in 3..30 {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            sum += sign * (4.0 - pow2) * uk / fact;
            uk *= u;
            fact *= (k + 1) as f64;
            pow2 *= 2.0;
        }
        sum
    } else {
        (2.0 * u - 3.0 + 4.0 * (-u).exp() - (-2.0 * u).exp()) / (u * u)
    }
}

/// The Allan variance at cluster size m of a unit-variance Gauss–Markov sequence sampled every
/// Δt = xT (the AR(1) sequence b_k with autocovariance φ^|l|, φ = e^{−x}), exact:
///
/// σ²(m) = [m(1 − φ²) − φ(1 − Φ)(3 − Φ)] / (m²(1 − φ)²), Φ = φ^m,
///
/// from σ²(m) = Var(block mean) − Cov(adjacent block means) with Σ_{l<m}(m − l)φ^l and
/// Σ_{i,j<m} φ^{m+j−i} = φ(1 − Φ)²/(1 − φ)² summed in closed form. Limits: σ²(1) = 1 − φ; white
/// noise 1/m as x → ∞; the continuous g(mx) as x → 0 at fixed mx. For (2m + 1)x < 1/2 the
/// numerator, a difference of O(mx) terms that is O((mx)³), is summed as its Taylor series
/// Σ_{k≥3} (−x)^k/k!·[4(m + 1)^k − (2m + 1)^k − m·2^k − 3] (the k = 0, 1, 2 coefficients vanish),
/// from N = m − m e^{−2x} − 3e^{−x} + 4e^{−(m+1)x} − e^{−(2m+1)x}.
pub fn gm_avar_sampled(x: f64, m: usize) -> f64 {
    let mf = m as f64;
    if x > 700.0 {
        return 1.0 / mf; // φ underflows: independent samples
    }
    let a = -(-x).exp_m1(); // 1 − φ
    let numerator = if (2.0 * mf + 1.0) * x < 0.5 {
        let (mut sum, mut xk, mut fact) = (0.0, x * x * x, 6.0);
        let (b1, b2) = (mf + 1.0, 2.0 * mf + 1.0);
        let (mut p1, mut p2, mut p3) = (b1.powi(3), b2.powi(3), 8.0);
        for k in 3..60 {
            let c = 4.0 * p1 - p2 - mf * p3 - 3.0;
            let term = if k % 2 == 0 { xk / fact } else { -xk / fact } * c;
            sum += term;
            if term.abs() <= 1e-17 * sum.abs() {
                break;
            }
            xk *= x;
            fact *= (k + 1) as f64;
            p1 *= b1;
            p2 *= b2;
            p3 *= 2.0;
        }
        sum
    } else {
        let phi = (-x).exp();
        let one_minus_big = -(-mf * x).exp_m1(); // 1 − Φ
        mf * -(-2.0 * x).exp_m1() - phi * one_minus_big * (2.0 + one_minus_big)
    };
    numerator / (mf * mf * a * a)
}

/// The theory of the three axes of a triad at sampling interval Δt.
pub fn triad(m: &TriadModel, mode: QuantMode, dt: f64) -> [AxisTheory; 3] {
    std::array::from_fn(|i| {
        let q_angle = match m.quantization {
            Some(Lsb::Increment(q)) => q,
            Some(Lsb::Rate(q)) => q * dt,
            None => 0.0,
        };
        let (quantization, rounding_white) = match mode {
            QuantMode::Carry => (q_angle / 12f64.sqrt(), 0.0),
            // Rate error of variance (q/Δt)²/12 per sample = white density q/√(12Δt).
            QuantMode::Round | QuantMode::Truncate => (0.0, q_angle / (12.0 * dt).sqrt()),
        };
        // White angle noise of Q (`quantization_noise`) has the carry quantizer's 3Q²/τ² and
        // PSD, independent of it.
        let quantization = quantization.hypot(m.quantization_noise[i]);
        let mut gauss_markov = Vec::new();
        if let Some((s, t)) = m.bias_gm
            && s[i] > 0.0
        {
            gauss_markov.push((s[i], t[i]));
        }
        let flicker = if m.bias_instability[i] > 0.0 {
            flicker_bank(m.bias_instability[i], m.bias_instability_band, dt)
                .iter()
                .map(|c| (c.sigma, c.tau))
                .collect()
        } else {
            Vec::new()
        };
        AxisTheory {
            white: m.noise[i].hypot(m.post_filter_noise[i]),
            post_filter: m.post_filter_noise[i],
            rounding_white,
            quantization,
            random_walk: m.random_walk[i],
            gauss_markov,
            flicker,
            bias_instability: m.bias_instability[i],
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `quantization_noise` Q is taken as the carry quantizer's 3Q²/τ², exactly, added in σ²
    /// to an LSB's Q = q/√12 in carry mode.
    #[test]
    fn quantization_noise_is_three_q_squared_over_tau_squared() {
        let m = crate::errors::template::parse(
            "[gyro]\nquantization_noise = [\"1 urad\", \"2 urad\", \"3 urad\"]\n\
             [accel]\nquantization_noise = \"0.5 mm/s\"\nquantization = \"1.2 mm/s\"\n",
            std::path::Path::new("q.toml"),
        )
        .unwrap();
        let dt = 0.01;
        let g = triad(&m.gyro, m.quantization_mode, dt);
        let a = triad(&m.accel, m.quantization_mode, dt);
        for k in [1usize, 2, 7, 100] {
            let tau = k as f64 * dt;
            let close = |got: f64, want: f64| {
                assert!((got / want - 1.0).abs() < 1e-12, "{got:e} vs {want:e}")
            };
            close(g[2].avar(k, dt), 3.0 * 9e-12 / (tau * tau));
            let q2 = 0.5e-3f64.powi(2) + 1.2e-3f64.powi(2) / 12.0;
            close(a[0].avar(k, dt), 3.0 * q2 / (tau * tau));
        }
    }
    use crate::analysis::octave_adev::OctaveAdev;
    use crate::errors::process::GaussMarkov;
    use crate::rng::NormalStream;

    #[test]
    fn gm_shape_limits_and_continuity() {
        // Continuous across the switch between series and closed form.
        let a = gm_shape(0.5 - 1e-12);
        let b = gm_shape(0.5 + 1e-12);
        assert!((a / b - 1.0).abs() < 1e-9, "{a} {b}");
        assert!((gm_shape(1e-6) / (2.0 / 3.0 * 1e-6) - 1.0).abs() < 1e-5);
        assert!((gm_shape(1e6) / (2.0 / 1e6) - 1.0).abs() < 1e-5);
    }

    /// The bank's exact curve sits on the nominal 0.664·B floor inside its band (within the
    /// ±10 % ripple of two components per decade) and the two agree on white noise.
    #[test]
    fn flicker_bank_curve_is_flat_in_band() {
        let mut m = TriadModel {
            bias_instability: [1e-5; 3],
            bias_instability_band: (1.0, 1000.0),
            ..TriadModel::default()
        };
        m.noise = [0.0; 3];
        let t = &triad(&m, QuantMode::Carry, 0.01)[0];
        for mm in [128usize, 1024, 8192, 65536] {
            let r = (t.avar(mm, 0.01) / t.nominal_avar(mm as f64 * 0.01)).sqrt();
            assert!((r - 1.0).abs() < 0.1, "m {mm}: {r}");
        }
    }

    /// The closed form against the direct double sum E[(Σc_j b_j)²]/(2m²) over the rate
    /// kernel c = (−1 ×m, +1 ×m), written with D_l = 1 − φ^l (= −expm1(−lx), exact to an ulp)
    /// as −ΣΣ c_i c_j D_|i−j| since Σc = 0: no cancellation of O(1) terms, so the two agree to
    /// round-off (4e-13 relative) for Δt/T from 1e-6 to 100, across the switch to the series.
    #[test]
    fn sampled_gm_matches_the_direct_sum() {
        for x in [1e-6, 1e-4, 3e-3, 0.05, 0.2, 1.0, 3.0, 10.0, 100.0] {
            for m in [1usize, 2, 3, 5, 8, 16, 33, 64] {
                let mut sum = 0.0;
                for i in 0..2 * m {
                    for j in 0..2 * m {
                        let ci = if i < m { -1.0 } else { 1.0 };
                        let cj = if j < m { -1.0 } else { 1.0 };
                        let l = i.abs_diff(j) as f64;
                        sum -= ci * cj * -(-l * x).exp_m1();
                    }
                }
                let direct = sum / (2.0 * (m * m) as f64);
                let closed = gm_avar_sampled(x, m);
                assert!(
                    (closed / direct - 1.0).abs() < 4e-13,
                    "x {x} m {m}: {closed:e} vs {direct:e}"
                );
            }
        }
    }

    /// Limits: σ²(1) = 1 − φ; independent samples (1/m) when T ≪ Δt; the continuous g(mx) as
    /// x → 0 at fixed mx (the two differ by O(x), here ≤ 2e-6); continuous across the switch
    /// between series and closed form (to the closed form's own round-off there).
    #[test]
    fn sampled_gm_limits() {
        for x in [1e-7f64, 0.01, 2.0] {
            let want = -(-x).exp_m1();
            assert!((gm_avar_sampled(x, 1) / want - 1.0).abs() < 1e-14);
        }
        for m in [1usize, 4, 1024] {
            assert!((gm_avar_sampled(60.0, m) * m as f64 - 1.0).abs() < 1e-15);
            assert_eq!(gm_avar_sampled(1e4, m), 1.0 / m as f64);
        }
        let m = 1usize << 20;
        for u in [0.01, 0.3, 1.0, 5.0, 100.0] {
            let r = gm_avar_sampled(u / m as f64, m) / gm_shape(u);
            assert!((r - 1.0).abs() < 2e-6, "u {u}: {r}");
        }
        for m in [1usize, 7, 1000] {
            let edge = 0.5 / (2.0 * m as f64 + 1.0);
            let (a, b) = (
                gm_avar_sampled(edge * (1.0 - 1e-12), m),
                gm_avar_sampled(edge * (1.0 + 1e-12), m),
            );
            // Just above the switch the closed form's numerator, O((mx)³) ≈ 5e-3 for m = 1,
            // is the difference of terms ≈ 0.3: it keeps ~14 digits, not 16.
            assert!((a / b - 1.0).abs() < 5e-12, "m {m}: {a} {b}");
        }
    }

    /// A simulated Gauss–Markov sequence follows its sampled curve: 8 records of 2^17 samples at
    /// T = 100Δt; the tolerance is 4σ of the mean of 8 χ² estimates with the random-walk edf
    /// (≈ n/m, the smallest of the table's, so conservative).
    #[test]
    fn gauss_markov_sequence_follows_theory() {
        let (sigma, t, dt, n) = (2.0, 1.0, 0.01, 1usize << 17);
        let mut sums = [0.0; 4];
        let ms = [16usize, 64, 256, 1024];
        for r in 0..8 {
            let mut gm = GaussMarkov::new(sigma, t, dt, NormalStream::new(r, "theory/gm"));
            let mut acc = OctaveAdev::new();
            (0..n).for_each(|_| acc.push(gm.step()));
            let pts = acc.points(dt, |_| crate::analysis::confidence::NoiseType::WhiteRate);
            for (s, &m) in sums.iter_mut().zip(&ms) {
                let p = pts.iter().find(|p| p.m == m).unwrap();
                *s += p.adev * p.adev / 8.0;
            }
        }
        for (s, &m) in sums.iter().zip(&ms) {
            let expect = sigma * sigma * gm_avar_sampled(dt / t, m);
            let tol = 4.0 * (2.0 / (8.0 * n as f64 / m as f64)).sqrt();
            assert!(
                (s / expect - 1.0).abs() < tol,
                "m {m}: {} tol {tol}",
                s / expect
            );
        }
    }
}
