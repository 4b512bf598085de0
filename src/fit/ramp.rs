//! The rate ramp read from the time series rather than from the Allan variance.
//!
//! Why: a ramp R adds R²τ²/2 to the Allan variance, and the last octaves of a random walk,
//! few and correlated, scatter upward in just that shape, so no χ² gate on the octaves tells
//! the two apart (docs/fit.md). In the time domain they differ: the least-squares slope b̂ of
//! the rate is unbiased for R, and its variance under the noise model alone is a quadratic
//! form of the slope weights w_k = (k − k̄)/S, S = Σ(k − k̄)² = n(n² − 1)/12, in the noise's
//! covariance, known term by term for the fitted model ([`slope_variance`]).
//!
//! The test: z = b̂/σ(b̂), σ from the model fitted without a ramp; the ramp earns its place
//! when |z| exceeds the two-sided 99.9 % normal point (3.29): per fit of six channels at most
//! 0.6 % odds of a spurious ramp (Bonferroni). A real ramp inflates the K of that fit, which
//! makes the test conservative, not wrong. When kept, the triad is refitted on the Allan
//! variance of the record with its line removed ([`crate::analysis::analyzer::Trend`]) —
//! unchanged by any ramp, whatever its size — and the interval of R is b̂ ± z₀.₉₉₅·σ(b̂) with σ
//! from that refit.
//!
//! Slope variance per unit coefficient, n samples at Δt, slope in rate per second (derived
//! in the functions, checked against direct double sums and the Allan variances of the same
//! covariances in the tests):
//!
//! * white N (per-sample variance N²/Δt): N²/(Δt³·S);
//! * quantization Q (rate error (e_k − e_{k−1})/Δt, e iid of variance Q²): Q²(n² − 1)/(2S²Δt⁴);
//! * random walk K (steps of variance K²Δt; Cov = K²Δt·min(j, k) + const): Σ_i W_i² with the
//!   tail sums W_i = Σ_{k≥i} w_k = i(n − i)/(2S), which is K²·6(n² + 1)/(5Δt·n(n² − 1)) (the
//!   continuous 6K²/(5T) of the slope of a Brownian motion over T);
//! * Gauss–Markov σ, T and every component of the bias-instability bank (AR(1) samples,
//!   Cov = σ²φ^{|j−k|}, φ = e^{−Δt/T}): Σ_j Σ_k w_j w_k φ^{|j−k|}/Δt², in O(n) by the
//!   recursion h_k = φ(h_{k−1} + w_{k−1}), Σ = Σw² + 2Σ w_k h_k.

pub use super::gmwm::RampTest;
use super::gmwm::{AxisFit, Component, GM_PENALTY, Model, Options, fit_axis_with, fit_triad_with};
use crate::analysis::analyzer::Analysis;
use crate::analysis::confidence::chi2_quantile;
use crate::analysis::octave_adev::AdevPoint;
use crate::errors::process::flicker_bank;

/// Two-sided confidence of the gate per channel.
pub const GATE_CONFIDENCE: f64 = 0.999;

/// Confidence of the stated interval of a kept ramp.
pub const INTERVAL_CONFIDENCE: f64 = 0.99;

/// The two-sided standard normal point of confidence c.
pub fn normal_point(c: f64) -> f64 {
    chi2_quantile(c, 1.0).sqrt()
}

fn s_sum(n: f64) -> f64 {
    n * (n * n - 1.0) / 12.0
}

/// Var of the slope per unit N² (white noise).
pub fn white_slope_var(n: usize, dt: f64) -> f64 {
    1.0 / (dt.powi(3) * s_sum(n as f64))
}

/// Var of the slope per unit Q² (carry quantization): Σ_k w_k(e_k − e_{k−1}) has the weight
/// −w_0 on e_{−1}, w_i − w_{i+1} = −1/S on e_0 … e_{n−2} and w_{n−1} on e_{n−1}; squared and
/// summed, 2((n − 1)/2)²/S² + (n − 1)/S² = (n² − 1)/(2S²).
pub fn quantization_slope_var(n: usize, dt: f64) -> f64 {
    let nf = n as f64;
    (nf * nf - 1.0) / (2.0 * s_sum(nf).powi(2) * dt.powi(4))
}

/// Var of the slope per unit K² (random walk): Σ_{i=1}^{n−1} i²(n − i)²/(4S²) with
/// Σ i²(n − i)² = (n⁵ − n)/30.
pub fn walk_slope_var(n: usize, dt: f64) -> f64 {
    let nf = n as f64;
    1.2 * (nf * nf + 1.0) / (dt * nf * (nf * nf - 1.0))
}

/// Var of the slope per unit σ² of an AR(1) component of correlation time `tau`.
pub fn ar1_slope_var(n: usize, dt: f64, tau: f64) -> f64 {
    let (kbar, s) = ((n as f64 - 1.0) / 2.0, s_sum(n as f64));
    ar1_quadratic(n, (-dt / tau).exp(), |k| (k as f64 - kbar) / s) / (dt * dt)
}

/// Σ_j Σ_k w_j w_k φ^{|j−k|} over j, k < n, in O(n) and without storing w.
pub fn ar1_quadratic(n: usize, phi: f64, w: impl Fn(usize) -> f64) -> f64 {
    let (mut h, mut prev, mut sq, mut cross) = (0.0, 0.0, 0.0, 0.0);
    for k in 0..n {
        let wk = w(k);
        h = phi * (h + prev);
        cross += wk * h;
        sq += wk * wk;
        prev = wk;
    }
    sq + 2.0 * cross
}

/// Σ_j Σ_k w_j w_k min(j, k) over j, k < n (the random walk's covariance per unit step
/// variance, up to a constant that weights summing to zero do not see) = Σ_{i≥1} W_i².
pub fn walk_quadratic(n: usize, w: impl Fn(usize) -> f64) -> f64 {
    let total: f64 = (0..n).map(&w).sum();
    let (mut before, mut sum) = (0.0, 0.0);
    for i in 1..n {
        before += w(i - 1);
        let tail = total - before;
        sum += tail * tail;
    }
    sum
}

/// Var of the least-squares slope (rate per second) of `n` samples under `model`, ramp
/// excluded.
pub fn slope_variance(model: &Model, n: usize) -> f64 {
    let dt = model.dt;
    let c = &model.c;
    let mut v = c[Component::Quantization as usize] * quantization_slope_var(n, dt)
        + (c[Component::WhiteNoise as usize] * model.output.white_long() + model.output.rounding)
            * white_slope_var(n, dt)
        + c[Component::RandomWalk as usize] * walk_slope_var(n, dt);
    if c[Component::GaussMarkov as usize] > 0.0 {
        v += c[Component::GaussMarkov as usize] * ar1_slope_var(n, dt, model.gm_tau);
    }
    let b2 = c[Component::BiasInstability as usize];
    if b2 > 0.0 {
        for comp in flicker_bank(b2.sqrt(), model.band, dt) {
            v += comp.sigma * comp.sigma * ar1_slope_var(n, dt, comp.tau);
        }
    }
    v
}

/// The slope variance under the least favourable of the models the octaves accept: the fit,
/// or the best fit with a random walk in it when its χ² is within χ²₂(99 %) of the fit's.
/// Why: a Gauss–Markov component with T of a few per cent of the record takes a random walk's
/// rise over the measured octaves about as well, but beyond T it is flat where the walk
/// keeps rising — and the slope is set by the longest scale, which the octaves barely see
/// (in the sweep of `tests/fit_ramp.rs` such a swap gave z = 9 on a record without a ramp).
pub fn null_variance(points: &[AdevPoint], n: usize, fit: &AxisFit) -> f64 {
    let v = slope_variance(&fit.model, n);
    let opts = Options {
        ramp: false,
        band: (fit.model.c[Component::BiasInstability as usize] > 0.0).then_some(fit.model.band),
        walk: true,
        output: fit.model.output.clone(),
    };
    match fit_axis_with(points, n, fit.model.dt, &opts) {
        Some(w) if w.chi2 <= fit.chi2 + GM_PENALTY => v.max(slope_variance(&w.model, n)),
        _ => v,
    }
}

/// Applies the ramp test to the fits of the six channels of a recording (gyro x y z, accel
/// x y z) fitted without ramps: every channel gets its [`RampTest`]; a triad with a kept ramp
/// is refitted with those axes' detrended Allan variance, and the kept ramp enters the
/// axis's model as R² (so the model's curve is that of the raw record). Channels of a table
/// (no trend) are left as they are.
pub fn apply(a: &Analysis, fits: &mut [Option<AxisFit>]) {
    let n = a.samples as usize;
    let gate = normal_point(GATE_CONFIDENCE);
    for base in [0, 3] {
        let mut tests: [Option<RampTest>; 3] = [None; 3];
        for (axis, t) in tests.iter_mut().enumerate() {
            let ch = base + axis;
            let (Some(trend), Some(fit)) = (&a.channels[ch].trend, &fits[ch]) else {
                continue;
            };
            let sigma = null_variance(&a.channels[ch].adev, n, fit).sqrt();
            let z = trend.slope / sigma;
            *t = Some(RampTest {
                slope: trend.slope,
                sigma_null: sigma,
                z,
                kept: z.abs() > gate,
                interval: None,
            });
        }
        if tests.iter().flatten().any(|t| t.kept) {
            let points = std::array::from_fn(|axis| {
                let c = &a.channels[base + axis];
                match (&c.trend, tests[axis]) {
                    (Some(trend), Some(t)) if t.kept => trend.detrended.as_slice(),
                    _ => c.adev.as_slice(),
                }
            });
            let outputs = std::array::from_fn(|axis| {
                fits[base + axis]
                    .as_ref()
                    .map(|f| f.model.output.clone())
                    .unwrap_or_default()
            });
            let refit = fit_triad_with(points, n, a.dt, false, outputs);
            for (axis, f) in refit.into_iter().enumerate() {
                fits[base + axis] = f;
            }
        }
        let z99 = normal_point(INTERVAL_CONFIDENCE);
        for (axis, t) in tests.into_iter().enumerate() {
            let (Some(mut t), Some(fit)) = (t, fits[base + axis].as_mut()) else {
                continue;
            };
            if t.kept {
                let points = &a.channels[base + axis]
                    .trend
                    .as_ref()
                    .expect("tested")
                    .detrended;
                let sigma = null_variance(points, n, fit).sqrt();
                t.interval = Some((t.slope - z99 * sigma, t.slope + z99 * sigma));
                fit.model.c[Component::Ramp as usize] = t.slope * t.slope;
            }
            fit.ramp = Some(t);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slope_w(n: usize) -> impl Fn(usize) -> f64 {
        let (kbar, s) = ((n as f64 - 1.0) / 2.0, s_sum(n as f64));
        move |k| (k as f64 - kbar) / s
    }

    /// The Allan weights of octave m on 2m samples (the second difference of the phase):
    /// −1 on the first m, +1 on the next m; the Allan variance is the quadratic form / (2m²).
    fn allan_w(m: usize) -> impl Fn(usize) -> f64 {
        move |k| if k < m { -1.0 } else { 1.0 }
    }

    fn brute(n: usize, w: &dyn Fn(usize) -> f64, cov: &dyn Fn(usize, usize) -> f64) -> f64 {
        let mut s = 0.0;
        for j in 0..n {
            for k in 0..n {
                s += w(j) * w(k) * cov(j, k);
            }
        }
        s
    }

    /// The random walk's quadratic form with the Allan weights is the fit's exact basis
    /// m/3·(1 + 1/(2m²)) per unit step variance (so the covariance is the one the fit models);
    /// with the slope weights it is the closed form 6(n² + 1)/(5n(n² − 1)) and the direct
    /// double sum of min(j, k).
    #[test]
    fn random_walk_matches_its_allan_basis_and_closed_form() {
        for m in [1usize, 2, 7, 64] {
            let mf = m as f64;
            let got = walk_quadratic(2 * m, allan_w(m)) / (2.0 * mf * mf);
            let want = mf / 3.0 * (1.0 + 1.0 / (2.0 * mf * mf));
            assert!((got / want - 1.0).abs() < 1e-13, "m {m}: {got} {want}");
        }
        for n in [3usize, 10, 257] {
            let got = walk_quadratic(n, slope_w(n));
            let direct = brute(n, &slope_w(n), &|j, k| j.min(k) as f64);
            assert!((got / direct - 1.0).abs() < 1e-11, "n {n}: {got} {direct}");
            let closed = walk_slope_var(n, 1.0);
            assert!((got / closed - 1.0).abs() < 1e-11, "n {n}: {got} {closed}");
        }
        let (n, dt) = (1usize << 20, 0.05);
        let t = n as f64 * dt;
        assert!((walk_slope_var(n, dt) / (1.2 / t) - 1.0).abs() < 1e-11);
    }

    /// The O(n) recursion equals the direct double sum of φ^{|j−k|} (slope and Allan weights);
    /// φ = 0 is white noise (Σw² = 1/S); and for T ≪ the record the component acts on the
    /// slowly varying slope weights as white noise of per-sample variance Σ_lag φ^|lag| =
    /// (1 + φ)/(1 − φ), to order T/T_rec (here 10⁻⁴).
    #[test]
    fn ar1_recursion_matches_the_double_sum_and_its_limits() {
        for (n, phi) in [(5usize, 0.3), (200, 0.97), (333, 0.999_9)] {
            let got = ar1_quadratic(n, phi, slope_w(n));
            let direct = brute(n, &slope_w(n), &|j, k| {
                phi.powi((j as i32 - k as i32).abs())
            });
            assert!((got / direct - 1.0).abs() < 1e-11, "n {n}: {got} {direct}");
            let ga = ar1_quadratic(2 * (n / 2), phi, allan_w(n / 2));
            let da = brute(2 * (n / 2), &allan_w(n / 2), &|j, k| {
                phi.powi((j as i32 - k as i32).abs())
            });
            assert!((ga / da - 1.0).abs() < 1e-11, "n {n}: {ga} {da}");
        }
        let n = 1000;
        let white = ar1_quadratic(n, 0.0, slope_w(n));
        assert!((white * s_sum(n as f64) - 1.0).abs() < 1e-12);
        // T = 100 Δt on a record of 10⁶ Δt: white of density 2σ²T·(1 − O(Δt/T)).
        let (n, dt, tau) = (1_000_000usize, 1.0, 100.0);
        let got = ar1_slope_var(n, dt, tau);
        // Per-sample white variance equivalent: Σ_lag φ^|lag| = (1 + φ)/(1 − φ).
        let phi = (-dt / tau).exp();
        let want = (1.0 + phi) / (1.0 - phi) * white_slope_var(n, dt) * dt;
        assert!((got / want - 1.0).abs() < 1e-3, "{got} {want}");
    }

    /// Quantization: the closed form against the direct sum over the e_k it weights.
    #[test]
    fn quantization_closed_form() {
        for n in [2usize, 9, 500] {
            let w = slope_w(n);
            // Coefficient of e_i, i = −1 … n−1: w_{i} − w_{i+1} with w outside 0..n zero.
            let wk = |k: i64| {
                if (0..n as i64).contains(&k) {
                    w(k as usize)
                } else {
                    0.0
                }
            };
            let direct: f64 = (-1..n as i64).map(|i| (wk(i) - wk(i + 1)).powi(2)).sum();
            let got = quantization_slope_var(n, 1.0);
            assert!((got / direct - 1.0).abs() < 1e-12, "n {n}: {got} {direct}");
        }
    }
}
