//! Sync in and out, end to end over loopback: the time-mark side channel (UDP and file), the
//! pulse output through the pacer with a line that records its edges, and the phase lock of
//! the output to a software PPS sent as UDP edge messages. Bounds hold on a loaded 2-core
//! machine (the VM stalls for milliseconds); each is derived where it is asserted.

use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use imu_emu::realtime::FrameBlock;
use imu_emu::realtime::clock::monotonic_ns;
use imu_emu::realtime::lock::{PhaseLock, Schedule};
use imu_emu::realtime::pacer::{self, Clocking, Extras, Pacing, Routed, Status};
use imu_emu::realtime::pulse::{Line, Pulse, PulseSpec};
use imu_emu::realtime::sink::{Sink, SinkStats};
use imu_emu::realtime::timemark::{MARK_LEN, Mark};

#[path = "common/loopback.rs"]
mod loopback;
#[path = "common/realtime_run.rs"]
mod realtime_run;
use loopback::{median, receive, utc_now_ns};

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");

fn run(args: &[&str]) -> String {
    let out = Command::new(BIN)
        .arg("run")
        .args(args)
        .stdout(Stdio::null())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    err
}

/// Time marks over UDP and to a CSV file in one run with 400 µs ± 50 µs latency at 200 Hz:
/// one mark per frame the frame reader got, indices 0, 1, 2, … each once; the time of validity
/// on the records' axis is (k+1)·5 ms exactly (the nominal grid: no clock error configured);
/// the due instant is the ToV plus a latency within 350–450 µs; the emission is never before
/// it is due (the pacer does not write early), and each frame reaches its reader (the kernel's
/// stamp) after the emission the mark states, less how well the run read the clocks' offset
/// (reported). A mark
/// carrying the write instant as the ToV, or a pacer ignoring the latency, fails here. The
/// file holds the same marks as the datagrams.
#[test]
fn time_marks_over_udp_and_file() {
    let dir = tempfile::tempdir().unwrap();
    let imu = loopback::timed_ln200(
        dir.path(),
        "latency = \"400 us\"\nlatency_spread = \"50 us\"\n",
    );
    let csv = dir.path().join("marks.csv");
    let (frames_to, frames) = receive();
    let (marks_to, marks) = receive();
    let err = run(&[
        "--imu",
        imu.to_str().unwrap(),
        "--rate",
        "200",
        "--duration",
        "2",
        // One mark per frame sent: none skipped as late.
        "--max-behind-ms",
        "60000",
        "--udp",
        &frames_to,
        "--time-marks",
        &format!("udp://{marks_to}"),
        "--time-marks",
        csv.to_str().unwrap(),
    ]);
    let frames = frames.join().unwrap();
    let marks: Vec<Mark> = (marks.join().unwrap().iter())
        .map(|(_, b)| {
            assert_eq!(b.len(), MARK_LEN);
            Mark::from_bytes(b).unwrap()
        })
        .collect();
    assert_eq!(marks.len(), 400, "{err}");
    assert_eq!(frames.len(), 400, "{err}");
    let u = realtime_run::clock_reading_ns(&err) as i64;
    for (k, m) in marks.iter().enumerate() {
        assert_eq!(m.index, k as u64);
        assert_eq!(m.tov_sim_ns, (k as i64 + 1) * 5_000_000);
        let lat = m.due_utc_ns - m.tov_utc_ns;
        assert!(
            (349_000..=451_000).contains(&lat),
            "frame {k}: latency {lat} ns"
        );
        assert!(m.emit_utc_ns >= m.due_utc_ns, "frame {k} written early");
        let arrival = frames[k].0 as i64;
        assert!(
            arrival >= m.emit_utc_ns - u,
            "frame {k} arrived {} ns before its emission",
            m.emit_utc_ns - arrival
        );
    }
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(imu_emu::realtime::timemark::CSV_HEADER));
    let from_file: Vec<String> = lines.map(String::from).collect();
    let from_udp: Vec<String> = marks.iter().map(Mark::to_csv).collect();
    assert_eq!(from_file, from_udp);
}

/// A line that records when it went high and low (CLOCK_MONOTONIC ns).
#[derive(Clone, Default)]
struct Recorder(Arc<Mutex<Vec<(i128, bool)>>>);

impl Line for Recorder {
    fn set(&mut self, high: bool) -> std::io::Result<()> {
        self.0.lock().unwrap().push((monotonic_ns(), high));
        Ok(())
    }
}

/// A sink that takes everything.
struct Null(SinkStats);

impl Sink for Null {
    fn label(&self) -> &str {
        "null"
    }
    fn write(&mut self, b: &[u8], ends: &[usize]) -> std::io::Result<()> {
        self.0.sent += ends.len() as u64;
        self.0.bytes += b.len() as u64;
        Ok(())
    }
    fn stats(&self) -> SinkStats {
        self.0
    }
}

/// Runs the pacer over `n` frames at 200 Hz whose times of validity are `tov(k)` and emission
/// 2 ms later, with a ToV pulse `spec` (and, given `pps_at`, a phase lock fed one PPS edge at
/// that offset from the start); returns the recorded edges, the frames' nominal ToVs as
/// CLOCK_MONOTONIC instants and the instant the pacer was started.
fn pulsed_locked(
    spec: &str,
    n: usize,
    tov: impl Fn(usize) -> i64,
    pps_at: Option<i128>,
) -> (Vec<(i128, bool)>, Vec<i128>, Status, i128) {
    let rec = Recorder::default();
    let spec: PulseSpec = spec.parse().unwrap();
    let hook = Pulse::new(spec, Box::new(rec.clone())).unwrap();
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let (rtx, _rrx) = tokio::sync::mpsc::channel(4);
    let start = monotonic_ns() + 50_000_000;
    let tovs: Vec<i64> = (0..n).map(&tov).collect();
    tx.try_send(FrameBlock {
        first: 0,
        streams: vec![(vec![0; n], (1..=n).collect())],
        emit_ns: tovs.iter().map(|t| t + 2_000_000).collect(),
        tov_ns: tovs.clone(),
        records: Vec::new(),
        ..FrameBlock::default()
    })
    .unwrap();
    drop(tx);
    let c = Clocking::new(200.0, Some(start), false).unwrap();
    let lock = pps_at.map(|at| {
        let (etx, erx) = std::sync::mpsc::channel();
        etx.send(start + at).unwrap();
        (erx, PhaseLock::new(1_000_000_000))
    });
    let called = monotonic_ns();
    let st = pacer::run_with(
        rx,
        rtx,
        vec![Routed::main(Box::new(Null(SinkStats::default())))],
        Pacing::Paced(c),
        Arc::new(AtomicBool::new(false)),
        Arc::new(Mutex::new(Status::default())),
        Extras {
            hooks: vec![Box::new(hook)],
            lock,
        },
    )
    .unwrap();
    let edges = rec.0.lock().unwrap().clone();
    let nominal = tovs.iter().map(|t| start + *t as i128).collect();
    (edges, nominal, st, called)
}

/// [`pulsed_locked`] without a lock.
fn pulsed(
    spec: &str,
    n: usize,
    tov: impl Fn(usize) -> i64,
) -> (Vec<(i128, bool)>, Vec<i128>, Status) {
    let (e, t, st, _) = pulsed_locked(spec, n, tov, None);
    (e, t, st)
}

/// A PPS edge 3 ms before the run's first whole second, taken before the first frame: the
/// lock slews the schedule (rate 1 − 1.2·3 ms/1 s, src/realtime/lock.rs), and the ToV pulses
/// of frames already queued follow it. Each rising edge is compared with the slewed schedule
/// as the test computes it, taking the edge when the pacer was called rather than at the
/// pacer's first wake-up, which is later but not after the first pulse: that shifts the
/// schedule by at most (1 − rate) times the time from the call to the first pulse, which is
/// what each pulse may come early by; none does. (How late they come is the wake-up delay, a
/// timing figure: printed.)
#[test]
fn pulses_follow_a_slewed_schedule() {
    let n = 200;
    let pps_at = 1_000_000_000 - 3_000_000;
    let (edges, nominal, st, called) =
        pulsed_locked("rts:tov", n, |k| (k as i64 + 1) * 5_000_000, Some(pps_at));
    assert_eq!(st.lock.map(|l| l.edges), Some(1));
    // The nominal ToVs are start + (k+1)·5 ms.
    let start = nominal[0] - 5_000_000;
    let mut sched = Schedule::new(start);
    PhaseLock::new(1_000_000_000).edge(&mut sched, start + pps_at, called);
    let rises: Vec<i128> = edges.iter().filter(|e| e.1).map(|e| e.0).collect();
    assert_eq!(rises.len(), n);
    let slew = 1.2 * 3e-3;
    let early = (slew * (rises[0] - called) as f64).ceil() as i128 + 1;
    let mut late = Vec::new();
    for (k, r) in rises.iter().enumerate() {
        let want = sched.at((k as i128 + 1) * 5_000_000);
        assert!(
            *r >= want - early,
            "pulse {k} {} ns early (at most {early})",
            want - r
        );
        late.push((r - want) as f64 / 1e3);
    }
    eprintln!(
        "pulses on a slewed schedule: median {:.1} µs late",
        median(late)
    );
}

/// A ToV pulse 1 ms after the ToV: one rising edge per frame, each at ToV + 1 ms
/// or later (the thread sleeps to an absolute instant and never fires early; a pulse at the
/// ToV would be 1 ms early); each falls at least the 300 µs width later. Irregular ToVs (a
/// ±1 ms zig-zag) are followed, not the nominal grid (every other pulse would be 1 ms early).
/// How late they come is the wake-up delay, a timing figure: printed.
#[test]
fn tov_pulse_edges_follow_validity() {
    let n = 200;
    let (edges, tovs, st) = pulsed("rts:tov:1ms:300us", n, |k| {
        (k as i64 + 1) * 5_000_000 + if k % 2 == 0 { 1_000_000 } else { -1_000_000 }
    });
    assert_eq!(st.frames, n as u64);
    let rises: Vec<i128> = edges.iter().filter(|e| e.1).map(|e| e.0).collect();
    // The recorder sees every edge since the hook was made: high, low, per pulse.
    assert_eq!(rises.len(), n);
    assert_eq!(edges.len(), 2 * n);
    let mut late = Vec::new();
    for (k, w) in edges.chunks(2).enumerate() {
        assert!(w[0].1 && !w[1].1, "pulse {k} edges out of order");
        let target = tovs[k] + 1_000_000;
        assert!(w[0].0 >= target, "pulse {k} {} ns early", target - w[0].0);
        assert!(w[1].0 - w[0].0 >= 300_000, "pulse {k} narrower than 300 µs");
        late.push((w[0].0 - target) as f64 / 1e3);
    }
    eprintln!(
        "ToV pulse lateness: median {:.1} µs; pacer {}",
        median(late),
        st.lateness.summary()
    );
}

/// Frames on trigger edges ([`Clocking::on_edges`]) are due at their edge, which has passed by
/// the time the frame exists: here the edges lie 1–1.2 s before the blocks reach the pacer
/// (far past the default 100 ms catch-up limit). Every frame is written, none skipped as too
/// late; the write lateness counts from each block's arrival, which comes after the pacer is
/// called, so it is at most how long the pacer ran; the edge-to-frame time, ≥ 1 s, is reported
/// apart. A pacer counting lateness from the edge would report ≥ 1 s and skip all.
#[test]
fn frames_on_edges_are_not_late() {
    let n = 20;
    let (tx, rx) = tokio::sync::mpsc::channel(n);
    let (rtx, _rrx) = tokio::sync::mpsc::channel(n);
    let start = monotonic_ns() - 1_200_000_000;
    for k in 0..n {
        // Irregular edges 7–13 ms apart, in blocks of one frame as a triggered producer sends.
        let at = (k as i64 + 1) * 10_000_000 + if k % 2 == 0 { 3_000_000 } else { -3_000_000 };
        tx.try_send(FrameBlock {
            first: k as u64,
            streams: vec![(vec![0; 1], vec![1])],
            emit_ns: vec![at],
            tov_ns: vec![at],
            records: Vec::new(),
            ..FrameBlock::default()
        })
        .unwrap();
    }
    drop(tx);
    let c = Clocking::new(100.0, Some(start), false)
        .unwrap()
        .with_edges();
    let called = monotonic_ns();
    let st = pacer::run(
        rx,
        rtx,
        vec![Routed::main(Box::new(Null(SinkStats::default())))],
        Pacing::Paced(c),
        Arc::new(AtomicBool::new(false)),
        Arc::new(Mutex::new(Status::default())),
    )
    .unwrap();
    let ran = monotonic_ns() - called;
    assert_eq!((st.frames, st.skipped), (n as u64, 0));
    assert_eq!(st.lateness.count(), n as u64);
    assert!(
        st.lateness.max_us() <= ran as f64 / 1e3,
        "{} (ran {ran} ns)",
        st.lateness.summary()
    );
    let e = st.edge_latency.expect("edge latency");
    assert_eq!(e.count(), n as u64);
    // The histogram's last bin holds everything over 100 ms: every frame is there.
    assert_eq!(e.quantile_us(0.0), Some(100_000.0), "{}", e.summary());
    assert!(e.max_us() >= 1_000_000.0, "{}", e.summary());
}

/// A PPS pulse: one edge per whole second of the records' axis (here frames at 200 Hz over
/// 3 s: the ToVs at 1, 2 and 3 s), none for the other frames.
#[test]
fn pps_pulse_marks_whole_seconds() {
    let (edges, tovs, _) = pulsed("dtr:pps", 600, |k| (k as i64 + 1) * 5_000_000);
    let rises: Vec<i128> = edges.iter().filter(|e| e.1).map(|e| e.0).collect();
    assert_eq!(rises.len(), 3, "{rises:?}");
    for (s, r) in rises.iter().enumerate() {
        let target = tovs[200 * (s + 1) - 1];
        // Never early, and within the second it marks (not the next one's pulse).
        assert!(
            *r >= target && *r - target < 1_000_000_000,
            "second {s}: {}",
            r - target
        );
    }
}

/// A software PPS 3 ms ahead of the run's whole seconds, sent as UDP edge messages (each
/// carrying its edge's UTC instant) pulls the output's phase: frames due in the first second
/// (before any edge) arrive at their nominal instants plus the pacer's delay d₀; after 10
/// edges they arrive 3 ms earlier, plus the same kind of delay d₁. The medians' difference is
/// 3 ms within 0.3 ms (the loop leaves 11·0.4¹⁰·3 ms ≈ 4 µs at 11 s, src/realtime/lock.rs; the
/// medians of the wake-up delay, ~0.1 ms each, cancel to a few tens of µs). No frame is lost or sent twice: the
/// reader gets every index exactly once (time marks) and as many frames. The summary reports
/// the phase error and the frequency offset. Each edge carries its own instant, so the pacer's
/// wake-up delay does not enter the measured phase; it only delays when a correction starts
/// (by up to a frame interval, 5 ms: 0.5 % of that second's correction). With no frequency
/// offset applied, the recurrence of src/realtime/lock.rs leaves ≈ 0.1 ppm in the integral and
/// under 1 µs of phase at the 13th edge; 0.1 ms and 5 ppm leave room for a stalled VM, while
/// a loop that did not lock shows 3 ms, and one with its sign reversed diverges.
#[test]
fn software_pps_pulls_the_phase() {
    let start = (utc_now_ns() / 1_000_000_000 + 3) * 1_000_000_000;
    let start_s = start / 1_000_000_000;
    let iso = {
        let out = Command::new("date")
            .args(["-u", "-d", &format!("@{start_s}"), "+%Y-%m-%dT%H:%M:%SZ"])
            .output()
            .unwrap();
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    };
    let pps_port = {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        s.local_addr().unwrap().port()
    };
    let pps_to = format!("127.0.0.1:{pps_port}");
    let secs = 14;
    let sender = {
        let to = pps_to.clone();
        std::thread::spawn(move || {
            let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
            for m in 1..secs {
                let edge = start + m as i128 * 1_000_000_000 - 3_000_000;
                while utc_now_ns() < edge {
                    std::thread::sleep(Duration::from_micros(200));
                }
                tx.send_to(&(edge as i64).to_le_bytes(), &to).unwrap();
            }
        })
    };
    let (frames_to, frames) = receive();
    let (marks_to, marks) = receive();
    let err = run(&[
        "--rate",
        "200",
        "--duration",
        &secs.to_string(),
        "--start-at",
        &iso,
        "--max-behind-ms",
        "60000",
        "--udp",
        &frames_to,
        "--time-marks",
        &format!("udp://{marks_to}"),
        "--pps-in",
        &format!("udp://{pps_to}"),
    ]);
    sender.join().unwrap();
    let frames = frames.join().unwrap();
    let marks: Vec<Mark> = (marks.join().unwrap().iter())
        .map(|(_, b)| Mark::from_bytes(b).unwrap())
        .collect();
    let n = secs * 200;
    assert_eq!(frames.len(), n, "{err}");
    assert_eq!(marks.len(), n, "{err}");
    for (k, m) in marks.iter().enumerate() {
        assert_eq!(m.index, k as u64, "{err}");
    }
    // Each frame's deadline as the pacer slewed it (its mark's due instant) minus the nominal
    // instant, (k+1)·5 ms after the start (ns), and the kernel's arrival stamp of the frame,
    // never before its deadline (less how well the run read the clocks' offset).
    let u = realtime_run::clock_reading_ns(&err);
    let nominal = |k: usize| start + (k as i128 + 1) * 5_000_000;
    let shift = |k: usize| marks[k].due_utc_ns as i128 - nominal(k);
    for k in 0..n {
        assert!(
            frames[k].0 >= marks[k].due_utc_ns as i128 - u,
            "frame {k} early: {err}"
        );
    }
    let first = (0..190).map(shift).map(i128::abs).max().unwrap();
    let after = (11 * 200..n)
        .map(|k| (shift(k) + 3_000_000).abs())
        .max()
        .unwrap();
    eprintln!(
        "before the first edge: {first} ns off; after 11 edges within {after} ns of −3 ms; {err}"
    );
    // Before any edge the deadlines are the nominal grid: the start instant and the marks go
    // through the same reading of the clocks' offset (1 ns for rounding). After 11 edges the
    // loop leaves 11·0.4¹⁰·3 ms ≈ 4.4 µs of the 3 ms (src/realtime/lock.rs); an edge the pacer
    // takes δ late adds up to 3.6e-3·δ, which the later edges divide by 0.4 each (a 100 ms
    // stall at the tenth edge: 0.9 µs): 20 µs holds them all.
    assert!(first <= 1, "{first} ns: {err}");
    assert!(after <= 20_000, "{after} ns: {err}");
    let line = err.lines().find(|l| l.contains("PPS lock")).unwrap();
    assert!(
        line.contains("phase error") && line.contains("frequency offset"),
        "{line}"
    );
    let num = |key: &str| -> f64 {
        let s = &line[line.find(key).unwrap() + key.len()..];
        s.trim().split(' ').next().unwrap().parse().unwrap()
    };
    assert!(num("phase error").abs() < 0.1, "{line}");
    assert!(num("frequency offset").abs() < 5.0, "{line}");
}

/// `run --trigger udp://…`: edges sent as UDP edge messages at irregular instants, each
/// carrying its own CLOCK_REALTIME instant; one frame and one time mark per edge after the
/// first, whose time of validity after t₀ is the edge's offset from the first edge, and no
/// frame leaves before its edge. Every edge goes through the emulator's one reading of the
/// offset between CLOCK_REALTIME and CLOCK_MONOTONIC, so their differences are exact: within
/// 1 ns (the ToV's rounding to whole ns).
#[test]
fn external_trigger_one_frame_per_edge() {
    use std::io::{BufRead, BufReader};
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("marks.csv");
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap();
    let (frames_to, frames) = receive();
    let mut child = Command::new(BIN)
        .args([
            "run",
            "--scene",
            "static",
            "--rate",
            "100",
            "--duration",
            "0.05",
        ])
        .args(["--trigger", &format!("udp://{port}"), "--udp", &frames_to])
        .args(["--time-marks", csv.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    while !line.contains("waiting for the first trigger edge") {
        line.clear();
        assert!(err.read_line(&mut line).unwrap() > 0, "no wait message");
    }
    // Offsets (ms) of the 6 edges: irregular, 5 sample intervals = --duration 0.05 at 100 Hz.
    let at_ms = [0.0, 7.0, 19.5, 23.0, 61.0, 70.0];
    let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
    let t0 = utc_now_ns() + 20_000_000;
    for ms in at_ms {
        let edge = t0 + (ms * 1e6) as i128;
        while utc_now_ns() < edge {
            std::thread::sleep(Duration::from_micros(200));
        }
        tx.send_to(&(edge as i64).to_le_bytes(), port).unwrap();
    }
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    assert!(child.wait().unwrap().success(), "{rest}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let marks: Vec<Vec<i64>> = (text.lines().skip(1))
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(marks.len(), 5, "{rest}");
    assert_eq!(frames.join().unwrap().len(), 5, "{rest}");
    for (k, m) in marks.iter().enumerate() {
        assert_eq!(m[0], k as i64);
        let want = (at_ms[k + 1] * 1e6) as i64;
        assert!(
            (m[1] - want).abs() <= 1,
            "mark {k}: tov {} ns, edge {want} ns",
            m[1]
        );
        assert!(m[4] >= m[2], "frame {k} written before its edge");
    }
    // The summary: nothing skipped as too late, and the edge-to-frame time reported apart
    // from the write lateness, which counts from when each frame existed (so its p99 cannot
    // exceed the edge-to-frame p99).
    assert!(rest.contains(", 0 skipped (too late)"), "{rest}");
    let p99 = |after: &str| -> f64 {
        let tail = &rest[rest
            .find(after)
            .unwrap_or_else(|| panic!("{after}: {rest}"))..];
        let at = tail.find("p99 ").unwrap() + 4;
        tail[at..].split(' ').next().unwrap().parse().unwrap()
    };
    assert!(
        p99("write lateness") <= p99("trigger edge to frame"),
        "{rest}"
    );
}
