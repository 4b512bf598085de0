//! The time-domain ramp test of `imu-emu fit` (src/fit/ramp.rs) on records without a ramp:
//! its z-statistics have unit variance (σ(b̂) is right) and the gate keeps no more spurious
//! ramps than its 99.9 % level allows.

use std::path::Path;

use imu_emu::errors::template;
use imu_emu::fit::closure;
use imu_emu::fit::compare::fit_all;
use imu_emu::fit::gmwm::Component;
use imu_emu::fit::ramp::slope_variance;

/// White noise and a random walk crossing at τ = 20 s (N²/τ = K²τ/3 there), the case where
/// the Allan-variance χ² gate kept 5 spurious ramps in 120 channel fits (docs/fit.md).
const WALK: &str = r#"
name = "walk"
rate_hz = 20
[gyro]
noise = "0.15 deg/sqrt(h)"
random_walk = "47 deg/h/sqrt(h)"
[accel]
noise = "0.07 m/s/sqrt(h)"
random_walk = "10.3 ug/sqrt(s)"
"#;

/// 2^15 samples at 20 Hz (T = 1638 s), seeds 1000–1019: 120 channel fits.
///
/// * Spurious ramps: the gate is two-sided 99.9 %, so the count is binomial(120, 0.001),
///   mean 0.12 and σ 0.35; 4σ above the mean is 1.5: at most one.
/// * Unit variance: under the null z = b̂/σ(b̂) is standard normal when σ(b̂) is right, so
///   s² = Σz²/120 (mean known to be 0) has mean 1 and standard deviation √(2/120) = 0.13;
///   4σ: s² within [0.48, 1.52]. The fitted K scatters by a few per cent across these octaves
///   (edf in the hundreds), which widens z's spread far less than that.
/// * The check can fail: with the random walk's term left out of σ(b̂) (white noise alone,
///   whose slope variance is ~100× smaller here) s² is far above the band.
#[test]
fn no_spurious_ramps_and_unit_variance_z() {
    let m = template::parse(WALK, Path::new("walk.toml")).unwrap();
    let (dt, samples) = (0.05, 1u64 << 15);
    let (mut kept, mut z2, mut z2_no_k, mut count) = (Vec::new(), 0.0, 0.0, 0);
    for seed in 1000..1020 {
        let rec = closure::simulate(m.clone(), dt, samples, seed, 1 << 12).unwrap();
        for (ch, f) in fit_all(&rec).iter().enumerate() {
            let f = f.as_ref().unwrap();
            let t = f.ramp.unwrap();
            if t.kept {
                kept.push(format!("seed {seed} channel {ch}: {t:?}\n{:?}", f.model));
            }
            z2 += t.z * t.z;
            let mut no_k = f.model.clone();
            no_k.c[Component::RandomWalk as usize] = 0.0;
            no_k.c[Component::Ramp as usize] = 0.0;
            z2_no_k += t.slope.powi(2) / slope_variance(&no_k, samples as usize);
            count += 1;
        }
    }
    assert_eq!(count, 120);
    let s2 = z2 / count as f64;
    assert!(kept.len() <= 1, "{}", kept.join("\n"));
    assert!((0.48..=1.52).contains(&s2), "s² = {s2}");
    let s2_no_k = z2_no_k / count as f64;
    assert!(s2_no_k > 1.52, "without K: s² = {s2_no_k}");
    eprintln!("s² = {s2:.3}, without K {s2_no_k:.1}, kept {}", kept.len());
}
