//! Live motion input in lockstep, over real loopback sockets and pipes: the survey scene's
//! states streamed at 100 Hz come out as records that match the analytic scene and that the
//! reference navigator integrates back to the truth; the same input gives the same bytes, a
//! recorded input replays to them; damaged, duplicated, reordered and missing states are
//! counted and never fatal.
//!
//! Figures measured when the tests were written are printed (`--nocapture`); each bound says
//! where it comes from.

use std::io::Write;
use std::net::{TcpListener, TcpStream, UdpSocket};
use std::path::Path;
use std::thread;
use std::time::Duration;

use imu_emu::earth;
use imu_emu::engine::released;
use imu_emu::input::RecordReader;
use imu_emu::live::binary::{self, Datagram};
use imu_emu::live::transport::{Endpoint, Receiver};
use imu_emu::live::{InputFormat, mavlink};
use imu_emu::math::{QuatExt, Vec3, euler_from_quat};
use imu_emu::motion::{Motion, Pose};
use imu_emu::nav::{NavState, Navigator, Settings, StateError};
use imu_emu::output::Format;
use imu_emu::protocol::spec::Source;
use imu_emu::record::Record;
use imu_emu::run::lockstep::{LiveSummary, Lockstep};
use imu_emu::sim::Simulation;
use imu_emu::source::AnyMotion;
use imu_emu::trajectory;

#[path = "common/live_cli.rs"]
mod live_cli;

fn survey() -> AnyMotion {
    Simulation::builder().build().unwrap().motion().clone()
}

/// The survey scene's states from t = 0 every 10 ms to `seconds`, as trajectory CSV (what
/// `imu-emu trajectory --rate 100` writes).
fn survey_csv(seconds: f64) -> String {
    trajectory::sample_motion(&survey(), 0.0, 100.0, (seconds * 100.0) as u64, None)
}

fn records(csv: &[u8]) -> Vec<Record> {
    let r = RecordReader::new(
        std::io::Cursor::new(csv.to_vec()),
        Path::new("out.csv"),
        Format::Csv,
    )
    .unwrap();
    r.map(Result::unwrap).collect()
}

/// Streams `text` into a lockstep run over a TCP loopback connection.
fn over_tcp(text: String, rate: f64, seconds: f64) -> (Vec<u8>, LiveSummary) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let sender = thread::spawn(move || {
        let mut s = TcpStream::connect(addr).unwrap();
        // The run may stop reading once its duration is written.
        let _ = s.write_all(text.as_bytes());
    });
    let (stream, _) = listener.accept().unwrap();
    let mut rx = Receiver::from_stream(Box::new(stream), InputFormat::Csv, "tcp");
    let b = Simulation::builder().rate(rate).duration(seconds);
    let run = Lockstep::new(b, InputFormat::Csv).unwrap();
    let mut out = Vec::new();
    let summary = run.run(&mut rx, &mut out, None, |_| ()).unwrap();
    sender.join().unwrap();
    (out, summary)
}

/// The survey's states with the exact body rate (deg/s) and NED velocity rate (m/s²) the
/// scene knows, as a simulation that sends them would: v̇^n from the sensed specific force by
/// the navigation equation v̇^n = C_b^n f^b − (2ω_ie^n + ω_en^n) × v^n + g^n.
fn survey_csv_with_rates(seconds: f64) -> String {
    let m = survey();
    let mut text = String::from("t,lat,lon,h,vn,ve,vd,roll,pitch,yaw,wx,wy,wz,an,ae,ad\n");
    let mut hint = 0;
    for k in 0..=(seconds * 100.0) as u64 {
        let t = k as f64 / 100.0;
        let p = m.pose(t);
        hint = m.piece_at(t, hint);
        let s = m.sense(hint, t);
        let (sl, cl) = p.lat.sin_cos();
        let g = Vec3::new(0.0, 0.0, earth::normal_gravity(sl, p.h));
        let coriolis = earth::omega_ie_n(sl, cl) * 2.0 + earth::omega_en_n(sl, cl, p.h, p.v_n);
        let a_n = p.q_b_n.rotate(s.f_b) - coriolis.cross(&p.v_n) + g;
        let (r, pi, y) = euler_from_quat(p.q_b_n);
        let w = s.omega_ib_b * (180.0 / std::f64::consts::PI);
        let vals = [
            t,
            p.lat.to_degrees(),
            p.lon.to_degrees(),
            p.h,
            p.v_n.x,
            p.v_n.y,
            p.v_n.z,
            r.to_degrees(),
            pi.to_degrees(),
            y.to_degrees(),
            w.x,
            w.y,
            w.z,
            a_n.x,
            a_n.y,
            a_n.z,
        ];
        let line: Vec<String> = vals.iter().map(|v| format!("{v:?}")).collect();
        text.push_str(&line.join(","));
        text.push('\n');
    }
    text
}

/// Largest errors (gyro, accel) over all records and over those away from the scene's own
/// breakpoints (where its bank acceleration jumps: no sampled model without the jump's time
/// can follow it; a record counts as near one when a breakpoint lies within the 9 states of
/// the stencils that made its piece, or in its piece).
struct Errors {
    all: (f64, f64),
    interior: (f64, f64),
}

fn errors_against_scene(out: &[Record], t0: f64, rate: f64) -> Errors {
    let n = out.len() as f64 / rate;
    let m = survey();
    let truth = Simulation::builder()
        .rate(rate)
        .start(t0)
        .duration(n)
        .build()
        .unwrap();
    let truth: Vec<Record> = truth.records().unwrap().flat_map(Result::unwrap).collect();
    assert_eq!(truth.len(), out.len());
    let mut breaks = Vec::new();
    let mut piece = m.piece_at(t0, 0);
    while m.piece_end(piece) < t0 + n {
        breaks.push(m.piece_end(piece));
        piece += 1;
    }
    let near = |t: f64| breaks.iter().any(|&b| t > b - 0.02 && t < b + 0.1);
    let mut e = Errors {
        all: (0.0, 0.0),
        interior: (0.0, 0.0),
    };
    for (a, b) in out.iter().zip(&truth) {
        assert_eq!(a.t, b.t);
        let (g, f) = ((a.gyro - b.gyro).amax(), (a.accel - b.accel).amax());
        e.all = (e.all.0.max(g), e.all.1.max(f));
        if !near(a.t) {
            e.interior = (e.interior.0.max(g), e.interior.1.max(f));
        }
    }
    println!("  ({} scene breakpoints)", breaks.len());
    e
}

/// Navigates `recs` from the scene's state at t₀: the largest 3-D position error (m).
fn navigate(recs: &[Record], t0: f64, rate: f64) -> f64 {
    let m = survey();
    let start = NavState::from_pose(&m.pose(t0));
    let mut nav = Navigator::new(start, rate, Settings::default()).unwrap();
    let mut worst = 0.0f64;
    for r in recs {
        nav.step(r.dtheta, r.dv);
        let s = nav.state();
        worst = worst.max(StateError::of(&s, &m.pose(s.t)).pos_ned.norm());
    }
    worst
}

/// The acceptance case: survey states at 100 Hz over TCP loopback, 400 Hz records for
/// 600 s, with and without the exact rates a simulation can send; errors of the records'
/// mean rates against the analytic scene and of the navigator integrating them.
///
/// Measured when written (plain / with rates): away from the scene's 14 breakpoints gyro
/// 2.4e-11 / 1.4e-12 rad/s, accel 1.5e-9 / 8.3e-11 m/s² (bounds about ×5: round-off of the
/// one-sided stencils); over the whole run, where the survey's bank acceleration jumps
/// between two states, gyro 1.5e-3 / 2.3e-4 rad/s and accel 7.4e-5 / 6.5e-6 m/s² (bounds
/// ×2–3; the aim, 1e-6 rad/s and 1e-4 m/s², holds for accel everywhere and for gyro
/// away from the jumps). Navigator: 4.4e-9 m worst over 600 s; the bound is the issue's
/// closure bound for this scene, 1e-3 m, and a 1e-6 m/s² accelerometer bias added to the same
/// records must break it (the comparison is live).
#[test]
fn survey_600s_at_100hz_matches_the_scene_and_navigates() {
    let (rate, seconds) = (400.0, 600.0);
    let cases = [
        (
            "plain",
            survey_csv(seconds + 1.0),
            [1e-10, 1e-8, 4e-3, 1e-4],
        ),
        (
            "rates",
            survey_csv_with_rates(seconds + 1.0),
            [1e-11, 5e-10, 6e-4, 2e-5],
        ),
    ];
    for (label, text, [gi, ai, ga, aa]) in cases {
        let (out, summary) = over_tcp(text, rate, seconds);
        let mut recs = records(&out);
        assert_eq!(recs.len() as u64, summary.records);
        assert_eq!(summary.records, (seconds * rate) as u64);
        assert_eq!(summary.stats.malformed, 0);
        // The model starts at its first knot: the ninth state (one-sided 9-point stencil).
        assert_eq!(summary.grid.t0, 0.08);
        let e = errors_against_scene(&recs, summary.grid.t0, rate);
        let worst = navigate(&recs, summary.grid.t0, rate);
        println!(
            "survey 100 Hz {label} → 400 Hz lockstep: gyro max {:.2e} rad/s (interior {:.2e}), accel max {:.2e} m/s² (interior {:.2e}); navigator 600 s: max position error {worst:.2e} m",
            e.all.0, e.interior.0, e.all.1, e.interior.1
        );
        assert!(e.interior.0 <= gi && e.interior.1 <= ai, "{label} interior");
        assert!(e.all.0 <= ga && e.all.1 <= aa, "{label} whole run");
        assert!(worst <= 1e-3, "{label}: navigator {worst:e} m");
        for r in &mut recs {
            r.dv[0] += 1e-6 / rate;
        }
        let biased = navigate(&recs, summary.grid.t0, rate);
        assert!(biased > 1e-2, "a 1e-6 m/s² bias gives only {biased:e} m");
    }
}

/// One survey state as a binary datagram.
fn datagram(p: &Pose, seq: u32) -> [u8; binary::LEN] {
    binary::encode(&Datagram {
        seq,
        week: binary::NO_WEEK,
        time: p.t,
        flags: 0,
        pos: [p.lat.to_degrees(), p.lon.to_degrees(), p.h],
        vel: p.v_n.into(),
        acc: [0.0; 3],
        quat: [p.q_b_n.w, p.q_b_n.i, p.q_b_n.j, p.q_b_n.k],
        rate: [0.0; 3],
    })
}

/// Binary datagrams over UDP loopback with damage: a datagram with a broken CRC, a short
/// one, a duplicate, two swapped (the later one arrives late), one never sent. All are
/// counted; the run goes on; the input recorded during the run replays (from a file, as a
/// stream) to the same bytes, and a second live run gives them too.
#[test]
fn udp_binary_damage_is_counted_and_replay_is_bit_identical() {
    let m = survey();
    let mut sent: Vec<Vec<u8>> = Vec::new();
    for i in 0..600u32 {
        let d = datagram(&m.pose(i as f64 * 0.01), i).to_vec();
        match i {
            100 => {
                let mut bad = d.clone();
                bad[40] ^= 0x10;
                sent.push(bad);
                sent.push(d);
            }
            200 => {
                sent.push(d.clone());
                sent.push(d);
            }
            300 => sent.push(d[..100].to_vec()),
            400 => {}
            _ => sent.push(d),
        }
    }
    // Swap 500 and 501: 501 first, 500 late.
    let k = sent
        .iter()
        .position(|d| u32::from_le_bytes(d[8..12].try_into().unwrap()) == 500)
        .unwrap();
    sent.swap(k, k + 1);

    let live = |sent: &[Vec<u8>]| -> (Vec<u8>, Vec<u8>, LiveSummary) {
        let rx_socket = live_cli::queued_udp(sent);
        let mut rx = Receiver::from_socket(rx_socket, InputFormat::Binary, "udp");
        let b = Simulation::builder().rate(400.0).format("ln200");
        let run = Lockstep::new(b, InputFormat::Binary).unwrap();
        let (mut out, mut rec) = (Vec::new(), Vec::new());
        let s = run.run(&mut rx, &mut out, Some(&mut rec), |_| ()).unwrap();
        (out, rec, s)
    };
    let (out, rec, s) = live(&sent);
    let st = &s.stats;
    println!("{}", st.summary());
    assert_eq!(st.messages, sent.len() as u64);
    assert_eq!(st.malformed, 2, "{:?}", st.problems);
    assert!(
        st.problems[0].contains("udp: datagram 101, byte 148: CRC"),
        "{:?}",
        st.problems
    );
    assert!(
        st.problems[1].contains("byte 0: 100 bytes, expected 152"),
        "{:?}",
        st.problems
    );
    assert_eq!(st.duplicates, 1);
    assert_eq!(st.reordered, 1);
    // Sequence breaks: 300 (short), 400 (never sent), 500 (arrived after 501).
    assert_eq!((st.gaps, st.missing), (3, 3));
    assert_eq!(st.states, 600 - 3);
    // Every record whose interval the last state closes: (5.99 − 0.08)·400, to round-off.
    assert_eq!(s.records, released(&s.grid, 5.99));
    assert!((2363..=2364).contains(&s.records), "{}", s.records);
    assert_eq!(out.len() as u64 % s.records, 0, "whole frames");

    let (again, _, _) = live(&sent);
    assert_eq!(again, out, "same input, same bytes");

    let dir = tempfile::TempDir::new().unwrap();
    let path = dir.path().join("input.rec");
    std::fs::write(&path, &rec).unwrap();
    let mut rx =
        Receiver::open(&Endpoint::Stream(path.clone()), InputFormat::Binary, None).unwrap();
    let b = Simulation::builder().rate(400.0).format("ln200");
    let mut replay = Vec::new();
    let r = Lockstep::new(b, InputFormat::Binary)
        .unwrap()
        .run(&mut rx, &mut replay, None, |_| ())
        .unwrap();
    assert_eq!(replay, out, "replay of the recorded input");
    // The stream cuts the short datagram at the next magic: the same two malformed messages.
    assert_eq!((r.stats.malformed, r.stats.skipped_bytes), (2, 0));
    assert_eq!(
        r.stats.problems[1].split(": ").last(),
        Some("100 bytes, expected 152")
    );
}

/// CSV lines through a FIFO with bad lines among them: each named by its line and column,
/// counted, and the output equals that of the clean input (the bad lines carried no state
/// the model needed: they are extra lines).
#[test]
fn fifo_csv_with_bad_lines() {
    let clean = survey_csv(3.0);
    let mut dirty = String::new();
    for (i, line) in clean.lines().enumerate() {
        dirty.push_str(line);
        dirty.push('\n');
        if i == 50 {
            dirty.push_str("1.0,45,nope,0,0,0,0,0,0,0\n");
            dirty.push_str("garbage\n");
            dirty.push_str("t,lat,lon,h,vn,ve,vd,roll,pitch,yaw\n");
        }
    }
    let dir = tempfile::TempDir::new().unwrap();
    let fifo = dir.path().join("states");
    nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
    let run = |text: String| {
        let f = fifo.clone();
        let writer = thread::spawn(move || std::fs::write(f, text).unwrap());
        let mut rx =
            Receiver::open(&Endpoint::Stream(fifo.clone()), InputFormat::Csv, None).unwrap();
        let b = Simulation::builder().rate(200.0);
        let mut out = Vec::new();
        let s = Lockstep::new(b, InputFormat::Csv)
            .unwrap()
            .run(&mut rx, &mut out, None, |_| ())
            .unwrap();
        writer.join().unwrap();
        (out, s)
    };
    let (a, sa) = run(clean);
    let (b, sb) = run(dirty);
    assert_eq!(a, b);
    assert_eq!(sa.stats.malformed, 0);
    assert_eq!(sb.stats.malformed, 2, "{:?}", sb.stats.problems);
    assert!(
        sb.stats.problems[0].contains("line 52, byte 7: column 3 (`lon`)"),
        "{:?}",
        sb.stats.problems
    );
    assert!(
        sb.stats.problems[1].contains("line 53"),
        "{:?}",
        sb.stats.problems
    );
}

/// MAVLink HIL_STATE_QUATERNION frames of the survey over a Unix socket pair: decoded,
/// counted, and the records follow the scene to the resolution the message allows (1 cm/s
/// velocities, float32 attitude and rates: the bounds are what that resolution gives through
/// the stencil, see docs/live-input.md).
#[test]
fn mavlink_stream_follows_the_scene_coarsely() {
    let m = survey();
    let mut bytes = Vec::new();
    for i in 0..500u64 {
        let p = m.pose(i as f64 * 0.01);
        let s = m.sense(m.piece_at(p.t, 0), p.t);
        let q = p.q_b_n;
        bytes.extend(mavlink::encode(
            i as u8,
            i * 10_000,
            [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
            [
                s.omega_ib_b.x as f32,
                s.omega_ib_b.y as f32,
                s.omega_ib_b.z as f32,
            ],
            [
                (p.lat.to_degrees() * 1e7).round() as i32,
                (p.lon.to_degrees() * 1e7).round() as i32,
                (p.h * 1e3).round() as i32,
            ],
            [p.v_n.x, p.v_n.y, p.v_n.z].map(|x| (x * 100.0).round() as i16),
        ));
    }
    let (mut a, b) = std::os::unix::net::UnixStream::pair().unwrap();
    let writer = thread::spawn(move || a.write_all(&bytes).unwrap());
    let mut rx = Receiver::from_stream(Box::new(b), InputFormat::Mavlink, "mavlink");
    let mut out = Vec::new();
    let s = Lockstep::new(Simulation::builder().rate(400.0), InputFormat::Mavlink)
        .unwrap()
        .run(&mut rx, &mut out, None, |_| ())
        .unwrap();
    writer.join().unwrap();
    assert_eq!(
        (s.stats.states, s.stats.malformed, s.stats.gaps),
        (500, 0, 0)
    );
    let recs = records(&out);
    let e = errors_against_scene(&recs, s.grid.t0, 400.0);
    let (eg, ea) = e.all;
    println!("survey over MAVLink: gyro max {eg:.2e} rad/s, accel max {ea:.2e} m/s²");
    // Measured 2.7e-7 rad/s and 1.1e-4 m/s²: float32 rates and attitude given, and over these
    // first 5 s the survey flies straight at constant speed, so the 1 cm/s velocity steps
    // barely show; a turn at 1 cm/s resolution costs far more (docs/live-input.md).
    assert!(eg < 1e-6 && ea < 5e-4, "{eg:e} {ea:e}");
}

/// A multicast source (`udp://GROUP:PORT`): the receiver joins the group and takes the
/// datagrams sent to it (looped back to this host).
#[test]
fn multicast_group_is_joined() {
    let group = "239.255.77.11";
    let mut rx = Receiver::open(
        &Endpoint::parse(&format!("udp://{group}:0")).unwrap(),
        InputFormat::Binary,
        Some(Duration::from_millis(500)),
    )
    .unwrap();
    let port = rx.local_addr().unwrap().port();
    let m = survey();
    // Every datagram is queued before the run reads any, so its end, 0.5 s after the last
    // one read, comes after them all whatever the load. Unbound, as a simulation's sender
    // usually is: the group is reached on the default multicast interface, the one the
    // receiver joined on.
    let s = UdpSocket::bind("0.0.0.0:0").unwrap();
    s.set_multicast_loop_v4(true).unwrap();
    for i in 0..40u32 {
        let d = datagram(&m.pose(i as f64 * 0.01), i);
        s.send_to(&d, (group, port)).unwrap();
    }
    let run = Lockstep::new(Simulation::builder().rate(400.0), InputFormat::Binary).unwrap();
    let mut out = Vec::new();
    let s = run.run(&mut rx, &mut out, None, |_| ()).unwrap();
    assert_eq!((s.stats.states, s.stats.missing), (40, 0));
    assert_eq!(s.records, released(&s.grid, 0.39));
}

fn imu_emu() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_imu-emu"))
}

/// The command line over TCP: `run --motion tcp://…` listens, takes the connection, writes
/// the same bytes as the library run on the same input (LN-200 model and frames, `run`'s
/// defaults; both end at a `--duration` of 1.5 s), and reports the bad line with its place;
/// the exit status is 0.
#[test]
fn cli_tcp_run_equals_the_library_and_reports() {
    let mut text = survey_csv(2.0);
    text.insert_str(text.find("\n1.0").unwrap() + 1, "1.0,x,0,0,0,0,0,0,0,0\n");
    let dir = tempfile::TempDir::new().unwrap();
    let out = dir.path().join("out.bin");
    let (child, mut conn) = live_cli::lockstep_over_tcp(&out, &["--duration", "1.5"]);
    conn.write_all(text.as_bytes()).unwrap();
    let done = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&done.stderr);
    assert!(done.status.success(), "{err}");
    assert!(err.contains("1 malformed"), "{err}");
    assert!(err.contains("line 102, byte 4: column 2 (`lat`)"), "{err}");

    let b = Simulation::builder()
        .defaults("ln200", "ln200")
        .duration(1.5);
    let mut rx = Receiver::from_stream(
        Box::new(std::io::Cursor::new(text.into_bytes())),
        InputFormat::Csv,
        "x",
    );
    let mut want = Vec::new();
    Lockstep::new(b, InputFormat::Csv)
        .unwrap()
        .run(&mut rx, &mut want, None, |_| ())
        .unwrap();
    assert_eq!(std::fs::read(&out).unwrap(), want);
}

/// Bad flags and an input too short for the model: a clear message, a failing exit status,
/// and no output file left behind.
#[test]
fn cli_refuses_bad_settings_and_short_input() {
    let dir = tempfile::TempDir::new().unwrap();
    let out = dir.path().join("out.bin");
    let run = |extra: &[&str], stdin: &str| {
        let mut c = imu_emu()
            .args(["run", "--motion", "-", "--file"])
            .arg(&out)
            .args(extra)
            .stdin(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let _ = c.stdin.take().unwrap().write_all(stdin.as_bytes());
        let o = c.wait_with_output().unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let (ok, err) = run(&["--input-format", "xml"], "");
    assert!(
        !ok && err.contains("--input-format xml: expected csv, bin or mavlink"),
        "{err}"
    );
    let (ok, err) = run(&["--time-mode", "fast"], "");
    assert!(
        !ok && err.contains("--time-mode fast: expected realtime or lockstep"),
        "{err}"
    );
    for (flags, msg) in [
        (
            &["--on-timeout", "later"][..],
            "--on-timeout later: expected stop, hold or extrapolate",
        ),
        (
            &["--correction-horizon", "0"][..],
            "--correction-horizon 0: expected a number of seconds of at least 0.001",
        ),
        (
            &["--output-delay", "nan"][..],
            "--output-delay NaN: expected",
        ),
        (&["--interp", "cubic"][..], "needs the quintic motion model"),
    ] {
        let (ok, err) = run(flags, "");
        assert!(!ok && err.contains(msg), "{flags:?}: {err}");
    }
    // Lockstep has no clock to run ahead of the input: the real-time settings are refused.
    let (ok, err) = run(&["--output-delay", "0.1", "--time-mode", "lockstep"], "");
    assert!(
        !ok && err.contains("--output-delay: applies to --time-mode realtime"),
        "{err}"
    );
    // Refused before any state arrives (stdin stays empty).
    let (ok, err) = run(&["--imu", "no-such-imu"], "");
    assert!(!ok && err.contains("no-such-imu"), "{err}");
    let short: String = survey_csv(0.05);
    for mode in ["lockstep", "realtime"] {
        let (ok, err) = run(&["--time-mode", mode], &short);
        assert!(
            !ok && err
                .contains("stdin: the input ended after 6 usable states; the motion model needs 9"),
            "{mode}: {err}"
        );
    }
    assert!(!out.exists(), "no partial output");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// Lockstep over `text` (CSV states) with `builder`: the bytes written.
fn lockstep_bytes(builder: imu_emu::sim::SimulationBuilder, text: &str) -> Vec<u8> {
    let mut rx = Receiver::from_stream(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        InputFormat::Csv,
        "x",
    );
    let mut out = Vec::new();
    Lockstep::new(builder, InputFormat::Csv)
        .unwrap()
        .run(&mut rx, &mut out, None, |_| ())
        .unwrap();
    out
}

/// GPS-tagged states in lockstep count from the start of the first GPS week seen, as in real
/// time. The survey's states over its first roll-in, 128 per second from 150 s + 2⁻²³ s
/// (a sub-µs fraction: 1.19e-7 s), tagged once in simulation seconds and once as GPS week
/// 2447, seconds of week 345 600 + the same: every tag is exact in an f64 both ways, and the
/// tags' differences — all the motion model's stencils see — are equal.
///
/// * The records' times are the GPS tags' seconds of week: t_k − 345 450 s equals the
///   simulation-second run's t_k to 1e-9 s (f64 at 3.5e5 s resolves 5.8e-11 s).
/// * Their increments are the same but for where the record instants round: 2⁻³⁵ s (half an
///   ulp at 3.5e5 s) at each end, so a Δv differs by at most |f|·2⁻³⁴ and a Δθ by |ω|·2⁻³⁴
///   (|f|, |ω| the largest in the run); twice that is the bound, for the quadrature nodes.
/// * NovAtel RAWIMUSX frames of the GPS run carry week 2447 and the records' seconds of week.
///
/// Counted from the GPS epoch instead (week·604 800 + sow in an f64, 1.48e9 s, ulp 2.4e-7 s)
/// the records' times are not seconds of week, and even taken modulo the week they are off by
/// 2.3e-7 s (the 2⁻²³ s rounded away, the grid on 2.4e-7 s steps); the Δθ then differ by
/// 2.3e-11 rad, above their bound of 1.6e-11 (measured by making that change).
#[test]
fn gps_tagged_lockstep_counts_from_the_week_start() {
    let (t0, sow0) = (150.0 + 2f64.powi(-23), 345_600.0 + 2f64.powi(-23));
    let sim_text = trajectory::sample_motion(&survey(), t0, 128.0, 384, None);
    let mut gps_text = String::from("gps_week,gps_sow");
    for line in sim_text.lines() {
        let (t, rest) = line.split_once(',').unwrap();
        match t.parse::<f64>() {
            Ok(t) => gps_text += &format!("2447,{},{rest}", t - t0 + sow0),
            Err(_) => gps_text += &format!(",{rest}"),
        }
        gps_text.push('\n');
    }
    let b = Simulation::builder().rate(400.0);
    let sim = records(&lockstep_bytes(b.clone(), &sim_text));
    let gps = records(&lockstep_bytes(b, &gps_text));
    assert_eq!(sim.len(), gps.len());
    assert!(sim.len() > 1100, "{} records", sim.len());
    let f_max = sim.iter().map(|r| r.accel.norm()).fold(0.0, f64::max);
    let w_max = sim.iter().map(|r| r.gyro.norm()).fold(0.0, f64::max);
    let (mut dt, mut dv, mut dth) = (0.0f64, 0.0f64, 0.0f64);
    for (a, g) in sim.iter().zip(&gps) {
        dt = dt.max((g.t.rem_euclid(604_800.0) - (sow0 - t0) - a.t).abs());
        dv = dv.max((g.dv - a.dv).norm());
        dth = dth.max((g.dtheta - a.dtheta).norm());
    }
    let ulp2 = 2f64.powi(-34);
    eprintln!(
        "GPS tags vs simulation seconds: time {dt:.1e} s, Δv {dv:.1e} m/s (bound {:.1e}), Δθ {dth:.1e} rad (bound {:.1e})",
        2.0 * f_max * ulp2,
        2.0 * w_max * ulp2
    );
    assert!(dt <= 1e-9, "times differ by {dt} s");
    assert!(gps[0].t < 604_800.0, "{} s: not seconds of week", gps[0].t);
    assert!(dv <= 2.0 * f_max * ulp2, "Δv differs by {dv}");
    assert!(dth <= 2.0 * w_max * ulp2, "Δθ differs by {dth}");

    let frames = lockstep_bytes(
        Simulation::builder()
            .rate(400.0)
            .defaults("ideal", "novatel-rawimusx"),
        &gps_text,
    );
    let mut dec = imu_emu::protocol::StreamDecoder::new(
        imu_emu::protocol::load("novatel-rawimusx").unwrap().1,
    );
    let mut fields = Vec::new();
    dec.feed(&frames, |f| {
        fields.push((
            f.get(Source::GpsWeek).unwrap(),
            f.get(Source::GpsSeconds).unwrap(),
        ))
    });
    assert_eq!(fields.len(), gps.len());
    for ((week, sow), r) in fields.iter().zip(&gps) {
        assert_eq!(*week, 2447.0);
        assert!((sow - r.t).abs() <= 1e-9, "frame {sow} s, record {} s", r.t);
    }
}

/// The record on the newest state's own time is released, as the real-time run releases it,
/// even when its time t₀ + k/rate, computed in f64, rounds an ulp past the tag read for that
/// state. GPS seconds of the week from 569 867.33 s to 569 869.33 s at 100 Hz (the states
/// of a real-time test whose replay lost that record one run in two): t₀ is the ninth state's
/// 569 867.41 s (the model's stencil), and t₀ + 768/400 comes out 1.2e-10 s after 569 869.33.
#[test]
fn the_record_on_the_newest_state_is_released() {
    let (first, last) = (56_986_733u64, 56_986_933u64); // hundredths of a second
    let tag = |c: u64| format!("{}.{:02}", c / 100, c % 100);
    let t0: f64 = tag(first + 8).parse().unwrap();
    let t_last: f64 = tag(last).parse().unwrap();
    assert!(t0 + 768.0 / 400.0 > t_last, "the case this test is for");
    let mut text = String::from("t,lat,lon,h,vn,ve,vd,roll,pitch,yaw\n");
    for c in first..=last {
        text.push_str(&format!("{},41.27,1.98,300,0,0,0,0,0,0\n", tag(c)));
    }
    let mut rx = Receiver::from_stream(
        Box::new(std::io::Cursor::new(text.into_bytes())),
        InputFormat::Csv,
        "x",
    );
    let b = Simulation::builder().defaults("ideal", "bin").rate(400.0);
    let s = Lockstep::new(b, InputFormat::Csv)
        .unwrap()
        .run(&mut rx, &mut std::io::sink(), None, |_| ())
        .unwrap();
    assert_eq!(s.grid.t0, t0);
    assert_eq!(s.newest, t_last);
    assert_eq!(s.records, 768, "every record up to the newest state's time");
}
