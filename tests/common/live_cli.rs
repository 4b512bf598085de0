//! Lockstep runs of the live test targets (tests/live.rs, tests/live_robust.rs,
//! tests/live_senders.rs): `imu-emu run --motion …` listening on a free loopback TCP port
//! and the connection to it, or on a pipe; the library's run on datagrams queued on a UDP
//! socket; the circle scene's states as lines.
// Each test target uses only some of these.
#![allow(dead_code)]

use std::io::Write;
use std::net::{TcpListener, TcpStream, UdpSocket};
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::thread;
use std::time::Duration;

use imu_emu::live::InputFormat;
use imu_emu::live::transport::Receiver;
use imu_emu::run::lockstep::{LiveSummary, Lockstep};
use imu_emu::sim::Simulation;
use imu_emu::source::AnyMotion;
use imu_emu::trajectory;

/// A free loopback TCP port.
pub fn free_tcp_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Spawns `imu-emu run --motion tcp://127.0.0.1:PORT --time-mode lockstep EXTRA --file OUT`
/// (stderr piped) on a free port.
pub fn lockstep_on_tcp(out: &Path, extra: &[&str]) -> (Child, u16) {
    let port = free_tcp_port();
    let child = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(["run", "--motion", &format!("tcp://127.0.0.1:{port}")])
        .args(["--time-mode", "lockstep"])
        .args(extra)
        .arg("--file")
        .arg(out)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    (child, port)
}

/// A connection to the emulator's port, once it listens (tried for up to 10 s; the
/// emulator binds after it starts).
pub fn connect(child: &mut Child, port: u16) -> TcpStream {
    for _ in 0..400 {
        if let Ok(c) = TcpStream::connect(("127.0.0.1", port)) {
            return c;
        }
        thread::sleep(Duration::from_millis(25));
    }
    let _ = child.kill();
    let _ = child.wait();
    panic!("the emulator does not listen on port {port}");
}

/// [`lockstep_on_tcp`] and a connection to it once it listens.
pub fn lockstep_over_tcp(out: &Path, extra: &[&str]) -> (Child, TcpStream) {
    let (mut child, port) = lockstep_on_tcp(out, extra);
    let c = connect(&mut child, port);
    (child, c)
}

/// The circle scene's motion: a constant turn, so that every state shapes the motion.
pub fn circle() -> AnyMotion {
    Simulation::builder()
        .scene("circle")
        .build()
        .unwrap()
        .motion()
        .clone()
}

/// The circle's states every 10 ms for `seconds`, as `imu-emu trajectory` writes them (a
/// comment, the header, then one line per state).
pub fn circle_lines(seconds: f64) -> Vec<String> {
    trajectory::sample_motion(
        &circle(),
        0.0,
        100.0,
        (seconds * 100.0) as u64,
        Some("circle"),
    )
    .lines()
    .map(str::to_string)
    .collect()
}

/// The lines, each with its line end.
pub fn join(lines: &[String]) -> String {
    lines.iter().map(|l| format!("{l}\n")).collect()
}

/// The flags of the runs [`lockstep_pipe`] makes: error-free records as CSV (every digit
/// shows).
pub const PIPE_RUN: [&str; 4] = ["--imu", "ideal", "--format", "csv"];

/// `imu-emu run --motion - --time-mode lockstep` with [`PIPE_RUN`] and `extra` on `text` on
/// a pipe: its exit status, stderr and output file (if one was left).
pub fn lockstep_pipe(text: &str, extra: &[&str]) -> (ExitStatus, String, Option<Vec<u8>>) {
    let dir = tempfile::TempDir::new().unwrap();
    let out = dir.path().join("out.csv");
    let mut child = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(["run", "--motion", "-", "--time-mode", "lockstep"])
        .args(PIPE_RUN)
        .args(extra)
        .arg("--file")
        .arg(&out)
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let text = text.to_string();
    let writer = thread::spawn(move || {
        let _ = stdin.write_all(text.as_bytes());
    });
    let done = child.wait_with_output().unwrap();
    writer.join().unwrap();
    let err = String::from_utf8_lossy(&done.stderr).into_owned();
    (done.status, err, std::fs::read(&out).ok())
}

/// A socket on a free loopback port with `datagrams` queued on it, its reads ending after
/// 0.5 s without one. Every datagram is queued before a run reads any (a 4 MiB buffer holds
/// them all): the run's end, at its socket's timeout, comes after the last one whatever the
/// load.
pub fn queued_udp<D: AsRef<[u8]>>(datagrams: &[D]) -> UdpSocket {
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    socket
        .set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    let addr = socket.local_addr().unwrap();
    imu_emu::realtime::udp::grow_receive_buffer(&socket);
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    for d in datagrams {
        s.send_to(d.as_ref(), addr).unwrap();
    }
    socket
}

/// The library's lockstep run of 2 s at 400 Hz on `rx` (states of `format`): its output
/// and summary.
pub fn lockstep_2s(rx: &mut Receiver, format: InputFormat) -> (Vec<u8>, LiveSummary) {
    let b = Simulation::builder().rate(400.0).duration(2.0);
    let mut out = Vec::new();
    let s = Lockstep::new(b, format)
        .unwrap()
        .run(rx, &mut out, None, |_| ())
        .unwrap();
    (out, s)
}
