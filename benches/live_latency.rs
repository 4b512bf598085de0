//! Live input latency: `cargo bench --bench live_latency` (LIVE_LATENCY_SECS per case,
//! default 20).
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

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::process::{Command, Stdio};
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

/// One case: the latencies (s, sorted) and the run's summary line.
fn case(rate: u32, delay: Option<f64>, seconds: f64) -> (Vec<f64>, String) {
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let sink = UdpSocket::bind("127.0.0.1:0").unwrap();
    let sink_port = sink.local_addr().unwrap().port();
    let mut args = vec![
        "run".to_string(),
        "--motion".into(),
        format!("udp://127.0.0.1:{port}"),
        "--input-format".into(),
        "bin".into(),
        "--input-timeout".into(),
        "1".into(),
        "--rate".into(),
        rate.to_string(),
        "--udp".into(),
        format!("127.0.0.1:{sink_port}"),
    ];
    if let Some(d) = delay {
        args.extend(["--output-delay".into(), d.to_string()]);
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(&args)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    while !line.contains("following udp://") {
        line.clear();
        assert!(err.read_line(&mut line).unwrap() > 0, "the run starts");
    }
    let origin = Instant::now();
    let reader = thread::spawn(move || {
        sink.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
        let mut buf = [0u8; 2048];
        let mut at = Vec::new();
        while sink.recv(&mut buf).is_ok() {
            at.push(origin.elapsed().as_secs_f64());
        }
        at
    });
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

fn main() {
    let seconds: f64 = std::env::var("LIVE_LATENCY_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20.0);
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
