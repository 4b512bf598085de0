//! Confidence intervals of Allan deviations: χ² quantiles and the equivalent degrees of
//! freedom (edf) of the overlapping estimator by noise type.
//!
//! Construction (NIST SP 1065 §5.3, Riley): an Allan variance estimate σ̂² with edf ν is
//! distributed as σ²·χ²_ν/ν, so the two-sided interval of confidence c is
//!
//! σ² ∈ [σ̂²·ν/χ²_{(1+c)/2}(ν), σ̂²·ν/χ²_{(1−c)/2}(ν)],
//!
//! and the deviation's interval is its square root. The edf depends on the noise type that
//! dominates at that τ; [`edf`] gives the simple approximations of SP 1065 Table 5.

use std::f64::consts::PI;

/// Noise types of the IEEE 952 rate model, named by what they do to the rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoiseType {
    /// Angle (phase) quantization: white phase noise, σ ∝ 1/τ.
    WhitePhase,
    /// White rate noise (ARW / VRW), σ ∝ τ^−½.
    WhiteRate,
    /// Flicker rate noise (bias instability), flat σ.
    FlickerRate,
    /// Random-walk rate noise (RRW), σ ∝ τ^½; also used for a rate ramp.
    RandomWalkRate,
}

/// Edf of the overlapping Allan variance at cluster size m from `phases` phase points
/// (n rate samples → n + 1 phases), NIST SP 1065 Table 5; clamped to ≥ 1.
pub fn edf(noise: NoiseType, phases: usize, m: usize) -> f64 {
    let n = phases as f64;
    let m = m as f64;
    let e = match noise {
        NoiseType::WhitePhase => (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m)),
        NoiseType::WhiteRate => {
            (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * 4.0 * m * m / (4.0 * m * m + 5.0)
        }
        NoiseType::FlickerRate => {
            if m == 1.0 {
                2.0 * (n - 2.0) * (n - 2.0) / (2.3 * n - 4.9)
            } else {
                5.0 * n * n / (4.0 * m * (n + 3.0 * m))
            }
        }
        NoiseType::RandomWalkRate => {
            (n - 2.0) / m * ((n - 1.0) * (n - 1.0) - 3.0 * m * (n - 1.0) + 4.0 * m * m)
                / ((n - 3.0) * (n - 3.0))
        }
    };
    if e.is_finite() { e.max(1.0) } else { 1.0 }
}

/// Interval [lo, hi] of the deviation σ̂ with `edf` degrees of freedom at confidence `c`.
pub fn adev_interval(adev: f64, edf: f64, c: f64) -> (f64, f64) {
    let lo_q = chi2_quantile((1.0 - c) / 2.0, edf);
    let hi_q = chi2_quantile((1.0 + c) / 2.0, edf);
    (adev * (edf / hi_q).sqrt(), adev * (edf / lo_q).sqrt())
}

/// ln Γ(x) for x > 0 (Lanczos, g = 7, 9 terms; relative error ≈ 1e-15).
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection keeps the series in its accurate range.
        return (PI / (PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularized lower incomplete gamma P(a, x): series below a + 1, continued fraction above.
pub fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let lead = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        let (mut sum, mut term, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (sum.ln() + lead).exp()
    } else {
        // Modified Lentz for the continued fraction of Q(a, x).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        1.0 - (lead.exp() * h)
    }
}

/// χ² cumulative distribution with ν degrees of freedom.
pub fn chi2_cdf(x: f64, nu: f64) -> f64 {
    gamma_p(nu / 2.0, x / 2.0)
}

/// The p-quantile of χ²_ν (0 < p < 1): Newton on the CDF (its derivative the χ² density),
/// each step kept inside a bracket of the root that every evaluation narrows, else the
/// bracket bisected — a handful of CDF evaluations where bisection to 1e-12 took about forty.
pub fn chi2_quantile(p: f64, nu: f64) -> f64 {
    let mut hi = nu.max(1.0);
    while chi2_cdf(hi, nu) < p {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    let k = nu / 2.0;
    let ln_norm = k * std::f64::consts::LN_2 + ln_gamma(k);
    let mut x = 0.5 * hi;
    for _ in 0..200 {
        let f = chi2_cdf(x, nu) - p;
        if f < 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let density = ((k - 1.0) * x.ln() - 0.5 * x - ln_norm).exp();
        let mut next = x - f / density;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        let done = (next - x).abs() <= 1e-14 * x || hi - lo <= 1e-14 * hi;
        x = next;
        if done {
            break;
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Newton agrees with plain bisection on the same CDF to 1e-11 over p from 1e-4 to
    /// 1 − 1e-4 and ν from 0.3 to 10⁵.
    #[test]
    fn chi2_quantile_agrees_with_bisection() {
        let bisect = |p: f64, nu: f64| {
            let mut hi = nu.max(1.0);
            while chi2_cdf(hi, nu) < p {
                hi *= 2.0;
            }
            let mut lo = 0.0;
            for _ in 0..2000 {
                let mid = 0.5 * (lo + hi);
                if chi2_cdf(mid, nu) < p {
                    lo = mid;
                } else {
                    hi = mid;
                }
                if hi - lo <= 1e-15 * hi {
                    break;
                }
            }
            0.5 * (lo + hi)
        };
        for nu in [0.3, 1.0, 2.0, 3.7, 10.0, 64.0, 500.0, 1e4, 1e5] {
            for p in [
                1e-4,
                0.005,
                0.025,
                0.16,
                0.5,
                0.84,
                0.975,
                0.995,
                1.0 - 1e-4,
            ] {
                let (got, want) = (chi2_quantile(p, nu), bisect(p, nu));
                assert!(
                    (got / want - 1.0).abs() < 1e-11,
                    "ν {nu}, p {p}: {got} vs {want}"
                );
            }
        }
    }

    /// Table values (Abramowitz & Stegun Table 26.8 / any χ² table, 4–5 digits).
    #[test]
    fn chi2_quantiles_match_tables() {
        for (p, nu, q) in [
            (0.975, 1.0, 5.02389),
            (0.025, 1.0, 0.000982069),
            (0.975, 10.0, 20.4832),
            (0.025, 10.0, 3.24697),
            (0.5, 2.0, 1.386294),
            (0.995, 100.0, 140.169),
            (0.005, 100.0, 67.3276),
        ] {
            let got = chi2_quantile(p, nu);
            assert!(
                (got / q - 1.0).abs() < 2e-5,
                "χ²_{p}({nu}) = {got}, table {q}"
            );
        }
    }

    #[test]
    fn ln_gamma_of_integers_and_half() {
        assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-13);
        assert!((ln_gamma(0.5) - PI.sqrt().ln()).abs() < 1e-13);
        assert!((ln_gamma(100.0) - 359.134_205_369_575_4).abs() < 1e-10);
    }

    /// The interval brackets the estimate and narrows as 1/√(2ν) for large ν.
    #[test]
    fn interval_width_for_large_edf() {
        let (lo, hi) = adev_interval(1.0, 20_000.0, 0.6827);
        assert!(lo < 1.0 && hi > 1.0);
        // 1σ of σ̂ is σ/√(2ν) = 0.005: the 68 % interval spans ≈ ±0.005.
        assert!(((hi - lo) / 2.0 - 0.005).abs() < 1e-4, "{lo} {hi}");
    }

    /// The white-rate edf agrees with the formula already used by `allan`.
    #[test]
    fn white_rate_edf_matches_allan_module() {
        for m in [1, 4, 64] {
            let a = edf(NoiseType::WhiteRate, 10_001, m);
            let b = super::super::allan::edf_white_rate(10_000, m);
            assert!((a - b).abs() < 1e-9);
        }
    }
}
