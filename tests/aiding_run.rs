//! `imu-emu run` with aiding streams (`--gnss FORMAT:SINK`, `--odometer SINK`, `--baro SINK`,
//! `--magnetometer SINK`) for one IMU and for a rig: every stream carries exactly the bytes
//! `generate` writes for the same scene and seed (CSV sensors without their header line),
//! over file sinks and over loopback UDP, and over UDP the frames of all streams arrive in
//! emission-time order on the IMU's pacer.

use std::net::UdpSocket;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");

/// 2 s of the circle with a receiver at 4 Hz and 0.05 s latency, an odometer at 10 Hz with
/// a scale factor and a lever arm, a noisy barometer with a drifting bias and a noisy
/// magnetometer with hard iron: every stream draws random numbers or depends on the
/// settings, so a wrong seed or table would change its bytes. `units` is appended (a rig).
fn scene(dir: &Path, name: &str, units: &str) -> std::path::PathBuf {
    let text = format!(
        r#"[trajectory]
scene = "circle"
[output]
duration_s = 2.0
[gnss]
rate_hz = 4.0
latency_s = 0.05
[odometer]
rate_hz = 10.0
scale_factor = 0.01
lever_arm_m = [0.0, 0.5, 0.0]
[baro]
rate_hz = 8.0
noise_pa = 2.0
bias_rw_pa_sqrt_s = 0.5
[magnetometer]
rate_hz = 20.0
hard_iron_t = [1e-6, 0.0, -2e-6]
noise_t = 1e-7
{units}"#
    );
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn imu_emu(dir: &Path, args: &[&str]) -> Output {
    Command::new(BIN)
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run imu-emu")
}

fn ok(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    err
}

/// `generate`'s files of every aiding stream for `scene` with seed 5: GNSS in three formats,
/// the sensors' CSV; returned as (name, bytes a stream carries): the sensors' without header.
fn generated(d: &Path, scene: &str) -> Vec<(&'static str, Vec<u8>)> {
    let args = [
        "generate",
        scene,
        "--seed",
        "5",
        "-o",
        "imu.csv",
        "--gnss",
        "nmea:g.nmea",
        "--gnss",
        "ubx:g.ubx",
        "--gnss",
        "mavlink:g.mav",
        "--odometer",
        "g-odo.csv",
        "--baro",
        "g-baro.csv",
        "--magnetometer",
        "g-mag.csv",
    ];
    ok(&imu_emu(d, &args));
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    let body = |f: &str| {
        let b = read(f);
        let nl = b.iter().position(|c| *c == b'\n').unwrap();
        b[nl + 1..].to_vec()
    };
    vec![
        ("nmea", read("g.nmea")),
        ("ubx", read("g.ubx")),
        ("mavlink", read("g.mav")),
        ("odometer", body("g-odo.csv")),
        ("baro", body("g-baro.csv")),
        ("magnetometer", body("g-mag.csv")),
    ]
}

/// `generate`'s aiding files of `generated` whole, headers included: what `run` writes to a
/// file sink of the same stream (a file starts with its header, whoever writes it).
fn generated_files(d: &Path) -> Vec<(&'static str, Vec<u8>)> {
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    [
        ("nmea", "g.nmea"),
        ("ubx", "g.ubx"),
        ("mavlink", "g.mav"),
        ("odometer", "g-odo.csv"),
        ("baro", "g-baro.csv"),
        ("magnetometer", "g-mag.csv"),
    ]
    .map(|(n, f)| (n, read(f)))
    .to_vec()
}

/// The `run` flags sending every aiding stream to `sink(name)`.
fn aiding_flags(sink: impl Fn(&str) -> String) -> Vec<String> {
    let mut v = Vec::new();
    for f in ["nmea", "ubx", "mavlink"] {
        v.extend(["--gnss".to_string(), format!("{f}:{}", sink(f))]);
    }
    for k in ["odometer", "baro", "magnetometer"] {
        v.extend([format!("--{k}"), sink(k)]);
    }
    v
}

/// One IMU, every sink a file (unpaced): each aiding file equals `generate`'s, the IMU's
/// frames equal `generate --format ln200`'s (merging changed none of them), and the summary
/// counts each stream's frames: 9 epochs (0, 0.25, …, 2 s), 20 odometer intervals, 17
/// barometer and 41 magnetometer instants (both ends of the span).
#[test]
fn single_imu_file_streams_equal_generate() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, "one.toml", "");
    generated(d, "one.toml");
    ok(&imu_emu(
        d,
        &[
            "generate", "one.toml", "--seed", "5", "--imu", "ln200", "--format", "ln200", "-o",
            "g.bin",
        ],
    ));
    let mut args: Vec<String> = ["run", "one.toml", "--seed", "5", "--file", "imu.bin"]
        .map(String::from)
        .to_vec();
    args.extend(aiding_flags(|n| format!("file:r-{n}")));
    let err = ok(&imu_emu(
        d,
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
    ));
    for (name, bytes) in &generated_files(d) {
        let got = std::fs::read(d.join(format!("r-{name}"))).unwrap();
        assert!(
            !bytes.is_empty() && got == *bytes,
            "{name} differs from generate's"
        );
    }
    assert_eq!(
        std::fs::read(d.join("imu.bin")).unwrap(),
        std::fs::read(d.join("g.bin")).unwrap()
    );
    for line in [
        "unit imu: 800 of 800 records",
        "stream gnss-nmea: 9 of 9 epochs, 0 skipped",
        "stream gnss-mavlink: 9 of 9 epochs",
        "stream odometer: 20 of 20 samples",
        "stream baro: 17 of 17 samples",
        "stream magnetometer: 41 of 41 samples",
    ] {
        assert!(err.contains(line), "{line}: {err}");
    }
}

/// Receives datagrams on `rx` until `n` have come.
fn receive(rx: &UdpSocket, n: usize) -> Vec<Vec<u8>> {
    let mut got = Vec::new();
    let mut buf = [0u8; 65536];
    while got.len() < n {
        // A signal to the test process (another test's child ending) may interrupt the wait.
        let len = loop {
            match rx.recv(&mut buf) {
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                r => break r.expect("a datagram within 60 s"),
            }
        };
        got.push(buf[..len].to_vec());
    }
    got
}

fn socket() -> (UdpSocket, u16) {
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    imu_emu::realtime::udp::grow_receive_buffer(&rx);
    let port = rx.local_addr().unwrap().port();
    (rx, port)
}

/// An odometer CSV row (`t` and four numbers), as opposed to a binary LN-200 frame.
fn odometer_row(dg: &[u8]) -> Option<f64> {
    let s = std::str::from_utf8(dg).ok()?.strip_suffix('\n')?;
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.parse().ok())
        .collect::<Option<_>>()?;
    (v.len() == 5).then_some(v[0])
}

/// One IMU's LN-200 frames (400 Hz), its NMEA epochs (4 Hz, 0.05 s latency) and its
/// odometer rows (10 Hz) on one UDP socket at four times real time: the NMEA datagrams put
/// together are `generate`'s file and the rows its CSV; before each epoch came exactly the
/// frames of times at or before its emission (k/400 ≤ t + 0.05), before each odometer row
/// those at or before its time (a tie goes to the IMU, the first stream).
#[test]
fn single_imu_streams_interleave_over_udp() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, "one.toml", "");
    let want = generated(d, "one.toml");
    let (rx, port) = socket();
    let dest = format!("udp:127.0.0.1:{port}");
    let child = Command::new(BIN)
        .current_dir(d)
        .args(["run", "one.toml", "--seed", "5", "--speed", "4"])
        .args(["--max-behind-ms", "60000"])
        .args(["--udp", &format!("127.0.0.1:{port}")])
        .args(["--gnss", &format!("nmea:{dest}"), "--odometer", &dest])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let got = receive(&rx, 800 + 9 + 20);
    let err = ok(&child.wait_with_output().unwrap());
    assert!(
        err.contains("stream odometer: 20 of 20 samples, 0 skipped"),
        "{err}"
    );

    let (mut frames, mut nmea, mut rows) = (0u64, Vec::new(), Vec::new());
    let mut epochs = 0;
    for dg in &got {
        if dg.starts_with(b"$") {
            let t_emit = 0.25 * epochs as f64 + 0.05;
            // The last epoch (t = 2 s) is emitted after the IMU's last frame.
            let due = ((t_emit * 400.0 + 1e-9).floor() as u64).min(800);
            assert_eq!(frames, due, "epoch {epochs}");
            epochs += 1;
            nmea.extend_from_slice(dg);
        } else if let Some(t) = odometer_row(dg) {
            assert_eq!(frames, (t * 400.0).round() as u64, "odometer row at {t}");
            rows.extend_from_slice(dg);
        } else {
            assert_eq!(dg.len(), 26, "an LN-200 frame");
            frames += 1;
        }
    }
    assert_eq!((frames, epochs), (800, 9));
    assert!(nmea == want[0].1, "NMEA differs from generate's");
    assert!(rows == want[3].1, "odometer rows differ from generate's");
}

/// A rig (one skew unit at 50 Hz, file sink) with every aiding stream: over files they
/// equal `generate`'s for the single-IMU scene with the same trajectory, tables and seed
/// (the rig's master seed); the barometer and magnetometer also over UDP at four times real
/// time, each row one datagram, together the same bytes.
#[test]
fn rig_streams_equal_generate_over_file_and_udp() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, "one.toml", "");
    let want = generated(d, "one.toml");
    let unit = "[[imu]]\nname = \"skew\"\nrate_hz = 50.0\nsink = \"file:skew.csv\"\n\
                [[imu.gyro]]\naxis = [1.0, 0.0, 0.0]\n";
    scene(d, "rig.toml", unit);
    let mut args: Vec<String> = ["run", "rig.toml", "--seed", "5"]
        .map(String::from)
        .to_vec();
    args.extend(aiding_flags(|n| format!("file:r-{n}")));
    let err = ok(&imu_emu(
        d,
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
    ));
    assert!(
        err.contains("stream magnetometer: 41 of 41 samples"),
        "{err}"
    );
    for (name, bytes) in &generated_files(d) {
        let got = std::fs::read(d.join(format!("r-{name}"))).unwrap();
        assert!(got == *bytes, "{name} differs from generate's");
    }

    let (rx, port) = socket();
    let dest = format!("udp:127.0.0.1:{port}");
    let child = Command::new(BIN)
        .current_dir(d)
        .args(["run", "rig.toml", "--seed", "5", "--speed", "4"])
        .args(["--max-behind-ms", "60000"])
        .args(["--baro", &dest, "--magnetometer", &dest])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let got = receive(&rx, 17 + 41);
    ok(&child.wait_with_output().unwrap());
    let (mut baro, mut mag) = (Vec::new(), Vec::new());
    for dg in &got {
        let commas = dg.iter().filter(|c| **c == b',').count();
        match commas {
            5 => baro.extend_from_slice(dg),
            9 => mag.extend_from_slice(dg),
            _ => panic!("not a sensor row: {}", String::from_utf8_lossy(dg)),
        }
    }
    assert!(baro == want[4].1, "barometer rows differ");
    assert!(mag == want[5].1, "magnetometer rows differ");
}

/// Bad aiding flags name the flag, the value and what is expected; `--trigger` is refused
/// where every sink is a file (an unpaced run has no edges to wait for); nothing is written.
#[test]
fn bad_aiding_flags_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, "one.toml", "");
    for (flags, want) in [
        (
            vec!["--odometer", "tcp:x"],
            "--odometer tcp:x: `tcp:x`: expected tcp:HOST:PORT",
        ),
        (
            vec!["--baro", "file:"],
            "--baro file:: `file:`: expected a path after `file:`",
        ),
        (
            vec!["--magnetometer", "udp:host"],
            "--magnetometer udp:host: `udp:host`: expected udp:HOST:PORT",
        ),
        (
            vec!["--gnss", "gps:file:g"],
            "--gnss gps:file:g: unknown format `gps`",
        ),
        (
            vec!["--gnss", "ubx:file:b.ubx", "--trigger", "udp://127.0.0.1:9"],
            "--trigger: needs a paced run",
        ),
    ] {
        let mut args = vec!["run", "one.toml", "--file", "imu.bin"];
        args.extend(&flags);
        let out = imu_emu(d, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(want),
            "{flags:?}: {err}"
        );
    }
    let left: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["one.toml"], "no output after a refused flag");
}

/// `--time-marks` next to aiding streams (a paced run, 1 s at real time): the marks are the
/// IMU's records alone — one per LN-200 frame, indices 0, 1, … 399 without a gap, each valid
/// at the end of its interval (k + 1)/400 s, due when valid — while the GNSS and barometer
/// frames, interleaved on the same pacer, pass unmarked and still carry exactly
/// `generate`'s bytes. Marking every merged frame would give 400 + 5 + 9 marks and shifted
/// indices.
#[test]
fn time_marks_count_only_the_imu_records_next_to_aiding_streams() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, "one.toml", "");
    let common = ["--seed", "5", "--duration", "1"];
    let mut args = vec!["run", "one.toml", "--speed", "1", "--file", "imu.bin"];
    args.extend(["--max-behind-ms", "60000"]);
    args.extend(["--gnss", "nmea:file:r.nmea", "--baro", "file:r-baro.csv"]);
    args.extend(["--time-marks", "marks.csv"]);
    args.extend(common);
    let err = ok(&imu_emu(d, &args));
    let mut gen_args = vec!["generate", "one.toml", "-o", "imu.csv"];
    gen_args.extend(["--gnss", "nmea:g.nmea", "--baro", "g-baro.csv"]);
    gen_args.extend(common);
    ok(&imu_emu(d, &gen_args));
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    assert!(
        read("r.nmea") == read("g.nmea"),
        "NMEA differs from generate's"
    );
    assert!(
        read("r-baro.csv") == read("g-baro.csv"),
        "baro differs from generate's"
    );
    let marks = String::from_utf8(read("marks.csv")).unwrap();
    let rows: Vec<Vec<i64>> = (marks.lines().skip(1))
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 400, "{err}");
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r[0], k as i64, "mark {k}: index");
        let tov = ((k as f64 + 1.0) / 400.0 * 1e9).round() as i64;
        assert_eq!(r[1], tov, "mark {k}: time of validity");
        // Without timing errors a record is due when valid.
        assert_eq!(r[2], r[3], "mark {k}: tov vs due");
    }
}
