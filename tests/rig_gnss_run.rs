//! `imu-emu run --gnss FORMAT:SINK` on a rig: the GNSS receiver's epochs on the same pacer as
//! the units, over loopback UDP. The NMEA sentences are checked against `generate`'s GNSS
//! truth for the same trajectory and receiver, and their datagrams against the units' on the
//! one socket: every frame in emission-time order.

use std::net::UdpSocket;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");

/// The circle scene for 1.5 s with a receiver at 5 Hz, 50 ms of latency and its own seed:
/// `units` appended for a rig, nothing for a single IMU.
fn scene(dir: &Path, name: &str, units: &str) -> std::path::PathBuf {
    let text = format!(
        r#"[trajectory]
scene = "circle"
[output]
duration_s = 1.5
[gnss]
rate_hz = 5.0
latency_s = 0.05
seed = 11
{units}"#
    );
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Seconds of the day of an NMEA `hhmmss.ss` field.
fn seconds_of_day(hms: &str) -> f64 {
    let h: f64 = hms[0..2].parse().unwrap();
    let m: f64 = hms[2..4].parse().unwrap();
    let s: f64 = hms[4..].parse().unwrap();
    3600.0 * h + 60.0 * m + s
}

/// Degrees of an NMEA `(d)ddmm.mmmm` field and its hemisphere.
fn degrees(field: &str, hemi: &str) -> f64 {
    let dot = field.find('.').unwrap();
    let d: f64 = field[..dot - 2].parse().unwrap();
    let m: f64 = field[dot - 2..].parse().unwrap();
    let v = d + m / 60.0;
    if hemi == "S" || hemi == "W" { -v } else { v }
}

/// A skew unit's CSV rows at 50 Hz and NMEA at 5 Hz on one UDP socket: every epoch arrives
/// as one datagram of GGA, RMC, VTG, ZDA and GST with valid checksums; its time (UTC, GPS −
/// 18 s, record time 0 at GPS week 0 second 0) and its position are those of `generate
/// --gnss-truth` for the same receiver; each epoch comes after every row of a time at or
/// before its emission (time of validity + latency) and before every later one.
#[test]
fn nmea_epochs_interleave_with_unit_frames_over_udp() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let single = scene(d, "one.toml", "");
    let out = Command::new(BIN)
        .args(["generate", single.to_str().unwrap(), "-o", "imu.csv"])
        .args(["--gnss-truth", "truth.csv"])
        .current_dir(d)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truth = std::fs::read_to_string(d.join("truth.csv")).unwrap();
    let truth: Vec<Vec<f64>> = (truth.lines().skip(1))
        .map(|l| {
            (l.split(',').enumerate())
                .map(|(i, x)| if i == 3 { 0.0 } else { x.parse().unwrap() })
                .collect()
        })
        .collect();
    assert_eq!(truth.len(), 8, "epochs at 0, 0.2, …, 1.4 s");

    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    imu_emu::realtime::udp::grow_receive_buffer(&rx);
    let port = rx.local_addr().unwrap().port();
    let rig = scene(
        d,
        "rig.toml",
        &format!(
            "[[imu]]\nname = \"skew\"\nrate_hz = 50.0\nseed = 3\nsink = \"udp:127.0.0.1:{port}\"\n\
             [[imu.gyro]]\naxis = [1.0, 0.0, 0.0]\n"
        ),
    );
    let child = Command::new(BIN)
        .args(["run", rig.to_str().unwrap(), "--speed", "2"])
        .args(["--max-behind-ms", "60000"])
        .args(["--gnss", &format!("nmea:udp:127.0.0.1:{port}")])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut got: Vec<String> = Vec::new();
    let mut buf = [0u8; 65536];
    while got.len() < 75 + 8 {
        // A signal to the test process (another test's child ending) may interrupt the wait.
        let n = loop {
            match rx.recv(&mut buf) {
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                r => break r.expect("a datagram within 60 s"),
            }
        };
        got.push(String::from_utf8(buf[..n].to_vec()).unwrap());
    }
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("stream gnss-nmea: 8 of 8 epochs, 0 skipped"),
        "{err}"
    );

    let (mut rows, mut epochs) = (0usize, 0usize);
    for dg in &got {
        if !dg.starts_with('$') {
            rows += 1;
            let t: f64 = dg.split(',').next().unwrap().parse().unwrap();
            assert!((t - rows as f64 / 50.0).abs() < 1e-9, "row {rows} at {t}");
            // Every epoch emitted at or before this row's time has been received already.
            let due = truth.iter().filter(|e| e[2] <= t + 1e-9).count();
            assert_eq!(epochs, due, "row at {t} s after {epochs} epochs");
            continue;
        }
        let e = &truth[epochs];
        epochs += 1;
        // Rows of times after the emission have not come yet.
        assert!(
            (rows as f64 / 50.0) <= e[2] + 1e-9,
            "epoch {epochs} after {rows} rows"
        );
        let sentences: Vec<&str> = dg.split("\r\n").filter(|s| !s.is_empty()).collect();
        let kinds: Vec<&str> = sentences.iter().map(|s| &s[3..6]).collect();
        assert_eq!(kinds, ["GGA", "RMC", "VTG", "ZDA", "GST"]);
        for s in &sentences {
            let (body, sum) = s[1..].split_once('*').unwrap();
            let x = body.bytes().fold(0u8, |a, b| a ^ b);
            assert_eq!(format!("{x:02X}"), sum, "{s}");
        }
        let gga: Vec<&str> = sentences[0].split(',').collect();
        let t = e[1];
        // The run counts from GPS week 0 (1980-01-06), when UTC was GPS time: no leap second.
        let sod = t.rem_euclid(86_400.0);
        assert!(
            (seconds_of_day(gga[1]) - sod).abs() < 0.006,
            "{} vs {t}",
            gga[1]
        );
        // Seven decimals of minutes: half a step is 0.5e-7/60 deg.
        let (lat, lon) = (degrees(gga[2], gga[3]), degrees(gga[4], gga[5]));
        assert!((lat - e[11]).abs() < 1e-9, "lat {lat} vs {}", e[11]);
        assert!((lon - e[12]).abs() < 1e-9, "lon {lon} vs {}", e[12]);
    }
    assert_eq!((rows, epochs), (75, 8));
}

/// A bad `--gnss` names the flag, the value and what is expected (a single IMU's run with
/// `--gnss`: tests/aiding_run.rs).
#[test]
fn bad_gnss_flags_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rig = scene(
        d,
        "rig.toml",
        "[[imu]]\nname = \"a\"\nmodel = \"ideal\"\nsink = \"file:a.csv\"\n",
    );
    for (file, flag, want) in [
        (
            &rig,
            "gps:udp:127.0.0.1:9",
            "--gnss gps:udp:127.0.0.1:9: unknown format `gps`",
        ),
        (&rig, "nmea:tcp:x", "--gnss nmea:tcp:x:"),
        (&rig, "nmea", "--gnss nmea:"),
    ] {
        let out = Command::new(BIN)
            .args(["run", file.to_str().unwrap(), "--gnss", flag])
            .current_dir(d)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(want), "{flag}: {err}");
    }
    assert!(!d.join("a.csv").exists(), "no output after a refused flag");
}
