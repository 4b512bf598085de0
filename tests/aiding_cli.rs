//! `imu-emu generate --gnss FORMAT:FILE --gnss-truth FILE` and the scene file's `[gnss]`:
//! the streams are written from the same motion and seed as the IMU records, are reproducible,
//! and bad settings fail naming the file, line or key, leaving no file behind.

#[path = "common/aiding.rs"]
mod aiding;
use aiding::{failed, imu_emu, ok};

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
    ok(&imu_emu(d, &args));
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
    ok(&imu_emu(d, &args));
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
    ok(&imu_emu(
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

/// `--baro` and `--magnetometer` on the straight scene (level, heading east at 1000 m, 41° N
/// 0° E, 100 m/s): 2 s at 5 Hz and 4 Hz are 11 and 9 samples; without noise the pressure is
/// the ISA's at 1000 m plus the bias; with a uniform field table (N, E, D) the body axes
/// (x east, y south, z down) read (E, −N, D) exactly, through the hard iron.
#[test]
fn generate_writes_baro_and_magnetometer() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut table = String::from("lat_deg,lon_deg,north_nt,east_nt,down_nt\n");
    for la in [40, 42] {
        for lo in [-1, 1] {
            table.push_str(&format!("{la},{lo},21000,-1500,38000\n"));
        }
    }
    std::fs::create_dir(d.join("fields")).unwrap();
    std::fs::write(d.join("fields/grid.csv"), &table).unwrap();
    let scene = "[trajectory]\nscene = \"straight\"\n[output]\nduration_s = 2.0\n\
                 [baro]\nrate_hz = 5\nnoise_pa = 0\nbias0_pa = -20\n\
                 [magnetometer]\nrate_hz = 4\nfield_table = \"fields/grid.csv\"\n\
                 hard_iron_t = [1e-6, 0.0, 0.0]\n";
    std::fs::write(d.join("s.toml"), scene).unwrap();
    let args = [
        "generate",
        "s.toml",
        "-o",
        "imu.csv",
        "--baro",
        "b.csv",
        "--magnetometer",
        "m.csv",
    ];
    ok(&imu_emu(d, &args));
    let read = |name: &str| -> (String, Vec<Vec<f64>>) {
        let text = std::fs::read_to_string(d.join(name)).unwrap();
        let mut lines = text.lines();
        let header = lines.next().unwrap().to_string();
        let rows = lines
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect();
        (header, rows)
    };
    let (h, rows) = read("b.csv");
    assert_eq!(
        h,
        "t,pressure_pa,altitude_m,true_pressure_pa,true_h_m,bias_pa"
    );
    assert_eq!(rows.len(), 11);
    let isa = imu_emu::aiding::baro::pressure(imu_emu::aiding::baro::geopotential(1000.0));
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r[0], k as f64 / 5.0);
        assert!((r[4] - 1000.0).abs() < 1e-6, "{r:?}");
        // dp/dh ≈ −11 Pa/m at 1000 m: 10⁻⁶ m of height is 10⁻⁵ Pa.
        assert!((r[3] - isa).abs() < 1e-4 && r[1] == r[3] - 20.0, "{r:?}");
        assert!(r[2] > 1001.0 && r[2] < 1002.0, "{r:?}");
    }
    let (h, rows) = read("m.csv");
    assert_eq!(
        h,
        "t,mag_x,mag_y,mag_z,true_x,true_y,true_z,field_n,field_e,field_d"
    );
    assert_eq!(rows.len(), 9);
    let (n, e, dn) = (21_000e-9, -1_500e-9, 38_000e-9);
    for r in &rows {
        let expected = [e + 1e-6, -n, dn, e, -n, dn, n, e, dn];
        for (got, want) in r[1..].iter().zip(expected) {
            assert!((got - want).abs() < 1e-18, "{r:?}");
        }
    }
    ok(&imu_emu(d, &args));
    assert_eq!(read("m.csv").1, rows);
}

/// A bad `[baro]` or `[magnetometer]` value names the file and key, an unknown key its line,
/// a bad field table its own file, line and column; nothing is left behind.
#[test]
fn bad_baro_and_magnetometer_settings_fail_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = "[trajectory]\nscene = \"straight\"\n[output]\nduration_s = 1.0\n";
    let run = |name: &str, table: &str| {
        std::fs::write(d.join(name), format!("{base}{table}")).unwrap();
        failed(imu_emu(
            d,
            &[
                "generate",
                name,
                "-o",
                "imu.csv",
                "--baro",
                "b.csv",
                "--magnetometer",
                "m.csv",
            ],
        ))
    };
    let e = run("a.toml", "[baro]\nnoise_pa = -1\n");
    assert!(
        e.contains("a.toml: `baro.noise_pa`") && e.contains("-1 must be ≥ 0"),
        "{e}"
    );
    let e = run("b.toml", "[baro]\nnoise = 1\n");
    assert!(e.contains("b.toml:6:1: `baro.noise`: unknown field"), "{e}");
    let e = run("c.toml", "[magnetometer]\nrate_hz = 0\n");
    assert!(
        e.contains("c.toml: `magnetometer.rate_hz`") && e.contains("outside (0, 1000]"),
        "{e}"
    );
    let e = run(
        "d.toml",
        "[magnetometer]\nsoft_iron = [[1, 0, 0], [0, 0, 0], [0, 0, 1]]\n",
    );
    assert!(
        e.contains("d.toml: `magnetometer.soft_iron`") && e.contains("invertible"),
        "{e}"
    );
    std::fs::write(
        d.join("g.csv"),
        "lat_deg,lon_deg,north_nt,east_nt,down_nt\n40,-1,1,2,3\n40,1,1,2,x\n",
    )
    .unwrap();
    let e = run("e.toml", "[magnetometer]\nfield_table = \"g.csv\"\n");
    assert!(
        e.contains("g.csv:3: `down_nt`: `x` is not a finite number"),
        "{e}"
    );
    let e = run("f.toml", "[magnetometer]\nfield_table = \"none.csv\"\n");
    assert!(
        e.contains("f.toml: `magnetometer.field_table`") && e.contains("none.csv"),
        "{e}"
    );
    // A grid that does not reach the flight: the time of the first sample outside.
    std::fs::write(
        d.join("far.csv"),
        "lat_deg,lon_deg,north_nt,east_nt,down_nt\n0,0,1,2,3\n0,1,1,2,3\n1,0,1,2,3\n1,1,1,2,3\n",
    )
    .unwrap();
    let e = run("h.toml", "[magnetometer]\nfield_table = \"far.csv\"\n");
    assert!(
        e.contains("magnetometer at t = 0 s") && e.contains("outside the magnetic field table"),
        "{e}"
    );
    for name in ["imu.csv", "b.csv", "m.csv"] {
        assert!(!d.join(name).exists(), "{name} left behind");
    }
}
