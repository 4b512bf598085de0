//! `imu-emu generate` on a rig scene writes the aiding files it is asked for (GNSS, its truth,
//! odometer, barometer, magnetometer) from the rig's motion, its `[gnss]`/`[odometer]`
//! settings and the master seed: byte for byte what a single IMU's scene of the same motion
//! and settings writes. A flag a rig cannot honour is refused by name, leaving no file.

#[path = "common/aiding.rs"]
mod aiding;
use aiding::{imu_emu, ok};

const AIDING: [&str; 14] = [
    "--gnss",
    "nmea:g.nmea",
    "--gnss",
    "ubx:g.ubx",
    "--gnss-truth",
    "g.csv",
    "--odometer",
    "o.csv",
    "--baro",
    "b.csv",
    "--magnetometer",
    "m.csv",
    "--seed",
    "11",
];

/// The example scene without its `[[imu]]` units: one ideal IMU on the same motion.
fn single_imu_scene(rig: &str) -> String {
    let mut out = String::new();
    let mut in_unit = false;
    for line in rig.lines() {
        if line.starts_with('[') {
            in_unit = line.starts_with("[[imu");
        }
        if !in_unit {
            out.push_str(line);
            out.push('\n');
        }
    }
    assert!(!out.contains("[[imu"));
    out
}

/// Every `$…*hh` sentence's checksum is the XOR of the bytes between `$` and `*`
/// (NMEA 0183); returns the sentences' talker+type names.
fn nmea_types(text: &str) -> Vec<String> {
    text.lines()
        .map(|l| {
            let (body, sum) = l[1..].split_once('*').expect("a checksum");
            let x = body.bytes().fold(0u8, |a, b| a ^ b);
            assert_eq!(format!("{x:02X}"), sum, "{l}");
            body[..5].to_string()
        })
        .collect()
}

#[test]
fn rig_generate_writes_the_aiding_streams_of_one_imu_on_the_same_motion() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rig = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/rig_aided.toml"
    ))
    .unwrap();
    std::fs::create_dir_all(d.join("rig")).unwrap();
    std::fs::create_dir_all(d.join("one")).unwrap();
    std::fs::write(d.join("rig/scene.toml"), &rig).unwrap();
    std::fs::write(d.join("one/scene.toml"), single_imu_scene(&rig)).unwrap();
    let mut args = vec!["generate", "scene.toml", "-o", "units"];
    args.extend(AIDING);
    ok(&imu_emu(&d.join("rig"), &args));
    args[3] = "imu.csv";
    ok(&imu_emu(&d.join("one"), &args));
    assert!(d.join("rig/units/nav.csv").exists() && d.join("rig/units/mems.csv").exists());
    for f in ["g.nmea", "g.ubx", "g.csv", "o.csv", "b.csv", "m.csv"] {
        let a = std::fs::read(d.join("rig").join(f)).unwrap();
        let b = std::fs::read(d.join("one").join(f)).unwrap();
        assert!(a.len() > 100, "{f}: {} bytes", a.len());
        assert!(a == b, "{f} differs between the rig and one IMU");
    }
    // 60 s at 5 Hz, both ends: 301 epochs, those in the 10 s outage (30, 40) without a fix.
    let truth = std::fs::read_to_string(d.join("rig/g.csv")).unwrap();
    let rows: Vec<Vec<&str>> = (truth.lines().skip(1))
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 301);
    for r in &rows {
        let (t, fix): (f64, &str) = (r[1].parse().unwrap(), r[3]);
        let outage = t > 30.0 - 1e-9 && t < 40.0 - 1e-9;
        assert_eq!(fix == "none", outage, "t = {t}: fix {fix}");
    }
    let types = nmea_types(&std::fs::read_to_string(d.join("rig/g.nmea")).unwrap());
    assert_eq!(types.iter().filter(|t| *t == "GPGGA").count(), 301);
    // The odometer: one row per 0.1 s over 60 s.
    let odo = std::fs::read_to_string(d.join("rig/o.csv")).unwrap();
    assert_eq!(odo.lines().count(), 1 + 600);
}

#[test]
fn rig_generate_refuses_a_flag_it_cannot_honour_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/examples/rig_aided.toml"),
        d.join("scene.toml"),
    )
    .unwrap();
    let mut args = vec!["generate", "scene.toml", "-o", "units"];
    args.extend(AIDING);
    args.extend(["--truth-errors", "e.csv"]);
    let out = imu_emu(d, &args);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--truth-errors"), "{err}");
    for f in [
        "g.nmea", "g.ubx", "g.csv", "o.csv", "b.csv", "m.csv", "e.csv",
    ] {
        assert!(!d.join(f).exists(), "{f} left behind");
    }
}
