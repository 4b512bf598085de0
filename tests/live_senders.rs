//! Live input as real senders send it (issue 38): a CSV header with a UTF-8 byte-order mark
//! and its columns in another order, CSV states lost on UDP, a TCP readiness probe and a
//! sender that reconnects. Real parts: the binary, a pipe, UDP and TCP on loopback.

use std::io::Write;
use std::net::TcpStream;
use std::process::{Child, ExitStatus};
use std::thread;
use std::time::{Duration, Instant};

use imu_emu::live::InputFormat;
use imu_emu::live::transport::Receiver;
use imu_emu::run::lockstep::LiveSummary;
use imu_emu::trajectory;

#[path = "common/live_cli.rs"]
mod live_cli;

use live_cli::{
    PIPE_RUN, circle_lines, join, lockstep_2s, lockstep_on_tcp, lockstep_pipe, queued_udp,
};

const BOM: &str = "\u{feff}";

/// `lines` (a comment, the header, the states) with the header and each state's fields in
/// the order `t,lon,lat,h,…`.
fn lon_first(lines: &[String]) -> Vec<String> {
    lines
        .iter()
        .map(|l| {
            if l.starts_with('#') {
                return l.clone();
            }
            let mut f: Vec<&str> = l.split(',').collect();
            f.swap(1, 2);
            f.join(",")
        })
        .collect()
}

/// The library's lockstep run of 2 s at 400 Hz on `datagrams` of CSV text sent over UDP
/// loopback; its output and summary.
fn csv_over_udp(datagrams: &[String]) -> (Vec<u8>, LiveSummary) {
    let mut rx = Receiver::from_socket(queued_udp(datagrams), InputFormat::Csv, "udp");
    lockstep_2s(&mut rx, InputFormat::Csv)
}

/// A CSV stream with a UTF-8 byte-order mark and the header `t,lon,lat,…` (issue 38: the
/// mark made the header a malformed line and the states were read in the default order,
/// latitude and longitude swapped, exit 0). Read as `generate --trajectory` reads a
/// trajectory file: the same samples, and the run writes the bytes of the plain file's —
/// on a pipe, and over UDP with a mark at the start of every datagram (each written as
/// `utf-8-sig`). A header that names a column the trajectory reader does not know fails the
/// run naming it, instead of reading the rows in the default order.
#[test]
fn a_byte_order_mark_and_another_column_order_are_read_as_a_trajectory_file() {
    let lines = circle_lines(3.0);
    let plain = join(&lines);
    // The mark right before the header, as a spreadsheet's export writes it.
    let marked = format!("{BOM}{}", join(&lon_first(&lines[1..])));
    let read = |text: &str| trajectory::parse(text, std::path::Path::new("x.csv")).unwrap();
    assert_eq!(read(&marked), read(&plain), "the trajectory reader");

    let (status, err, want) = lockstep_pipe(&plain, &[]);
    assert!(status.success(), "{err}");
    let (status, err, got) = lockstep_pipe(&marked, &[]);
    assert!(status.success(), "{err}");
    assert!(err.contains(" 0 malformed,"), "{err}");
    assert!(
        got.is_some() && got == want,
        "a pipe: not the plain file's bytes"
    );

    let datagrams: Vec<String> = lon_first(&lines)
        .iter()
        .map(|l| format!("{BOM}{l}"))
        .collect();
    let (got, s) = csv_over_udp(&datagrams);
    assert_eq!(s.stats.malformed, 0, "{:?}", s.stats.problems);
    let mut rx = Receiver::from_stream(
        Box::new(std::io::Cursor::new(plain.into_bytes())),
        InputFormat::Csv,
        "plain",
    );
    let (want, _) = lockstep_2s(&mut rx, InputFormat::Csv);
    assert!(got == want, "UDP: not the plain file's bytes");

    let unknown = marked.replacen("t,lon,lat", "time,lon,lat", 1);
    let (status, err, out) = lockstep_pipe(&unknown, &[]);
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains("stdin: line 1, byte 3: header: column 1: unknown column `time`"),
        "{err}"
    );
    assert!(err.contains("the sender's columns are unknown"), "{err}");
    assert!(out.is_none());
}

/// CSV states lost on UDP (issue 38: the binary datagram's losses were counted from its
/// sequence numbers, CSV's not at all): told from the time steps and counted as missing in
/// gaps, as the binary datagram's are — three single losses, a run of four, and a pair sent
/// in the wrong order (missing when its successor comes, late when it comes).
#[test]
fn lost_csv_states_are_counted_from_the_time_steps() {
    let lines = circle_lines(3.0);
    // lines[2 + k] is the state at k·10 ms.
    let mut sent: Vec<String> = lines[..2].to_vec();
    let mut at = 0;
    for (k, l) in lines[2..].iter().enumerate() {
        if [40, 77, 130].contains(&k) || (100..104).contains(&k) {
            continue;
        }
        if k == 160 {
            at = sent.len();
        }
        sent.push(l.clone());
    }
    sent.swap(at, at + 1);
    let (_, s) = csv_over_udp(&sent);
    let st = &s.stats;
    assert_eq!(
        (st.missing, st.gaps, st.reordered),
        (3 + 4 + 1, 3 + 1 + 1, 1),
        "{st:?}"
    );
    assert!(
        st.summary().contains(" 8 missing in 5 gaps,"),
        "{}",
        st.summary()
    );
}

/// Waits for `child` (a hang guard of 120 s: how soon is the run's timeout, not a test's);
/// its status and stderr.
fn outcome(mut child: Child) -> (ExitStatus, String) {
    let mut err = child.stderr.take().unwrap();
    let reader = thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut err, &mut s).unwrap();
        s
    });
    let give_up = Instant::now() + Duration::from_secs(120);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > give_up {
            child.kill().unwrap();
            panic!("the run did not end: {}", reader.join().unwrap());
        }
        thread::sleep(Duration::from_millis(20));
    };
    (status, reader.join().unwrap())
}

/// `imu-emu run --motion tcp://… --time-mode lockstep` with [`PIPE_RUN`] and `extra`, its
/// output in a new folder, once a readiness probe found it listening (connected and closed
/// without a byte): the folder, the output's path, the run and its port.
fn probed_tcp_run(extra: &[&str]) -> (tempfile::TempDir, std::path::PathBuf, Child, u16) {
    let dir = tempfile::TempDir::new().unwrap();
    let out = dir.path().join("out.csv");
    let mut flags = PIPE_RUN.to_vec();
    flags.extend(extra);
    let (mut child, port) = lockstep_on_tcp(&out, &flags);
    drop(live_cli::connect(&mut child, port));
    (dir, out, child, port)
}

/// A TCP input (issue 38: a client that connected and closed — a readiness probe — ended
/// the run with exit 1, "0 usable states", and the sender then found the port closed): two
/// probes, a connection that sends only the header, then the states in two connections, the
/// second going on where the first stopped. The listener takes one connection after
/// another; the run writes the bytes a pipe run of the states writes, and counts the
/// connections that brought no state. The run ends at its `--duration`, which only the
/// second connection's states reach.
#[test]
fn tcp_probes_and_reconnects_are_followed() {
    let lines = circle_lines(3.0);
    let (_dir, out, child, port) = probed_tcp_run(&["--duration", "2"]);
    drop(TcpStream::connect(("127.0.0.1", port)).unwrap());
    let send = |text: String| {
        let mut c = TcpStream::connect(("127.0.0.1", port)).unwrap();
        c.write_all(text.as_bytes()).unwrap();
    };
    send(join(&lines[..2]));
    // A connection that ends inside a line: that line is one malformed message, and the
    // next connection starts a line of its own.
    send(join(&lines[2..150]) + "1.48,41");
    send(join(&lines[150..]));
    let (status, err) = outcome(child);
    assert!(status.success(), "{err}");
    assert!(
        err.contains("5 connections, 3 without a state taken"),
        "{err}"
    );
    assert!(err.contains(" 1 malformed,"), "{err}");
    let (status, perr, want) = lockstep_pipe(&join(&lines), &["--duration", "2"]);
    assert!(status.success(), "{perr}");
    assert!(
        want.is_some() && std::fs::read(&out).ok() == want,
        "not the pipe run's bytes: {err}"
    );
}

/// A TCP input whose connections bring no usable state — probes, a sender whose every line
/// is wrong — ends by `--input-timeout` after its last data, as any input does: exit 1 with
/// the counts (the connections among them) and the first problems, no output left.
#[test]
fn a_tcp_input_without_a_usable_state_ends_at_its_timeout() {
    let (_dir, out, child, port) = probed_tcp_run(&["--input-timeout", "1"]);
    let mut c = TcpStream::connect(("127.0.0.1", port)).unwrap();
    c.write_all(b"t,lat,lon,h,vn,ve,vd,roll,pitch,yaw\n0,45,7\n0.01,45,7\n")
        .unwrap();
    drop(c);
    let (status, err) = outcome(child);
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(err.contains("after 0 usable states"), "{err}");
    assert!(
        err.contains("2 connections, 2 without a state taken"),
        "{err}"
    );
    assert!(
        err.contains(&format!(
            "first: tcp://127.0.0.1:{port}: line 2, byte 0: 3 fields, expected 10"
        )),
        "{err}"
    );
    assert!(!out.exists());
}
