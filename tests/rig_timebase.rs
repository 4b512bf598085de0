//! `imu-emu run` of a rig on `--time-base gps|utc` with `--start-at`: the units' frames and the
//! GNSS stream carry the time base's GPS time from the rig's t₀ on, over file sinks (an
//! unpaced run, so the instants are exact and the test needs no wall clock).

use std::path::Path;
use std::process::Command;

use imu_emu::protocol::spec::Source;

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");

/// 2026-03-01T12:00:00Z: Unix 1 772 366 400 s; GPS = Unix − 315 964 800 (the GPS epoch,
/// 1980-01-06) + 18 leap seconds = 1 456 401 618 s = week 2408, 43 218 s.
const START: &str = "2026-03-01T12:00:00Z";
const WEEK: f64 = 2408.0;
const SOW: f64 = 43_218.0;

/// A rig on the circle for 1.5 s: one iXCOM unit at 100 Hz to `nav.bin`, the receiver at
/// 5 Hz; run with `args` and NMEA to `g.nmea`. Returns the stderr.
fn run(d: &Path, args: &[&str]) -> String {
    let scene = d.join("rig.toml");
    std::fs::write(
        &scene,
        "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 1.5\n[gnss]\nrate_hz = 5.0\n\
         [[imu]]\nname = \"nav\"\nmodel = \"ideal\"\nformat = \"imar-ixcom\"\nrate_hz = 100.0\n\
         sink = \"file:nav.bin\"\n",
    )
    .unwrap();
    let out = Command::new(BIN)
        .args(["run", scene.to_str().unwrap(), "--gnss", "nmea:file:g.nmea"])
        .args(args)
        .current_dir(d)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    err
}

/// Each iXCOM frame's GPS week and seconds (s).
fn frame_times(d: &Path) -> Vec<(f64, f64)> {
    let (_, plan) = imu_emu::protocol::load("imar-ixcom").unwrap();
    let mut dec = imu_emu::protocol::StreamDecoder::new(plan);
    let mut out = Vec::new();
    dec.feed(&std::fs::read(d.join("nav.bin")).unwrap(), |f| {
        let sow =
            f.get(Source::GpsWholeSeconds).unwrap() + f.get(Source::GpsMicros).unwrap() * 1e-6;
        out.push((f.get(Source::GpsWeek).unwrap(), sow));
    });
    out
}

/// The (day, month, year, seconds of day) of each epoch's ZDA sentence.
fn zda(d: &Path) -> Vec<(u32, u32, u32, f64)> {
    let text = std::fs::read_to_string(d.join("g.nmea")).unwrap();
    (text.lines().filter(|l| l.starts_with("$GPZDA")))
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let hms = f[1];
            let sod = 3600.0 * hms[0..2].parse::<f64>().unwrap()
                + 60.0 * hms[2..4].parse::<f64>().unwrap()
                + hms[4..].parse::<f64>().unwrap();
            (
                f[2].parse().unwrap(),
                f[3].parse().unwrap(),
                f[4].parse().unwrap(),
                sod,
            )
        })
        .collect()
}

/// `--time-base gps --start-at 2026-03-01T12:00:00Z`: unit record k (valid at k/100 s) carries
/// week 2408 and 43 218 + k/100 s (to the field's 1 µs), and the NMEA epochs (at 0, 0.2, …,
/// 1.4 s) date 2026-03-01 and UTC 12:00:00 + their time. A rig left on week 0 (the old
/// reference) dates them 1980; a time base without the leap seconds is 18 s off.
#[test]
fn gps_time_base_reaches_units_and_gnss() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let err = run(d, &["--time-base", "gps", "--start-at", START]);
    assert!(
        err.contains("time base gps: t₀ at week 2408, 43218"),
        "{err}"
    );
    let frames = frame_times(d);
    assert_eq!(frames.len(), 150, "{err}");
    for (k, (week, sow)) in frames.iter().enumerate() {
        let want = SOW + (k + 1) as f64 / 100.0;
        assert_eq!(*week, WEEK, "frame {k}");
        assert!((sow - want).abs() < 1.5e-6, "frame {k}: {sow} vs {want}");
    }
    let epochs = zda(d);
    assert_eq!(epochs.len(), 8, "{err}");
    for (i, (day, month, year, sod)) in epochs.iter().enumerate() {
        assert_eq!((*day, *month, *year), (1, 3, 2026), "epoch {i}");
        let want = 12.0 * 3600.0 + 0.2 * i as f64;
        assert!((sod - want).abs() < 0.006, "epoch {i}: {sod} vs {want}");
    }
}

/// `--time-base utc`: the frames' "GPS" fields carry UTC (GPS week and seconds counted
/// without leap seconds): 18 s less than on the GPS time base. The GNSS stream keeps true
/// time: its ZDA sentences read the same UTC as on the GPS time base (a receiver's UTC does
/// not depend on the IMU's time scale; taking the frames' reference for GPS time put them
/// 18 s early).
#[test]
fn utc_time_base_on_a_rig() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let err = run(d, &["--time-base", "utc", "--start-at", START]);
    let frames = frame_times(d);
    assert_eq!(frames.len(), 150, "{err}");
    let (week, sow) = frames[0];
    assert_eq!(week, WEEK);
    assert!((sow - (SOW - 18.0 + 0.01)).abs() < 1.5e-6, "{sow}");
    let epochs = zda(d);
    assert_eq!(epochs.len(), 8, "{err}");
    for (i, (day, month, year, sod)) in epochs.iter().enumerate() {
        assert_eq!((*day, *month, *year), (1, 3, 2026), "epoch {i}");
        let want = 12.0 * 3600.0 + 0.2 * i as f64;
        assert!((sod - want).abs() < 0.006, "epoch {i}: {sod} vs {want}");
    }
}
