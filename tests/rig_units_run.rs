//! Rig units with a producer of their own — a template's `[output_filter]`, its sampling-clock
//! `[timing]` errors — through `imu-emu` in every clock (docs/rig.md, "Timing errors and output
//! filters"): offline (`generate`), paced (`run --speed 2` to a pty, UDP on loopback and a
//! file), lockstep (`run --motion -`, states through a pipe) and live real time (`run --motion
//! udp://…`). Same scene and seeds: the paced run's bytes are `generate`'s; a one-unit rig in
//! lockstep writes the single IMU's lockstep bytes; the real-time run's files begin with the
//! bytes lockstep makes from its recorded input. tests/rig_units.rs checks the same units
//! against the single IMU and closed forms through the library.

use std::io::{Read, Write};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

#[path = "common/loopback.rs"]
mod loopback;
#[path = "common/realtime_run.rs"]
mod realtime_run;
use loopback::{send_states, survey_csv};

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");

/// The example template with an output filter (ADIS16448 figures, 819.2 → 204.8 Hz).
const FILTERED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/filtered.toml");

/// An LN-200 with sampling-clock errors (its own clock's offset, drift and random walk,
/// jitter, gyro–accelerometer skew) and emission errors (latency with a spread, late frames,
/// skipped samples).
const TIMED: &str = "name = \"timed\"\nbase = \"ln200\"\n[timing]\nclock_offset = \"50 ppm\"\n\
clock_drift = \"0.5 ppm/s\"\nclock_random_walk = \"0.1 ppm/sqrt(s)\"\njitter = \"2 us\"\n\
skew = \"20 us\"\nlatency = \"400 us\"\nlatency_spread = \"50 us\"\nlate_probability = 0.05\n\
late_delay = \"3 ms\"\nmissing_probability = 0.03\n";

/// Writes `text` to `dir/name`.
fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `imu-emu args` in `dir` with `stdin` piped in (empty: none); asserts success and
/// returns its standard error.
fn ok(dir: &Path, args: &[&str], stdin: &[u8]) -> String {
    let mut child = Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut pipe = child.stdin.take().unwrap();
    let input = stdin.to_vec();
    // The run may stop reading once its duration is written.
    let writer = std::thread::spawn(move || {
        let _ = pipe.write_all(&input);
    });
    let out: Output = child.wait_with_output().unwrap();
    writer.join().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "imu-emu {args:?} failed: {err}");
    err
}

/// Whether `hay` contains `needle` as a contiguous run of bytes.
fn contains(hay: &[u8], needle: &[u8]) -> bool {
    needle.is_empty() || hay.windows(needle.len()).any(|w| w == needle)
}

/// A rig of a filtered unit (KVH 1750 Format C frames to a pty and a file), a unit with every
/// timing error (KVH 1750 frames over UDP on loopback) and a plain LN-200 (CSV to a file), run
/// paced at twice real time: the file sinks hold `generate`'s bytes, the UDP datagrams in
/// order are `generate`'s bytes (the timed unit's frames leave at their emission times:
/// latency and late frames delay, never reorder them), and what a reader of the pty got from
/// the moment it opened it is a contiguous run of `generate`'s bytes (a frame lost or changed
/// would break it: 5 frame lengths are tried as the start, the reader may open mid-frame).
#[test]
fn paced_rig_units_write_generate_bytes() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let timed = write(d, "timed.toml", TIMED);
    let link = d.join("f-pty");
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    imu_emu::realtime::udp::grow_receive_buffer(&rx);
    let port = rx.local_addr().unwrap().port();
    let scene = write(
        d,
        "rig.toml",
        &format!(
            "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 2.0\n\
             [[imu]]\nname = \"f\"\nmodel = \"{FILTERED}\"\nformat = \"kvh1750-c\"\nrate_hz = 204.8\n\
             lever_arm_m = [0.3, -0.2, 0.1]\nsink = [\"pty:{}\", \"file:f.bin\"]\n\
             [[imu]]\nname = \"t\"\nmodel = \"{}\"\nformat = \"kvh1750\"\nrate_hz = 200.0\n\
             mounting_deg = [0.0, 0.0, 90.0]\nsink = \"udp:127.0.0.1:{port}\"\n\
             [[imu]]\nname = \"p\"\nmodel = \"ln200\"\nformat = \"csv\"\nrate_hz = 200.0\nsink = \"file:p.csv\"\n",
            link.display(),
            timed.display()
        ),
    );
    let s = scene.to_str().unwrap();
    ok(d, &["generate", s, "-o", "gen"], b"");
    let gen_t = std::fs::read(d.join("gen/t.bin")).unwrap();
    let child = Command::new(BIN)
        .args(["run", s, "--speed", "2", "--max-behind-ms", "60000"])
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while link.symlink_metadata().is_err() {
        assert!(t.elapsed() < Duration::from_secs(20), "no pty link");
        std::thread::sleep(Duration::from_millis(5));
    }
    let mut pty = serialport::new(link.to_string_lossy(), 921_600)
        .timeout(Duration::from_millis(50))
        .open_native()
        .expect("open the pty slave");
    pty.set_exclusive(false).unwrap();
    let reader = std::thread::spawn(move || {
        let (mut got, mut buf) = (Vec::new(), [0u8; 4096]);
        // Until the run closes the pty, with a hang guard.
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(120) {
            match pty.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(_) => break, // the run closed the pty
            }
        }
        got
    });
    let mut udp = Vec::new();
    let mut buf = [0u8; 2048];
    while udp.len() < gen_t.len() {
        let n = loop {
            match rx.recv(&mut buf) {
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                r => break r.expect("a datagram of unit t within 60 s"),
            }
        };
        udp.extend_from_slice(&buf[..n]);
    }
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let got = reader.join().unwrap();
    let read = |p: &str| std::fs::read(d.join(p)).unwrap();
    let gen_f = read("gen/f.bin");
    assert!(gen_f.len() > 10_000 && gen_t.len() > 5_000);
    assert!(
        read("f.bin") == gen_f,
        "unit f's file differs from generate's"
    );
    assert!(read("p.csv") == read("gen/p.csv"), "unit p's file differs");
    assert!(
        udp == gen_t,
        "unit t's datagrams differ from generate's bytes"
    );
    let frame = imu_emu::protocol::load("kvh1750-c").unwrap().1.len();
    assert_eq!(gen_f.len() % frame, 0);
    // The reader gets every frame the run says it sent to the pty after the reader came.
    let pty_line = (err.lines())
        .find(|l| l.contains(&format!("pty {}:", link.display())))
        .unwrap_or_else(|| panic!("the pty's counts in {err}"));
    let sent: usize = pty_line
        .split(": ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(sent > 0, "{err}");
    assert_eq!(got.len(), sent * frame, "{err}");
    assert!(contains(&gen_f, &got), "the pty's bytes are not generate's");
}

/// In lockstep on states through a pipe, a one-unit rig (the unit at the reference point in
/// the body's axes, with the seed the single IMU is given) writes the single IMU's lockstep
/// bytes on the same states, for a unit with an output filter and for one with every timing
/// error; the unit's own seed (none given: drawn from the master seed and its name) gives
/// other bytes, so the comparison can fail.
#[test]
fn lockstep_rig_units_write_the_single_imu_bytes() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let timed = write(d, "timed.toml", TIMED);
    let input = survey_csv(3.0);
    for (model, rate) in [
        (FILTERED.to_string(), "204.8"),
        (timed.display().to_string(), "200"),
    ] {
        let single = d.join("single.csv");
        let args = [
            "run",
            "--imu",
            &model,
            "--rate",
            rate,
            "--duration",
            "2",
            "--seed",
            "42",
            "--format",
            "csv",
            "--motion",
            "-",
            "--time-mode",
            "lockstep",
            "--file",
        ];
        let mut a: Vec<&str> = args.to_vec();
        let single_s = single.to_str().unwrap();
        a.push(single_s);
        ok(d, &a, input.as_bytes());
        let rig = |seed: &str| {
            let scene = write(
                d,
                "rig.toml",
                &format!(
                    "[output]\nduration_s = 2.0\n[[imu]]\nname = \"u\"\nmodel = \"{model}\"\n\
                     format = \"csv\"\nrate_hz = {rate}\n{seed}"
                ),
            );
            let out = d.join("u.csv");
            let sink = format!("u=file:{}", out.display());
            let s = scene.to_str().unwrap();
            let args = [
                "run",
                s,
                "--motion",
                "-",
                "--time-mode",
                "lockstep",
                "--unit-sink",
                &sink,
            ];
            ok(d, &args, input.as_bytes());
            std::fs::read(out).unwrap()
        };
        let want = std::fs::read(&single).unwrap();
        assert!(want.len() > 20_000, "{model}: {} bytes", want.len());
        assert!(
            rig("seed = 42") == want,
            "{model}: the rig unit's bytes differ"
        );
        assert!(
            rig("") != want,
            "{model}: another seed gives the same bytes"
        );
    }
}

/// In real time, a rig of a filtered unit at a lever arm and a unit with every timing error
/// follows the survey's states sent over UDP on loopback at 100 Hz, with a 60 ms output delay,
/// recording its input: each unit's file holds the rows a lockstep run makes from the
/// recorded input, up to where the run says its output first left the input — the input's
/// end (what follows was made past the newest state, after the input ended), or earlier on a
/// machine that delayed a state past the delay — for the 1.5 s and more of records lockstep
/// makes.
#[test]
fn realtime_rig_units_are_lockstep_of_their_recorded_input() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let timed = write(d, "timed.toml", TIMED);
    let scene = write(
        d,
        "rig.toml",
        &format!(
            "[output]\nduration_s = 30.0\n\
             [[imu]]\nname = \"f\"\nmodel = \"{FILTERED}\"\nformat = \"csv\"\nrate_hz = 204.8\n\
             lever_arm_m = [1.5, -0.4, 0.3]\n\
             [[imu]]\nname = \"t\"\nmodel = \"{}\"\nformat = \"csv\"\nrate_hz = 200.0\n",
            timed.display()
        ),
    );
    let s = scene.to_str().unwrap();
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let motion = format!("udp://127.0.0.1:{port}");
    let mut child = Command::new(BIN)
        .current_dir(d)
        .args(["run", s, "--motion", &motion, "--input-timeout", "0.5"])
        .args(["--max-behind-ms", "60000"])
        .args(["--output-delay", "0.06", "--record-input", "in.rec"])
        .args(["--unit-sink", "f=file:f.csv", "--unit-sink", "t=file:t.csv"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut text = String::new();
    while !text.contains("following udp://") {
        let mut line = String::new();
        let n = std::io::BufRead::read_line(&mut err, &mut line).unwrap();
        assert!(n > 0, "the run did not start: {text}");
        text += &line;
    }
    send_states(port, &survey_csv(2.5));
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
    assert!(child.wait().unwrap().success(), "{text}{rest}");
    let args = [
        "run",
        s,
        "--motion",
        "in.rec",
        "--time-mode",
        "lockstep",
        "--unit-sink",
        "f=file:rf.csv",
        "--unit-sink",
        "t=file:rt.csv",
    ];
    ok(d, &args, b"");
    for (live, replay, rate) in [("f.csv", "rf.csv", 204.8), ("t.csv", "rt.csv", 200.0)] {
        let (live, replay) = (
            std::fs::read(d.join(live)).unwrap(),
            std::fs::read(d.join(replay)).unwrap(),
        );
        let rows = replay.iter().filter(|&&b| b == b'\n').count() - 1;
        assert!(
            rows as f64 > 1.5 * rate * 0.95,
            "{rows} records in lockstep"
        );
        let until = realtime_run::departed(&rest).unwrap_or(f64::INFINITY);
        // The rows up to that time, by their time column.
        let upto = |csv: &[u8]| -> Vec<String> {
            (String::from_utf8_lossy(csv).lines())
                .take_while(|l| {
                    (l.split(',').next().and_then(|t| t.parse::<f64>().ok()))
                        .is_none_or(|t| t <= until + 1e-9)
                })
                .map(String::from)
                .collect()
        };
        let (l, r) = (upto(&live), upto(&replay));
        assert!(r.len() > 1, "{rest}");
        assert!(
            l.len() >= r.len() && l[..r.len()] == r[..],
            "the real-time records up to {until} s are not lockstep's: {text}{rest}"
        );
    }
}
