//! `imu-emu validate` end to end: it passes on `ideal` and on the LN-200 template, and the
//! report can fail — a generator told to scale white noise by σ·√Δt instead of σ/√Δt is caught.

use std::path::Path;
use std::process::{Command, Output};

fn validate(out: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .arg("validate")
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .expect("run imu-emu validate")
}

fn report(out: &Path) -> String {
    std::fs::read_to_string(out.join("report.md")).expect("report.md written")
}

#[test]
fn ideal_passes_and_adds_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let o = validate(dir.path(), &["--imu", "ideal"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let r = report(dir.path());
    assert!(r.contains("**PASS**"), "{r}");
    assert!(r.contains("error chain empty — pass"), "{r}");
    // The error-free half: static grid, five dynamic scenes, six closures.
    assert!(r.contains("| survey | definition"), "{r}");
    assert!(r.contains("| polar | 48000 |"), "{r}");
}

#[test]
fn ln200_passes_with_plots() {
    let dir = tempfile::tempdir().unwrap();
    let o = validate(dir.path(), &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let r = report(dir.path());
    assert!(r.contains("**PASS**") && !r.contains("FAIL"), "{r}");
    // Both rates, every specified LN-200 term judged (Q and N, 6 channels, 2 rates).
    assert_eq!(r.matches("| pass |").count() - 27, 24, "{r}");
    for f in ["adev-psd-100hz.png", "adev-psd-1000hz.png"] {
        let png = std::fs::read(dir.path().join(f)).unwrap();
        assert!(
            png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 20_000,
            "{f}"
        );
        assert!(r.contains(&format!("]({f})")), "{f} not linked");
    }
}

#[test]
fn wrong_noise_scaling_fails() {
    let dir = tempfile::tempdir().unwrap();
    let o = validate(dir.path(), &["--sabotage", "noise-scaling"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("validation failed"), "{err}");
    let r = report(dir.path());
    assert!(r.contains("**FAIL**"), "{r}");
    // Every white-noise row at 100 Hz is off by the factor Δt = 1/100. (At 1 kHz the LN-200
    // accelerometer noise is below its LSB, so its N band is wide and not every row fails.)
    let at_100 = &r[r.find("### 100 Hz").unwrap()..r.find("### 1000 Hz").unwrap()];
    assert_eq!(
        at_100
            .lines()
            .filter(|l| l.contains("random walk (ARW/VRW)") && l.contains("**FAIL**"))
            .count(),
        6,
        "{r}"
    );
}
