//! A rig of several units on one motion: lever arms and mountings exact on the error-free
//! signal, skew-redundant units, and scheduled sensor failures scored by a parity-space
//! residual computed here from the units' outputs.

use std::ops::ControlFlow;

use imu_emu::math::{Mat3, QuatExt, Vec3, quat_from_euler};
use imu_emu::motion::Motion;
use imu_emu::quadrature::GaussLegendre;
use imu_emu::rig::UnitSpec;
use imu_emu::rig::{Rig, SkewLayout, SkewSensor, UnitOutputs, dodecahedron_axes};
use imu_emu::sim::Simulation;

/// What one unit wrote: main output, truth and failures, as text.
struct Written {
    main: String,
    truth: String,
    failures: String,
}

fn write_all(rig: Rig) -> Vec<Written> {
    let n = rig.units().len();
    let mut bufs: Vec<[Vec<u8>; 3]> = (0..n).map(|_| Default::default()).collect();
    {
        let mut outs: Vec<UnitOutputs<'_>> = bufs
            .iter_mut()
            .map(|[m, t, f]| UnitOutputs {
                main: m,
                truth: Some(t),
                failures: Some(f),
            })
            .collect();
        rig.write(&mut outs, |_| ControlFlow::Continue(())).unwrap();
    }
    bufs.into_iter()
        .map(|[m, t, f]| Written {
            main: String::from_utf8(m).unwrap(),
            truth: String::from_utf8(t).unwrap(),
            failures: String::from_utf8(f).unwrap(),
        })
        .collect()
}

/// The rows of a CSV text (header skipped) as numbers.
fn rows(text: &str) -> Vec<Vec<f64>> {
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// A scene file: the 500 m circle at 50 m/s with a 5°, 1 Hz roll oscillation (so ω̇ reaches
/// 5° × (2π·1 Hz)² ≈ 3.4 rad/s² and the lever arm's tangential term is large), 100 Hz.
fn scene(dir: &std::path::Path, extra: &str) -> std::path::PathBuf {
    let p = dir.join("rig.toml");
    let text = format!(
        "[trajectory]\nscene = \"circle\"\n[trajectory.params]\nroll_osc_deg = 5.0\nroll_osc_hz = 1.0\n[output]\nduration_s = 3.0\n{extra}"
    );
    std::fs::write(&p, text).unwrap();
    p
}

/// The closed form of a point at `r` (body frame): interval means of ω̇ × r + ω × (ω × r)
/// − Γ r over (t_{k−1}, t_k], with mean(ω̇) = (ω(t_k) − ω(t_{k−1}))/Δt and ω × (ω × r)
/// averaged by a 16-point Gauss–Legendre rule (the engine uses 3 points, so this is an
/// independent quadrature; both are exact to round-off for the smooth motion over 10 ms).
/// Γ^b = C_n^b Γ^n C_b^n is `generator::gravitation_gradient_b` at the interval's middle;
/// Γ^n is checked against the field's central differences in src/earth.rs.
fn lever_arm_term(m: &impl Motion, t0: f64, dt: f64, k: usize, r: Vec3) -> Vec3 {
    let omega = |t: f64| m.sense(m.piece_at(t, 0), t).omega_ib_b;
    let (lo, hi) = (t0 + (k - 1) as f64 * dt, t0 + k as f64 * dt);
    let alpha = (omega(hi) - omega(lo)) * (1.0 / dt);
    let gl = GaussLegendre::new(16).unwrap();
    let mut c = Vec3::zeros();
    for (x, w) in gl.nodes.iter().zip(&gl.weights) {
        let t = lo + x * dt;
        let o = omega(t);
        c += o.cross(&o.cross(&r)) * *w;
    }
    // The gravitation's gradient at the interval's middle, the engine's rule (its mean
    // differs by at most (ωΔt)²/6·|Γ|: src/generator.rs, with its test).
    c -= imu_emu::generator::gravitation_gradient_b(&m.pose(lo + 0.5 * dt)) * r;
    alpha.cross(&r) + c
}

/// Three ideal units — at the reference point; 1.5 m away; mounted at (10°, 20°, 30°) at
/// the same place — and a skew unit there with six dodecahedral gyros and three
/// accelerometers at their own positions: every error-free reading equals the closed form
/// (reference reading + ω̇ × r + ω × (ω × r), turned into the unit's axes, projected on each
/// sense axis) to round-off (1e-12 of values up to 10 m/s²). A wrong sign of either term,
/// a lever arm in the wrong frame or a skipped mounting misses by more than 1e-4.
#[test]
fn lever_arms_and_mountings_are_exact() {
    let dir = tempfile::TempDir::new().unwrap();
    let path = scene(dir.path(), "");
    let r = [1.5, -0.8, 0.4];
    let mount = [10.0, 20.0, 30.0];
    let mut arm = UnitSpec::imu("arm", "ideal");
    arm.lever_arm_m = r;
    let mut turned = arm.clone();
    turned.name = "turned".into();
    turned.mounting_deg = mount;
    let positions = [[0.05, 0.0, 0.0], [0.0, -0.07, 0.02], [0.0, 0.0, 0.1]];
    let mut layout = SkewLayout {
        gyros: dodecahedron_axes().map(SkewSensor::along).to_vec(),
        accels: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 1.0]]
            .map(SkewSensor::along)
            .to_vec(),
    };
    for (a, p) in layout.accels.iter_mut().zip(positions) {
        a.position_m = Vec3::from(p);
    }
    let mut skew = UnitSpec::skew("skew", layout.clone());
    skew.lever_arm_m = r;
    skew.mounting_deg = mount;
    let rig = Simulation::from_scene_file(&path)
        .unwrap()
        .rate(100.0)
        .unit(UnitSpec::imu("ref", "ideal"))
        .unit(arm)
        .unit(turned)
        .unit(skew)
        .build_rig()
        .unwrap();
    assert_eq!(rig.groups(), vec![vec![0, 1, 2, 3]]);
    let motion = rig.motion().clone();
    let grid = rig.units()[0].grid();
    let dt = 1.0 / grid.rate_hz;
    let out = write_all(rig);
    let [reference, arm, turned, skew] = [0, 1, 2, 3].map(|i| rows(&out[i].main));
    let c_b_c = {
        let [a, b, c] = mount.map(f64::to_radians);
        quat_from_euler(a, b, c).to_mat().transpose()
    };
    assert_eq!(reference.len(), 300);
    let mut worst: f64 = 0.0;
    for k in 1..=reference.len() {
        let v3 = |row: &Vec<f64>, i: usize| Vec3::new(row[i], row[i + 1], row[i + 2]);
        let (w, f) = (v3(&reference[k - 1], 1), v3(&reference[k - 1], 4));
        let f_arm = f + lever_arm_term(&motion, grid.t0, dt, k, Vec3::from(r));
        let diff = |a: Vec3, b: Vec3| (a - b).amax();
        worst = worst
            .max(diff(v3(&arm[k - 1], 1), w))
            .max(diff(v3(&arm[k - 1], 4), f_arm))
            .max(diff(v3(&arm[k - 1], 10), f_arm * dt) / dt)
            .max(diff(v3(&turned[k - 1], 1), c_b_c * w))
            .max(diff(v3(&turned[k - 1], 4), c_b_c * f_arm));
        let s = &skew[k - 1];
        for (i, g) in layout.gyros.iter().enumerate() {
            worst = worst.max((s[1 + i] - g.axis.dot(&(c_b_c * w))).abs());
        }
        for (j, a) in layout.accels.iter().enumerate() {
            let p = Vec3::from(r) + c_b_c.tr_mul(&a.position_m);
            let f_p = f + lever_arm_term(&motion, grid.t0, dt, k, p);
            worst = worst.max((s[7 + j] - a.axis.dot(&(c_b_c * f_p))).abs());
        }
    }
    assert!(
        worst < 1e-12,
        "largest difference from the closed form {worst:e}"
    );
    // The test has teeth: the tangential term (ω̇ up to 3.4 rad/s² about x, moving y and z
    // by up to 3.4 × 0.8 m/s²) and the centripetal one (about ω² r ≈ 0.01 × 1.5 m/s² on x)
    // are far above the tolerance, and so is the gravitation's gradient (γ/R·1.5 ≈ 2.3e-6
    // m/s² on x, (2γ/R)·0.4 ≈ 1.2e-6 on z), checked at its own size by
    // rig_units::a_unit_below_the_reference_reads_the_gravity_there.
    let most = |i: usize| {
        (0..300)
            .map(|k| (arm[k][i] - reference[k][i]).abs())
            .fold(0.0, f64::max)
    };
    assert!(
        most(4) > 0.01 && most(5) > 1.0 && most(6) > 0.5,
        "{} {} {}",
        most(4),
        most(5),
        most(6)
    );
}

/// The projector onto the parity space of sense axes `h` (rows): P = I − H (HᵀH)⁻¹ Hᵀ.
fn parity_projector(h: &[Vec3]) -> Vec<Vec<f64>> {
    let mut hth = Mat3::zeros();
    for u in h {
        for r in 0..3 {
            for c in 0..3 {
                hth[(r, c)] += u[r] * u[c];
            }
        }
    }
    let inv = hth.try_inverse().expect("the axes span space");
    let n = h.len();
    (0..n)
        .map(|i| {
            (0..n)
                .map(|j| (i == j) as u8 as f64 - h[i].dot(&(inv * h[j])))
                .collect()
        })
        .collect()
}

/// Six dodecahedral gyros with white noise σ = 1e-3 rad/s per 100 Hz record, on the banked
/// circle, each failure kind in its own 5 s window. With m the six readings, the parity
/// residual p = P m (P the projector onto the left null space of the axes) sees no motion.
///
/// * Without a failure |p|²/σ² is χ² with tr P = 3 degrees of freedom: its mean over K
///   records is 3 ± 4·√(6/K).
/// * On channel i, the estimate δ̂ = eᵢᵀp / c (c = eᵢᵀPeᵢ = ½ here) is the injected amount δ
///   plus noise eᵢᵀPn/c + β nᵢ, where β nᵢ is noise the failure itself carries (β = −1 for
///   stuck, null, saturation, a dropped record; the jump a for a scale factor); its variance
///   is σ²(1/c + 2β + β²) ≤ σ²(1/c + 3), so its window mean is within 4σ√((1/c + 3)/K) of the
///   mean injected amount (computed here from the truth file and the failures file).
/// * A noise burst of σ_b adds σ_b² to δ̂'s variance σ²/c: the sample variance is within
///   4·√(2/K) of σ²/c + σ_b² (relative).
#[test]
fn parity_residual_finds_each_failure() {
    let dir = tempfile::TempDir::new().unwrap();
    let failures = [
        ("bias-step", "gyro_0", 5.0, "magnitude = 0.01"),
        ("bias-ramp", "gyro_1", 12.0, "magnitude = 0.004"),
        ("scale-factor-jump", "gyro_2", 19.0, "magnitude = 0.2"),
        ("stuck", "gyro_3", 26.0, ""),
        ("null", "gyro_4", 33.0, ""),
        ("saturation", "gyro_5", 40.0, "magnitude = 0.02"),
        ("noise-burst", "random gyro", 47.0, "magnitude = 0.005"),
        ("intermittent", "gyro_2", 54.0, "magnitude = 0.3"),
    ];
    let mut text = String::from("[[imu]]\nname = \"skew\"\nrate_hz = 100.0\n");
    for u in dodecahedron_axes() {
        text += &format!("[[imu.gyro]]\naxis = {u:?}\nnoise = \"1e-4 rad/s/sqrt(Hz)\"\n");
    }
    for (kind, sensor, at, mag) in failures {
        text += &format!(
            "[[imu.failure]]\nkind = \"{kind}\"\nsensor = \"{sensor}\"\nat_s = {at}\nduration_s = 5.0\n{mag}\n"
        );
    }
    let text = text.replace("duration_s = 3.0", "");
    let path = scene(dir.path(), &text);
    let rig = Simulation::from_scene_file(&path)
        .unwrap()
        .duration(60.0)
        .build_rig()
        .unwrap();
    let h: Vec<Vec3> = dodecahedron_axes().map(Vec3::from).to_vec();
    let p = parity_projector(&h);
    let out = write_all(rig).remove(0);
    let (main, truth) = (rows(&out.main), rows(&out.truth));
    assert_eq!((main.len(), truth.len()), (6000, 6000));
    let sigma = 1e-3;
    let residual = |m: &[f64]| -> Vec<f64> {
        (0..6)
            .map(|i| (0..6).map(|j| p[i][j] * m[1 + j]).sum())
            .collect()
    };
    // kind, sensor, then channel, start, end, magnitude.
    let listed: Vec<Vec<f64>> = (out.failures.lines().skip(1))
        .map(|l| l.split(',').skip(2).map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(listed.len(), failures.len());
    // No failure: χ² with 3 degrees of freedom.
    let quiet: Vec<usize> = (0..6000).filter(|&k| truth[k][13] == 0.0).collect();
    let k = quiet.len() as f64;
    let chi2 = quiet
        .iter()
        .map(|&i| residual(&main[i]).iter().map(|x| x * x).sum::<f64>() / (sigma * sigma))
        .sum::<f64>()
        / k;
    assert!(
        (chi2 - 3.0).abs() < 4.0 * (6.0 / k).sqrt(),
        "mean |p|²/σ² = {chi2} over {k}"
    );
    for (n, f) in listed.iter().enumerate() {
        let (ch, start, end, a) = (f[0] as usize, f[1], f[2], f[3]);
        let kind = failures[n].0;
        let c = p[ch][ch];
        let window: Vec<usize> = (0..6000)
            .filter(|&i| main[i][0] >= start - 1e-9 && main[i][0] < end - 1e-9)
            .collect();
        assert_eq!(window.len(), 500, "{kind}");
        for &i in &window {
            assert_eq!(
                truth[i][13],
                (1u64 << ch) as f64,
                "{kind} mask at {}",
                main[i][0]
            );
        }
        let est = |i: usize| residual(&main[i])[ch] / c;
        let held = main[window[0] - 1][1 + ch];
        let truth_of = |i: usize| truth[i][1 + ch];
        let (used, expect): (Vec<usize>, Box<dyn Fn(usize) -> f64>) = match kind {
            "bias-step" => (window.clone(), Box::new(|_| a)),
            "bias-ramp" => (window.clone(), Box::new(|i| a * (main[i][0] - start))),
            "scale-factor-jump" => (window.clone(), Box::new(|i| a * truth_of(i))),
            "stuck" => (window.clone(), Box::new(|i| held - truth_of(i))),
            "null" => (window.clone(), Box::new(|i| -truth_of(i))),
            "saturation" => (
                window.clone(),
                Box::new(|i| a * truth_of(i).signum() - truth_of(i)),
            ),
            "intermittent" => {
                let dropped: Vec<usize> = window
                    .iter()
                    .copied()
                    .filter(|&i| main[i][1 + ch] == 0.0)
                    .collect();
                let (kk, q) = (500.0, a);
                let d = dropped.len() as f64;
                assert!(
                    (d - kk * q).abs() < 4.0 * (kk * q * (1.0 - q)).sqrt(),
                    "{d} dropped"
                );
                (dropped, Box::new(|i| -truth_of(i)))
            }
            "noise-burst" => {
                let k = window.len() as f64;
                let mean = window.iter().map(|&i| est(i)).sum::<f64>() / k;
                let var = window.iter().map(|&i| (est(i) - mean).powi(2)).sum::<f64>() / (k - 1.0);
                let want = sigma * sigma / c + a * a;
                assert!(
                    (var / want - 1.0).abs() < 4.0 * (2.0 / k).sqrt(),
                    "noise burst: variance {var:e}, expected {want:e}"
                );
                continue;
            }
            other => panic!("{other}"),
        };
        let k = used.len() as f64;
        let got = used.iter().map(|&i| est(i)).sum::<f64>() / k;
        let want = used.iter().map(|&i| expect(i)).sum::<f64>() / k;
        let tol = 4.0 * sigma * ((1.0 / c + 3.0) / k).sqrt();
        assert!(
            (got - want).abs() < tol,
            "{kind} on channel {ch}: residual says {got:e}, injected {want:e} (±{tol:e})"
        );
        // And the jump is far above the noise: a detector would see it.
        assert!(want.abs() > 10.0 * tol, "{kind}: {want:e} is not a jump");
    }
}

fn imu_emu(cwd: &std::path::Path, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(cwd)
        .args(args)
        .output()
        .unwrap()
}

/// `generate examples/rig.toml` writes one file per unit (LN-200 frames of 26 bytes at
/// 400 Hz, 100 Hz CSV records, the skew unit's 1 + 2 × 9 columns) and, with `--truth`, each
/// unit's error-free readings and its failure schedule with the random choices made inside
/// their ranges.
#[test]
fn generate_writes_one_output_per_unit() {
    let dir = tempfile::TempDir::new().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/rig.toml");
    let out = imu_emu(
        dir.path(),
        &["generate", scene, "-o", "out", "--truth", "truth"],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let d = dir.path();
    assert_eq!(
        std::fs::metadata(d.join("out/nav.bin")).unwrap().len(),
        8000 * 26
    );
    let tactical = std::fs::read_to_string(d.join("out/tactical.csv")).unwrap();
    assert_eq!(tactical.lines().count(), 1 + 2000);
    let skew = std::fs::read_to_string(d.join("out/skew.csv")).unwrap();
    assert_eq!(skew.lines().count(), 1 + 2000);
    assert!(skew.lines().all(|l| l.split(',').count() == 19));
    let truth = rows(&std::fs::read_to_string(d.join("truth/skew.csv")).unwrap());
    assert_eq!(truth.len(), 2000);
    let failures = std::fs::read_to_string(d.join("truth/skew.failures.csv")).unwrap();
    let lines: Vec<Vec<&str>> = failures
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(lines.len(), 3, "{failures}");
    assert_eq!(lines[0][..4], ["bias-step", "gyro_2", "2", "5"]);
    let stuck = &lines[1];
    let (ch, start): (usize, f64) = (stuck[2].parse().unwrap(), stuck[3].parse().unwrap());
    assert!(
        stuck[0] == "stuck" && ch < 6 && (10.0..=15.0).contains(&start),
        "{stuck:?}"
    );
    assert_eq!(stuck[4].parse::<f64>().unwrap(), start + 4.0);
    // The truth's `failed` column marks the stuck channel from its start on.
    for r in &truth {
        let stuck_on = r[0] >= start && r[0] < start + 4.0;
        let bias_on = (5.0..8.0).contains(&r[0]);
        let burst_on = (12.0..13.0).contains(&r[0]);
        let want = (stuck_on as u64) << ch | (bias_on as u64) << 2 | (burst_on as u64) << 7;
        assert_eq!(r[19] as u64, want, "t = {}", r[0]);
    }
    for name in ["nav", "tactical"] {
        let t = std::fs::read_to_string(d.join(format!("truth/{name}.failures.csv"))).unwrap();
        assert_eq!(t.lines().count(), 1);
    }
}

/// Bad `[[imu]]` entries are refused naming the file and the key (and the line for a wrong
/// key or type), and nothing is written.
#[test]
fn bad_rig_entries_name_the_file_and_key() {
    let dir = tempfile::TempDir::new().unwrap();
    let cases = [
        (
            "[[imu]]\nname = \"a\"\nrate = 100.0\n",
            "rig.toml:5:1",
            "rate",
        ),
        (
            "[[imu]]\nname = \"a\"\n[[imu.gyro]]\naxis = [0.0, 0.0, 0.0]\n",
            "rig.toml",
            "imu[0].gyro[0].axis",
        ),
        (
            "[[imu]]\nname = \"a\"\n[[imu.failure]]\nkind = \"stuck\"\nsensor = \"gyro_7\"\nat_s = 1.0\n",
            "rig.toml",
            "imu[0].failure[0].sensor",
        ),
        (
            "[[imu]]\nname = \"a\"\n[[imu.failure]]\nkind = \"melt\"\nsensor = \"gyro_x\"\nat_s = 1.0\n",
            "rig.toml",
            "imu[0].failure[0].kind",
        ),
        (
            "[[imu]]\nname = \"a\"\n[[imu.failure]]\nkind = \"bias-step\"\nsensor = \"gyro_x\"\nat_s = 1.0\n",
            "rig.toml",
            "imu[0].failure[0].magnitude",
        ),
        (
            "[[imu]]\nname = \"a\"\n[[imu]]\nname = \"a\"\n",
            "rig.toml",
            "imu[1].name",
        ),
        (
            "[[imu]]\nname = \"a\"\nmodel = \"nope\"\n",
            "rig.toml",
            "imu[0].model",
        ),
        (
            "[[imu]]\nname = \"a\"\nrate_hz = -5.0\n",
            "rig.toml",
            "imu[0].rate_hz",
        ),
        (
            "[[imu]]\nname = \"a\"\n[[imu.failure]]\nkind = \"intermittent\"\nsensor = \"accel_y\"\nat_s = 1.0\nmagnitude = 2.0\n",
            "rig.toml",
            "imu[0].failure[0].magnitude",
        ),
    ];
    for (text, place, key) in cases {
        std::fs::write(
            dir.path().join("rig.toml"),
            format!("[output]\nduration_s = 1.0\n{text}"),
        )
        .unwrap();
        let out = imu_emu(
            dir.path(),
            &["generate", "rig.toml", "-o", "out", "--truth", "t"],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{text}");
        assert!(err.contains(place) && err.contains(key), "{text}: {err}");
        assert!(!dir.path().join("out/a.csv").exists() && !dir.path().join("t/a.csv").exists());
    }
}

/// `run` on a rig refuses the flags of one IMU's sinks rather than quietly sending every
/// unit there (tests/rig_run.rs streams rigs).
#[test]
fn single_imu_commands_refuse_a_rig() {
    let dir = tempfile::TempDir::new().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/rig.toml");
    let out = imu_emu(
        dir.path(),
        &["run", scene, "--speed", "max", "--file", "x.bin"],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("--file x.bin: a rig's streams name their unit (nav, tactical, skew)"),
        "{err}"
    );
    assert!(!dir.path().join("x.bin").exists());
}
