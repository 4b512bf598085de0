//! `imu-emu navigate --gnss FILE`: the records of a tactical IMU (hg1700: 1 °/h, 1 mg biases)
//! on the circle scene, navigated with the fixes of `generate --gnss-truth` (5 Hz, white
//! errors of σ = 0.5 m and 0.05 m/s per axis, a 60 s outage from the scene file): the error
//! stays within the fixes' scatter while they arrive, grows through the outage, comes back
//! after it, and is far below the free-inertial error the summary reports next to it.

use std::path::Path;
use std::process::{Command, Output};

fn imu_emu(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run imu-emu")
}

fn ok(out: Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

const SCENE: &str = "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 300.0\n\
[gnss]\nrate_hz = 5\nlever_arm_m = [0.5, 0.2, -1.0]\npos_white_m = [0.5, 0.5, 0.5]\n\
pos_gm_m = [0.0, 0.0, 0.0]\nvel_white_m_s = [0.05, 0.05, 0.05]\noutages_s = [[150.0, 210.0]]\n";

const SIGMA_POS: f64 = 0.5;

/// Rows of a CSV with a header, as numbers (non-numeric fields as NaN).
fn rows(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let head = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .map(|x| x.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    (head, rows)
}

#[test]
fn gnss_aided_error_is_bounded_grows_in_the_outage_and_recovers() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SCENE).unwrap();
    ok(imu_emu(
        d,
        &[
            "generate",
            "s.toml",
            "--imu",
            "hg1700",
            "--rate",
            "100",
            "--seed",
            "3",
            "-o",
            "r.bin",
            "--format",
            "bin",
            "--gnss-truth",
            "g.csv",
        ],
    ));
    let summary = ok(imu_emu(
        d,
        &[
            "navigate",
            "r.bin",
            "--scene-file",
            "s.toml",
            "--gnss",
            "g.csv",
            "--gnss-sigma",
            "0.5,0.05",
            "--gnss-lever-arm",
            "0.5,0.2,-1.0",
            "--errors",
            "e.csv",
        ],
    ));
    // The outage, as the GNSS file has it: its first and last epochs without a fix.
    let (head, epochs) = rows(&d.join("g.csv"));
    let fix = head.iter().position(|h| h == "fix").unwrap();
    let text = std::fs::read_to_string(d.join("g.csv")).unwrap();
    let none: Vec<f64> = text
        .lines()
        .skip(1)
        .zip(&epochs)
        .filter(|(l, _)| l.split(',').nth(fix) == Some("none"))
        .map(|(_, r)| r[1])
        .collect();
    let (out0, out1) = (none[0], none[none.len() - 1] + 0.2);
    assert_eq!((out0, none.len()), (150.0, 300));
    let fixes = epochs.len() - none.len();
    assert!(
        summary.contains(&format!("GNSS-aided with {fixes} fixes")),
        "{summary}"
    );

    let (_, errs) = rows(&d.join("e.csv"));
    let (mut worst_settled, mut at_outage_end, mut before_outage) = (0.0f64, 0.0, 0.0f64);
    for r in &errs {
        let t = r[0];
        // Kalman posterior of a measured state: P⁺ = (P⁻⁻¹ + R⁻¹)⁻¹ ≤ R, so each axis errs
        // with σ ≤ the fix's σ (and between fixes, 0.2 s of coasting adds millimetres);
        // |x| > 5σ has probability 5.7e-7, over 25 000 records × 3 axes (strongly correlated
        // within a fix interval: ~1100 independent fixes) a false failure has odds < 2e-3.
        // From 20 s (initial convergence) on, outside the outage and the 30 s after it.
        if t >= 20.0 && !(out0..out1 + 30.0).contains(&t) {
            for x in &r[1..4] {
                worst_settled = worst_settled.max(x.abs() / SIGMA_POS);
            }
            if t < out0 {
                before_outage = before_outage.max(r[1].hypot(r[2]));
            }
        }
        if (t - (out1 - 0.01)).abs() < 1e-6 {
            at_outage_end = r[1].hypot(r[2]);
        }
    }
    assert!(worst_settled < 5.0, "aided error reached {worst_settled} σ");
    // Without fixes the residual heading, attitude and bias errors drive the error away:
    // after 60 s it is beyond the band (5σ = 2.5 m) the fixes held it in, and beyond every
    // error before the outage.
    assert!(
        at_outage_end > 5.0 * SIGMA_POS && at_outage_end > 3.0 * before_outage,
        "horizontal error {at_outage_end} m at the outage end, {before_outage} m before"
    );
    // The free-inertial error of the same records after 300 s is two orders above the aided
    // final error, and well above 60 s of coasting from an aligned, bias-corrected state.
    let free: f64 = summary
        .split("free-inertial: final position error ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{summary}"));
    let last = errs.last().unwrap()[10];
    assert!(
        free > 100.0 * last && free > 5.0 * at_outage_end,
        "free {free} m, aided final {last} m"
    );
    eprintln!(
        "worst aided {worst_settled} σ; outage end {at_outage_end} m (before {before_outage} m); free {free} m"
    );
}

/// Bad `--gnss` input fails naming the file, line and column, or the flag; nothing written.
#[test]
fn bad_gnss_input_fails_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(imu_emu(
        d,
        &[
            "generate",
            "--scene",
            "circle",
            "--duration",
            "2",
            "-o",
            "r.csv",
        ],
    ));
    std::fs::write(
        d.join("g.csv"),
        "t,fix,meas_lat,meas_lon,meas_h,meas_vn,meas_ve,meas_vd\n1,autonomous,0,0,nan,0,0,0\n",
    )
    .unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec![
            "navigate", "r.csv", "--scene", "circle", "--errors", "e.csv",
        ];
        args.extend_from_slice(extra);
        let out = imu_emu(d, &args);
        assert!(!out.status.success());
        assert!(!d.join("e.csv").exists());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let e = run(&["--gnss", "g.csv"]);
    assert!(e.contains("g.csv:2: column 5 (`meas_h`)"), "{e}");
    let e = run(&["--gnss", "g.csv", "--gnss-sigma", "1"]);
    assert!(e.contains("--gnss-sigma `1`: expected 2"), "{e}");
    let e = run(&["--gnss", "g.csv", "--gnss-sigma", "0,1"]);
    assert!(e.contains("must be positive"), "{e}");
    let e = run(&["--gnss", "g.csv", "--gnss-lever-arm", "1,x,0"]);
    assert!(e.contains("--gnss-lever-arm `1,x,0`"), "{e}");
    let e = run(&["--gnss", "missing.csv"]);
    assert!(e.contains("missing.csv"), "{e}");
}
