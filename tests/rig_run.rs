//! `imu-emu run` on a rig scene file: every unit from one process on one pacer, each in its
//! own protocol and rate to its own sinks. Checked against `generate`'s per-unit bytes,
//! decoded by the project's frame decoders over loopback UDP and a real pty, with the
//! merged order of all units on one socket following the shared clock.

#[path = "common/realtime_run.rs"]
mod realtime_run;
use std::io::Read;
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use imu_emu::protocol::{StreamDecoder, load};

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");

/// Three units: LN-200 frames at 400 Hz at the reference point, KVH 1750 frames with a µs
/// time tag at 100 Hz 1.2 m aft, and a two-gyro skew-redundant unit as CSV at 50 Hz.
fn scene(dir: &Path, duration_s: f64, sinks: [&str; 3]) -> std::path::PathBuf {
    let text = format!(
        r#"[trajectory]
scene = "circle"
[output]
duration_s = {duration_s}
[[imu]]
name = "nav"
model = "ln200"
format = "ln200"
seed = 1
{}
[[imu]]
name = "aft"
model = "hg1700"
format = "kvh1750-b"
rate_hz = 100.0
seed = 2
lever_arm_m = [-1.2, 0.0, 0.3]
{}
[[imu]]
name = "skew"
rate_hz = 50.0
seed = 3
{}
[[imu.gyro]]
axis = [1.0, 0.0, 0.0]
noise = "0.01 deg/sqrt(h)"
[[imu.gyro]]
axis = [0.0, 0.6, 0.8]
"#,
        sinks[0], sinks[1], sinks[2]
    );
    let p = dir.join("rig.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn imu_emu(args: &[&str], dir: &Path) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run imu-emu")
}

fn ok(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "imu-emu failed: {err}");
    err
}

/// Unpaced into files, a rig's run writes exactly `generate`'s bytes per unit (the skew
/// unit's CSV with its header): merging the units loses, repeats or reorders no
/// frame of any one unit, and the summary counts every record of every unit.
#[test]
fn file_sinks_are_generate_bytes() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(
        d,
        2.0,
        [
            r#"sink = "file:nav.bin""#,
            r#"sink = ["file:aft.bin"]"#,
            r#"sink = "file://skew.csv""#,
        ],
    );
    let s = s.to_str().unwrap();
    let err = ok(&imu_emu(&["run", s], d));
    ok(&imu_emu(&["generate", s, "-o", "gen"], d));
    let read = |p: &str| std::fs::read(d.join(p)).unwrap();
    assert_eq!(read("nav.bin"), read("gen/nav.bin"));
    assert_eq!(read("aft.bin"), read("gen/aft.bin"));
    assert_eq!(read("skew.csv"), read("gen/skew.csv"));
    for line in [
        "unit nav: 800 of 800 records, 0 skipped",
        "unit aft: 200 of 200 records, 0 skipped",
        "unit skew: 100 of 100 records, 0 skipped",
    ] {
        assert!(err.contains(line), "no `{line}` in {err}");
    }
}

/// Which unit a datagram is from, by its shape.
fn unit_of(d: &[u8], nav_len: usize, aft_len: usize) -> usize {
    if d.first().is_some_and(u8::is_ascii_digit) {
        2
    } else if d.len() == nav_len {
        0
    } else {
        assert_eq!(d.len(), aft_len, "a datagram of no unit");
        1
    }
}

/// All three units to one UDP socket at twice real time: every frame arrives, each unit's
/// frames decode with continuous counters, and the datagrams arrive in the order of the
/// records' times on the shared clock: record k of a unit at rate r is due at k/r, the KVH
/// frames' time tags and the skew rows' `t` say the same, and no datagram comes before one
/// of an earlier instant.
#[test]
fn udp_units_merge_in_emission_order() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    imu_emu::realtime::udp::grow_receive_buffer(&rx);
    let port = rx.local_addr().unwrap().port();
    let sink = format!(r#"sink = "udp:127.0.0.1:{port}""#);
    let s = scene(d, 1.5, [&sink, &sink, &sink]);
    let child = Command::new(BIN)
        .args(["run", s.to_str().unwrap(), "--speed", "2"])
        // Every frame is compared: none may be skipped as late.
        .args(["--max-behind-ms", "60000"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (nav_plan, aft_plan) = (load("ln200").unwrap().1, load("kvh1750-b").unwrap().1);
    let (planned, rates) = ([600usize, 150, 75], [400.0, 100.0, 50.0]);
    let mut got: Vec<Vec<u8>> = Vec::new();
    let mut buf = [0u8; 65536];
    while got.len() < planned.iter().sum() {
        // A signal to the test process (another test's child ending) may interrupt the wait.
        let n = loop {
            match rx.recv(&mut buf) {
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                r => break r.expect("a datagram within 60 s"),
            }
        };
        got.push(buf[..n].to_vec());
    }
    let err = ok(&child.wait_with_output().unwrap());
    let mut seen = [0usize; 3];
    let mut streams = [Vec::new(), Vec::new()];
    let mut last_t = 0.0;
    for dg in &got {
        let u = unit_of(dg, nav_plan.len(), aft_plan.len());
        seen[u] += 1;
        let t = seen[u] as f64 / rates[u];
        match u {
            1 => {
                let tag = aft_plan.decode(dg).unwrap().contract(None)[0].unwrap();
                assert!((tag - t).abs() < 1e-6, "KVH frame {} tagged {tag}", seen[u]);
            }
            2 => {
                let row = std::str::from_utf8(dg).unwrap();
                let tag: f64 = row.split(',').next().unwrap().parse().unwrap();
                assert!((tag - t).abs() < 1e-9, "skew row {} at {tag}", seen[u]);
            }
            _ => {}
        }
        if u < 2 {
            streams[u].extend_from_slice(dg);
        }
        assert!(
            t >= last_t - 1e-9,
            "a frame of {t} s after one of {last_t} s"
        );
        last_t = t;
    }
    assert_eq!(seen.to_vec(), planned.to_vec());
    for (bytes, plan, n) in [(&streams[0], &nav_plan, 600), (&streams[1], &aft_plan, 150)] {
        let mut dec = StreamDecoder::new(plan.clone());
        dec.feed(bytes, |_| {});
        let st = dec.stats();
        assert_eq!(
            (st.frames, st.check_failures, st.counter_gaps),
            (n, 0, 0),
            "{}",
            plan.name
        );
    }
    assert!(
        err.contains("unit aft: 150 of 150 records, 0 skipped"),
        "{err}"
    );
}

/// The LN-200 unit on a real pty and the KVH unit on UDP, at real time: the reader of the
/// pty, reading until the run closes it, decodes every frame the run says it sent there,
/// contiguous (no counter gap from its first frame on) unless the run reports frames it could
/// not deliver; the UDP reader gets every KVH frame, each tagged with its record's time, and
/// the summary gives per unit its records and per sink what it delivered.
#[test]
fn pty_and_udp_units_are_decoded() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let link = d.join("nav-pty");
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let port = rx.local_addr().unwrap().port();
    let s = scene(
        d,
        3.0,
        [
            &format!(r#"sink = "pty:{}""#, link.display()),
            &format!(r#"sink = "udp://127.0.0.1:{port}""#),
            r#"sink = "file:skew.csv""#,
        ],
    );
    let child = Command::new(BIN)
        .args(["run", s.to_str().unwrap(), "--max-behind-ms", "60000"])
        .current_dir(d)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while link.symlink_metadata().is_err() {
        assert!(t.elapsed() < Duration::from_secs(20), "no pty link");
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut port_ = serialport::new(link.to_string_lossy(), 921_600)
        .timeout(Duration::from_millis(50))
        .open_native()
        .expect("open the pty slave");
    port_.set_exclusive(false).unwrap();
    let reader = std::thread::spawn(move || {
        let (mut got, mut buf) = (Vec::new(), [0u8; 4096]);
        // Until the run closes its end (an error or nothing), with a hang guard.
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(120) {
            match port_.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(_) => break,
            }
        }
        got
    });
    let aft = load("kvh1750-b").unwrap().1;
    let mut buf = [0u8; 2048];
    for k in 1..=300 {
        // A signal to the test process (another test's child ending) may interrupt the wait.
        let n = loop {
            match rx.recv(&mut buf) {
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                r => break r.expect("a KVH datagram"),
            }
        };
        let tag = aft.decode(&buf[..n]).unwrap().contract(None)[0].unwrap();
        assert!(
            (tag - k as f64 / 100.0).abs() < 1e-6,
            "frame {k} tagged {tag}"
        );
    }
    let got = reader.join().unwrap();
    let err = ok(&child.wait_with_output().unwrap());
    let mut dec = StreamDecoder::new(load("ln200").unwrap().1);
    dec.feed(&got, |_| {});
    let st = dec.stats();
    let pty_line = (err.lines())
        .find(|l| l.contains(&format!("pty {}:", link.display())))
        .unwrap_or_else(|| panic!("the pty's counts in {err}"));
    let count = |what: &str| -> u64 {
        let at = pty_line.find(what).unwrap();
        let head = pty_line[..at].trim_end();
        head.rsplit([' ', ':']).next().unwrap().parse().unwrap()
    };
    assert_eq!(st.frames, count(" sent"), "{err}");
    assert_eq!(st.check_failures, 0, "{err}");
    assert!(
        st.counter_gaps == 0 || count(" dropped (slow consumer)") > 0,
        "{err}"
    );
    for line in [
        "unit nav: 1200 of 1200 records",
        "unit aft: 300 of 300 records",
        "300 sent, 0 dropped (slow consumer)",
    ] {
        assert!(err.contains(line), "no `{line}` in {err}");
    }
    assert!(
        err.contains(&format!("`nav` on {}", link.display())),
        "{err}"
    );
}

/// Bad sinks and flags that do not fit a rig are refused before anything runs, naming the
/// file and key or the flag.
#[test]
fn bad_sinks_are_refused() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(
        d,
        1.0,
        [r#"sink = "udp:nowhere""#, "", r#"sink = "file:s.csv""#],
    );
    let s = s.to_str().unwrap();
    let out = imu_emu(&["run", s], d);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("imu[0].sink") && err.contains("udp:HOST:PORT"),
        "{err}"
    );
    let s2 = scene(d, 1.0, ["", "", ""]);
    let s2 = s2.to_str().unwrap();
    for (args, expect) in [
        (vec!["--unit-sink", "tail=file:x.bin"], "no unit `tail`"),
        (vec!["--unit-sink", "nav"], "expected NAME=SINK"),
        (
            vec!["--unit-sink", "nav=carrier-pigeon:x:1"],
            "unknown sink kind `carrier-pigeon`",
        ),
        (
            vec!["--udp", "127.0.0.1:9"],
            "--udp 127.0.0.1:9: a rig's streams name their unit (nav, aft, skew)",
        ),
    ] {
        let out = imu_emu(&[&["run", s2], &args[..]].concat(), d);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} ran");
        assert!(err.contains(expect), "{args:?}: {err}");
    }
    // --unit-sink replaces the scene's sinks of that unit: nothing is opened from the file.
    let out = imu_emu(
        &[
            "run",
            s,
            "--unit-sink",
            "nav=file:n.bin",
            "--unit-sink",
            "aft=file:a.bin",
        ],
        d,
    );
    ok(&out);
    assert_eq!(std::fs::read(d.join("n.bin")).unwrap().len(), 400 * 26);
    let single = imu_emu(&["run", "--scene", "static", "--unit-sink", "a=file:x"], d);
    assert!(String::from_utf8_lossy(&single.stderr).contains("lists no `[[imu]]` units"));
}
