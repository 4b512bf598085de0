//! Every combination of issue 22's table, end to end through the `imu-emu` binary over real
//! loopback parts (UDP sockets, files, a pipe; a software PPS as UDP edge messages): each
//! test runs one row and compares its bytes with the run the clock allows — the offline
//! `generate` of the same scene and seeds for a paced run, the lockstep replay of the run's
//! own `--record-input` for a live real-time run (the frames before the newest state are
//! lockstep's bytes; what follows is the bounded extrapolation until the input's timeout).
//! docs/run.md lists the rows and what each does.
//!
//! A rig unit with `[output_filter]`/`[timing]`, one IMU with `[output_filter]` + `--trigger`
//! and `compare` on aided scenes have their own test targets (tests/rig_units.rs,
//! tests/rig_units_run.rs, tests/rig_trigger.rs,
//! tests/compare.rs).

use std::path::Path;

#[path = "common/hil.rs"]
mod hil;
#[path = "common/realtime_run.rs"]
mod rt;
use hil::{
    Tagged, failed, free_udp_port, imu_emu, joined, marks, number_before, ok, receive, start,
    survey_rows,
};

/// Real-time runs here trail their input by 200 ms: far more than a loopback datagram takes
/// on a loaded machine, so every frame before the newest state is interpolated (never a
/// correction), and the bytes compare exactly.
const DELAY: &str = "0.2";

/// The states are sent this much ahead of their tags (a simulator running ahead): 51.25 ms,
/// half a 400 Hz period off the records' grid.
const AHEAD_NS: i128 = 51_250_000;

/// Each time mark's time of validity, on the host's clock, is its record's GPS instant plus
/// the output delay: the GPS time base put the tags on the host's GPS clock. The run converts
/// the tags to the monotonic clock and the marks back to UTC through one reading of the
/// clocks' offset, so its offset from the tags' 2.5 ms grid is the rounding of a record time
/// (GPS seconds of the week in an f64, 1.2e-10 s apart) to whole nanoseconds: at most 1 ns.
/// On the sim time base the first state's arrival (51.25 ms before its tag, plus the
/// loopback's µs) would set t₀, about 1.25 ms off that grid.
fn on_the_tags(m: &[[i128; 5]], tags: &Tagged) {
    assert!(!m.is_empty());
    for r in m {
        let off = hil::gps_of_utc(r[2]) - 200_000_000 - tags.first_ns;
        let residual = (off + 1_250_000).rem_euclid(2_500_000) - 1_250_000;
        assert!(
            residual.abs() <= 1,
            "{r:?}: {residual} ns off the tags' grid"
        );
    }
}

/// What a live run's summary says of where its output left its input.
struct Left {
    /// The output's frames are the input's (a lockstep replay's) up to this time (s); past the
    /// newest state of all, every frame was made from the input.
    until: f64,
    /// A state came after the delay before the input's end, so the run extrapolated and
    /// corrected mid-run (possible on a loaded machine).
    mid_run: bool,
    /// Frames past the newest state of the moment, over the run.
    extrapolated: usize,
    /// Frames past the newest state of all, at most: the run stops extrapolating once the
    /// silence that ends it is over (`--on-timeout stop`), the input's timeout after the newest
    /// state arrived, which is at most the arrival jitter the run reports after its tag's
    /// instant. Per stream, at `rate`, in [`Left::past`].
    span: f64,
}

impl Left {
    /// Reads the summary in `err`; `newest` is the newest state's time (s) and `timeout` the
    /// input's timeout (s).
    fn read(err: &str, newest: f64, timeout: f64) -> Left {
        let summary = err
            .lines()
            .find(|l| l.contains("extrapolated)"))
            .unwrap_or_else(|| panic!("a live summary: {err}"));
        let extrapolated = number_before(summary, "extrapolated)") as usize;
        let jitter = hil::number_after(summary, "jitter ") * 1e-3;
        let left = rt::departed(summary).unwrap_or(f64::INFINITY);
        // The times are GPS seconds of the week: 1e-6 s is far above their rounding.
        let mid_run = left < newest - 1e-6;
        if mid_run {
            eprintln!(
                "the output left the input at {left} s, before its end at {newest} s: {summary}"
            );
        }
        Left {
            until: left.min(newest),
            mid_run,
            extrapolated,
            span: timeout + jitter,
        }
    }

    /// Most records of a stream at `rate` past the newest state: those in the span, and one
    /// for the grid's phase.
    fn past(&self, rate: f64) -> usize {
        (self.span * rate).ceil() as usize + 1
    }
}

/// A live stream of fixed-size frames (`size` bytes, `rate` Hz from `t0`) is the lockstep
/// replay's up to where the run left its input, and has no more frames past the newest state
/// than the run extrapolated, nor than the silence allows.
fn frames_follow(
    what: &str,
    live: &[u8],
    replay: &[u8],
    (size, rate, t0): (usize, f64, f64),
    l: &Left,
) {
    assert!(!replay.is_empty(), "{what}: the replay wrote nothing");
    assert_eq!(live.len() % size, 0, "{what}: whole frames");
    let same = rt::records_to(t0, rate, l.until).min(replay.len() / size) * size;
    assert!(
        live.len() >= same && live[..same] == replay[..same],
        "{what}: the live frames up to {} s are not the lockstep replay's",
        l.until
    );
    if !l.mid_run {
        assert!(
            live.starts_with(replay),
            "{what}: the live bytes ({}) do not begin with the lockstep replay's ({})",
            live.len(),
            replay.len()
        );
    }
    let past = (live.len() / size).saturating_sub(replay.len() / size);
    assert!(
        past <= l.extrapolated && past <= l.past(rate),
        "{what}: {past} frames past the replay's, {} extrapolated, {} at most in the silence",
        l.extrapolated,
        l.past(rate)
    );
}

/// A live text stream (CSV rows, NMEA sentences: `per` lines per epoch at `rate` Hz) begins
/// with the lockstep replay's lines and has at most the silence's epochs more; compared only
/// when the run never left its input before the end (text lines carry no grid to cut at).
fn lines_follow(what: &str, live: &[u8], replay: &[u8], (per, rate): (usize, f64), l: &Left) {
    let (live, replay) = (
        String::from_utf8_lossy(live).into_owned(),
        String::from_utf8_lossy(replay).into_owned(),
    );
    let (live, replay): (Vec<&str>, Vec<&str>) = (live.lines().collect(), replay.lines().collect());
    assert!(!replay.is_empty(), "{what}: the replay wrote nothing");
    if l.mid_run {
        eprintln!("{what}: not compared, the run left its input before its end");
        return;
    }
    assert!(
        live.starts_with(&replay),
        "{what}: the live lines ({}) do not begin with the lockstep replay's ({})",
        live.len(),
        replay.len()
    );
    let past = live.len() - replay.len();
    assert!(
        past <= per * l.past(rate),
        "{what}: {past} lines past the replay's, at most {per} × {}",
        l.past(rate)
    );
}

/// Starts `imu-emu BEFORE --motion udp://127.0.0.1:PORT AFTER` in `dir`, in real time on the
/// GPS time base, [`DELAY`] behind its input, which ends after 0.5 s of silence and is
/// recorded to `dir/in.rec`.
fn start_live(dir: &Path, port: u16, before: &[&str], after: &[&str]) -> hil::Started {
    let motion = format!("udp://127.0.0.1:{port}");
    let mut args = before.to_vec();
    args.extend([
        "--motion",
        &motion,
        "--time-base",
        "gps",
        "--output-delay",
        DELAY,
    ]);
    // No frame is skipped as late: the bytes are compared with the replay's.
    args.extend(["--input-timeout", "0.5", "--record-input", "in.rec"]);
    args.extend(["--max-behind-ms", "60000"]);
    args.extend_from_slice(after);
    start(dir, &args)
}

/// Replays the input a real-time run recorded in `dir/in.rec`, in lockstep, with `args`.
fn replay(dir: &Path, args: &[&str]) -> String {
    let mut all = vec![
        "run",
        "--motion",
        "in.rec",
        "--time-mode",
        "lockstep",
        "--time-base",
        "gps",
    ];
    all.extend_from_slice(args);
    ok(&imu_emu(dir, &all))
}

/// NMEA sentences per epoch of `text`: its lines over its GGA sentences.
fn per_epoch(text: &[u8]) -> usize {
    let text = String::from_utf8_lossy(text);
    let epochs = text.lines().filter(|l| l.starts_with("$GPGGA")).count();
    assert!(epochs > 0, "{text}");
    text.lines().count().div_ceil(epochs)
}

/// Seconds of the day of an NMEA `hhmmss.ss` field.
fn seconds_of_day(hms: &str) -> f64 {
    let h: f64 = hms[0..2].parse().unwrap();
    let m: f64 = hms[2..4].parse().unwrap();
    let s: f64 = hms[4..].parse().unwrap();
    3600.0 * h + 60.0 * m + s
}

/// Row 1: live `--motion` + `--gnss nmea:…` + odometer, barometer and magnetometer +
/// `--time-base gps`. GPS-tagged states go over UDP at their instants on the host's GPS
/// clock; the IMU frames and the NMEA epochs go to UDP receivers, the sensors' rows to
/// files. Every stream begins with the bytes the lockstep replay of the recorded input
/// writes; the NMEA times are the tags' UTC (GPS − 18 s), so the GPS time base was used (on
/// the sim time base the epochs would be dated from 1980).
#[test]
fn live_motion_with_gnss_and_sensors_on_gps_time() {
    let _rt = rt::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rows = survey_rows(d, 2.0);
    let port = free_udp_port();
    let (imu_to, imu_rx) = receive();
    let (gnss_to, gnss_rx) = receive();
    let gnss = format!("nmea:udp:{gnss_to}");
    let run = start_live(
        d,
        port,
        &["run"],
        &[
            "--udp",
            &imu_to,
            "--gnss",
            &gnss,
            "--odometer",
            "file:odo.csv",
            "--baro",
            "file:baro.csv",
            "--magnetometer",
            "file:mag.csv",
        ],
    );
    let tagged = Tagged::from_now(rows, 0.3);
    tagged.send(port);
    let err = run.finish();
    let imu = joined(&imu_rx.join().unwrap());
    let nmea = joined(&gnss_rx.join().unwrap());
    replay(
        d,
        &[
            "--file",
            "imu.bin",
            "--gnss",
            "nmea:file:gnss.nmea",
            "--odometer",
            "file:odo2.csv",
            "--baro",
            "file:baro2.csv",
            "--magnetometer",
            "file:mag2.csv",
        ],
    );
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    let l = Left::read(&err, tagged.newest_sow(), 0.5);
    let t0 = hil::number_after(&err, "from t = ");
    // LN-200 frames: 26 bytes at 400 Hz; NMEA epochs at 5 Hz, the sensors' rows at 10 Hz.
    frames_follow("imu", &imu, &read("imu.bin"), (26, 400.0, t0), &l);
    let per = per_epoch(&read("gnss.nmea"));
    lines_follow("nmea", &nmea, &read("gnss.nmea"), (per, 5.0), &l);
    for (live, again) in [
        ("odo.csv", "odo2.csv"),
        ("baro.csv", "baro2.csv"),
        ("mag.csv", "mag2.csv"),
    ] {
        lines_follow(live, &read(live), &read(again), (1, 10.0), &l);
    }
    // The NMEA epochs' UTC lies within the tags' span, less the 18 leap seconds.
    let text = String::from_utf8(nmea).unwrap();
    let day = |ns: i128| ((ns - 18_000_000_000).rem_euclid(86_400_000_000_000)) as f64 / 1e9;
    let (lo, hi) = (day(tagged.tag_ns(0)), day(tagged.tag_ns(tagged.rows.len())));
    let epochs: Vec<f64> = (text.lines())
        .filter(|l| l.starts_with("$GPGGA"))
        .map(|l| seconds_of_day(l.split(',').nth(1).unwrap()))
        .collect();
    assert!(epochs.len() >= 8, "{text}");
    for t in &epochs {
        assert!(
            (lo..=hi + 0.5).contains(t),
            "{t} outside {lo}..{hi}: {text}"
        );
    }
}

/// The rig scene [`hil::TWO_UNITS`] with `extra` after its units, in `dir/rig.toml`.
fn rig_scene(dir: &Path, extra: &str) -> std::path::PathBuf {
    let p = dir.join("rig.toml");
    std::fs::write(&p, format!("{}{extra}", hil::TWO_UNITS)).unwrap();
    p
}

/// A live rig on GPS time: the rig scene's units follow GPS-tagged states over UDP in real
/// time with `--time-base gps`, `nav` to a UDP receiver, `tac` to a file, plus whatever
/// `extra` routes. Returns the run's stderr, `nav`'s bytes and the states sent; the input is
/// in `dir/in.rec`.
fn live_rig(dir: &Path, scene: &Path, extra: &[&str]) -> (String, Vec<u8>, Tagged) {
    let rows = survey_rows(dir, 2.0);
    let port = free_udp_port();
    let (nav_to, nav_rx) = receive();
    let nav = format!("nav=udp:{nav_to}");
    let mut args = vec!["--unit-sink", &nav, "--unit-sink", "tac=file:tac.csv"];
    args.extend_from_slice(extra);
    let run = start_live(dir, port, &["run", scene.to_str().unwrap()], &args);
    let tags = Tagged::from_now(rows, 0.3);
    tags.send_ahead(port, AHEAD_NS);
    let err = run.finish();
    (err, joined(&nav_rx.join().unwrap()), tags)
}

/// The first time column of a CSV file's first row after its header.
fn first_t(csv: &[u8]) -> f64 {
    let text = String::from_utf8_lossy(csv);
    let row = text.lines().find(|l| !l.starts_with(['#', 't'])).unwrap();
    row.split(',').next().unwrap().parse().unwrap()
}

/// Row 2: a rig (`[[imu]]`) following live `--motion` on `--time-base gps`. Each unit's
/// stream begins with the lockstep replay's bytes for that unit. The GPS time base maps the
/// tags onto the host's clock: every `nav` time mark's time of validity (UTC) plus the 18
/// leap seconds falls exactly on the 2.5 ms grid of the tags (on the sim time base it would
/// be the first state's arrival, microseconds off any grid), and is due exactly the output
/// delay later.
#[test]
fn live_rig_on_gps_time() {
    let _rt = rt::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = rig_scene(d, "");
    let (err, nav, tags) = live_rig(d, &scene, &["--time-marks", "nav=marks.csv"]);
    replay(
        d,
        &[
            scene.to_str().unwrap(),
            "--unit-sink",
            "nav=file:nav.bin",
            "--unit-sink",
            "tac=file:tac2.csv",
        ],
    );
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    let l = Left::read(&err, tags.newest_sow(), 0.5);
    let t0 = hil::number_after(&err, "from t = ");
    frames_follow("nav", &nav, &read("nav.bin"), (26, 400.0, t0), &l);
    lines_follow("tac", &read("tac.csv"), &read("tac2.csv"), (1, 100.0), &l);
    let t = first_t(&read("tac.csv"));
    assert!(t > 0.0 && t < 604_800.0, "{t}: {err}");
    let m = marks(&d.join("marks.csv"));
    assert_eq!(m.len(), nav.len() / 26, "one mark per nav frame: {err}");
    on_the_tags(&m, &tags);
}

/// The host's UTC now (ns since the Unix epoch).
fn utc_now_ns() -> i128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as i128
}

/// Sends a software PPS: an 8-byte edge message (its CLOCK_REALTIME instant) to `port` at
/// each whole UTC second in (`from_ns`, `to_ns`); how many were sent.
fn send_pps(port: u16, from_ns: i128, to_ns: i128) -> usize {
    let s = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut sent = 0;
    let mut edge = (from_ns / 1_000_000_000 + 1) * 1_000_000_000;
    while edge < to_ns {
        while utc_now_ns() < edge {
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
        s.send_to(&(edge as i64).to_le_bytes(), ("127.0.0.1", port))
            .unwrap();
        sent += 1;
        edge += 1_000_000_000;
    }
    sent
}

/// A UTC instant (ns since the Unix epoch, whole seconds) as RFC 3339.
fn rfc3339(utc_ns: i128) -> String {
    let out = std::process::Command::new("date")
        .args(["-u", "-d", &format!("@{}", utc_ns / 1_000_000_000)])
        .arg("+%Y-%m-%dT%H:%M:%SZ")
        .output()
        .unwrap();
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

/// The edges a run's summary says its PPS lock took.
fn lock_edges(err: &str) -> usize {
    let line = err
        .lines()
        .find(|l| l.contains("PPS lock"))
        .unwrap_or_else(|| {
            panic!("no PPS lock in the summary: {err}");
        });
    number_before(line, "edges") as usize
}

/// Row 3: a rig + `--time-marks` + `--pps-in` (a software PPS over UDP), paced at real time
/// from a whole second: `nav`'s frames reach a UDP receiver and `tac`'s rows a file, each the
/// offline `generate`'s bytes of that unit; one mark per `nav` frame, on its 2.5 ms grid; the
/// lock took every edge sent. `--pulse` needs a modem line: without a serial port it is
/// refused naming the flag and the way out; with `--pulse-port` it is described as marking
/// the unit asked for (its edges: the next test).
#[test]
fn rig_with_time_marks_pps_and_pulse() {
    let _rt = rt::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = rig_scene(d, "[output]\nduration_s = 2.0\n");
    let s = scene.to_str().unwrap();
    ok(&imu_emu(d, &["generate", s, "-o", "offline"]));
    // t₀ at a whole second 1 to 2 s ahead, as RFC 3339. The run refuses an instant already
    // past when it starts; a machine that took longer than that to start it is told so by the
    // run, and the row is run again at a later second (three tries).
    let mut tries = 0;
    let (out, sent, nav_rx) = loop {
        tries += 1;
        let pps_port = free_udp_port();
        let (nav_to, nav_rx) = receive();
        let t0 = (utc_now_ns() / 1_000_000_000 + 2) * 1_000_000_000;
        let at = rfc3339(t0);
        let pps = format!("udp://127.0.0.1:{pps_port}");
        let nav = format!("nav=udp:{nav_to}");
        let sender = std::thread::spawn(move || send_pps(pps_port, t0, t0 + 2_000_000_000));
        let out = imu_emu(
            d,
            &[
                "run",
                s,
                "--speed",
                "1",
                "--start-at",
                &at,
                "--max-behind-ms",
                "10000",
                "--pps-in",
                &pps,
                "--time-marks",
                "nav=marks.csv",
                "--unit-sink",
                &nav,
                "--unit-sink",
                "tac=file:tac.csv",
            ],
        );
        let sent = sender.join().unwrap();
        let past = String::from_utf8_lossy(&out.stderr).contains("in the past");
        if out.status.success() || !past || tries == 3 {
            break (out, sent, nav_rx);
        }
        eprintln!("the run started after its instant {at}: again");
    };
    let err = ok(&out);
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    assert_eq!(joined(&nav_rx.join().unwrap()), read("offline/nav.bin"));
    assert_eq!(read("tac.csv"), read("offline/tac.csv"));
    let m = marks(&d.join("marks.csv"));
    assert_eq!(m.len(), 800, "{err}");
    for (k, r) in m.iter().enumerate() {
        assert_eq!(
            (r[0], r[1]),
            (k as i128, (k as i128 + 1) * 2_500_000),
            "{r:?}"
        );
    }
    assert_eq!(lock_edges(&err), sent, "{err}");

    let why = failed(&imu_emu(
        d,
        &["run", s, "--pulse", "rts:tov", "--pulse-unit", "tac"],
    ));
    assert!(
        why.contains("--pulse") && why.contains("--pulse-port DEV") && why.contains("`tac`"),
        "{why}"
    );
    let out = imu_emu(
        d,
        &[
            "run",
            s,
            "--pulse",
            "rts:tov",
            "--pulse-unit",
            "tac",
            "--pulse-port",
            "/dev/ttyX9",
            "--describe",
        ],
    );
    ok(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.contains("pulse rts:tov on /dev/ttyX9, marking tac"),
        "{text}"
    );
}

/// A line that counts its rising edges.
#[derive(Clone, Default)]
struct Rising(std::sync::Arc<std::sync::atomic::AtomicUsize>);

impl imu_emu::realtime::pulse::Line for Rising {
    fn set(&mut self, high: bool) -> std::io::Result<()> {
        if high {
            self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        Ok(())
    }
}

/// Row 3's pulse on a line given in code (a GPIO in a rig; a counter here — a pty has no
/// modem lines): the rig scene's run paced at 4× real time for 1 s, a time-of-validity pulse
/// on `tac`'s records rises once per `tac` record (100), not per `nav` frame (400); the files
/// are `generate`'s bytes.
#[test]
fn rig_pulse_marks_its_unit() {
    let _rt = rt::serial();
    use imu_emu::run::{Control, RunSpec, Speed, StreamId};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = rig_scene(d, "[output]\nduration_s = 1.0\n");
    ok(&imu_emu(
        d,
        &["generate", scene.to_str().unwrap(), "-o", "offline"],
    ));
    let line = Rising::default();
    let signal = imu_emu::sim::Simulation::builder()
        .scene_file(&scene)
        .unwrap();
    let file = |n: &str| format!("file:{}", d.join(n).display());
    let run = RunSpec::from_signal(signal)
        .unwrap()
        .sink(StreamId::unit("nav"), &file("nav.bin"))
        .unwrap()
        .sink(StreamId::unit("tac"), &file("tac.csv"))
        .unwrap()
        .speed(Speed::Factor(4.0))
        // The files are compared with generate's: no frame may be skipped as late.
        .max_behind_ms(60_000.0)
        .pulse("rts:tov", Some("tac"))
        .pulse_on(line.clone())
        .build()
        .unwrap();
    assert!(
        run.describe()
            .contains("pulse rts:tov on the line given in code, marking tac")
    );
    run.execute(&Control::new()).unwrap();
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    assert_eq!(read("nav.bin"), read("offline/nav.bin"));
    assert_eq!(read("tac.csv"), read("offline/tac.csv"));
    assert_eq!(line.0.load(std::sync::atomic::Ordering::Relaxed), 100);
}

/// Row 7: live `--motion` + `--time-marks` + `--pps-in` on the GPS time base, and `--pulse`
/// without a serial port. The marks: one per frame, each ToV on the tags' grid and due the
/// output delay later; the PPS lock took every edge sent at the whole seconds the states
/// span; the frames are the lockstep replay's bytes. Refused when the run is built, naming the
/// flag and why: the pulse without a port, the PPS on the sim time base (the sender's clock),
/// a start instant (a live run starts with its first state).
#[test]
fn live_motion_with_sync_lines() {
    let _rt = rt::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rows = survey_rows(d, 2.5);
    let port = free_udp_port();
    let pps_port = free_udp_port();
    let motion = format!("udp://127.0.0.1:{port}");
    let pps = format!("udp://127.0.0.1:{pps_port}");
    for (extra, flag, why) in [
        (["--pulse", "rts:pps"], "--pulse", "--pulse-port DEV"),
        (["--pps-in", &pps], "--pps-in", "--time-base gps"),
        (["--start-at", "next-second"], "--start-at", "first state"),
    ] {
        let mut args = vec!["run", "--motion", &motion, "--file", "x.bin"];
        args.extend(extra);
        let err = failed(&imu_emu(d, &args));
        assert!(err.contains(flag) && err.contains(why), "{err}");
        assert!(!d.join("x.bin").exists());
    }
    let run = start_live(
        d,
        port,
        &["run"],
        &[
            "--file",
            "imu.bin",
            "--time-marks",
            "marks.csv",
            "--pps-in",
            &pps,
        ],
    );
    let tags = Tagged::from_now(rows, 0.3);
    // Edges at the whole seconds from 0.5 s after the first state to the last: at least one.
    // GPS ns since 1980-01-06 = Unix ns − 315 964 800 s + the leap seconds (18 since 2017).
    let leap = hil::gps_now().0 + 315_964_800_000_000_000 - utc_now_ns();
    let leap = (leap as f64 / 1e9).round() as i128 * 1_000_000_000;
    let (from, to) = (
        tags.first_ns + 500_000_000,
        tags.tag_ns(tags.rows.len() - 1),
    );
    let unix = move |gps: i128| gps + 315_964_800_000_000_000 - leap;
    let sender = std::thread::spawn(move || send_pps(pps_port, unix(from), unix(to)));
    tags.send_ahead(port, AHEAD_NS);
    let err = run.finish();
    let sent = sender.join().unwrap();
    assert!(sent >= 1);
    assert_eq!(lock_edges(&err), sent, "{err}");
    replay(d, &["--file", "again.bin"]);
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    let live = read("imu.bin");
    let l = Left::read(&err, tags.newest_sow(), 0.5);
    let t0 = hil::number_after(&err, "from t = ");
    frames_follow("imu", &live, &read("again.bin"), (26, 400.0, t0), &l);
    let m = marks(&d.join("marks.csv"));
    assert_eq!(m.len(), live.len() / 26, "{err}");
    on_the_tags(&m, &tags);
}

/// Row 7's last case: lockstep has no wall clock, so `--start-at` (even a garbage one) is
/// refused naming the flag, before any output exists; a paced run reads the value and
/// refuses garbage naming the flag too.
#[test]
fn lockstep_start_at_is_refused() {
    let _rt = rt::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let err = failed(&imu_emu(
        d,
        &[
            "run",
            "--motion",
            "-",
            "--time-mode",
            "lockstep",
            "--start-at",
            "garbage",
            "--file",
            "x.bin",
        ],
    ));
    assert!(
        err.contains("--start-at") && err.contains("first state"),
        "{err}"
    );
    let err = failed(&imu_emu(
        d,
        &[
            "run",
            "--start-at",
            "garbage",
            "--speed",
            "1",
            "--file",
            "x.bin",
        ],
    ));
    assert!(
        err.contains("--start-at") && err.contains("garbage"),
        "{err}"
    );
    assert!(!d.join("x.bin").exists());
}

/// Row 8: a rig scene's `[gnss]` and `[odometer]` tables with live `--motion`: routed, they
/// are streamed beside the units (each stream the lockstep replay's bytes, then at most the
/// extrapolation); not routed, the description warns naming each table and how to route it.
#[test]
fn live_rig_streams_its_gnss_and_odometer() {
    let _rt = rt::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = rig_scene(
        d,
        "[gnss]\nrate_hz = 5.0\nseed = 3\n[odometer]\nrate_hz = 10.0\n",
    );
    let s = scene.to_str().unwrap();
    let out = imu_emu(
        d,
        &["run", s, "--motion", "udp://127.0.0.1:9", "--describe"],
    );
    ok(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    for t in ["[gnss]", "[odometer]"] {
        assert!(
            text.lines()
                .any(|l| l.starts_with("warning:") && l.contains(t)),
            "{text}"
        );
    }
    let routes = [
        "--gnss",
        "nmea:file:gnss.nmea",
        "--odometer",
        "file:odo.csv",
    ];
    let (err, nav, tags) = live_rig(d, &scene, &routes);
    let mut again = vec![s, "--unit-sink", "nav=file:nav.bin", "--unit-sink"];
    again.extend(["tac=file:tac2.csv", "--gnss", "nmea:file:gnss2.nmea"]);
    again.extend(["--odometer", "file:odo2.csv"]);
    replay(d, &again);
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    let l = Left::read(&err, tags.newest_sow(), 0.5);
    let t0 = hil::number_after(&err, "from t = ");
    frames_follow("nav", &nav, &read("nav.bin"), (26, 400.0, t0), &l);
    let per = per_epoch(&read("gnss2.nmea"));
    lines_follow(
        "gnss",
        &read("gnss.nmea"),
        &read("gnss2.nmea"),
        (per, 5.0),
        &l,
    );
    lines_follow(
        "odometer",
        &read("odo.csv"),
        &read("odo2.csv"),
        (1, 10.0),
        &l,
    );
    assert!(
        err.contains("gnss-nmea") && err.contains("odometer"),
        "{err}"
    );
}

/// Row 9: `run --imu examples/filtered.toml`: the template's 204.8 Hz wins over the default
/// protocol's 400 Hz (its output filter's internal rate is a multiple of it), unpaced to a
/// file and paced to UDP, both `generate`'s bytes in that protocol at that rate.
#[test]
fn filtered_template_keeps_its_rate() {
    let _rt = rt::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let t = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/filtered.toml");
    let common = ["--imu", t, "--duration", "1"];
    let mut g = vec![
        "generate", "--format", "ln200", "--rate", "204.8", "-o", "g.bin",
    ];
    g.extend(common);
    ok(&imu_emu(d, &g));
    let mut r = vec!["run", "--file", "r.bin"];
    r.extend(common);
    let err = ok(&imu_emu(d, &r));
    assert!(err.contains("at 204.8 Hz"), "{err}");
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    assert_eq!(read("r.bin"), read("g.bin"));
    let (to, rx) = receive();
    let mut p = vec![
        "run",
        "--udp",
        &to,
        "--speed",
        "4",
        "--max-behind-ms",
        "10000",
    ];
    p.extend(common);
    ok(&imu_emu(d, &p));
    assert_eq!(joined(&rx.join().unwrap()), read("g.bin"));
}

/// Lockstep with a GNSS epoch on t₀ itself: states tagged from 375 445.12 s of the week (the
/// model's t₀, 8 states later, is 375 445.20 s, on the 5 Hz epoch grid). The epoch at t₀ used
/// to be made when the model held one knot and no piece, and the run failed on a NaN latitude
/// (a 1-in-20 chance for live states tagged on a 10 ms grid); it is now made from the first
/// piece, and stamped with t₀'s UTC (GPS − 18 s).
#[test]
fn lockstep_gnss_epoch_on_t0() {
    let _rt = rt::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rows = survey_rows(d, 1.0);
    let week = 2400;
    let tags = Tagged {
        week,
        first_ns: week as i128 * hil::WEEK_NS + 375_445_120_000_000,
        rows,
    };
    std::fs::write(d.join("in.csv"), tags.csv().join("\n") + "\n").unwrap();
    let args = [
        "run",
        "--motion",
        "in.csv",
        "--time-mode",
        "lockstep",
        "--time-base",
        "gps",
    ];
    let mut all = args.to_vec();
    all.extend([
        "--file",
        "imu.bin",
        "--gnss",
        "nmea:file:g.nmea",
        "--baro",
        "file:b.csv",
    ]);
    ok(&imu_emu(d, &all));
    let text = std::fs::read_to_string(d.join("g.nmea")).unwrap();
    let first = text.lines().find(|l| l.starts_with("$GPGGA")).unwrap();
    // 375 445.2 s of the week − 18 s = day 4, 08:17:07.20 UTC.
    assert_eq!(first.split(',').nth(1), Some("081707.20"), "{text}");
}
