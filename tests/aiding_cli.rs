//! `imu-emu generate --gnss FORMAT:FILE --gnss-truth FILE` and the scene file's `[gnss]`:
//! the streams are written from the same motion and seed as the IMU records, are reproducible,
//! and bad settings fail naming the file, line or key, leaving no file behind.

use std::path::Path;
use std::process::{Command, Output};

fn imu_emu(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run imu-emu")
}

fn ok(out: Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn failed(out: Output) -> String {
    assert!(!out.status.success());
    String::from_utf8_lossy(&out.stderr).into_owned()
}

const SCENE: &str = "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 4.0\n\
[gnss]\nrate_hz = 10\nlever_arm_m = [1.0, 0.0, -0.5]\noutages_s = [[1.0, 2.0]]\n";

/// 4 s at 10 Hz: 41 epochs (both ends), 10 of them in the outage; three formats and the
/// truth from one command; the same command again writes the same bytes.
#[test]
fn generate_writes_every_gnss_stream_and_its_truth() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("rig.toml"), SCENE).unwrap();
    let args = [
        "generate",
        "rig.toml",
        "-o",
        "imu.csv",
        "--gnss",
        "nmea:g.nmea",
        "--gnss",
        "ubx:g.ubx",
        "--gnss",
        "mavlink:g.mav",
        "--gnss-truth",
        "g.csv",
    ];
    ok(imu_emu(d, &args));
    let truth = std::fs::read_to_string(d.join("g.csv")).unwrap();
    let rows: Vec<Vec<&str>> = truth
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 41);
    assert_eq!(rows.iter().filter(|r| r[3] == "none").count(), 10);
    assert_eq!(rows[40][1], "4");
    let nmea = std::fs::read_to_string(d.join("g.nmea")).unwrap();
    assert_eq!(nmea.lines().count(), 5 * 41);
    let ubx = std::fs::read(d.join("g.ubx")).unwrap();
    assert_eq!(ubx.len(), 41 * (8 + 92));
    let mav = std::fs::read(d.join("g.mav")).unwrap();
    assert!(mav.len() > 41 * 12 && mav[0] == 0xFD);
    let first = [nmea.into_bytes(), ubx, mav, truth.into_bytes()];
    ok(imu_emu(d, &args));
    for (name, bytes) in ["g.nmea", "g.ubx", "g.mav", "g.csv"].iter().zip(first) {
        assert_eq!(std::fs::read(d.join(name)).unwrap(), bytes, "{name}");
    }
}

/// A value out of range names the scene file and the key; an unknown key names the line;
/// a bad `--gnss` names the format; nothing is left behind.
#[test]
fn bad_gnss_settings_fail_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("fast.toml"),
        SCENE.replace("rate_hz = 10", "rate_hz = 50"),
    )
    .unwrap();
    let e = failed(imu_emu(
        d,
        &[
            "generate",
            "fast.toml",
            "-o",
            "imu.csv",
            "--gnss",
            "nmea:g.nmea",
        ],
    ));
    assert!(
        e.contains("fast.toml: `gnss.rate_hz`") && e.contains("50 Hz is outside 1–20 Hz"),
        "{e}"
    );
    std::fs::write(d.join("typo.toml"), SCENE.replace("rate_hz", "rate")).unwrap();
    let e = failed(imu_emu(d, &["generate", "typo.toml", "-o", "imu.csv"]));
    assert!(
        e.contains("typo.toml:6:1: `gnss.rate`: unknown field"),
        "{e}"
    );
    let e = failed(imu_emu(
        d,
        &[
            "generate",
            "--scene",
            "circle",
            "--duration",
            "1",
            "-o",
            "imu.csv",
            "--gnss",
            "sirf:g",
        ],
    ));
    assert!(
        e.contains("GNSS format `sirf`: expected one of nmea, ubx, mavlink"),
        "{e}"
    );
    let left: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| !n.ends_with(".toml"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

/// The commented `[gnss]` table of examples/survey.toml, uncommented, is the default receiver
/// (plus the outage and seed it shows as examples).
#[test]
fn example_scene_file_documents_the_gnss_defaults() {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/survey.toml"))
            .unwrap();
    let table: String = text
        .lines()
        .skip_while(|l| *l != "# [gnss]")
        .filter_map(|l| l.strip_prefix("# "))
        .filter(|l| l.starts_with('[') || l.contains(" = "))
        .map(|l| format!("{l}\n"))
        .collect();
    let file: toml::Table = toml::from_str(&table).unwrap();
    let cfg: imu_emu::aiding::GnssConfig = file["gnss"].clone().try_into().unwrap();
    let expected = imu_emu::aiding::GnssConfig {
        outages_s: vec![[120.0, 180.0]],
        seed: Some(20_261_124),
        ..Default::default()
    };
    assert_eq!(cfg, expected);
}

/// `--odometer FILE` on the straight scene (level, 100 m/s along body x): with 49.3 ticks/m at
/// 7 Hz the count after sample k is ⌊100·(k/7)·49.3⌋; a bad `[odometer]` value names its key.
#[test]
fn generate_writes_the_odometer() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = "[trajectory]\nscene = \"straight\"\n[output]\nduration_s = 1.0\n\
                 [odometer]\nrate_hz = 7\ncounts_per_m = 49.3\n";
    std::fs::write(d.join("odo.toml"), scene).unwrap();
    ok(imu_emu(
        d,
        &[
            "generate",
            "odo.toml",
            "-o",
            "imu.csv",
            "--odometer",
            "odo.csv",
        ],
    ));
    let text = std::fs::read_to_string(d.join("odo.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("t,ticks,delta_ticks,speed_m_s,true_distance_m")
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 7);
    for (k, r) in rows.iter().enumerate() {
        let k = (k + 1) as f64;
        assert_eq!(r[1], (100.0 * k / 7.0 * 49.3).floor(), "sample {k}");
        assert!((r[4] - 100.0 / 7.0).abs() < 1e-9, "{}", r[4]);
    }
    std::fs::write(d.join("bad.toml"), scene.replace("49.3", "0")).unwrap();
    let e = failed(imu_emu(
        d,
        &[
            "generate",
            "bad.toml",
            "-o",
            "imu.csv",
            "--odometer",
            "o.csv",
        ],
    ));
    assert!(
        e.contains("bad.toml: `odometer.counts_per_m`") && e.contains("0 must be > 0"),
        "{e}"
    );
    assert!(!d.join("o.csv").exists() && !d.join("imu2.csv").exists());
}
