//! The real-time emulator end to end: `imu-emu run` on a pty, on UDP loopback and into files,
//! checked against `imu-emu generate`'s bytes for the same seed; frames arriving at their
//! wall-clock instants (rate, constant delay, drift, nothing before `--start-at`); losses
//! reported as they happened; refusals and exit statuses. Every bound is derived from the
//! run's settings or from what it reports (kernel arrival stamps against the pacer's reported
//! write lateness), so it holds on a loaded 2-core machine; typical lateness figures belong to
//! `benches/latency.rs`.

use std::io::Read;
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use imu_emu::protocol::{StreamDecoder, load};
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

#[path = "common/realtime_run.rs"]
mod realtime_run;
#[path = "common/udp_rx.rs"]
mod udp_rx;
use realtime_run::serial;

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");
const PROTOCOL: &str = "kvh1750";

fn imu_emu(args: &[&str]) -> Command {
    let mut c = Command::new(BIN);
    c.args(args);
    c
}

fn output(args: &[&str]) -> Output {
    let out = imu_emu(args).output().expect("run imu-emu");
    assert!(
        out.status.success(),
        "imu-emu {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// `generate`'s frames for the same run settings: the reference bytes.
fn reference(common: &[&str]) -> Vec<u8> {
    let mut args = vec!["generate", "--format", PROTOCOL, "--imu", "ln200"];
    args.extend_from_slice(common);
    output(&args).stdout
}

/// Spawns `run` with stderr captured.
fn spawn_run(args: &[&str]) -> Child {
    // The frames of every test are PROTOCOL's unless the test names its own.
    let protocol: &[&str] = if args.contains(&"--protocol") {
        &[]
    } else {
        &["--protocol", PROTOCOL]
    };
    imu_emu(&[&["run"], protocol, args].concat())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn imu-emu run")
}

fn finish(child: Child) -> String {
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "run failed: {err}");
    err
}

/// A loopback receiver with a 4 MiB buffer (SO_RCVBUFFORCE as root, else as large as
/// allowed), so a test thread descheduled for a while loses no datagram.
fn receiver() -> UdpSocket {
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    imu_emu::realtime::udp::grow_receive_buffer(&rx);
    rx
}

fn wait_for(path: &Path) {
    let t = Instant::now();
    while path.symlink_metadata().is_err() {
        assert!(
            t.elapsed() < Duration::from_secs(20),
            "{} never appeared",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Checks that `got` (bytes a reader received) is a sequence of whole frames of `reference`,
/// in order, starting at a frame boundary — after at most one frame's worth of leading bytes
/// (a reader may attach mid-frame) and up to a trailing partial frame — and that every frame
/// decodes. Returns (frames, counter gaps): frames the emulator dropped show as gaps.
///
/// Frames repeat (a static stretch quantized to the same counts, the counter wrapping at 128),
/// so a frame's place in the reference is ambiguous: the check takes the earliest match at or
/// after the previous frame's, which never rejects a true sequence; gaps are counted by the
/// frame counter, as a receiver counts them.
fn frames_in_order(got: &[u8], reference: &[u8], len: usize) -> (usize, u64) {
    assert!(got.len() >= 2 * len, "only {} bytes received", got.len());
    let refs: Vec<&[u8]> = reference.chunks_exact(len).collect();
    let skip = (0..len)
        .find(|&p| refs.contains(&&got[p..p + len]))
        .expect("the received bytes contain no frame of the reference stream");
    let whole = (got.len() - skip) / len * len;
    let got = &got[skip..skip + whole];
    let mut next = 0;
    for (i, f) in got.chunks_exact(len).enumerate() {
        let at = refs[next..]
            .iter()
            .position(|r| r == &f)
            .unwrap_or_else(|| panic!("received frame {i} is not a later frame of generate's"));
        next += at + 1;
    }
    let (_, plan) = load(PROTOCOL).unwrap();
    let mut dec = StreamDecoder::new(plan);
    dec.feed(got, |_| {});
    assert_eq!(dec.stats().frames as usize, whole / len);
    assert_eq!(dec.stats().check_failures, 0);
    (whole / len, dec.stats().counter_gaps)
}

/// The count before `what` in the emulator's summary (`12 dropped (slow consumer)`).
fn count_in(summary: &str, what: &str) -> u64 {
    summary
        .split([',', '\n', ':'])
        .find_map(|s| s.trim().strip_suffix(what))
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or_else(|| panic!("no `{what}` count in {summary}"))
}

/// Reads a serial port until `n` bytes have come (a hang guard of 60 s).
fn read_frames(port: &mut serialport::TTYPort, n: usize) -> Vec<u8> {
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    let t = Instant::now();
    while got.len() < n {
        assert!(
            t.elapsed() < Duration::from_secs(60),
            "{} bytes came",
            got.len()
        );
        match port.read(&mut buf) {
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => panic!("reading the pty: {e}"),
        }
    }
    got
}

fn open_port(path: &Path) -> serialport::TTYPort {
    let mut p = serialport::new(path.to_string_lossy(), 921_600)
        .timeout(Duration::from_millis(50))
        .open_native()
        .expect("open the pty slave");
    p.set_exclusive(false).unwrap();
    serialport::SerialPort::clear(&p, serialport::ClearBuffer::Input).unwrap();
    p
}

/// A reader on the pty gets generate's frames, contiguous, decodable; it closes and reopens
/// mid-run and gets frames again; a SIGINT ends the run, which removes its link. The run is
/// long (10 min at 2×) and ended by the test once both reads are done, so neither read
/// depends on how soon the machine schedules the test.
#[test]
fn pty_stream_is_generate_and_survives_reopen() {
    let _cpu = serial();
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("imu");
    let common = ["--rate", "1000", "--duration", "600", "--seed", "7"];
    let len = load(PROTOCOL).unwrap().1.len();
    let child = spawn_run(
        &[
            &common[..],
            &[
                "--speed",
                "2",
                "--max-behind-ms",
                "60000",
                "--pty",
                link.to_str().unwrap(),
            ],
        ]
        .concat(),
    );
    wait_for(&link);
    let mut port = open_port(&link);
    let first = read_frames(&mut port, 500 * len);
    drop(port);
    let mut port = open_port(&link);
    let second = read_frames(&mut port, 500 * len);
    drop(port);
    kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).unwrap();
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(130), "{err}");
    // generate's frames for as far as the run went: the 600 s one's first part.
    let made = count_in(&err, "sent") as usize;
    let mut args = vec!["generate", "--format", PROTOCOL, "--imu", "ln200"];
    let secs = format!("{}", (made + 1000) as f64 / 1000.0);
    args.extend(["--rate", "1000", "--seed", "7", "--duration", &secs]);
    let reference = output(&args).stdout;
    let (n1, jumps1) = frames_in_order(&first, &reference, len);
    let (n2, jumps2) = frames_in_order(&second, &reference, len);
    assert!(n1 >= 499 && n2 >= 499, "{n1}, {n2} frames: {err}");
    // Counters are continuous unless the emulator says it dropped or skipped frames.
    if jumps1 + jumps2 > 0 {
        let lost = count_in(&err, "dropped (slow consumer)") + count_in(&err, "skipped (too late)");
        assert!(
            lost > 0,
            "{jumps1}+{jumps2} gaps the emulator did not count: {err}"
        );
    }
    assert!(
        link.symlink_metadata().is_err(),
        "the pty link was left behind"
    );
}

/// A reader that opens the pty and never reads: the run still ends on time, the frames that
/// did not fit are dropped and counted.
#[test]
fn stalled_reader_never_slows_the_run() {
    let _cpu = serial();
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("stalled");
    let child = spawn_run(&[
        "--rate",
        "2000",
        "--duration",
        "2",
        "--protocol",
        PROTOCOL,
        "--pty",
        link.to_str().unwrap(),
    ]);
    wait_for(&link);
    let port = open_port(&link);
    let err = finish(child);
    drop(port);
    // Every frame is accounted for, and the writes never waited for the reader: 4000 frames ×
    // 36 B = 144 kB into a pty that holds at most 64 KiB are mostly dropped as the slow
    // consumer's (or before the reader came), not held up until they are too late.
    let lost = [
        "dropped (slow consumer)",
        "dropped (no reader)",
        "skipped (too late)",
    ]
    .map(|w| count_in(&err, w));
    assert_eq!(
        count_in(&err, "sent") + lost.iter().sum::<u64>(),
        4000,
        "{err}"
    );
    assert!(lost[0] + lost[1] > 4000 - 65_536 / 36, "{err}");
}

/// UDP loopback: every datagram is one frame, and together they are generate's bytes.
#[test]
fn udp_datagrams_are_generate_frames() {
    let _cpu = serial();
    let rx = receiver();
    let dest = rx.local_addr().unwrap().to_string();
    let common = ["--rate", "1000", "--duration", "1", "--seed", "9"];
    let reference = reference(&common);
    let len = load(PROTOCOL).unwrap().1.len();
    let child = spawn_run(
        &[
            &common[..],
            &["--speed", "4", "--max-behind-ms", "60000", "--udp", &dest],
        ]
        .concat(),
    );
    let mut got = Vec::new();
    let mut buf = [0u8; 2048];
    while got.len() < reference.len() {
        let n = rx.recv(&mut buf).expect("a datagram within 10 s");
        assert_eq!(n, len, "one frame per datagram");
        got.extend_from_slice(&buf[..n]);
    }
    finish(child);
    assert_eq!(got, reference);
}

/// Nobody listening: the run completes and says what it sent.
#[test]
fn udp_without_listener_completes() {
    let _cpu = serial();
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dest = format!("127.0.0.1:{port}");
    let err = finish(spawn_run(&[
        "--rate",
        "400",
        "--duration",
        "1",
        "--speed",
        "2",
        "--protocol",
        PROTOCOL,
        "--udp",
        &dest,
    ]));
    assert!(err.contains("unit imu: 400 of 400 records"), "{err}");
}

/// `decode --udp-listen` is the consumer side: it decodes the emulator's datagrams live
/// (unicast to `host`, or a multicast group it joins).
fn decode_over_udp(host: &str) {
    let _cpu = serial();
    let port = UdpSocket::bind("0.0.0.0:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dest = format!("{host}:{port}");
    let mut dec = imu_emu(&[
        "decode",
        "--protocol",
        PROTOCOL,
        "--udp-listen",
        &dest,
        "--frames",
        "400",
        "--duration",
        "600",
    ])
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    // The CSV header comes once the socket is bound.
    let mut stdout = dec.stdout.take().unwrap();
    let mut first = [0u8; 1];
    stdout.read_exact(&mut first).unwrap();
    finish(spawn_run(&[
        "--rate",
        "400",
        "--duration",
        "1",
        "--speed",
        "4",
        "--max-behind-ms",
        "60000",
        "--protocol",
        PROTOCOL,
        "--udp",
        &dest,
    ]));
    let mut csv = String::new();
    stdout.read_to_string(&mut csv).unwrap();
    let out = dec.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    // The header (its first byte already read) and one line per frame.
    assert_eq!(csv.lines().count(), 401, "{err}");
    assert!(
        err.contains("400 frames, 0 check failures, 0 counter gaps,")
            && err.contains(" 0 bytes skipped"),
        "{err}"
    );
}

#[test]
fn decode_listens_on_udp() {
    decode_over_udp("127.0.0.1");
}

/// The same through a multicast group (TTL 1, loopback on): the decoder joins it.
#[test]
fn decode_listens_on_udp_multicast() {
    decode_over_udp("239.255.42.42");
}

/// Same seed, same bytes: an unpaced run into a file and a paced one (×50) are both exactly
/// `generate --format`'s output, with an error model and a scene file.
#[test]
fn file_output_is_generate_bytes() {
    let _cpu = serial();
    let dir = tempfile::tempdir().unwrap();
    let common = [
        "--scene",
        "circle",
        "--rate",
        "200",
        "--duration",
        "3",
        "--seed",
        "11",
    ];
    let reference = reference(&common);
    for speed in ["max", "50"] {
        let out = dir.path().join(format!("{speed}.bin"));
        let mut args = common.to_vec();
        args.extend(["--speed", speed, "--file", out.to_str().unwrap()]);
        if speed != "max" {
            // Paced: no frame may be skipped as late.
            args.extend(["--max-behind-ms", "60000"]);
        }
        finish(spawn_run(&args));
        assert!(std::fs::read(&out).unwrap() == reference, "--speed {speed}");
    }
}

/// Refusals name what is wrong: a serial link too slow for the frames, a bad speed or instant.
#[test]
fn refuses_impossible_settings() {
    let _cpu = serial();
    for (args, says) in [
        (
            &["--serial", "/dev/null", "--baud", "9600", "--rate", "1000"][..],
            "bit/s",
        ),
        (&["--speed", "0"][..], "--speed 0"),
        (&["--start-at", "tomorrow"][..], "--start-at"),
        // 3000 26-byte frames: 78 000 bytes, over the 65 507 of a UDP datagram.
        (
            &["--udp", "127.0.0.1:9", "--udp-batch", "3000"][..],
            "65507",
        ),
        (&["--udp", "127.0.0.1:0"][..], "port 0"),
        (
            &["--start-at", "2020-01-01T00:00:00Z", "--udp", "127.0.0.1:9"][..],
            "in the past",
        ),
    ] {
        let out = imu_emu(&[&["run", "--duration", "1"], args].concat())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        // One clear message: no warning before it, nothing streamed.
        assert!(
            !out.status.success()
                && err.contains(says)
                && !err.contains("warning")
                && !err.contains("sent, "),
            "{args:?}: {err}"
        );
    }
}

/// `--serial` on a tty (the slave of a pty pair the test holds, standing in for a UART):
/// the bytes at the other end are generate's.
#[test]
fn serial_sink_writes_generate_frames() {
    let _cpu = serial();
    use std::os::fd::AsRawFd;
    let common = ["--rate", "500", "--duration", "1", "--seed", "5"];
    let reference = reference(&common);
    let pair = nix::pty::openpty(None, None).unwrap();
    let mut t = nix::sys::termios::tcgetattr(&pair.slave).unwrap();
    nix::sys::termios::cfmakeraw(&mut t);
    nix::sys::termios::tcsetattr(&pair.slave, nix::sys::termios::SetArg::TCSANOW, &t).unwrap();
    let dev = std::fs::read_link(format!("/proc/self/fd/{}", pair.slave.as_raw_fd())).unwrap();
    let child = spawn_run(
        &[
            &common[..],
            &[
                "--speed",
                "4",
                "--max-behind-ms",
                "60000",
                "--serial",
                dev.to_str().unwrap(),
                "--baud",
                "921600",
            ],
        ]
        .concat(),
    );
    let mut master = std::fs::File::from(pair.master);
    let len = reference.len();
    // Read on a thread, so a short stream fails the test instead of hanging it.
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut got = vec![0u8; len];
        let _ = tx.send(master.read_exact(&mut got).map(|_| got));
    });
    let got = rx
        .recv_timeout(std::time::Duration::from_secs(30))
        .expect("the whole stream within 30 s")
        .unwrap();
    finish(child);
    assert!(
        got == reference,
        "the serial stream differs from generate's"
    );
}

/// Sinks with their own protocol: the same records as stim300 frames on one UDP port and as
/// the main protocol's in a file, each exactly `generate --format` of that protocol.
#[test]
fn each_sink_its_own_protocol() {
    let _cpu = serial();
    let dir = tempfile::tempdir().unwrap();
    let rx = receiver();
    let dest = format!("{},protocol=stim300", rx.local_addr().unwrap());
    let file = dir.path().join("main.bin");
    let common = ["--rate", "500", "--duration", "1", "--seed", "13"];
    let main_ref = reference(&common);
    let stim_ref = output(
        &[
            &["generate", "--format", "stim300", "--imu", "ln200"],
            &common[..],
        ]
        .concat(),
    )
    .stdout;
    let child = spawn_run(
        &[
            &common[..],
            &[
                "--speed",
                "5",
                "--max-behind-ms",
                "60000",
                "--protocol",
                PROTOCOL,
                "--udp",
                &dest,
                "--file",
            ],
            &[file.to_str().unwrap()],
        ]
        .concat(),
    );
    let mut got = Vec::new();
    let mut buf = [0u8; 2048];
    while got.len() < stim_ref.len() {
        let n = rx.recv(&mut buf).expect("a datagram within 10 s");
        got.extend_from_slice(&buf[..n]);
    }
    finish(child);
    assert!(
        got == stim_ref,
        "the stim300 stream differs from generate's"
    );
    assert!(
        std::fs::read(&file).unwrap() == main_ref,
        "the main stream differs"
    );
}

/// `--realtime` where SCHED_FIFO is refused (CAP_SYS_NICE dropped with util-linux `setpriv`;
/// RLIMIT_RTPRIO is 0 here): a clear warning, then the run completes at normal priority with
/// the same bytes.
#[test]
fn realtime_refused_falls_back_with_a_warning() {
    let _cpu = serial();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("fifo.bin");
    let common = ["--scene", "static", "--rate", "200", "--duration", "0.5"];
    let out = Command::new("setpriv")
        .args(["--bounding-set", "-sys_nice", "--inh-caps", "-sys_nice"])
        .arg(env!("CARGO_BIN_EXE_imu-emu"))
        .args(["run", "--protocol", PROTOCOL, "--realtime", "--speed", "1"])
        .args(["--max-behind-ms", "60000"])
        .args(common)
        .args(["--file", file.to_str().unwrap()])
        .output()
        .expect("setpriv (util-linux) runs the emulator without CAP_SYS_NICE");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("SCHED_FIFO refused") && err.contains("running at normal priority"),
        "{err}"
    );
    assert!(std::fs::read(&file).unwrap() == reference(&common));
}

// ---------------------------------------------------------------------------------------------
// Wall-clock correctness: arrival instants against `--start-at`, losses, lateness, signals.
// ---------------------------------------------------------------------------------------------

/// The protocol of the timing tests: kvh1750 with a µs time tag, so each datagram says which
/// record it carries whatever was lost before it (its counter wraps every 128 frames).
const TIMED: &str = "kvh1750-b";

/// CLOCK_REALTIME now (ns since the Unix epoch), the clock `--start-at` is given in.
fn utc_now_ns() -> i128 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_nanos() as i128
}

/// `ns` since the epoch as RFC 3339 UTC to the µs: the test's own civil-date conversion
/// (H. Hinnant's `civil_from_days`), independent of the emulator's parser.
fn utc_string(ns: i128) -> String {
    let s = ns.div_euclid(1_000_000_000) as i64;
    let us = ns.rem_euclid(1_000_000_000) / 1000;
    let (days, rem) = (s.div_euclid(86_400), s.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{us:06}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// A whole-µs instant `secs` ahead of now, and its RFC 3339 form for `--start-at`.
fn instant_ahead(secs: f64) -> (i128, String) {
    let ns = (utc_now_ns() + (secs * 1e9) as i128) / 1000 * 1000;
    (ns, utc_string(ns))
}

/// A datagram as it arrived: the kernel's CLOCK_REALTIME stamp (ns), and its bytes.
type Arrival = (i128, Vec<u8>);

/// Record index k (1-based: record k ends at `--start 0` + k/rate) of each datagram, from
/// its decoded time tag, with its arrival; checks that every datagram is one whole frame and
/// that the records come in order, each at most once.
fn records(got: &[Arrival], rate: f64) -> Vec<(u64, i128)> {
    let (_, plan) = load(TIMED).unwrap();
    let mut out: Vec<(u64, i128)> = Vec::with_capacity(got.len());
    for (at, bytes) in got {
        assert_eq!(bytes.len(), plan.len(), "one frame per datagram");
        let t = plan.decode(bytes).expect("a valid frame").contract(None)[0].unwrap();
        let k = (t * rate).round();
        assert!(
            (t * rate - k).abs() < 1e-3,
            "time tag {t} s is off the grid"
        );
        let k = k as u64;
        assert!(
            out.last().is_none_or(|l| l.0 < k),
            "record {k} after {:?}",
            out.last()
        );
        out.push((k, *at));
    }
    out
}

/// The most consecutive records missing between two received ones.
fn longest_gap(ks: &[u64]) -> u64 {
    ks.windows(2).map(|w| w[1] - w[0] - 1).max().unwrap_or(0)
}

/// Lateness figures (µs) of the run summary: `write lateness p50 A µs, p99 B µs, max C µs`.
fn lateness_us(summary: &str) -> [f64; 3] {
    let tail = summary
        .split_once("write lateness ")
        .unwrap_or_else(|| panic!("no lateness in {summary}"))
        .1;
    let mut out = [0.0; 3];
    for (o, name) in out.iter_mut().zip(["p50 ", "p99 ", "max "]) {
        let v = tail
            .split_once(name)
            .unwrap()
            .1
            .split_once(" µs")
            .unwrap()
            .0;
        *o = v
            .parse()
            .unwrap_or_else(|_| panic!("{name}`{v}` in {summary}"));
    }
    out
}

/// `--speed 1` with `--start-at`: frame k leaves at start + k/rate on the wall clock. Every
/// datagram's arrival, stamped by the kernel as it reaches the test's socket (during the
/// emulator's write), is checked against the instant the test gave, not against anything the
/// emulator computed: the pacer never writes before a frame's deadline, and counts a frame's
/// write lateness until its write returns, so each arrival lies within
/// [deadline − u, deadline + worst + u] — worst the largest write lateness the run reports
/// (printed in whole µs: half a µs more), u how well it read the host's UTC − monotonic offset,
/// through which it put the instant on its clock (reported too). Frames at the wrong rate, a
/// constant delay or a drift fall outside; so do frames sent before `--start-at`. The
/// typical lateness (median, percentiles) is a timing figure: benches/latency.rs.
#[test]
fn frames_arrive_at_their_wall_clock_instants() {
    const RATE: f64 = 200.0;
    const SECS: f64 = 4.0;
    let planned = (RATE * SECS) as u64;
    let _cpu = serial();
    let mut tries = 0;
    let (start, err, got) = loop {
        tries += 1;
        let receiving = udp_rx::UdpRx::start();
        // The run refuses an instant already past when it starts; a machine that took longer
        // than that to start it is told so, and the test runs again at a later instant.
        let (start, at) = instant_ahead(1.5);
        let child = spawn_run(&[
            "--protocol",
            TIMED,
            "--rate",
            &RATE.to_string(),
            "--duration",
            &SECS.to_string(),
            "--start",
            "0",
            "--speed",
            "1",
            // Every frame is sent however late: its lateness is what is bounded.
            "--max-behind-ms",
            "60000",
            "--udp",
            &receiving.dest,
            "--start-at",
            &at,
        ]);
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        let got = receiving.stop();
        if out.status.success() {
            break (start, err, got);
        }
        assert!(err.contains("in the past") && tries < 3, "{err}");
    };
    let got = records(&got, RATE);
    let [p50, p99, max] = lateness_us(&err);
    let u = realtime_run::clock_reading_ns(&err);
    // Every frame is accounted for: received, or reported skipped or dropped (none here).
    let lost = count_in(&err, "skipped (too late)") + count_in(&err, "dropped (slow consumer)");
    assert_eq!(got.len() as u64 + lost, planned, "{err}");
    assert_eq!(lost, 0, "{err}");
    let worst = (max * 1e3) as i128 + 500;
    let mut errs: Vec<(u64, i128)> = got
        .iter()
        .map(|&(k, at)| (k, at - (start + (k as f64 * 1e9 / RATE) as i128)))
        .collect();
    errs.sort_by_key(|e| e.1);
    let (early, late) = (errs[0], errs[errs.len() - 1]);
    eprintln!(
        "arrival − deadline: {:.3} to {:.3} ms; emulator p50 {p50} p99 {p99} max {max} µs; clocks read to ±{u} ns",
        early.1 as f64 / 1e6,
        late.1 as f64 / 1e6
    );
    assert!(
        early.1 >= -u,
        "record {} came {} ns early: {err}",
        early.0,
        -early.1
    );
    assert!(
        late.1 <= worst + u,
        "record {} came {} ns late, past the worst reported {worst} ns: {err}",
        late.0,
        late.1
    );
    // The summary's figures: finite, non-negative, ordered.
    assert!(
        [p50, p99, max].iter().all(|x| x.is_finite() && *x >= 0.0) && p50 <= p99 && p99 <= max,
        "{err}"
    );
}

/// Frames lost to a stall are all reported. The emulator is stopped (SIGSTOP) for 0.4 s at
/// 1000 frames/s: the frames due more than `--max-behind-ms` (100 ms) before it resumes are
/// skipped, about 300, more than two periods of the 128-value frame counter, so a count of
/// counter gaps would see about 44. The records missing by their time tags must be exactly
/// what the summary reports lost.
#[test]
fn reported_losses_are_the_records_missing() {
    const RATE: f64 = 1000.0;
    let planned = 5000;
    let _cpu = serial();
    let receiving = udp_rx::UdpRx::start();
    let child = spawn_run(&[
        "--protocol",
        TIMED,
        "--rate",
        &RATE.to_string(),
        "--duration",
        "5",
        "--start",
        "0",
        "--udp",
        &receiving.dest,
    ]);
    receiving.wait_for(300);
    let pid = Pid::from_raw(child.id() as i32);
    kill(pid, Signal::SIGSTOP).unwrap();
    std::thread::sleep(Duration::from_millis(400));
    kill(pid, Signal::SIGCONT).unwrap();
    let err = finish(child);
    let got = records(&receiving.stop(), RATE);
    let reported = count_in(&err, "skipped (too late)") + count_in(&err, "dropped (slow consumer)");
    let missing = planned - got.len() as u64;
    let ks: Vec<u64> = got.iter().map(|g| g.0).collect();
    let gap = longest_gap(&ks);
    assert!(
        gap > 2 * 128,
        "a 0.4 s stop lost only {gap} frames in a row: {err}"
    );
    assert_eq!(
        missing, reported,
        "{missing} records missing, {reported} reported lost: {err}"
    );
    assert_eq!(count_in(&err, "sent"), got.len() as u64, "{err}");
}

/// A pty reader that pauses for 1.5 s at 2000 frames/s: what does not fit the pty's buffers
/// (about 64 KiB, some 1600 frames of 40 bytes) is dropped and counted, far more than one
/// counter period. The records missing from what the reader got, by their time tags, must be
/// exactly the frames reported lost (no reader yet, slow consumer, too late).
#[test]
fn pty_losses_are_the_records_missing() {
    use std::os::unix::fs::OpenOptionsExt;
    const RATE: f64 = 2000.0;
    let planned = 6000;
    let _cpu = serial();
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("imu");
    let child = spawn_run(&[
        "--protocol",
        TIMED,
        "--rate",
        &RATE.to_string(),
        "--duration",
        "3",
        "--start",
        "0",
        "--pty",
        link.to_str().unwrap(),
    ]);
    wait_for(&link);
    // No input flush on opening (a serial-port library's `clear`): the emulator discards
    // what was queued before a reader came, and a flush here could drop a frame it counted.
    let mut pty = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOCTTY)
        .open(&link)
        .unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    let opened = Instant::now();
    let mut paused = false;
    // Until the emulator closes its end (EIO).
    while let Ok(n @ 1..) = pty.read(&mut buf) {
        got.extend_from_slice(&buf[..n]);
        if !paused && opened.elapsed() > Duration::from_millis(300) {
            std::thread::sleep(Duration::from_millis(1500));
            paused = true;
        }
    }
    let err = finish(child);
    let (_, plan) = load(TIMED).unwrap();
    let mut dec = StreamDecoder::new(plan);
    let mut ks: Vec<u64> = Vec::new();
    dec.feed(&got, |d| {
        ks.push((d.contract(None)[0].unwrap() * RATE).round() as u64)
    });
    assert_eq!(dec.stats().check_failures, 0, "a torn frame");
    assert!(ks.windows(2).all(|w| w[0] < w[1]), "records out of order");
    let reported = count_in(&err, "dropped (slow consumer)")
        + count_in(&err, "dropped (no reader)")
        + count_in(&err, "skipped (too late)");
    let gap = longest_gap(&ks);
    assert!(
        gap > 2 * 128,
        "a 1.5 s pause lost only {gap} frames in a row: {err}"
    );
    assert_eq!(
        planned - ks.len() as u64,
        reported,
        "records missing vs reported lost: {err}"
    );
}

/// SIGINT and SIGTERM end a run with its summary and the shell's status for the signal
/// (130, 143), so a script can tell an interrupted run from a complete one.
#[test]
fn a_signal_ends_the_run_with_the_shells_status() {
    let _cpu = serial();
    for (sig, code) in [(Signal::SIGINT, 130), (Signal::SIGTERM, 143)] {
        let rx = receiver();
        let dest = rx.local_addr().unwrap().to_string();
        let child = spawn_run(&["--rate", "200", "--duration", "60", "--udp", &dest]);
        rx.recv(&mut [0u8; 2048]).expect("frames within 10 s");
        kill(Pid::from_raw(child.id() as i32), sig).unwrap();
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{sig}: {err}");
        assert!(
            err.contains(&format!("interrupted by {sig}: ")) && err.contains(" of 12000 records"),
            "{err}"
        );
        assert!(!err.contains("error"), "{err}");
    }
}

/// Two runs on one `--pty` path: the second is refused and the link stays the first's; with
/// `--take-over` a third replaces it, the first (ending) leaves the third's link alone, and
/// the third removes it when it ends.
#[test]
fn a_pty_link_has_one_owner() {
    let _cpu = serial();
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("imu");
    let path = link.to_str().unwrap();
    let first = spawn_run(&["--rate", "100", "--duration", "60", "--pty", path]);
    wait_for(&link);
    let first_pts = std::fs::read_link(&link).unwrap();
    let out = imu_emu(&["run", "--duration", "1", "--pty", path])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("in use") && err.contains("--take-over"),
        "{err}"
    );
    assert_eq!(std::fs::read_link(&link).unwrap(), first_pts);
    let third = spawn_run(&[
        "--rate",
        "100",
        "--duration",
        "60",
        "--take-over",
        "--pty",
        path,
    ]);
    let t = Instant::now();
    while std::fs::read_link(&link).is_ok_and(|p| p == first_pts) {
        assert!(t.elapsed() < Duration::from_secs(20), "no take-over");
        std::thread::sleep(Duration::from_millis(10));
    }
    let third_pts = std::fs::read_link(&link).unwrap();
    for (child, owns) in [(first, false), (third, true)] {
        kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).unwrap();
        let out = child.wait_with_output().unwrap();
        assert_eq!(out.status.code(), Some(130));
        let left = std::fs::read_link(&link).ok();
        if owns {
            assert_eq!(left, None, "the owner left its link behind");
        } else {
            assert_eq!(
                left,
                Some(third_pts.clone()),
                "a run removed a link it lost"
            );
        }
    }
}

/// Log lines on a stderr that is not a terminal are plain text: no colour escapes.
#[test]
fn logs_to_a_pipe_are_plain() {
    let _cpu = serial();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("f.bin");
    let out = output(&[
        "run",
        "-v",
        "--duration",
        "0.1",
        "--file",
        file.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(" INFO ") && !err.contains('\x1b'), "{err:?}");
}
