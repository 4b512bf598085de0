//! Every typical profile (`NAME:typical`, templates/NAME.toml `[typical]`) against the public
//! recording of a real unit it was read from: at each τ the recording gives a figure for, the
//! profile's Allan deviation lies inside the recorded range (over the unit's axes or runs).
//!
//! Two checks per figure. (1) The exact theoretical ADEV of what the chain generates
//! ([`imu_emu::analysis::theory`]: white noise, flicker bank, random walk, quantization at the
//! recording's rate) lies inside the recorded range — deterministic, so a profile with a wrong
//! figure or unit fails it. (2) The overlapping ADEV of a simulated static record (the chain at
//! the recording's rate, fixed seed) matches that theory within 4σ of the estimator's scatter,
//! and so lies inside the recorded range widened by the same 4σ.
//!
//! Scatter: the simulated series is reduced to means of d samples while it streams (its ADEV at
//! cluster m/d uses the phase points of the full series that fall on multiples of d, so it
//! estimates the same σ(τ)); with N reduced points and cluster m the edf of the overlapping
//! estimate is taken as (N/m)(1 − 3m/N), NIST SP 1065 Table 5's random-walk-FM figure — the
//! smallest of the noise types present, so the bound is conservative for white and flicker
//! noise — times the number of axes pooled (axes with the same figures, σ² averaged). The 1σ
//! of σ̂/σ is 1/√(2·edf) and the bound 4 of those: a correct chain fails one check with
//! probability ≈ 6·10⁻⁵, and the fixed seeds make every run identical.
//!
//! The figures are printed (`cargo test --release --test typical_profiles -- --nocapture`).

mod common;

use common::{BLOCK, errors6, stream, zero};
use imu_emu::analysis::{allan, theory};
use imu_emu::errors::{ErrorChain, ImuModel, template};
use imu_emu::units::G0;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// One recorded figure: the ADEV of some axes of one sensor at τ, as a level (deg/h or µg)
/// or as a white-noise density σ·√τ (deg/√h or m/s/√h), inside [lo, hi].
struct Figure {
    gyro: bool,
    axes: &'static [usize],
    tau: f64,
    density: bool,
    lo: f64,
    hi: f64,
}

const XYZ: &[usize] = &[0, 1, 2];

fn level(gyro: bool, axes: &'static [usize], tau: f64, lo: f64, hi: f64) -> Figure {
    Figure {
        gyro,
        axes,
        tau,
        density: false,
        lo,
        hi,
    }
}

fn density(gyro: bool, tau: f64, lo: f64, hi: f64) -> Figure {
    Figure {
        gyro,
        axes: XYZ,
        tau,
        density: true,
        lo,
        hi,
    }
}

/// A profile, the recording's rate, and how long to simulate.
struct Case {
    name: &'static str,
    rate: f64,
    seconds: f64,
    figures: Vec<Figure>,
}

/// σ in SI at τ → the figure's unit.
fn to_unit(f: &Figure, sigma: f64, tau: f64) -> f64 {
    match (f.gyro, f.density) {
        (true, false) => sigma / DEG * 3600.0,
        (true, true) => sigma * tau.sqrt() / DEG * 60.0,
        (false, false) => sigma / G0 * 1e6,
        (false, true) => sigma * tau.sqrt() * 60.0,
    }
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

fn check(case: &Case, seed: u64) {
    let m = template::load(&format!("{}:typical", case.name)).unwrap();
    let dt = 1.0 / case.rate;
    let n = (case.seconds * case.rate) as usize;
    let d = case
        .figures
        .iter()
        .map(|f| ((f.tau / dt).round() as usize).max(1))
        .min()
        .unwrap();
    let series = simulate(&m, case.rate, seed, n, d);
    let nr = series[0].len();
    let gyro = theory::triad(&m.gyro, m.quantization_mode, dt);
    let accel = theory::triad(&m.accel, m.quantization_mode, dt);
    for f in &case.figures {
        let mr = ((f.tau / dt / d as f64).round() as usize).max(1);
        let tau = (mr * d) as f64 * dt;
        let off = if f.gyro { 0 } else { 3 };
        let th = if f.gyro { &gyro } else { &accel };
        let avar_sim = f
            .axes
            .iter()
            .map(|&i| {
                allan::overlapping_at(&series[off + i], dt * d as f64, &[mr])[0]
                    .adev
                    .powi(2)
            })
            .sum::<f64>()
            / f.axes.len() as f64;
        let avar_th =
            f.axes.iter().map(|&i| th[i].avar(mr * d, dt)).sum::<f64>() / f.axes.len() as f64;
        let (sim, exact) = (
            to_unit(f, avar_sim.sqrt(), tau),
            to_unit(f, avar_th.sqrt(), tau),
        );
        let (nf, mf) = (nr as f64, mr as f64);
        let edf = (nf / mf) * (1.0 - 3.0 * mf / nf) * f.axes.len() as f64;
        let tol = 4.0 / (2.0 * edf).sqrt();
        let what = format!(
            "{}:typical {} axes {:?} τ = {tau:.3} s {}",
            case.name,
            if f.gyro { "gyro" } else { "accel" },
            f.axes,
            if f.density { "density" } else { "level" }
        );
        eprintln!(
            "{what}: recorded [{}, {}], theory {exact:.5}, simulated {sim:.5} (±{:.1} %)",
            f.lo,
            f.hi,
            100.0 * tol
        );
        assert!(
            (f.lo..=f.hi).contains(&exact),
            "{what}: theory {exact} outside the recorded [{}, {}]",
            f.lo,
            f.hi
        );
        assert!(
            (sim / exact - 1.0).abs() <= tol,
            "{what}: simulated {sim} vs theory {exact} (±{tol})"
        );
        assert!(
            sim >= f.lo * (1.0 - tol) && sim <= f.hi * (1.0 + tol),
            "{what}: simulated {sim} outside the recorded [{}, {}] ± {tol}",
            f.lo,
            f.hi
        );
    }
}

/// LN-200 gyros, SMAC-Group avar `ln200_av` (6 h at 400 Hz): ARW 0.038–0.041 deg/√h,
/// σ(655 s) 0.09–0.105 deg/h, still falling at 1300 s below 0.055–0.075 deg/h (an upper
/// bound: checked against the top of it). Simulated 24 h: 4σ is 0.6 % at 1 s, 20 % at 1300 s.
#[test]
fn ln200() {
    check(
        &Case {
            name: "ln200",
            rate: 400.0,
            seconds: 86400.0,
            figures: vec![
                density(true, 1.0, 0.038, 0.041),
                level(true, XYZ, 655.0, 0.09, 0.105),
                level(true, XYZ, 1300.0, 0.0, 0.075),
            ],
        },
        1,
    );
}

/// iMAR FSAS-class gyros, SMAC-Group avar `imar_av` (4 h at 400 Hz): ARW 0.090–0.114 deg/√h,
/// σ(T/10 = 1440 s) 0.16–0.21 deg/h (still falling). Simulated 24 h.
#[test]
fn fsas() {
    check(
        &Case {
            name: "fsas",
            rate: 400.0,
            seconds: 86400.0,
            figures: vec![
                density(true, 1.0, 0.090, 0.114),
                level(true, XYZ, 1440.0, 0.16, 0.21),
            ],
        },
        2,
    );
}

/// KVH 1750, SMAC-Group avar `kvh1750_av` (10⁶ samples, τ labelled for 1 kHz): white
/// densities 0.0031 deg/√h and 24 µg/√Hz (= 0.0141 m/s/√h; ranges: the rounding of the
/// published figure), Allan minima 0.039–0.064 deg/h and 33–43 µg, at T/10 = 100 s. Simulated
/// 10⁷ samples.
#[test]
fn kvh1750() {
    let vrw = |ug: f64| ug * 1e-6 * G0 * 60.0;
    check(
        &Case {
            name: "kvh1750",
            rate: 1000.0,
            seconds: 10000.0,
            figures: vec![
                density(true, 0.01, 0.00305, 0.00315),
                level(true, XYZ, 100.0, 0.039, 0.064),
                density(false, 0.01, vrw(23.5), vrw(24.5)),
                level(false, XYZ, 100.0, 33.0, 43.0),
            ],
        },
        3,
    );
}

/// ADIS16405, SMAC-Group imudata (six runs of 2.8 h at 100 Hz): ARW 2.29–2.79 deg/√h, Allan
/// minimum 19–34 deg/h at τ 45–960 s; VRW 0.20–0.30 m/s/√h, minimum 200–345 µg at τ 6–21 s.
/// Simulated 28 h.
#[test]
fn adis16405() {
    check(
        &Case {
            name: "adis16405",
            rate: 100.0,
            seconds: 100800.0,
            figures: vec![
                density(true, 1.0, 2.29, 2.79),
                level(true, XYZ, 60.0, 19.0, 34.0),
                level(true, XYZ, 240.0, 19.0, 34.0),
                level(true, XYZ, 960.0, 19.0, 34.0),
                density(false, 0.1, 0.20, 0.30),
                level(false, XYZ, 6.0, 200.0, 345.0),
                level(false, XYZ, 12.0, 200.0, 345.0),
                level(false, XYZ, 21.0, 200.0, 345.0),
            ],
        },
        4,
    );
}

/// MPU-6050, sunsided/sensor-fusion set-2 (655 s at 99 Hz; simulated at 100 Hz): ARW
/// 0.55–0.77 deg/√h, VRW 0.18–0.29 m/s/√h; at T/10 = 65 s, still falling: gyro 4–10 deg/h,
/// accel 39–71 µg. Simulated 6.5 h.
#[test]
fn mpu6000() {
    check(
        &Case {
            name: "mpu6000",
            rate: 100.0,
            seconds: 23400.0,
            figures: vec![
                density(true, 1.0, 0.55, 0.77),
                level(true, &[0, 2], 65.0, 4.0, 10.0),
                level(true, &[1], 65.0, 4.0, 10.0),
                density(false, 1.0, 0.18, 0.29),
                level(false, XYZ, 65.0, 39.0, 71.0),
            ],
        },
        5,
    );
}

/// ADIS16448, gaowenliang/imu_utils (≈ 2 h at 200 Hz): ARW 0.61–0.62 deg/√h, minimum
/// 15–17.5 deg/h at τ 15–28 s (x without, y and z with rate random walk); VRW 0.10–0.12
/// m/s/√h, minimum 89–170 µg (at T/10 = 720 s here). Simulated 20 h.
#[test]
fn adis16448() {
    let mut figures = vec![density(true, 0.1, 0.61, 0.62)];
    for axes in [&[0usize][..], &[1, 2]] {
        for tau in [15.0, 20.0, 28.0] {
            figures.push(level(true, axes, tau, 15.0, 17.5));
        }
    }
    figures.push(density(false, 0.1, 0.10, 0.12));
    figures.push(level(false, XYZ, 720.0, 89.0, 170.0));
    check(
        &Case {
            name: "adis16448",
            rate: 200.0,
            seconds: 72000.0,
            figures,
        },
        6,
    );
}

/// BMI160, gaowenliang/imu_utils (≈ 3.3 h at 200 Hz): ARW 0.27–0.32 deg/√h, minimum 4.2–8.5
/// deg/h at τ 40–80 s (x, z with rate random walk, y without); VRW 0.077–0.095 m/s/√h,
/// minimum 38–53 µg (at T/10 = 1200 s here). Simulated 33 h.
#[test]
fn bmi160() {
    let mut figures = vec![density(true, 0.1, 0.27, 0.32)];
    for axes in [&[0usize, 2][..], &[1]] {
        for tau in [40.0, 80.0] {
            figures.push(level(true, axes, tau, 4.2, 8.5));
        }
    }
    figures.push(density(false, 0.1, 0.077, 0.095));
    figures.push(level(false, XYZ, 1200.0, 38.0, 53.0));
    check(
        &Case {
            name: "bmi160",
            rate: 200.0,
            seconds: 118800.0,
            figures,
        },
        7,
    );
}

/// Intersense NavChip, SMAC-Group avar `navchip_av` (3.45 h at 250 Hz): gyro σ(1 s) at most
/// 0.22–0.25 deg/√h (checked against the top), minimum 11.4–11.9 deg/h at τ 4–16 s; VRW
/// 0.028–0.031 m/s/√h, minimum 25–49 µg at τ ≈ 33 s. Simulated 20 h.
#[test]
fn navchip() {
    check(
        &Case {
            name: "navchip",
            rate: 250.0,
            seconds: 72000.0,
            figures: vec![
                density(true, 1.0, 0.0, 0.25),
                level(true, XYZ, 4.0, 11.4, 11.9),
                level(true, XYZ, 8.0, 11.4, 11.9),
                level(true, XYZ, 16.0, 11.4, 11.9),
                density(false, 0.1, 0.028, 0.031),
                level(false, XYZ, 33.0, 25.0, 49.0),
            ],
        },
        8,
    );
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
