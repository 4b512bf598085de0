//! The real-time emulator end to end: `imu-emu run` on a pty, on UDP loopback and into files,
//! checked against `imu-emu generate`'s bytes for the same seed. Timing bounds are generous
//! (the VM stalls for milliseconds); timing figures belong to `benches/latency.rs`.

use std::io::Read;
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use imu_emu::protocol::{StreamDecoder, load};

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

/// Reads a serial port for `secs`, returning what arrived.
fn read_for(port: &mut serialport::TTYPort, secs: f64) -> Vec<u8> {
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    let t = Instant::now();
    while t.elapsed().as_secs_f64() < secs {
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
/// mid-run and gets frames again; the run ends on time and removes its link.
#[test]
fn pty_stream_is_generate_and_survives_reopen() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("imu");
    let common = ["--rate", "1000", "--duration", "6", "--seed", "7"];
    let reference = reference(&common);
    let len = load(PROTOCOL).unwrap().1.len();
    let started = Instant::now();
    let child = spawn_run(
        &[
            &common[..],
            &["--speed", "2", "--pty", link.to_str().unwrap()],
        ]
        .concat(),
    );
    wait_for(&link);
    let mut port = open_port(&link);
    let first = read_for(&mut port, 0.8);
    drop(port);
    std::thread::sleep(Duration::from_millis(200));
    let mut port = open_port(&link);
    let second = read_for(&mut port, 0.8);
    drop(port);
    let err = finish(child);
    let took = started.elapsed().as_secs_f64();
    // 0.8 s at 2000 frames/s: well over 500 frames each, whatever the machine's stalls.
    let (n1, jumps1) = frames_in_order(&first, &reference, len);
    let (n2, jumps2) = frames_in_order(&second, &reference, len);
    assert!(n1 > 500 && n2 > 500, "{n1}, {n2} frames: {err}");
    // Counters are continuous unless the emulator says it dropped or skipped frames.
    if jumps1 + jumps2 > 0 {
        let lost = count_in(&err, "dropped (slow consumer)") + count_in(&err, "skipped (too late)");
        assert!(
            lost > 0,
            "{jumps1}+{jumps2} gaps the emulator did not count: {err}"
        );
    }
    assert!(took < 15.0, "a 3 s run took {took:.1} s");
    assert!(err.contains("6000 of 6000 frames"), "{err}");
    assert!(
        link.symlink_metadata().is_err(),
        "the pty link was left behind"
    );
}

/// A reader that opens the pty and never reads: the run still ends on time, the frames that
/// did not fit are dropped and counted.
#[test]
fn stalled_reader_never_slows_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("stalled");
    let started = Instant::now();
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
    let took = started.elapsed().as_secs_f64();
    assert!(took < 10.0, "a 2 s run took {took:.1} s: {err}");
    let dropped = count_in(&err, "dropped (slow consumer)");
    // 4000 frames × 36 B = 144 kB into a pty that holds a few tens of kB.
    assert!(dropped > 1000, "{err}");
}

/// UDP loopback: every datagram is one frame, and together they are generate's bytes.
#[test]
fn udp_datagrams_are_generate_frames() {
    let rx = receiver();
    let dest = rx.local_addr().unwrap().to_string();
    let common = ["--rate", "1000", "--duration", "1", "--seed", "9"];
    let reference = reference(&common);
    let len = load(PROTOCOL).unwrap().1.len();
    let child = spawn_run(&[&common[..], &["--speed", "4", "--udp", &dest]].concat());
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
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dest = format!("127.0.0.1:{port}");
    let started = Instant::now();
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
    assert!(err.contains("400 of 400 frames"), "{err}");
    assert!(started.elapsed() < Duration::from_secs(10));
}

/// `decode --udp-listen` is the consumer side: it decodes the emulator's datagrams live
/// (unicast to `host`, or a multicast group it joins).
fn decode_over_udp(host: &str) {
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
        "20",
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
        finish(spawn_run(
            &[
                &common[..],
                &["--speed", speed, "--file", out.to_str().unwrap()],
            ]
            .concat(),
        ));
        assert!(std::fs::read(&out).unwrap() == reference, "--speed {speed}");
    }
}

/// Refusals name what is wrong: a serial link too slow for the frames, a bad speed or instant.
#[test]
fn refuses_impossible_settings() {
    for (args, says) in [
        (
            &["--serial", "/dev/null", "--baud", "9600", "--rate", "1000"][..],
            "bit/s",
        ),
        (&["--speed", "0"][..], "--speed 0"),
        (&["--start-at", "tomorrow"][..], "--start-at"),
        (&["--protocol", "csv"][..], "generate"),
    ] {
        let out = imu_emu(&[&["run", "--duration", "1"], args].concat())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(says),
            "{args:?}: {err}"
        );
    }
}

/// `--serial` on a tty (the slave of a pty pair the test holds, standing in for a UART):
/// the bytes at the other end are generate's.
#[test]
fn serial_sink_writes_generate_frames() {
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

/// `--start-at` an instant 1.5 s ahead: nothing goes out before it, the run ends on time.
#[test]
fn start_at_delays_the_first_frame() {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
        + 1.5;
    let (s, frac) = (secs.floor() as i64, secs.fract());
    // Civil date of `s` (the test's own conversion, independent of the emulator's parser).
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
    let at = format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{:06}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60,
        (frac * 1e6) as u64
    );
    let started = Instant::now();
    let err = finish(spawn_run(&[
        "--rate",
        "400",
        "--duration",
        "0.5",
        "--protocol",
        PROTOCOL,
        "--udp",
        "127.0.0.1:9",
        "--start-at",
        &at,
    ]));
    let took = started.elapsed().as_secs_f64();
    assert!(
        (1.9..10.0).contains(&took),
        "took {took:.2} s for {at}: {err}"
    );
    assert!(err.contains("200 of 200 frames"), "{err}");
}

/// Sinks with their own protocol: the same records as stim300 frames on one UDP port and as
/// the main protocol's in a file, each exactly `generate --format` of that protocol.
#[test]
fn each_sink_its_own_protocol() {
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
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("fifo.bin");
    let common = ["--scene", "static", "--rate", "200", "--duration", "0.5"];
    let out = Command::new("setpriv")
        .args(["--bounding-set", "-sys_nice", "--inh-caps", "-sys_nice"])
        .arg(env!("CARGO_BIN_EXE_imu-emu"))
        .args(["run", "--protocol", PROTOCOL, "--realtime", "--speed", "1"])
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
