//! `examples/hil.rs` built by cargo and run as a user would: a loopback sender streams the
//! survey scene's states at 100 Hz, tagged with the host's GPS time, to its UDP input; the
//! `nav` unit's iXCOM frames are read from its pty, the `aux` unit's RAWIMUSX frames and the
//! NMEA sentences from UDP, all decoded with the library's decoders (NMEA's ZDA by hand: the
//! library writes NMEA but has no reader). Ctrl-C (SIGINT) stops the program through its
//! `Control`, and its summary follows.
//!
//! Checked: both units' frames and the GNSS epochs arrive whole (no check failure, no counter
//! gap) and carry the GPS time of the states — the sender's week, times of week inside the
//! span of the states sent, one record interval (or one epoch interval) apart, each unit on
//! its own grid. A run dated on UTC instead of GPS time would be 18 s off, on the simulation's
//! own time base weeks off: both fail the span check.

use std::io::{BufRead, BufReader, Read};
use std::net::UdpSocket;
use std::os::fd::AsFd;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use imu_emu::protocol::spec::Source;
use imu_emu::protocol::{StreamDecoder, load};
use imu_emu::realtime::hostclock::GpsClock;
use imu_emu::timebase::LeapTable;

/// Seconds of states sent.
const SECONDS: f64 = 3.0;
/// GPS − UTC over the test's lifetime (s).
const LEAP_S: f64 = 18.0;
const WEEK_S: f64 = 604_800.0;

/// Builds the example with the test's profile and target directory; its path.
fn example() -> PathBuf {
    // The test binary is TARGET/PROFILE/deps/NAME; cargo puts examples in TARGET/PROFILE/examples.
    let exe = std::env::current_exe().unwrap();
    let profile_dir = exe.parent().unwrap().parent().unwrap().to_path_buf();
    let profile = match profile_dir.file_name().unwrap().to_str().unwrap() {
        "debug" => "dev",
        p => p,
    };
    let built = Command::new(env!("CARGO"))
        .args(["build", "--quiet", "--example", "hil", "--profile", profile])
        .arg("--target-dir")
        .arg(profile_dir.parent().unwrap())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .status()
        .unwrap();
    assert!(built.success(), "cargo build --example hil");
    profile_dir.join("examples").join("hil")
}

/// A free loopback UDP port (bound, then released for the program to bind).
fn free_port() -> u16 {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.local_addr().unwrap().port()
}

/// The survey's states at 100 Hz for `SECONDS`, their time column replaced by GPS week and
/// seconds from `gps0` (s since the GPS epoch); the tags, in the same order.
fn states(gps0: f64) -> (Vec<String>, Vec<f64>) {
    let sim = imu_emu::sim::Simulation::builder().build().unwrap();
    let n = (SECONDS * 100.0) as u64;
    let csv = imu_emu::trajectory::sample_motion(sim.motion(), 0.0, 100.0, n, None);
    let mut lines = vec!["gps_week,gps_sow,lat,lon,h,vn,ve,vd,roll,pitch,yaw".to_string()];
    let mut tags = Vec::new();
    for l in csv.lines().skip(1) {
        let (t, rest) = l.split_once(',').unwrap();
        let g = gps0 + t.parse::<f64>().unwrap();
        let week = (g / WEEK_S).floor();
        lines.push(format!("{week},{:.6},{rest}", g - week * WEEK_S));
        tags.push(g);
    }
    (lines, tags)
}

/// A reader of datagrams on its own thread, until none is left once `done` is set.
fn udp_reader(sock: UdpSocket, done: Arc<AtomicBool>) -> std::thread::JoinHandle<Vec<Vec<u8>>> {
    sock.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    // A reader thread not scheduled for a while loses nothing.
    imu_emu::realtime::udp::grow_receive_buffer(&sock);
    std::thread::spawn(move || {
        let (mut got, mut buf) = (Vec::new(), [0u8; 4096]);
        loop {
            match sock.recv(&mut buf) {
                Ok(n) => got.push(buf[..n].to_vec()),
                Err(_) if done.load(Ordering::Relaxed) => return got,
                Err(_) => {}
            }
        }
    })
}

/// The pty published at `link`, opened raw and read on its own thread until it closes.
fn pty_reader(link: &Path) -> std::thread::JoinHandle<Vec<u8>> {
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(link)
        .unwrap();
    let mut t = nix::sys::termios::tcgetattr(f.as_fd()).unwrap();
    nix::sys::termios::cfmakeraw(&mut t);
    nix::sys::termios::tcsetattr(f.as_fd(), nix::sys::termios::SetArg::TCSANOW, &t).unwrap();
    std::thread::spawn(move || {
        let (mut got, mut buf) = (Vec::new(), [0u8; 4096]);
        // The master closing (EIO) ends the stream.
        while let Ok(n) = f.read(&mut buf) {
            if n == 0 {
                break;
            }
            got.extend_from_slice(&buf[..n]);
        }
        got
    })
}

/// Each frame's GPS time (s since the GPS epoch) from `bytes` in `protocol`; fails on a frame
/// that does not check.
fn frame_times(protocol: &str, chunks: &[Vec<u8>]) -> Vec<f64> {
    let (_, plan) = load(protocol).unwrap();
    let mut dec = StreamDecoder::new(plan);
    let mut out = Vec::new();
    for c in chunks {
        dec.feed(c, |f| {
            let week = f.get(Source::GpsWeek).unwrap();
            let sow = match f.get(Source::GpsSeconds) {
                Some(s) => s,
                None => {
                    f.get(Source::GpsWholeSeconds).unwrap()
                        + f.get(Source::GpsMicros).unwrap() * 1e-6
                }
            };
            out.push(week * WEEK_S + sow);
        });
    }
    let s = dec.stats();
    assert_eq!(
        (s.check_failures, s.framing_errors),
        (0, 0),
        "{protocol}: {s:?}"
    );
    out
}

/// The frames of unit `unit` the summary says were not delivered: skipped as too late, or
/// dropped by its sinks (a slow consumer, no reader yet).
fn reported_lost(summary: &str, unit: &str) -> u64 {
    let number = |line: &str, what: &str| -> u64 {
        match line.split_once(what) {
            Some((head, _)) => head.rsplit([',', ' ']).next().unwrap().parse().unwrap(),
            None => 0,
        }
    };
    let mut lines = summary
        .lines()
        .skip_while(|l| !l.trim_start().starts_with(&format!("unit {unit}: ")));
    let head = lines
        .next()
        .unwrap_or_else(|| panic!("unit {unit} in {summary}"));
    let mut lost = number(head, " skipped (too late)");
    // Its sinks' lines, up to the next unit's or stream's.
    let other =
        |l: &str| l.trim_start().starts_with("unit ") || l.trim_start().starts_with("stream ");
    for l in lines.take_while(|l| !other(l)) {
        lost += number(l, " dropped (slow consumer)") + number(l, " dropped (no reader)");
    }
    lost
}

/// GPS time (s since the GPS epoch) of each epoch's ZDA sentence, its checksum checked.
fn zda_times(datagrams: &[Vec<u8>]) -> Vec<f64> {
    let text: String = datagrams
        .iter()
        .map(|d| String::from_utf8(d.clone()).unwrap())
        .collect();
    let mut out = Vec::new();
    for l in text.lines().filter(|l| l.starts_with("$GPZDA")) {
        let (body, sum) = l[1..].split_once('*').unwrap();
        let xor = body.bytes().fold(0u8, |a, b| a ^ b);
        assert_eq!(u8::from_str_radix(sum, 16).unwrap(), xor, "{l}");
        let f: Vec<&str> = body.split(',').collect();
        let sod = 3600.0 * f[1][0..2].parse::<f64>().unwrap()
            + 60.0 * f[1][2..4].parse::<f64>().unwrap()
            + f[1][4..].parse::<f64>().unwrap();
        let (d, m, y): (u32, u32, i32) = (
            f[2].parse().unwrap(),
            f[3].parse().unwrap(),
            f[4].parse().unwrap(),
        );
        let days = days_since_gps_epoch(y, m, d);
        out.push(days as f64 * 86_400.0 + sod + LEAP_S);
    }
    out
}

/// Days from 1980-01-06 to the civil date (proleptic Gregorian; H. Hinnant's days_from_civil).
fn days_since_gps_epoch(y: i32, m: u32, d: u32) -> i64 {
    let civil = |y: i32, m: u32, d: u32| -> i64 {
        let y = if m <= 2 { y - 1 } else { y } as i64;
        let era = y.div_euclid(400);
        let yoe = y - era * 400;
        let mp = (m as i64 + 9) % 12;
        let doy = (153 * mp + 2) / 5 + d as i64 - 1;
        era * 146_097 + yoe * 365 + yoe / 4 - yoe / 100 + doy
    };
    civil(y, m, d) - civil(1980, 1, 6)
}

/// Times `ts` (s since the GPS epoch) are `dt` apart in order — or whole multiples of it where
/// frames were lost, `lost` at most, as the run reported — none before the first state (the
/// model's first knot is later still) nor after `now` (the host's GPS time once every frame was
/// read: a real-time run sends a record after its time of validity).
fn check_times(
    what: &str,
    ts: &[f64],
    (dt, tol): (f64, f64),
    lost: u64,
    first_state: f64,
    now: f64,
    min: usize,
) {
    assert!(
        ts.len() >= min,
        "{what}: {} frames, expected at least {min}",
        ts.len()
    );
    let mut missing = 0;
    for w in ts.windows(2) {
        let steps = ((w[1] - w[0]) / dt).round();
        assert!(
            steps >= 1.0 && (w[1] - w[0] - steps * dt).abs() < tol,
            "{what}: {} then {}",
            w[0],
            w[1]
        );
        missing += steps as u64 - 1;
    }
    assert!(
        missing <= lost,
        "{what}: {missing} frames missing, {lost} reported lost"
    );
    let (first, last) = (ts[0], *ts.last().unwrap());
    assert!(
        first >= first_state && last <= now,
        "{what}: frames from {first} to {last} s, the first state at {first_state} s, GPS time now {now} s"
    );
}

#[test]
fn hil_example_streams_a_two_unit_rig_and_nmea_on_gps_time() {
    let bin = example();
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("imu-nav");
    let input = free_port();
    let aux_rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    let gnss_rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut child = Command::new(bin)
        .arg(format!("udp://127.0.0.1:{input}"))
        .arg(&link)
        .arg(aux_rx.local_addr().unwrap().to_string())
        .arg(gnss_rx.local_addr().unwrap().to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut notes = String::new();
    while !notes.contains("following udp://") {
        let mut line = String::new();
        assert!(
            err.read_line(&mut line).unwrap() > 0,
            "the program starts: {notes}"
        );
        notes += &line;
    }
    let pty = pty_reader(&link);
    let done = Arc::new(AtomicBool::new(false));
    let (aux, gnss) = (
        udp_reader(aux_rx, done.clone()),
        udp_reader(gnss_rx, done.clone()),
    );

    let clock = GpsClock::new(LeapTable::builtin());
    let start = Instant::now();
    let gps0 = clock.now_gps_ns() as f64 * 1e-9;
    let (lines, tags) = states(gps0);
    let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
    tx.send_to(lines[0].as_bytes(), ("127.0.0.1", input))
        .unwrap();
    for (l, g) in lines[1..].iter().zip(&tags) {
        let at = start + Duration::from_secs_f64(g - gps0);
        if let Some(d) = at.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
        tx.send_to(l.as_bytes(), ("127.0.0.1", input)).unwrap();
    }
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
    let mut summary = String::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut summary)
        .unwrap();
    let status = child.wait().unwrap();
    done.store(true, Ordering::Relaxed);
    println!("{notes}{rest}{summary}");
    assert!(status.success(), "{rest}");
    assert!(rest.contains("| nav: "), "status lines: {rest}");
    assert!(
        summary.contains("unit nav: ") && summary.contains("unit aux: "),
        "{summary}"
    );

    let now = clock.now_gps_ns() as f64 * 1e-9;
    let nav = frame_times("imar-ixcom", &[pty.join().unwrap()]);
    // iXCOM carries whole microseconds.
    let lost = reported_lost(&summary, "nav");
    check_times("nav", &nav, (1.0 / 400.0, 2e-6), lost, tags[0], now, 400);
    let aux = frame_times("novatel-rawimusx", &aux.join().unwrap());
    let lost = reported_lost(&summary, "aux");
    check_times("aux", &aux, (1.0 / 125.0, 1e-6), lost, tags[0], now, 125);
    let epochs = zda_times(&gnss.join().unwrap());
    // ZDA carries hundredths of a second; epochs fall on whole fifths of a GPS second.
    check_times("gnss", &epochs, (0.2, 0.011), 0, tags[0], now, 5);
    for t in &epochs {
        let fifths = t * 5.0;
        assert!((fifths - fifths.round()).abs() < 0.06, "epoch at {t} s");
    }
    println!(
        "nav {} frames from {:.3} s, aux {} frames from {:.3} s, {} NMEA epochs from {:.2} s (GPS s of week)",
        nav.len(),
        nav[0] % WEEK_S,
        aux.len(),
        aux[0] % WEEK_S,
        epochs.len(),
        epochs[0] % WEEK_S
    );
}
