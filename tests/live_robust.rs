//! Live input a hostile sender could send (issue 23): a state with huge given rates or
//! accelerations, a position jump the velocities do not carry, a line of megabytes without a
//! line end. Each is counted with its place and dropped; the run goes on and writes exactly
//! the bytes of the same input without it. Real parts: the binary, a pipe, TCP and UDP on
//! loopback.

use std::io::Write;
use std::process::{Command, ExitStatus};
use std::thread;

use imu_emu::live::binary::{self, Datagram};
use imu_emu::live::transport::Receiver;
use imu_emu::live::{InputFormat, csv::MAX_LINE_BYTES};
use imu_emu::motion::Motion;

#[path = "common/live_cli.rs"]
mod live_cli;
#[path = "common/rusage.rs"]
mod rusage;
use rusage::wait_with_rusage;

use live_cli::{circle, circle_lines, join, lockstep_2s, lockstep_pipe, queued_udp};

fn imu_emu() -> Command {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
}

/// Line `n` (1-based, as the run counts them) of `lines` with column `col` set to `value`.
fn set(lines: &mut [String], n: usize, col: usize, value: &str) {
    let mut f: Vec<&str> = lines[n - 1].split(',').collect();
    f[col] = value;
    lines[n - 1] = f.join(",");
}

/// A state whose given body rate is 1e300 deg/s, another whose given acceleration is 1e300
/// m/s² (issue 23 item 1: each once stopped the run with "gyro_x is NaN in the error-free
/// signal", exit 1, no output): both refused naming their line and column, the run ends
/// normally, and its output is the bytes of the same input without those two lines.
#[test]
fn huge_given_rates_and_accelerations_are_refused_and_counted() {
    let mut lines = circle_lines(3.0);
    lines[1].push_str(",wx,wy,wz,an,ae,ad");
    for l in &mut lines[2..] {
        l.push_str(",0,0,0,0,0,0");
    }
    let clean = join(&lines);
    set(&mut lines, 150, 10, "1e300");
    set(&mut lines, 200, 13, "1e300");
    let (status, err, out) = lockstep_pipe(&join(&lines), &[]);
    assert!(status.success(), "{err}");
    assert!(err.contains(", 2 refused,"), "{err}");
    assert!(
        err.contains("stdin: line 150: `wx`: the given body rate"),
        "{err}"
    );
    assert!(
        err.contains("stdin: line 200: `an`: the given acceleration 1e300 m/s²"),
        "{err}"
    );
    let mut without = lines.clone();
    without.remove(199);
    without.remove(149);
    let (status, err, want) = lockstep_pipe(&join(&without), &[]);
    assert!(status.success(), "{err}");
    assert!(
        out.is_some() && out == want,
        "not the bytes without the two lines"
    );
    // Without those lines the output differs: dropping a state is visible.
    assert!(want != lockstep_pipe(&clean, &[]).2);
}

/// The motion's state at `t` as a binary datagram carrying a body rate.
fn datagram(m: &impl Motion, t: f64, seq: u32, rate: [f64; 3]) -> Vec<u8> {
    let p = m.pose(t);
    binary::encode(&Datagram {
        seq,
        week: binary::NO_WEEK,
        time: t,
        flags: binary::FLAG_RATE,
        pos: [p.lat.to_degrees(), p.lon.to_degrees(), p.h],
        vel: p.v_n.into(),
        acc: [0.0; 3],
        quat: [p.q_b_n.w, p.q_b_n.i, p.q_b_n.j, p.q_b_n.k],
        rate,
    })
    .to_vec()
}

/// `datagrams` sent over UDP loopback to a lockstep run of 2 s; its output and summary.
fn over_udp(datagrams: Vec<Vec<u8>>) -> (Vec<u8>, imu_emu::run::lockstep::LiveSummary) {
    let mut rx = Receiver::from_socket(queued_udp(&datagrams), InputFormat::Binary, "udp");
    lockstep_2s(&mut rx, InputFormat::Binary)
}

/// A binary datagram with ω = 1e300 rad/s (issue 23 item 1) over UDP: refused, named by its
/// datagram, and the output is that of the input without it.
#[test]
fn a_datagram_with_a_huge_body_rate_is_refused() {
    let m = circle();
    let with = |bad: bool| -> Vec<Vec<u8>> {
        (0..250u32)
            .filter(|&i| bad || i != 120)
            .map(|i| {
                let w = if bad && i == 120 { 1e300 } else { 0.01 };
                datagram(&m, f64::from(i) * 0.01, i, [w, 0.0, 0.0])
            })
            .collect()
    };
    let (out, s) = over_udp(with(true));
    // The run ends at its 2 s; the refused datagram is no gap in the sequence numbers.
    let st = &s.stats;
    assert_eq!(
        (st.refused, st.states + 1, st.gaps),
        (1, st.messages, 0),
        "{s:?}"
    );
    assert_eq!(
        s.stats.problems,
        vec!["udp: datagram 121: `wx`: the given body rate 1e300 rad/s is beyond the limit of 1e4 rad/s".to_string()]
    );
    let (want, _) = over_udp(with(false));
    assert!(out == want, "not the bytes without the datagram");
}

/// Five states 9° (1000 km) north of the track (issue 23 item 4: the ideal IMU spiked to
/// 162 rad/s and 9639 m/s², exit 0): `generate --trajectory` refuses the file naming the
/// line and `lat`, leaving no output; a live run refuses the five states, counted with their
/// lines, and writes the bytes of the input without them.
#[test]
fn a_position_jump_is_refused() {
    let mut lines = circle_lines(4.0);
    for n in 300..305 {
        let lat: f64 = lines[n - 1].split(',').nth(1).unwrap().parse().unwrap();
        set(&mut lines, n, 1, &(lat + 9.0).to_string());
    }
    let dir = tempfile::TempDir::new().unwrap();
    let traj = dir.path().join("jump.csv");
    std::fs::write(&traj, join(&lines)).unwrap();
    let out = dir.path().join("imu.csv");
    let done = imu_emu()
        .args(["generate", "--trajectory"])
        .arg(&traj)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&done.stderr);
    assert_eq!(done.status.code(), Some(1), "{err}");
    assert!(
        err.contains("jump.csv:300: column 2 (`lat`): the position moved 999"),
        "{err}"
    );
    assert!(!out.exists());

    let (status, err, got) = lockstep_pipe(&join(&lines), &[]);
    assert!(status.success(), "{err}");
    assert!(
        err.contains("396 states taken;") && err.contains(", 5 refused,"),
        "{err}"
    );
    for n in 300..305 {
        assert!(
            err.contains(&format!("stdin: line {n}: `lat`: the position moved")),
            "{err}"
        );
    }
    let mut without = lines.clone();
    without.drain(299..304);
    let (status, err, want) = lockstep_pipe(&join(&without), &[]);
    assert!(status.success(), "{err}");
    assert!(
        got.is_some() && got == want,
        "not the bytes without the five lines"
    );
}

/// Runs `imu-emu run --motion tcp://… --time-mode lockstep` on `text` sent over TCP loopback;
/// its exit status, stderr, output and peak resident memory (kB, from `wait4`).
fn lockstep_tcp(text: Vec<u8>) -> (ExitStatus, String, Option<Vec<u8>>, i64) {
    let dir = tempfile::TempDir::new().unwrap();
    let out = dir.path().join("out.bin");
    let (mut child, mut conn) = live_cli::lockstep_over_tcp(&out, &["--duration", "2"]);
    let sender = thread::spawn(move || {
        let _ = conn.write_all(&text);
    });
    let stderr = child.stderr.take().unwrap();
    let reader = thread::spawn(move || std::io::read_to_string(stderr).unwrap());
    let (status, maxrss) = wait_with_rusage(child);
    sender.join().unwrap();
    let err = reader.join().unwrap();
    (status, err, std::fs::read(&out).ok(), maxrss)
}

/// A 24 MB line without a line end over TCP (issue 23 item 3: read whole, searched from its
/// start on every read — quadratic CPU, memory the size of the line): refused as too long,
/// named by its line; its bytes are skipped and counted; the states after it are taken, the
/// output is the bytes of the input without that line, and the run's peak memory is within
/// 8 MB of the same run without it (it was over 24 MB more).
#[test]
fn a_megabyte_line_without_a_line_end_is_cut_and_counted() {
    let lines = circle_lines(3.0);
    let n = 24 << 20;
    let mut text = join(&lines[..100]).into_bytes();
    text.extend(std::iter::repeat_n(b'7', n));
    text.push(b'\n');
    text.extend(join(&lines[100..]).into_bytes());
    let (status, err, got, peak) = lockstep_tcp(text);
    assert!(status.success(), "{err}");
    assert!(err.contains("1 malformed"), "{err}");
    assert!(
        err.contains(&format!(
            "line 101, byte {MAX_LINE_BYTES}: line longer than {MAX_LINE_BYTES} bytes"
        )),
        "{err}"
    );
    assert!(
        err.contains(&format!("{} bytes skipped", n - MAX_LINE_BYTES)),
        "{err}"
    );
    let (status, err, want, base) = lockstep_tcp(join(&lines).into_bytes());
    assert!(status.success(), "{err}");
    assert!(
        got.is_some() && got == want,
        "not the bytes without the long line"
    );
    println!("peak memory {peak} kB, {base} kB without the long line");
    assert!(peak < base + 8 * 1024, "{peak} kB vs {base} kB");
}

/// A state whose time tag is off the sender's time line (issue 38: `t` = 1e9 s among states
/// at 0–4 s once made a lockstep run compute records up to 1e9 s, its memory growing without
/// bound and deaf to SIGINT; with a duration, specific forces of 1e80 m/s² came out with
/// exit 0): refused with its line, step and limit, counted, and the run writes the bytes of
/// the input without it. A step a hundred times the input's spacing is still bridged (a
/// hundred states lost in a row), so the limit is what it says.
#[test]
fn a_time_tag_off_the_time_line_is_refused() {
    let lines = circle_lines(4.0);
    let mut outlier = lines.clone();
    set(&mut outlier, 250, 0, "1e9");
    let (status, err, got) = lockstep_pipe(&join(&outlier), &[]);
    assert!(status.success(), "{err}");
    assert!(err.contains(", 1 refused,"), "{err}");
    assert!(
        err.contains(
            "stdin: line 250: `t`: 999999998 s after the newest state (2.46 s), beyond the longest step the model bridges there (1 s)"
        ),
        "{err}"
    );
    let mut without = lines.clone();
    without.remove(249);
    let (status, err, want) = lockstep_pipe(&join(&without), &[]);
    assert!(status.success(), "{err}");
    assert!(
        got.is_some() && got == want,
        "not the bytes without the line"
    );

    // 99 states lost in a row: a step of 100 spacings (1 s) is bridged, so nothing refused.
    let mut outage = lines.clone();
    outage.drain(150..249);
    let (status, err, _) = lockstep_pipe(&join(&outage), &[]);
    assert!(status.success(), "{err}");
    assert!(err.contains(", 0 refused,"), "{err}");
}

/// An input that gives no usable state (issue 38: the run said only "the input ended after 0
/// usable states"): the error counts what became of its messages and names the first
/// problems with their lines, and the run fails with no output left.
#[test]
fn an_input_without_a_usable_state_says_why() {
    let mut text = String::from("t,lat,lon,h,vn,ve,vd,roll,pitch,yaw\n");
    for k in 0..20 {
        text.push_str(&format!("{},45,7,100,0,0\n", k as f64 * 0.01));
    }
    let (status, err, out) = lockstep_pipe(&text, &[]);
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(err.contains("after 0 usable states"), "{err}");
    assert!(err.contains("21 messages (1 without a state"), "{err}");
    assert!(err.contains("; 20 malformed,"), "{err}");
    assert!(
        err.contains("; first: stdin: line 2, byte 0: 6 fields, expected 10;"),
        "{err}"
    );
    assert!(err.contains("; stdin: line 4, byte 0: "), "{err}");
    assert!(
        !err.contains("stdin: line 5"),
        "three problems named: {err}"
    );
    assert!(out.is_none());
}
