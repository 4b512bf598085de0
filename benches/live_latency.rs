//! Live input latency: `cargo bench --bench live_latency` (LIVE_LATENCY_SECS per case,
//! default 20; LIVE_LATENCY_TABLES=latency or =rig for one of the two tables; IMU_EMU_BIN
//! runs another build of the emulator, e.g. an older one, for comparison).
//!
//! A sender thread streams the survey scene's states at 100 Hz in real time (binary
//! datagrams over UDP loopback) to `imu-emu run --motion udp://… --time-mode realtime`,
//! which writes LN-200 frames to a UDP sink read by a second thread of this process. Both
//! threads timestamp with the same monotonic clock: latency of state i = arrival of the frame
//! whose time of validity is t_i − the instant state i was sent. Frame n (1-based, in arrival
//! order) is the record of (t₀ + (n−1)/f, t₀ + n/f], t₀ read from the run's summary; a lost
//! frame datagram would shift the count, so the frames received are checked against the
//! frames the run reports.
//!
//! Cases: 400 Hz and 1 kHz output, with the default delay (period + measured jitter + 3 ms)
//! and a minimal one (0: every frame is due when its state is, so each is extrapolated from
//! the state before).
//!
//! Then the pacer's write lateness (what the run's summary reports: write completion − the
//! frame's deadline) of one IMU against a two-unit rig, the same input, both following live
//! states in real time (the just-in-time driver) and paced on the known scene: the live rig
//! must write as punctually as one IMU.

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Child, ChildStderr, Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

use imu_emu::live::binary::{self, Datagram};
use imu_emu::motion::{Motion, Pose};
use imu_emu::sim::Simulation;

fn datagram(p: &Pose, seq: u32) -> [u8; binary::LEN] {
    binary::encode(&Datagram {
        seq,
        week: binary::NO_WEEK,
        time: p.t,
        flags: 0,
        pos: [p.lat.to_degrees(), p.lon.to_degrees(), p.h],
        vel: p.v_n.into(),
        acc: [0.0; 3],
        quat: [p.q_b_n.w, p.q_b_n.i, p.q_b_n.j, p.q_b_n.k],
        rate: [0.0; 3],
    })
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// The emulator measured: this build's, or `IMU_EMU_BIN` (another build, to compare).
fn bin() -> String {
    std::env::var("IMU_EMU_BIN").unwrap_or_else(|_| env!("CARGO_BIN_EXE_imu-emu").into())
}

/// A live run started with `args` (its `--motion` on `port`), once it listens: the child, its
/// stderr, and the instant the bench's times count from.
fn start(args: &[String]) -> (Child, BufReader<ChildStderr>, Instant) {
    let mut child = Command::new(bin())
        .args(args)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    while !line.contains("following udp://") {
        line.clear();
        assert!(err.read_line(&mut line).unwrap() > 0, "the run starts");
    }
    (child, err, Instant::now())
}

/// Streams the survey's states at 100 Hz in real time to `port` for `seconds`: each state,
/// and when it was sent (s after `origin`).
fn send_states(port: u16, seconds: f64, origin: Instant) -> (Vec<Pose>, Vec<f64>) {
    let sim = Simulation::builder().build().unwrap();
    let m = sim.motion();
    let states: Vec<Pose> = (0..=(seconds * 100.0) as u64)
        .map(|k| m.pose(k as f64 / 100.0))
        .collect();
    let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
    let start = Instant::now();
    let mut sent = Vec::with_capacity(states.len());
    for (i, p) in states.iter().enumerate() {
        let at = start + Duration::from_secs_f64(p.t);
        if let Some(d) = at.checked_duration_since(Instant::now()) {
            thread::sleep(d);
        }
        sent.push(origin.elapsed().as_secs_f64());
        tx.send_to(&datagram(p, i as u32), ("127.0.0.1", port))
            .unwrap();
    }
    (states, sent)
}

/// A free loopback port.
fn free_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The arguments of a live run on `port` (binary states, 1 s input timeout).
fn live_args(port: u16) -> Vec<String> {
    [
        "run",
        "--motion",
        &format!("udp://127.0.0.1:{port}"),
        "--input-format",
        "bin",
        "--input-timeout",
        "1",
    ]
    .map(String::from)
    .to_vec()
}

/// One case: the latencies (s, sorted) and the run's summary line.
fn case(rate: u32, delay: Option<f64>, seconds: f64) -> (Vec<f64>, String) {
    let port = free_port();
    let sink = UdpSocket::bind("127.0.0.1:0").unwrap();
    // A reader descheduled for a while on a loaded machine loses no datagram.
    imu_emu::realtime::udp::grow_receive_buffer(&sink);
    let sink_port = sink.local_addr().unwrap().port();
    let mut args = live_args(port);
    args.extend([
        "--rate".into(),
        rate.to_string(),
        "--udp".into(),
        format!("127.0.0.1:{sink_port}"),
    ]);
    if let Some(d) = delay {
        args.extend(["--output-delay".into(), d.to_string()]);
    }
    let (mut child, err, origin) = start(&args);
    let reader = thread::spawn(move || {
        sink.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
        let mut buf = [0u8; 2048];
        let mut at = Vec::new();
        while sink.recv(&mut buf).is_ok() {
            at.push(origin.elapsed().as_secs_f64());
        }
        at
    });
    let (states, sent) = send_states(port, seconds, origin);
    let rest: Vec<String> = err.lines().map_while(Result::ok).collect();
    child.wait().unwrap();
    let frames_at = reader.join().unwrap();
    let summary = rest
        .iter()
        .find(|l| l.contains("frames at"))
        .cloned()
        .unwrap_or_else(|| panic!("no summary in {rest:?}"));
    let frames: usize = summary
        .split("imu-emu: ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("frame count in {summary}"));
    assert_eq!(frames_at.len(), frames, "frame datagrams lost: {summary}");
    let t0: f64 = summary
        .split("from t = ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("t0 in {summary}"));
    let mut lat: Vec<f64> = states
        .iter()
        .zip(&sent)
        .filter_map(|(p, &s)| {
            let n = ((p.t - t0) * rate as f64).round();
            (n >= 1.0)
                .then(|| frames_at.get(n as usize - 1))
                .flatten()
                .map(|&f| f - s)
        })
        .collect();
    lat.sort_by(f64::total_cmp);
    (lat, summary)
}

/// A rig of two LN-200 units (on the survey scene, or live): `nav` at the reference point in LN-200
/// frames at 400 Hz (the one-IMU case's stream), `arm` 1.5 m away, yawed and pitched, in
/// KVH 1750 frames at 100 Hz.
const RIG: &str = r#"
[[imu]]
name = "nav"
model = "ln200"
format = "ln200"
rate_hz = 400.0
[[imu]]
name = "arm"
model = "ln200"
format = "kvh1750"
rate_hz = 100.0
lever_arm_m = [1.5, -0.4, 0.3]
mounting_deg = [0.0, 10.0, 90.0]
"#;

/// The pacer's write lateness (the summary's `p50 … µs, p99 … µs, max … µs`) of one run:
/// one IMU or the rig, following live states (`live`) or paced on the known survey scene,
/// its frames to UDP sockets drained by a thread. Returns the frames written, the figures
/// and the summary.
fn write_lateness(rig: bool, live: bool, seconds: f64, dir: &Path) -> (u64, [f64; 3], String) {
    let port = free_port();
    let drain = UdpSocket::bind("127.0.0.1:0").unwrap();
    imu_emu::realtime::udp::grow_receive_buffer(&drain);
    let to = format!("udp:{}", drain.local_addr().unwrap());
    let mut args = if live {
        live_args(port)
    } else {
        [
            "run",
            "--scene",
            "survey",
            "--duration",
            &seconds.to_string(),
        ]
        .map(String::from)
        .to_vec()
    };
    if rig {
        let scene = dir.join("rig.toml");
        std::fs::write(&scene, RIG).unwrap();
        args.insert(1, scene.display().to_string());
        for u in ["nav", "arm"] {
            args.extend(["--unit-sink".into(), format!("{u}={to}")]);
        }
    } else {
        args.extend([
            "--rate".into(),
            "400".into(),
            "--udp".into(),
            to[4..].into(),
        ]);
    }
    let drained = thread::spawn(move || {
        drain
            .set_read_timeout(Some(Duration::from_secs(3)))
            .unwrap();
        let mut buf = [0u8; 2048];
        let mut n = 0u64;
        while drain.recv(&mut buf).is_ok() {
            n += 1;
        }
        n
    });
    let mut child;
    let err;
    if live {
        let origin;
        (child, err, origin) = start(&args);
        send_states(port, seconds, origin);
    } else {
        child = Command::new(bin())
            .args(&args)
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        err = BufReader::new(child.stderr.take().unwrap());
    }
    let rest: Vec<String> = err.lines().map_while(Result::ok).collect();
    assert!(child.wait().unwrap().success(), "{rest:?}");
    drained.join().unwrap();
    let text = rest.join("\n");
    let line = (rest.iter())
        .find(|l| l.contains("write lateness p50"))
        .unwrap_or_else(|| panic!("no write lateness in {text}"));
    let num = |key: &str| -> f64 {
        line.split(key)
            .nth(1)
            .and_then(|s| s.split(' ').next())
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("`{key}` in {line}"))
    };
    // The first count of the line (`2968 frames of 2 streams`; older builds: `8369 of 8369
    // frames`, `1100 frames of 3 units`).
    let frames = (line.split(' ').find_map(|w| w.parse().ok()))
        .unwrap_or_else(|| panic!("frames in {line}"));
    (frames, [num("p50 "), num("p99 "), num("max ")], text)
}

fn main() {
    let seconds: f64 = std::env::var("LIVE_LATENCY_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20.0);
    let tables = std::env::var("LIVE_LATENCY_TABLES").unwrap_or("latency,rig".into());
    if tables.contains("latency") {
        latency_table(seconds);
    }
    if tables.contains("rig") {
        rig_table(seconds);
    }
}

/// The pacer's write lateness of one IMU against the two-unit rig's, live and paced.
fn rig_table(seconds: f64) {
    let dir = tempfile::tempdir().unwrap();
    println!(
        "\nwrite lateness (the run's summary), {seconds} s per case, frames to UDP on loopback; \
         one IMU: LN-200 frames at 400 Hz; rig: that unit and a second at 100 Hz\n"
    );
    println!("| signal | clock | frames written | p50 (µs) | p99 (µs) | max (µs) |");
    println!("|---|---|---:|---:|---:|---:|");
    for live in [true, false] {
        for rig in [false, true] {
            let (frames, l, summary) = write_lateness(rig, live, seconds, dir.path());
            println!(
                "| {} | {} | {frames} | {:.0} | {:.0} | {:.0} |",
                if rig { "rig (2 units)" } else { "one IMU" },
                if live {
                    "live, real time (just in time)"
                } else {
                    "paced (survey scene)"
                },
                l[0],
                l[1],
                l[2]
            );
            eprintln!("{summary}");
        }
    }
}

/// State arrival → emission of the frame of that time, at 400 Hz and 1 kHz.
fn latency_table(seconds: f64) {
    println!(
        "state arrival → emission of the frame of that time, {seconds} s of 100 Hz states per case"
    );
    println!("| output | delay | states | p50 (ms) | p99 (ms) | max (ms) |");
    println!("|---|---|---|---|---|---|");
    for rate in [400, 1000] {
        for delay in [None, Some(0.0)] {
            let (lat, summary) = case(rate, delay, seconds);
            let used = summary
                .split("delay ")
                .nth(1)
                .and_then(|s| s.split(';').next())
                .unwrap_or("?");
            let name = match delay {
                None => format!("default ({used})"),
                Some(_) => format!("minimal ({used})"),
            };
            println!(
                "| {rate} Hz | {name} | {} | {:.2} | {:.2} | {:.2} |",
                lat.len(),
                percentile(&lat, 0.5) * 1e3,
                percentile(&lat, 0.99) * 1e3,
                lat.last().unwrap() * 1e3
            );
            eprintln!("{summary}");
        }
    }
}
