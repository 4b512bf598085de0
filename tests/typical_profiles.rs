//! Every typical profile (`NAME:typical`, templates/NAME.toml `[typical]`) against the public
//! recording of a real unit it was read from. The recording's figures are the overlay table
//! `docs/data/NAME-real-adev.csv` (an Allan deviation table as `analyze --reference` and `fit`
//! read it, citing its data set): each test parses its table with the library's parser, and at
//! every τ the table gives, the profile's Allan deviation lies inside the table's stated range
//! (over the unit's axes or runs).
//!
//! Two checks per figure. (1) The exact theoretical ADEV of what the chain generates
//! ([`imu_emu::analysis::theory`]: white noise, flicker bank, random walk, quantization at the
//! recording's rate) lies inside the recorded range — deterministic, so a profile with a wrong
//! figure or unit fails it. (2) The overlapping ADEV of a simulated static record (the chain at
//! the recording's rate, fixed seed) matches that theory within 4σ of the estimator's scatter,
//! and so lies inside the recorded range widened by the same 4σ.
//!
//! Scatter: the simulated series is reduced to means of d samples while it streams (d the
//! greatest common divisor of the table's cluster sizes; its ADEV at cluster m/d uses the
//! phase points of the full series that fall on multiples of d, so it estimates the same
//! σ(τ)); with N reduced points and cluster m the edf of the overlapping estimate is taken as
//! (N/m)(1 − 3m/N), NIST SP 1065 Table 5's random-walk-FM figure — the smallest of the noise
//! types present, so the bound is conservative for white and flicker noise — times the number
//! of axes pooled (axes of one sensor with the same model, σ² averaged). The 1σ of σ̂/σ is
//! 1/√(2·edf) and the bound 4 of those: a correct chain fails one check with probability
//! ≈ 6·10⁻⁵, and the fixed seeds make every run identical.
//!
//! The figures are printed (`cargo test --release --test typical_profiles -- --nocapture`).

mod common;

use std::path::Path;

use common::{BLOCK, errors6, stream, zero};
use imu_emu::analysis::adev_table::{self, AdevTable, TableOptions};
use imu_emu::analysis::{allan, theory};
use imu_emu::errors::{ErrorChain, ImuModel, template};
use imu_emu::units::G0;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// The overlay table of `name`'s real unit, parsed.
fn table(name: &str) -> AdevTable {
    let path = format!(
        "{}/docs/data/{name}-real-adev.csv",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap();
    adev_table::parse(&text, Path::new(&path), TableOptions::default()).unwrap()
}

/// The six error axes of a static record of `n` samples, as means of `d` samples.
fn simulate(m: &ImuModel, rate: f64, seed: u64, n: usize, d: usize) -> [Vec<f64>; 6] {
    let mut chain = ErrorChain::new(m, rate, seed);
    let mut out: [Vec<f64>; 6] = std::array::from_fn(|_| Vec::with_capacity(n / d + 1));
    let mut acc = [0.0; 6];
    stream(&mut chain, rate, n, BLOCK, zero, |k0, block| {
        for (j, r) in block.iter().enumerate() {
            acc.iter_mut()
                .zip(errors6(r, &zero(k0 + j, rate)))
                .for_each(|(a, v)| *a += v);
            if (k0 + j + 1) % d == 0 {
                for (o, a) in out.iter_mut().zip(acc.iter_mut()) {
                    o.push(*a / d as f64);
                    *a = 0.0;
                }
            }
        }
    });
    out
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// `name:typical` simulated for `seconds` at its table's rate against every figure of the table.
fn check(name: &str, seconds: f64, seed: u64) {
    let t = table(name);
    let m = template::load(&format!("{name}:typical")).unwrap();
    let dt = t.dt;
    let n = (seconds / dt).round() as usize;
    let d = t.channels.iter().flatten().fold(0, |g, p| gcd(g, p.m));
    let series = simulate(&m, 1.0 / dt, seed, n, d);
    let nr = series[0].len() as f64;
    let theories = [
        theory::triad(&m.gyro, m.quantization_mode, dt),
        theory::triad(&m.accel, m.quantization_mode, dt),
    ];
    let mut checked = 0;
    for (s, th) in theories.iter().enumerate() {
        let (sensor, unit, k) = if s == 0 {
            ("gyro", "deg/h", 3600.0 / DEG)
        } else {
            ("accel", "µg", 1e6 / G0)
        };
        // Axes with the same model and the same figures are pooled.
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for i in 0..3 {
            let same = |g: &Vec<usize>| {
                th[g[0]] == th[i] && t.channels[3 * s + g[0]] == t.channels[3 * s + i]
            };
            match groups.iter_mut().find(|g| same(g)) {
                Some(g) => g.push(i),
                None => groups.push(vec![i]),
            }
        }
        for axes in &groups {
            for p in &t.channels[3 * s + axes[0]] {
                let (lo, hi) = p.range.expect("the table states a range");
                let (lo, hi) = (lo * k, hi * k);
                let mr = p.m / d;
                let tau = p.m as f64 * dt;
                let pooled = |f: &dyn Fn(usize) -> f64| {
                    axes.iter().map(|&i| f(i)).sum::<f64>() / axes.len() as f64
                };
                let sim = pooled(&|i| {
                    allan::overlapping_at(&series[3 * s + i], dt * d as f64, &[mr])[0]
                        .adev
                        .powi(2)
                })
                .sqrt()
                    * k;
                let exact = pooled(&|i| th[i].avar(p.m, dt)).sqrt() * k;
                let mf = mr as f64;
                let edf = (nr / mf) * (1.0 - 3.0 * mf / nr) * axes.len() as f64;
                let tol = 4.0 / (2.0 * edf).sqrt();
                let what = format!("{name}:typical {sensor} axes {axes:?} τ = {tau} s");
                eprintln!(
                    "{what}: recorded [{lo:.5}, {hi:.5}] {unit}, theory {exact:.5}, \
                     simulated {sim:.5} (±{:.1} %)",
                    100.0 * tol
                );
                assert!(
                    (lo..=hi).contains(&exact),
                    "{what}: theory {exact} outside the recorded [{lo}, {hi}]"
                );
                assert!(
                    (sim / exact - 1.0).abs() <= tol,
                    "{what}: simulated {sim} vs theory {exact} (±{tol})"
                );
                assert!(
                    sim >= lo * (1.0 - tol) && sim <= hi * (1.0 + tol),
                    "{what}: simulated {sim} outside the recorded [{lo}, {hi}] ± {tol}"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 0, "{name}: the table has no figure");
}

/// LN-200 gyros, SMAC-Group avar `ln200_av` (6 h at 400 Hz): ARW 0.038–0.041 deg/√h,
/// σ(655 s) 0.09–0.105 deg/h, still falling at 1311 s: 0.055–0.075 deg/h. Simulated 24 h: 4σ
/// is 0.7 % at 1.28 s, 20 % at 1311 s.
#[test]
fn ln200() {
    check("ln200", 86400.0, 1);
}

/// iMAR FSAS-class gyros, SMAC-Group avar `imar_av` (4 h at 400 Hz): ARW 0.090–0.114 deg/√h,
/// σ(T/10 = 1440 s) 0.16–0.21 deg/h (still falling). Simulated 24 h.
#[test]
fn fsas() {
    check("fsas", 86400.0, 2);
}

/// KVH 1750, SMAC-Group avar `kvh1750_av` (10⁶ samples, τ labelled for 1 kHz): white
/// densities 0.0031 deg/√h and 24 µg/√Hz (ranges: the rounding of the published figure),
/// Allan minima 0.039–0.064 deg/h and 33–43 µg, at T/10 = 100 s. Simulated 10⁷ samples.
#[test]
fn kvh1750() {
    check("kvh1750", 10000.0, 3);
}

/// ADIS16405, SMAC-Group imudata (six runs of 2.8 h at 100 Hz): ARW 2.29–2.79 deg/√h, Allan
/// minimum 19–34 deg/h at τ 45–960 s; VRW 0.20–0.30 m/s/√h, minimum 200–345 µg at τ 6–21 s.
/// Simulated 28 h.
#[test]
fn adis16405() {
    check("adis16405", 100800.0, 4);
}

/// MPU-6050, sunsided/sensor-fusion set-2 (655 s at 99 Hz): ARW 0.55–0.77 deg/√h, VRW
/// 0.18–0.29 m/s/√h; at T/10 = 65 s, still falling: gyro 4–10 deg/h, accel 39–71 µg.
/// Simulated 6.5 h.
#[test]
fn mpu6000() {
    check("mpu6000", 23400.0, 5);
}

/// ADIS16448, gaowenliang/imu_utils (≈ 2 h at 200 Hz): ARW 0.61–0.62 deg/√h, minimum
/// 15–17.5 deg/h at τ 15–28 s (x without, y and z with rate random walk); VRW 0.10–0.12
/// m/s/√h, minimum 89–170 µg (at T/10 = 720 s here). Simulated 20 h.
#[test]
fn adis16448() {
    check("adis16448", 72000.0, 6);
}

/// BMI160, gaowenliang/imu_utils (≈ 3.3 h at 200 Hz): ARW 0.27–0.32 deg/√h, minimum 4.2–8.5
/// deg/h at τ 40–80 s (x, z with rate random walk, y without); VRW 0.077–0.095 m/s/√h,
/// minimum 38–53 µg (at T/10 = 1200 s here). Simulated 33 h.
#[test]
fn bmi160() {
    check("bmi160", 118800.0, 7);
}

/// Intersense NavChip, SMAC-Group avar `navchip_av` (3.45 h at 250 Hz): gyro σ(1 s)
/// 0.22–0.25 deg/√h, minimum 11.4–11.9 deg/h at τ 4–16 s; VRW 0.028–0.031 m/s/√h, minimum
/// 25–49 µg at τ ≈ 33 s. Simulated 20 h.
#[test]
fn navchip() {
    check("navchip", 72000.0, 8);
}

/// The typical profile of a template with its own datasheet figures differs from them only in
/// the keys of its `[typical]` table; `:datasheet` is the default; a template without a
/// typical profile says so, naming the file and the key; a bad key inside `[typical]` is
/// reported with its full path.
#[test]
fn profiles_select_and_report() {
    let ds = template::load("ln200").unwrap();
    assert_eq!(template::load("ln200:datasheet").unwrap(), ds);
    let ty = template::load("ln200:typical").unwrap();
    assert_eq!(ty.name, "ln200:typical");
    assert!((ty.gyro.noise[0] - 0.0395 * DEG / 60.0).abs() < 1e-18);
    assert!((ds.gyro.noise[0] - 0.07 * DEG / 60.0).abs() < 1e-18);
    assert_eq!(ty.accel, ds.accel);
    assert_eq!(ty.gyro.bias_turn_on, ds.gyro.bias_turn_on);
    // The datasheet's ARW is outside the recorded range: the profile is what makes the check pass.
    let dt = 1.0 / 400.0;
    let th = theory::triad(&ds.gyro, ds.quantization_mode, dt);
    let arw = th[0].avar(400, dt).sqrt() / DEG * 60.0;
    assert!(arw > 0.041 * 1.5, "datasheet ARW {arw}");
    for name in [
        "ln200",
        "fsas",
        "kvh1750",
        "adis16405",
        "mpu6000",
        "adis16448",
        "bmi160",
        "navchip",
    ] {
        assert!(template::typical_names().contains(&name), "{name}");
    }
    let e = template::load("stim300:typical").unwrap_err().to_string();
    assert!(
        e.contains("templates/stim300.toml") && e.contains("`typical`"),
        "{e}"
    );
    let path = std::path::Path::new("u.toml");
    let e = template::parse_profile(
        "[typical.gyro]\nnoise = \"-1 deg/sqrt(h)\"\n",
        path,
        template::Profile::Datasheet,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("u.toml: `typical.gyro.noise`") && e.contains("negative"),
        "{e}"
    );
    let e = template::parse_profile("[typical]\nrate_hz = 5\n", path, template::Profile::Typical)
        .unwrap_err()
        .to_string();
    assert!(e.contains("`typical.rate_hz`"), "{e}");
    let based = template::parse_profile(
        "base = \"ln200:typical\"\nname = \"mine\"\n",
        path,
        template::Profile::Datasheet,
    )
    .unwrap();
    assert_eq!(based.gyro, ty.gyro);
}
