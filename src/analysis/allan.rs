//! Overlapping Allan deviation of one axis of rate data (IEEE Std 952-1997, Annex C; Riley,
//! *Handbook of Frequency Stability Analysis*, NIST SP 1065, §5.2.4).
//!
//! For a rate series y_k (k = 0 … n−1) sampled at Δt, the integrated angle (the "phase")
//! θ_0 = 0, θ_k = Δt·Σ_{i<k} y_i has N = n + 1 points, and at cluster size m, τ = m·Δt,
//!
//! σ²(τ) = Σ_{k=0}^{N−2m−1} (θ_{k+2m} − 2θ_{k+m} + θ_k)² / (2τ²(N − 2m)),
//!
//! which is O(N) per τ. The cumulative sum is formed with compensated (Neumaier) summation
//! after subtracting the series mean — σ(τ) does not depend on a constant offset, and without
//! it θ grows linearly and the second differences lose digits on long records.
//!
//! The confidence half-width attached to each point is σ/√(2·edf), the 1σ width of a χ²
//! estimate with edf equivalent degrees of freedom, using the Howe–Allan–Barnes (1981)
//! edf of the overlapping estimator for **white rate noise** (white FM; NIST SP 1065
//! Table 5). It is exact in form only for white noise: for random-walk or flicker rate
//! noise the true scatter at long τ is larger, so use it as a guide, not a test bound.

/// One point of an Allan deviation curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AllanPoint {
    /// Cluster size m (samples per averaging interval).
    pub m: usize,
    /// Averaging time τ = m·Δt (s).
    pub tau: f64,
    /// Overlapping Allan deviation σ(τ), in the unit of the rate.
    pub adev: f64,
    /// Approximate 1σ half-width of `adev`: σ/√(2·edf), edf for white rate noise ([`edf_white_rate`]).
    pub half_width: f64,
}

/// Octave-spaced cluster sizes m = 1, 2, 4, … with m ≤ (n − 1)/2 for n rate samples.
pub fn octave_clusters(n: usize) -> Vec<usize> {
    std::iter::successors(Some(1usize), |m| m.checked_mul(2))
        .take_while(|m| 2 * m < n)
        .collect()
}

/// Overlapping Allan deviation of the rate series `y` (sampled at `dt`) at octave-spaced τ.
pub fn overlapping(y: &[f64], dt: f64) -> Vec<AllanPoint> {
    overlapping_at(y, dt, &octave_clusters(y.len()))
}

/// Overlapping Allan deviation of `y` at the given cluster sizes; sizes with m = 0 or
/// 2m ≥ n (fewer than two second differences) are skipped.
pub fn overlapping_at(y: &[f64], dt: f64, clusters: &[usize]) -> Vec<AllanPoint> {
    let n = y.len();
    let valid: Vec<usize> = clusters
        .iter()
        .copied()
        .filter(|&m| m > 0 && 2 * m < n)
        .collect();
    if valid.is_empty() {
        return Vec::new();
    }
    let theta = phase(y, dt);
    valid
        .into_iter()
        .map(|m| {
            let adev = adev_from_phase(&theta, m, dt);
            AllanPoint {
                m,
                tau: m as f64 * dt,
                adev,
                half_width: adev / (2.0 * edf_white_rate(n, m)).sqrt(),
            }
        })
        .collect()
}

/// Equivalent degrees of freedom of the overlapping estimate at cluster size m from n rate
/// samples (N = n + 1 phase points), for white rate noise (Howe, Allan & Barnes 1981):
/// edf = [3(N−1)/(2m) − 2(N−2)/N] · 4m²/(4m² + 5).
pub fn edf_white_rate(n: usize, m: usize) -> f64 {
    let big_n = (n + 1) as f64;
    let m = m as f64;
    (3.0 * (big_n - 1.0) / (2.0 * m) - 2.0 * (big_n - 2.0) / big_n) * 4.0 * m * m
        / (4.0 * m * m + 5.0)
}

/// The integrated angle θ_k = Δt·Σ_{i<k}(y_i − ȳ), k = 0 … n, by compensated summation.
fn phase(y: &[f64], dt: f64) -> Vec<f64> {
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let mut theta = Vec::with_capacity(y.len() + 1);
    theta.push(0.0);
    let (mut sum, mut comp) = (0.0f64, 0.0f64);
    for &v in y {
        let x = (v - mean) * dt;
        let t = sum + x;
        comp += if sum.abs() >= x.abs() {
            (sum - t) + x
        } else {
            (x - t) + sum
        };
        sum = t;
        theta.push(sum + comp);
    }
    theta
}

/// σ(τ) at cluster size m from the phase points θ (N = θ.len(), 2m < N − 1).
fn adev_from_phase(theta: &[f64], m: usize, dt: f64) -> f64 {
    let terms = theta.len() - 2 * m;
    let ss: f64 = (0..terms)
        .map(|k| {
            let d = theta[k + 2 * m] - 2.0 * theta[k + m] + theta[k];
            d * d
        })
        .sum();
    let tau = m as f64 * dt;
    (ss / (2.0 * tau * tau * terms as f64)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{NormalStream, splitmix64};

    /// Uniform draw in [0, 1) from a counter (independent of the normal streams).
    fn uniform(seed: u64, k: u64) -> f64 {
        (splitmix64(seed ^ splitmix64(k)) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    #[test]
    fn clusters_are_octaves_within_the_record() {
        assert_eq!(octave_clusters(9), vec![1, 2, 4]);
        assert_eq!(octave_clusters(8), vec![1, 2]);
        assert!(octave_clusters(2).is_empty());
        assert!(overlapping(&[1.0, 2.0], 0.1).is_empty());
        assert_eq!(overlapping_at(&[0.0; 10], 0.1, &[0, 3, 5]).len(), 1);
    }

    /// White rate noise of density N (rate σ = N/√Δt per sample): σ(τ) = N/√τ.
    /// 200 000 samples; every octave with m ≤ n/50 (edf ≥ 66, 1σ ≤ 9 %) must fall within 4
    /// of its own half-widths. The half-width itself is calibrated below.
    #[test]
    fn white_noise_follows_n_over_sqrt_tau() {
        let (density, dt, n) = (2.0e-3, 0.01f64, 200_000);
        let mut s = NormalStream::new(1, "allan/white");
        let y: Vec<f64> = (0..n).map(|_| density / dt.sqrt() * s.draw()).collect();
        for p in overlapping(&y, dt).iter().filter(|p| p.m <= n / 50) {
            let expect = density / p.tau.sqrt();
            assert!(
                (p.adev - expect).abs() <= 4.0 * p.half_width,
                "τ {} σ {:e} expected {:e} ± {:e}",
                p.tau,
                p.adev,
                expect,
                p.half_width
            );
        }
    }

    /// The documented half-width is the 1σ scatter for white noise: over 400 independent
    /// records of 2000 samples, the RMS of (σ̂ − σ)/half-width is 1 within ±0.15 (the RMS of
    /// 400 unit normals scatters by 1/√800 = 0.035; 0.15 also covers the χ² skew at edf ≈ 35).
    #[test]
    fn half_width_is_the_white_noise_scatter() {
        let (dt, n, records) = (1.0, 2000, 400);
        let mut s = NormalStream::new(2, "allan/calibration");
        for m in [1usize, 8, 32] {
            let mut sum_z2 = 0.0;
            for _ in 0..records {
                let y: Vec<f64> = (0..n).map(|_| s.draw()).collect();
                let p = overlapping_at(&y, dt, &[m])[0];
                let z = (p.adev - 1.0 / p.tau.sqrt()) / p.half_width;
                sum_z2 += z * z;
            }
            let rms = (sum_z2 / records as f64).sqrt();
            assert!(
                (rms - 1.0).abs() < 0.15,
                "m {m}: RMS normalised error {rms}"
            );
        }
    }

    /// Random walk of the rate, b⁺ = b + K√Δt n: for this discrete walk exactly
    /// σ²(τ) = K²τ/3 · (1 + 1/(2m²)) (sum of the squared increment weights of the cluster
    /// difference), → K√(τ/3) at long τ. Averaged over 16 records of 100 000 samples; the
    /// tolerance is 4σ of the mean σ² with the random-walk edf ≈ (N/m)(1 − 3m/N) of
    /// NIST SP 1065 Table 5 (from ±3.6 % on σ² at m = 64 to ±15 % at m = 1024).
    #[test]
    fn random_walk_follows_k_sqrt_tau_over_3() {
        let (k, dt, n, records) = (3.0e-4, 0.01f64, 100_000, 16);
        let clusters = [64, 128, 256, 512, 1024];
        let mut mean_var = [0.0; 5];
        let mut s = NormalStream::new(3, "allan/random-walk");
        for _ in 0..records {
            let mut b = 0.0;
            let y: Vec<f64> = (0..n)
                .map(|_| {
                    b += k * dt.sqrt() * s.draw();
                    b
                })
                .collect();
            for (acc, p) in mean_var.iter_mut().zip(overlapping_at(&y, dt, &clusters)) {
                *acc += p.adev * p.adev / records as f64;
            }
        }
        for (&m, &var) in clusters.iter().zip(&mean_var) {
            let tau = m as f64 * dt;
            let mf = m as f64;
            let exact = k * k * tau / 3.0 * (1.0 + 1.0 / (2.0 * mf * mf));
            let edf = (n as f64 / mf) * (1.0 - 3.0 * mf / n as f64);
            let tol = 4.0 * (2.0 / (edf * records as f64)).sqrt();
            assert!(
                (var / exact - 1.0).abs() < tol,
                "τ {tau}: σ² ratio {} tol {tol}",
                var / exact
            );
            // The long-τ closed form differs from the exact one by 1/(2m²) < 1.3e-4 here.
            assert!((exact / (k * k * tau / 3.0) - 1.0) < 1.3e-4);
        }
    }

    /// A rate ramp of slope R (interval means y_k = R(k + ½)Δt, an exactly quadratic θ):
    /// σ(τ) = Rτ/√2 exactly; only round-off (≈ 1e-9 relative here) separates them.
    #[test]
    fn ramp_follows_r_tau_over_sqrt2() {
        let (r, dt, n) = (1.0e-3, 0.01, 10_000);
        let y: Vec<f64> = (0..n).map(|k| r * (k as f64 + 0.5) * dt).collect();
        let points = overlapping(&y, dt);
        assert_eq!(points.len(), 13);
        for p in points {
            let expect = r * p.tau / std::f64::consts::SQRT_2;
            assert!(
                (p.adev / expect - 1.0).abs() < 1e-7,
                "τ {}: {:e} vs {expect:e}",
                p.tau,
                p.adev
            );
        }
    }

    /// Quantization of the integrated angle: θ_k carries an independent error uniform over
    /// one LSB q, so each second difference has variance 6·q²/12 and σ(τ) = √3·(q/√12)/τ
    /// = q/(2τ). 100 000 samples: the white-phase edf (N+1)(N−2m)/(2(N−m)) ≥ 33 000 at every
    /// octave m ≤ n/4 gives a 1σ ≤ 0.39 %; the tolerance is 4σ of each point (≤ 1.6 %; a
    /// uniform error has a lighter tail than the Gaussian behind the χ² width, so this is
    /// conservative).
    #[test]
    fn angle_quantization_follows_sqrt3_q_over_tau() {
        let (q, dt, n) = (1.0e-6, 0.002, 100_000u64);
        let e: Vec<f64> = (0..=n).map(|k| q * (uniform(4, k) - 0.5)).collect();
        let y: Vec<f64> = e.windows(2).map(|w| (w[1] - w[0]) / dt).collect();
        let big_n = (n + 1) as f64;
        for p in overlapping(&y, dt).iter().filter(|p| p.m as u64 <= n / 4) {
            let expect = 3f64.sqrt() * (q / 12f64.sqrt()) / p.tau;
            let mf = p.m as f64;
            let edf = (big_n + 1.0) * (big_n - 2.0 * mf) / (2.0 * (big_n - mf));
            let tol = 4.0 / (2.0 * edf).sqrt();
            assert!(
                (p.adev / expect - 1.0).abs() < tol,
                "τ {}: ratio {} tol {tol}",
                p.tau,
                p.adev / expect
            );
        }
    }

    /// A constant offset changes nothing (the mean is removed before integration).
    #[test]
    fn offset_invariance() {
        let mut s = NormalStream::new(5, "allan/offset");
        let y: Vec<f64> = (0..4096).map(|_| s.draw()).collect();
        let shifted: Vec<f64> = y.iter().map(|v| v + 1.0e3).collect();
        for (a, b) in overlapping(&y, 0.1).iter().zip(overlapping(&shifted, 0.1)) {
            assert!((a.adev / b.adev - 1.0).abs() < 1e-9);
        }
    }
}
