//! The TCP sinks end to end: `imu-emu run --tcp HOST:PORT` (the emulator connects to a
//! consumer) and `--tcp-listen ADDR:PORT` (the consumer connects to the emulator) over
//! loopback. A consumer connected for the whole run gets `generate`'s bytes; one that connects
//! late, leaves and comes back gets, on each connection, whole frames that are a contiguous
//! stretch of `generate`'s, and the summary's counts add up to what it could and could not
//! have received. A UDP sink on the same stream tells the test how far the run has got, so
//! "late" and "away" are facts, not sleeps.

use std::io::{BufRead, BufReader, Read};
use std::net::{TcpListener, TcpStream, UdpSocket};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");
/// 36-byte frames.
const PROTOCOL: &str = "kvh1750";
const LEN: usize = 36;

/// The run's settings shared with the reference.
fn common(rate: &str, duration: &str) -> Vec<String> {
    ["--rate", rate, "--duration", duration, "--seed", "11"]
        .map(String::from)
        .to_vec()
}

/// `generate`'s frames for `common`: the reference bytes.
fn reference(common: &[String]) -> Vec<u8> {
    let out = Command::new(BIN)
        .args(["generate", "--imu", "ln200", "--format", PROTOCOL])
        .args(common)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(out.stdout.len() % LEN, 0);
    out.stdout
}

/// `run` with `args`, its stderr lines sent to the returned channel as they come.
fn spawn_run(common: &[String], args: &[&str]) -> (Child, mpsc::Receiver<String>) {
    let mut child = Command::new(BIN)
        .args(["run", "--imu", "ln200", "--protocol", PROTOCOL])
        .args(common)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (tx, rx) = mpsc::channel();
    let err = child.stderr.take().unwrap();
    std::thread::spawn(move || {
        for l in BufReader::new(err).lines().map_while(Result::ok) {
            let _ = tx.send(l);
        }
    });
    (child, rx)
}

/// Waits for the run's end; its whole stderr.
fn finish(mut child: Child, lines: mpsc::Receiver<String>, seen: &[String]) -> String {
    let status = child.wait().unwrap();
    let mut err = seen.join("\n");
    for l in lines {
        err += "\n";
        err += &l;
    }
    assert!(status.success(), "run failed: {err}");
    err
}

/// The unit's frames skipped as too late, from the summary.
fn unit_skipped(summary: &str) -> u64 {
    let line = (summary.lines())
        .find(|l| l.trim_start().starts_with("unit imu:"))
        .unwrap_or_else(|| panic!("no unit line in {summary}"));
    let before = line.split(" skipped (too late)").next().unwrap();
    before.rsplit([',', ' ']).next().unwrap().parse().unwrap()
}

/// The sink's counts in the summary: (sent, dropped (slow consumer), dropped (no reader)).
fn counts(summary: &str, label: &str) -> (u64, u64, u64) {
    let line = (summary.lines())
        .find(|l| l.trim_start().starts_with(label))
        .unwrap_or_else(|| panic!("no `{label}` line in {summary}"));
    let n = |what: &str| -> u64 {
        let before = line.split(what).next().unwrap();
        let num = before.rsplit([',', ':']).next().unwrap().trim();
        num.parse().unwrap_or_else(|_| panic!("`{what}` in {line}"))
    };
    (
        n(" sent"),
        n(" dropped (slow consumer)"),
        n(" dropped (no reader)"),
    )
}

/// Frames the UDP sink has delivered so far, counted on a thread of its own.
fn udp_progress() -> (String, Arc<AtomicU64>) {
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    imu_emu::realtime::udp::grow_receive_buffer(&rx);
    let dest = rx.local_addr().unwrap().to_string();
    let n = Arc::new(AtomicU64::new(0));
    let m = n.clone();
    std::thread::spawn(move || {
        let mut buf = [0u8; 2048];
        while rx.recv(&mut buf).is_ok() {
            m.fetch_add(1, Ordering::Relaxed);
        }
    });
    (dest, n)
}

/// Waits until `n` reaches `k` (the run has written at least k frames to its UDP sink).
fn wait_until(n: &AtomicU64, k: u64) {
    let t = Instant::now();
    while n.load(Ordering::Relaxed) < k {
        assert!(t.elapsed() < Duration::from_secs(30), "the run stalled");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Where `got` (whole frames) sits in `reference`: the index of its first frame. It must be
/// a contiguous stretch of the reference's frames, starting on a frame boundary.
fn stretch(got: &[u8], reference: &[u8]) -> usize {
    assert!(!got.is_empty(), "nothing received");
    assert_eq!(got.len() % LEN, 0);
    (0..reference.len() / LEN)
        .find(|&k| reference[k * LEN..].starts_with(got))
        .expect("the bytes received are not a contiguous stretch of generate's frames")
}

/// Reads `frames` whole frames from `s` (at least), then drops it mid-run; the whole frames.
fn read_some(mut s: TcpStream, frames: usize) -> Vec<u8> {
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut got = vec![0u8; frames * LEN];
    s.read_exact(&mut got).expect("frames within 20 s");
    got
}

/// Reads `s` to the end of the run.
fn read_to_end(mut s: TcpStream) -> Vec<u8> {
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut got = Vec::new();
    s.read_to_end(&mut got).expect("the run's end within 30 s");
    got
}

/// Accepts one connection within 20 s.
fn accept(l: &TcpListener) -> TcpStream {
    l.set_nonblocking(true).unwrap();
    let t = Instant::now();
    loop {
        match l.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false).unwrap();
                return s;
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                assert!(t.elapsed() < Duration::from_secs(20), "no connection");
                std::thread::sleep(Duration::from_millis(5));
            }
            Err(e) => panic!("accept: {e}"),
        }
    }
}

/// A consumer listening from the start gets exactly `generate`'s bytes, and the summary
/// says every frame was sent.
#[test]
fn tcp_consumer_gets_generate_bytes() {
    let c = common("400", "1");
    let reference = reference(&c);
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let dest = l.local_addr().unwrap().to_string();
    let (child, lines) = spawn_run(
        &c,
        &["--speed", "4", "--max-behind-ms", "60000", "--tcp", &dest],
    );
    let got = read_to_end(accept(&l));
    let err = finish(child, lines, &[]);
    assert_eq!(got, reference);
    let n = (reference.len() / LEN) as u64;
    assert_eq!(counts(&err, &format!("tcp {dest}")), (n, 0, 0), "{err}");
}

/// The two ways a consumer meets the emulator.
#[derive(Clone, Copy)]
enum Kind {
    /// `--tcp`: the consumer listens, the emulator connects.
    Connect,
    /// `--tcp-listen`: the emulator listens, the consumer connects.
    Listen,
}

/// A consumer that connects after the run has started, reads a while, leaves, stays away
/// while 200 more frames go out, and comes back to the end: each connection carries whole
/// frames, a contiguous stretch of `generate`'s (the second one to the last frame), and
/// sent + dropped + no reader = every frame; the frames before the first connection count
/// as no reader, and those sent but never read lie in the time away.
fn late_leaving_consumer(kind: Kind) {
    let c = common("200", "8");
    let reference = reference(&c);
    let total = reference.len() / LEN;
    let (udp, progress) = udp_progress();
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dest = format!("127.0.0.1:{port}");
    let (flag, label) = match kind {
        Kind::Connect => ("--tcp", format!("tcp {dest}")),
        Kind::Listen => ("--tcp-listen", format!("tcp-listen {dest}")),
    };
    let (child, lines) = spawn_run(&c, &["--udp", &udp, flag, &dest]);
    let connect = || match kind {
        Kind::Connect => {
            let l = TcpListener::bind(("127.0.0.1", port)).unwrap();
            accept(&l)
            // The listener closes here: while the consumer is away the emulator's
            // connection attempts are refused.
        }
        Kind::Listen => TcpStream::connect(("127.0.0.1", port)).unwrap(),
    };
    wait_until(&progress, 100);
    let first = read_some(connect(), 100);
    let away = progress.load(Ordering::Relaxed);
    wait_until(&progress, away + 200);
    let second = read_to_end(connect());
    let err = finish(child, lines, &[]);

    let (a1, a2) = (stretch(&first, &reference), stretch(&second, &reference));
    let (b1, b2) = (a1 + first.len() / LEN, a2 + second.len() / LEN);
    // The UDP sink had delivered frame 100 before the consumer came, and the TCP sink is at
    // most one write behind it: one wake-up's frames, at most --max-behind-ms (100 ms, 20
    // frames at 200 Hz) of catch-up plus the frame due.
    assert!(
        a1 >= 100 - 21,
        "the first connection came after frame 100: {a1}"
    );
    assert!(a2 > b1, "the consumer was away");
    // Frames more than --max-behind-ms late (a stalled machine) are skipped for every sink
    // and counted once for the unit.
    let skipped = unit_skipped(&err);
    assert!(
        b2 <= total && b2 as u64 + skipped >= total as u64,
        "the second connection runs to the last frame: {b2} of {total}; {err}"
    );
    let (sent, dropped, no_reader) = counts(&err, &label);
    let read = (first.len() + second.len()) as u64 / LEN as u64;
    assert_eq!(sent + dropped + no_reader + skipped, total as u64, "{err}");
    assert!(no_reader >= a1 as u64, "frames before any consumer: {err}");
    assert!(read <= sent, "{err}");
    assert!(
        sent - read <= (a2 - b1) as u64,
        "frames sent and not read must lie in the time away: {err}"
    );
}

#[test]
fn tcp_consumer_connects_late_leaves_and_returns() {
    late_leaving_consumer(Kind::Connect);
}

#[test]
fn tcp_listen_client_connects_late_leaves_and_returns() {
    late_leaving_consumer(Kind::Listen);
}

/// A listening sink on port 0 says which port the system gave it; addresses that cannot
/// work are refused before the run starts, naming the flag.
#[test]
fn tcp_addresses_checked() {
    let c = common("100", "2");
    let (child, lines) = spawn_run(&c, &["--tcp-listen", "127.0.0.1:0"]);
    let mut seen = Vec::new();
    let port = loop {
        let l = lines.recv_timeout(Duration::from_secs(20)).expect("a note");
        seen.push(l.clone());
        if let Some(rest) = l.split("on tcp 127.0.0.1:").nth(1) {
            break rest.split(' ').next().unwrap().parse::<u16>().unwrap();
        }
    };
    assert_ne!(port, 0);
    let got = read_to_end(TcpStream::connect(("127.0.0.1", port)).unwrap());
    finish(child, lines, &seen);
    assert_eq!(got.len() % LEN, 0, "whole frames");
    for (args, says) in [
        (["--tcp", "127.0.0.1:0"], "--tcp 127.0.0.1:0"),
        (["--tcp", "9001"], "expected tcp:HOST:PORT"),
        (
            ["--tcp-listen", "nowhere:9001"],
            "--tcp-listen nowhere:9001",
        ),
    ] {
        let out = Command::new(BIN)
            .args(["run", "--duration", "1"])
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}
