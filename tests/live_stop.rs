//! A signal before the first live state stops the run as a signal should (issue 23, item 6):
//! exit 128 + its number (143 for SIGTERM, 130 for SIGINT) with "interrupted by", never
//! "the input ended after 0 usable states" (exit 1), and never a run that keeps waiting for
//! a sender. Every input that waits: a UDP socket, a TCP listener before a sender connects,
//! a silent pipe on stdin; in real time and in lockstep.

use std::io::{BufRead, BufReader};
use std::net::{TcpListener, UdpSocket};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

fn free_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Starts `run --motion SOURCE` with `mode`; its stderr lines come on the channel.
fn start(source: &str, mode: &str, dir: &std::path::Path) -> (Child, mpsc::Receiver<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(dir)
        .args(["run", "--motion", source, "--time-mode", mode])
        .args([
            "--input-format",
            "bin",
            "--imu",
            "ideal",
            "--file",
            "out.bin",
        ])
        // A pipe that stays open and silent: stdin waits for a sender that never writes.
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let err = child.stderr.take().unwrap();
    let (tx, rx) = mpsc::channel();
    thread::spawn(move || {
        for l in BufReader::new(err).lines().map_while(Result::ok) {
            if tx.send(l).is_err() {
                break;
            }
        }
    });
    (child, rx)
}

/// Sends `sig` once `ready` says the run waits for its input, then expects it to end with
/// `code` (a hang guard of 60 s: how soon is a timing figure), having said it was
/// interrupted; nothing left behind.
fn stops(
    (mut child, lines): (Child, mpsc::Receiver<String>),
    ready: impl Fn(&mpsc::Receiver<String>) -> bool,
    sig: Signal,
    code: i32,
    dir: &std::path::Path,
) {
    let give_up = Instant::now() + Duration::from_secs(60);
    while !ready(&lines) {
        assert!(
            Instant::now() < give_up,
            "the run never waited for its input"
        );
        thread::sleep(Duration::from_millis(20));
    }
    // The run is waiting for a state that never comes: give it time to be blocked there.
    thread::sleep(Duration::from_millis(300));
    kill(Pid::from_raw(child.id() as i32), sig).unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > deadline {
            child.kill().unwrap();
            panic!("{sig:?} did not stop a run waiting for its input");
        }
        thread::sleep(Duration::from_millis(20));
    };
    let err: Vec<String> = lines.iter().collect();
    let err = err.join("\n");
    assert_eq!(status.code(), Some(code), "{sig:?}: {err}");
    assert!(err.contains("interrupted by"), "{err}");
    assert!(!err.contains("usable states"), "{err}");
    assert!(
        !dir.join("out.bin").exists(),
        "no output of a run that never began"
    );
}

/// A line saying the run follows its input has been printed.
fn following(lines: &mpsc::Receiver<String>) -> bool {
    lines.try_iter().any(|l| l.contains("following"))
}

#[test]
fn udp_input_waiting_for_its_first_state() {
    for (mode, sig, code) in [
        ("realtime", Signal::SIGTERM, 143),
        ("lockstep", Signal::SIGINT, 130),
    ] {
        let dir = tempfile::TempDir::new().unwrap();
        let src = format!("udp://127.0.0.1:{}", free_port());
        stops(
            start(&src, mode, dir.path()),
            following,
            sig,
            code,
            dir.path(),
        );
    }
}

#[test]
fn tcp_listener_before_a_sender_connects() {
    for (mode, sig, code) in [
        ("realtime", Signal::SIGINT, 130),
        ("lockstep", Signal::SIGTERM, 143),
    ] {
        let dir = tempfile::TempDir::new().unwrap();
        let port = free_port();
        let src = format!("tcp://127.0.0.1:{port}");
        // Listening: the port cannot be bound any more (a connection would be taken).
        let listening =
            |_: &mpsc::Receiver<String>| TcpListener::bind(("127.0.0.1", port)).is_err();
        stops(
            start(&src, mode, dir.path()),
            listening,
            sig,
            code,
            dir.path(),
        );
    }
}

#[test]
fn silent_pipe_on_stdin() {
    for (mode, sig, code) in [
        ("lockstep", Signal::SIGTERM, 143),
        ("realtime", Signal::SIGINT, 130),
    ] {
        let dir = tempfile::TempDir::new().unwrap();
        stops(
            start("-", mode, dir.path()),
            following,
            sig,
            code,
            dir.path(),
        );
    }
}
