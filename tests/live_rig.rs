//! A rig of several IMUs following live motion input in lockstep: one process, one causal
//! motion model shared by every unit, each unit at its own rate and format with its own
//! placement and seed. A one-unit rig writes the bytes of the single-IMU run; a two-unit rig
//! fed the survey scene's states through a pipe matches, unit by unit, the same rig run on
//! the analytic scene (lever arm and mounting included); a recorded input replays to the
//! same bytes; bad lines are named and counted, never fatal.
//!
//! Figures measured when the tests were written are printed (`--nocapture`); each bound says
//! where it comes from.

#[path = "common/realtime_run.rs"]
mod realtime_run;
use std::io::Write;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use imu_emu::input::RecordReader;
use imu_emu::live::InputFormat;
use imu_emu::live::transport::Receiver;
use imu_emu::motion::Motion;
use imu_emu::output::Format;
use imu_emu::record::Record;
use imu_emu::rig::UnitOutputs;
use imu_emu::run::lockstep::Lockstep;
use imu_emu::sim::Simulation;
use imu_emu::source::AnyMotion;
use imu_emu::trajectory;

fn survey() -> AnyMotion {
    Simulation::builder().build().unwrap().motion().clone()
}

/// The survey scene's states from t = 0 every 10 ms to `seconds`, as trajectory CSV (what
/// `imu-emu trajectory --rate 100` writes).
fn survey_csv(seconds: f64) -> String {
    trajectory::sample_motion(&survey(), 0.0, 100.0, (seconds * 100.0) as u64, None)
}

fn receiver(text: &str) -> Receiver {
    Receiver::from_stream(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        InputFormat::Csv,
        "input",
    )
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

fn write_scene(dir: &Path, units: &str) -> PathBuf {
    let p = dir.join("rig.toml");
    std::fs::write(&p, format!("[trajectory]\nscene = \"survey\"\n{units}")).unwrap();
    p
}

/// A rig of one unit at the reference point in the body's axes, with the seed the single
/// IMU is given, writes exactly the single-IMU lockstep run's bytes on the same input: the
/// rig's unit and the single IMU share the template's error chain (seeded alike), the
/// generator on the one live model and the encoder. A seed left to the rig is drawn from the
/// master seed and the unit's name, so it differs from the single IMU's (the second case
/// shows the comparison can fail).
#[test]
fn one_unit_rig_writes_the_single_imu_bytes() {
    let _rt = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let input = survey_csv(4.0);
    for (model, format, rate) in [("ln200", "ln200", 400.0), ("hg1700", "csv", 200.0)] {
        let single = |seed: u64| {
            let b = Simulation::builder()
                .imu(model)
                .format(format)
                .rate(rate)
                .seed(seed)
                .duration(3.0);
            let mut out = Vec::new();
            let s = Lockstep::new(b, InputFormat::Csv)
                .unwrap()
                .run(&mut receiver(&input), &mut out, None, |_| ())
                .unwrap();
            assert_eq!(s.records, 3 * rate as u64);
            out
        };
        let rig = |seed: &str| {
            let units = format!(
                "[output]\nduration_s = 3.0\n[[imu]]\nname = \"nav\"\nmodel = \"{model}\"\nformat = \"{format}\"\nrate_hz = {rate}\n{seed}"
            );
            let b = Simulation::builder()
                .scene_file(write_scene(dir.path(), &units))
                .unwrap();
            let mut out = Vec::new();
            let run = Lockstep::rig(b, InputFormat::Csv).unwrap();
            assert_eq!(run.outputs(), 1);
            let s = run
                .run_to(&mut receiver(&input), &mut [&mut out], None, |_| ())
                .unwrap();
            assert_eq!(s.outputs.len(), 1);
            assert_eq!(s.outputs[0].1, 3 * rate as u64);
            assert_eq!(s.grid.t0, 0.08, "the model's first knot");
            out
        };
        let want = single(42);
        assert!(!want.is_empty());
        assert_eq!(rig("seed = 42"), want, "{model} {format}");
        assert_ne!(
            rig(""),
            want,
            "{model}: the rig's own seed gives other errors"
        );
    }
}

/// Two ideal units, 400 Hz at the reference point and 100 Hz 1.5 m ahead, 0.4 m left and
/// 0.3 m below with the case yawed 90° and pitched 10°.
const TWO_UNITS: &str = r#"
[output]
duration_s = 30.0
[[imu]]
name = "ref"
model = "ideal"
format = "csv"
rate_hz = 400.0
[[imu]]
name = "arm"
model = "ideal"
format = "csv"
rate_hz = 100.0
lever_arm_m = [1.5, -0.4, 0.3]
mounting_deg = [0.0, 10.0, 90.0]
"#;

fn imu_emu() -> Command {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
}

/// Runs `c` with `stdin` written into its standard input from another thread (the run may
/// stop reading once its duration is written), stderr captured.
fn piped(c: &mut Command, stdin: Vec<u8>) -> std::process::Output {
    let mut child = c
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut pipe = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || {
        let _ = pipe.write_all(&stdin);
    });
    let o = child.wait_with_output().unwrap();
    writer.join().unwrap();
    o
}

/// `imu-emu run RIG --motion - --time-mode lockstep` with `stdin` piped in, each unit to
/// `DIR/NAME.csv`: (exit status, stderr, each unit's bytes).
fn cli(dir: &Path, scene: &Path, stdin: &[u8], extra: &[&str]) -> (bool, String, Vec<Vec<u8>>) {
    let names = ["ref", "arm"];
    let mut c = imu_emu();
    c.arg("run").arg(scene);
    c.args(["--motion", "-", "--time-mode", "lockstep"])
        .args(extra);
    for n in names {
        c.arg("--unit-sink").arg(format!(
            "{n}=file:{}",
            dir.join(format!("{n}.csv")).display()
        ));
    }
    let o = piped(&mut c, stdin.to_vec());
    let outs = names
        .iter()
        .map(|n| std::fs::read(dir.join(format!("{n}.csv"))).unwrap_or_default())
        .collect();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        outs,
    )
}

/// The survey's piece ends (where its bank acceleration jumps) between `t0` and `t1`.
fn breakpoints(t0: f64, t1: f64) -> Vec<f64> {
    let m = survey();
    let mut breaks = Vec::new();
    let mut piece = m.piece_at(t0, 0);
    while m.piece_end(piece) < t1 {
        breaks.push(m.piece_end(piece));
        piece += 1;
    }
    breaks
}

/// Largest gyro and accel differences, over every record and over those away from the
/// scene's breakpoints (as tests/live.rs counts them: a record is near one when a breakpoint
/// lies within the 9 states of the stencils that made its piece, or in its piece).
fn errors(out: &[Record], truth: &[Record], breaks: &[f64]) -> [f64; 4] {
    assert_eq!(out.len(), truth.len());
    let near = |t: f64| breaks.iter().any(|&b| t > b - 0.02 && t < b + 0.1);
    let mut e = [0.0f64; 4];
    for (a, b) in out.iter().zip(truth) {
        assert_eq!(a.t, b.t);
        let (g, f) = ((a.gyro - b.gyro).amax(), (a.accel - b.accel).amax());
        e[2] = e[2].max(g);
        e[3] = e[3].max(f);
        if !near(a.t) {
            e[0] = e[0].max(g);
            e[1] = e[1].max(f);
        }
    }
    e
}

/// The acceptance case of a live rig: the survey's states at 100 Hz through a pipe into
/// `run RIG --motion -` in lockstep. Each unit's records against the same rig generated on
/// the analytic scene (its lever arm and mounting exact there: tests/rig.rs checks them
/// against the closed form ω̇ × r + ω × (ω × r)), within the bounds of tests/live.rs's
/// single-IMU lockstep case: away from the scene's breakpoints 1e-10 rad/s and 1e-8 m/s²,
/// everywhere 4e-3 rad/s and 1e-4 m/s².
///
/// Measured when written (30 s, ref 400 Hz / arm 100 Hz): see the printed line.
#[test]
fn two_units_from_a_pipe_follow_the_analytic_truth() {
    let _rt = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let scene = write_scene(dir.path(), TWO_UNITS);
    let input = survey_csv(31.0);
    let (ok, err, outs) = cli(dir.path(), &scene, input.as_bytes(), &[]);
    assert!(ok, "{err}");
    assert!(
        err.contains("unit ref: 12000 records at 400 Hz from t = 0.08 s"),
        "{err}"
    );
    assert!(
        err.contains("unit arm: 3000 records at 100 Hz from t = 0.08 s"),
        "{err}"
    );

    let truth = generated(&scene);
    let breaks = breakpoints(0.08, 30.08);
    for ((name, out), want) in ["ref", "arm"].iter().zip(&outs).zip(&truth) {
        let (out, want) = (records(out), records(want));
        let e = errors(&out, &want, &breaks);
        println!(
            "live rig, unit {name}: gyro {:.2e} rad/s (interior {:.2e}), accel {:.2e} m/s² (interior {:.2e}); {} breakpoints",
            e[2],
            e[0],
            e[3],
            e[1],
            breaks.len()
        );
        assert!(e[0] <= 1e-10 && e[1] <= 1e-8, "{name} interior: {e:?}");
        assert!(e[2] <= 4e-3 && e[3] <= 1e-4, "{name} whole run: {e:?}");
    }
    // The comparison sees the lever arm: the same rig without it is far outside the bound.
    let no_arm = write_scene(
        dir.path(),
        &TWO_UNITS.replace("lever_arm_m = [1.5, -0.4, 0.3]", ""),
    );
    let without = records(&generated(&no_arm)[1]);
    let e = errors(&records(&outs[1]), &without, &[]);
    println!(
        "arm unit against the rig without its lever arm: accel {:.2e} m/s²",
        e[3]
    );
    assert!(e[3] > 1e-6, "{e:?}");
}

/// Each unit's output of the rig `scene` generated on its analytic scene from t = 0.08 s.
fn generated(scene: &Path) -> Vec<Vec<u8>> {
    let rig = Simulation::builder()
        .scene_file(scene)
        .unwrap()
        .start(0.08)
        .build_rig()
        .unwrap();
    let mut bufs = vec![Vec::new(); rig.units().len()];
    {
        let mut o: Vec<UnitOutputs<'_>> = bufs
            .iter_mut()
            .map(|b| UnitOutputs {
                main: b,
                truth: None,
                failures: None,
            })
            .collect();
        rig.write(&mut o, |_| ControlFlow::Continue(())).unwrap();
    }
    bufs
}

/// `--record-input` keeps the input as received; a run replayed from it (`--motion FILE`)
/// writes every unit's bytes again, and so does a second run on the same input.
#[test]
fn replay_gives_every_unit_the_same_bytes() {
    let _rt = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let scene = write_scene(dir.path(), &TWO_UNITS.replace("30.0", "5.0"));
    let input = survey_csv(6.0);
    let rec = dir.path().join("input.csv");
    let rec_arg = rec.display().to_string();
    let (ok, err, first) = cli(
        dir.path(),
        &scene,
        input.as_bytes(),
        &["--record-input", &rec_arg],
    );
    assert!(ok, "{err}");
    assert!(first.iter().all(|o| o.len() > 1000));
    let (ok, err, again) = cli(dir.path(), &scene, input.as_bytes(), &[]);
    assert!(ok, "{err}");
    assert_eq!(again, first, "same input, same bytes");

    let replay = dir.path().join("replay");
    std::fs::create_dir(&replay).unwrap();
    let mut c = imu_emu();
    c.arg("run").arg(&scene);
    c.args(["--motion", &rec_arg, "--time-mode", "lockstep"]);
    for n in ["ref", "arm"] {
        c.arg("--unit-sink").arg(format!(
            "{n}=file:{}",
            replay.join(format!("{n}.csv")).display()
        ));
    }
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (n, want) in ["ref", "arm"].iter().zip(&first) {
        assert_eq!(
            &std::fs::read(replay.join(format!("{n}.csv"))).unwrap(),
            want,
            "{n}"
        );
    }
}

/// Bad lines in the pipe are named by line and column, counted, and do not stop the run;
/// they carried no state the model needed, so every unit's bytes equal the clean run's.
#[test]
fn bad_lines_are_named_and_never_fatal() {
    let _rt = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let scene = write_scene(dir.path(), &TWO_UNITS.replace("30.0", "3.0"));
    let clean = survey_csv(4.0);
    let mut dirty = String::new();
    for (i, line) in clean.lines().enumerate() {
        dirty.push_str(line);
        dirty.push('\n');
        if i == 50 {
            dirty.push_str("1.0,45,nope,0,0,0,0,0,0,0\n");
            dirty.push_str("garbage\n");
        }
    }
    let (ok, err, a) = cli(dir.path(), &scene, clean.as_bytes(), &[]);
    assert!(ok, "{err}");
    let (ok, err, b) = cli(dir.path(), &scene, dirty.as_bytes(), &[]);
    assert!(ok, "{err}");
    assert_eq!(a, b);
    assert!(err.contains("2 malformed"), "{err}");
    assert!(
        err.contains("stdin: line 52, byte 7: column 3 (`lon`)"),
        "{err}"
    );
    assert!(err.contains("stdin: line 53"), "{err}");
}

/// The rig of `TWO_UNITS` over 3 s follows the survey's states sent over UDP on loopback at
/// 100 Hz in real time (one CSV line a datagram, each at its own instant), `--time-mode
/// realtime`, each unit to its file sink through the one pacer. Each unit gets every record
/// of its grid (1200 at 400 Hz, 300 at 100 Hz from t = 0.08 s), and they match the rig
/// generated on the analytic scene within the lockstep case's bounds
/// (two_units_from_a_pipe_follow_the_analytic_truth) up to where the run says its output
/// first left the input: states that arrive within the 60 ms delay leave the chain following
/// the received pieces, so real time computes the lockstep records (the whole run, unless
/// the machine delayed a state past the delay). The summary names each unit; the arm
/// unit against the rig without its mounting is far outside the bound.
#[test]
fn two_units_follow_udp_input_in_real_time() {
    let _rt = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let scene = write_scene(dir.path(), &TWO_UNITS.replace("30.0", "3.0"));
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mut c = imu_emu();
    c.arg("run").arg(&scene).args([
        "--motion",
        &format!("udp://127.0.0.1:{port}"),
        "--input-timeout",
        "1",
        "--output-delay",
        "0.06",
        "--max-behind-ms",
        "60000",
    ]);
    for n in ["ref", "arm"] {
        c.arg("--unit-sink").arg(format!(
            "{n}=file:{}",
            dir.path().join(format!("{n}.csv")).display()
        ));
    }
    let mut child = c.stderr(Stdio::piped()).spawn().unwrap();
    let mut err = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut text = String::new();
    while !text.contains("following udp://") {
        let mut l = String::new();
        assert!(
            std::io::BufRead::read_line(&mut err, &mut l).unwrap() > 0,
            "{text}"
        );
        text += &l;
    }
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let start = std::time::Instant::now();
    for (k, line) in survey_csv(3.5).lines().enumerate() {
        let due = std::time::Duration::from_millis(10 * k as u64);
        if let Some(w) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(w);
        }
        sock.send_to(line.as_bytes(), ("127.0.0.1", port)).unwrap();
    }
    let status = child.wait().unwrap();
    std::io::Read::read_to_string(&mut err, &mut text).unwrap();
    println!("{text}");
    assert!(status.success(), "{text}");
    assert!(
        text.contains("unit ref: 1200 records at 400 Hz from t = 0.08 s"),
        "{text}"
    );
    assert!(
        text.contains("unit arm: 300 records at 100 Hz from t = 0.08 s"),
        "{text}"
    );
    let truth = generated(&scene);
    let breaks = breakpoints(0.08, 3.08);
    // A file sink starts with the CSV header, whatever the clock: the generated file's.
    let header = |b: &[u8]| b[..=b.iter().position(|&c| c == b'\n').unwrap()].to_vec();
    let outs: Vec<Vec<Record>> = ["ref", "arm"]
        .iter()
        .zip(&truth)
        .map(|(n, t)| {
            let file = std::fs::read(dir.path().join(format!("{n}.csv"))).unwrap();
            assert_eq!(header(&file), header(t), "unit {n}'s header");
            records(&file)
        })
        .collect();
    let until = realtime_run::departed(&text).unwrap_or(f64::INFINITY);
    for ((name, out), want) in ["ref", "arm"].iter().zip(&outs).zip(&truth) {
        let followed: Vec<Record> = out
            .iter()
            .filter(|r| r.t <= until + 1e-9)
            .cloned()
            .collect();
        assert!(!followed.is_empty(), "{text}");
        let want: Vec<Record> = records(want).into_iter().take(followed.len()).collect();
        let e = errors(&followed, &want, &breaks);
        println!(
            "real-time rig, unit {name}: gyro {:.2e} rad/s (interior {:.2e}), accel {:.2e} m/s² (interior {:.2e})",
            e[2], e[0], e[3], e[1]
        );
        assert!(e[0] <= 1e-10 && e[1] <= 1e-8, "{name} interior: {e:?}");
        assert!(e[2] <= 4e-3 && e[3] <= 1e-4, "{name} whole run: {e:?}");
    }
    // Over these first 3 s the survey barely turns: the lever arm moves the arm unit's
    // accel by 5e-9 m/s² only (measured), below the bound; the 30 s lockstep case checks
    // the arm. Its mounting is seen here: the rig without it is far outside the bound.
    let unmounted = write_scene(
        dir.path(),
        &TWO_UNITS
            .replace("30.0", "3.0")
            .replace("mounting_deg = [0.0, 10.0, 90.0]", ""),
    );
    let e = errors(&outs[1], &records(&generated(&unmounted)[1]), &[]);
    assert!(e[3] > 1e-3, "{e:?}");
}

/// What a live rig cannot do is refused with the reason, before any output exists (a start
/// instant, which a live run takes from its first state); an input too short for the model
/// fails and leaves no file behind. (Aiding streams, the GPS time base and sinks of every
/// kind, refused here before the run was one composable pipeline, now work:
/// tests/combinations.rs; a trigger on a live rig: tests/rig_trigger.rs.)
#[test]
fn live_rig_refusals_are_clear() {
    let _rt = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let scene = write_scene(dir.path(), TWO_UNITS);
    let short = survey_csv(0.05);
    for (extra, stdin, msg) in [
        (
            &["--start-at", "next-second"][..],
            "",
            "--start-at: a --motion run starts with its first state",
        ),
        (
            &[][..],
            short.as_str(),
            "stdin: the input ended after 6 usable states; the motion model needs 9",
        ),
    ] {
        let mut c = imu_emu();
        c.arg("run").arg(&scene).args(["--motion", "-"]);
        if !extra.contains(&"--time-mode") {
            c.args(["--time-mode", "lockstep"]);
        }
        for n in ["ref", "arm"] {
            c.arg("--unit-sink").arg(format!(
                "{n}=file:{}",
                dir.path().join(format!("{n}.csv")).display()
            ));
        }
        // A second sink for a unit comes after its file sink above.
        let mut child = c
            .args(extra)
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let _ = child.stdin.take().unwrap().write_all(stdin.as_bytes());
        let o = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(msg), "{extra:?}: {err}");
        for n in ["ref", "arm"] {
            assert!(
                !dir.path().join(format!("{n}.csv")).exists(),
                "{extra:?}: {n}"
            );
        }
    }
}

/// examples/rig.toml (LN-200 frames at 400 Hz; an HG1700 at 100 Hz upside down 1.2 m aft;
/// a six-gyro skew-redundant unit with a bias step, a stuck gyro and a noise burst) fed its
/// own circle's states at 100 Hz, `imu-emu trajectory examples/rig.toml`, through a pipe:
/// every unit's record count, and the CSV units against the same rig generated on the
/// analytic scene. The error terms and failures draw from the same seeds in both runs, so
/// what is left is the motion model's error, held to the one-IMU lockstep test's whole-run
/// bounds (4e-3 rad/s, 1e-4 m/s²); a failure not applied (the 0.01 rad/s bias step, the
/// 0.05 m/s² noise burst) or another seed (the skew accelerometers' white noise, σ =
/// 0.05 m/s/√h × √100 Hz = 8.3e-3 m/s²) would break them. Measured when written: skew unit
/// 2.4e-10, HG1700 2.3e-7 (one quantum of its velocity increment, 2⁻²⁷ ft/s, at 100 Hz: the
/// model's 1e-10 error moves a rounding across a quantum now and then).
#[test]
fn example_rig_follows_its_own_states_with_its_failures() {
    let _rt = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/rig.toml");
    let states = imu_emu()
        .arg("trajectory")
        .arg(&example)
        .args(["--rate", "100", "--duration", "21"])
        .output()
        .unwrap();
    assert!(states.status.success());
    let names = ["nav", "tactical", "skew"];
    let mut c = imu_emu();
    c.arg("run").arg(&example);
    c.args(["--motion", "-", "--time-mode", "lockstep"]);
    for n in names {
        c.arg("--unit-sink")
            .arg(format!("{n}=file:{}", dir.path().join(n).display()));
    }
    let o = piped(&mut c, states.stdout);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    for line in [
        "unit nav: 8000 records at 400 Hz from t = 0.08 s",
        "unit tactical: 2000 records at 100 Hz from t = 0.08 s",
        "unit skew: 2000 records at 100 Hz from t = 0.08 s",
    ] {
        assert!(err.contains(line), "{err}");
    }
    let want = generated(&example);
    // LN-200 frames: 26 bytes each (their counts are compared through the summary).
    let nav = std::fs::read(dir.path().join("nav")).unwrap();
    assert_eq!(nav.len(), want[0].len());
    for (i, n) in names.iter().enumerate().skip(1) {
        let got = String::from_utf8(std::fs::read(dir.path().join(n)).unwrap()).unwrap();
        let want = String::from_utf8(want[i].clone()).unwrap();
        assert_eq!(got.lines().next(), want.lines().next(), "{n}: header");
        let (mut worst, mut rows) = (0.0f64, 0);
        for (a, b) in got.lines().zip(want.lines()).skip(1) {
            let a: Vec<f64> = a.split(',').map(|x| x.parse().unwrap()).collect();
            let b: Vec<f64> = b.split(',').map(|x| x.parse().unwrap()).collect();
            assert_eq!(a[0], b[0], "{n}: t");
            // Rates and specific forces (the increments are them × Δt).
            let half = (a.len() - 1) / 2;
            for (j, (x, y)) in a[1..=half].iter().zip(&b[1..=half]).enumerate() {
                let gyro = if i == 1 { j < 3 } else { j < 6 };
                let bound = if gyro { 4e-3 } else { 1e-4 };
                assert!(
                    (x - y).abs() <= bound,
                    "{n} t = {} column {j}: {x} vs {y}",
                    a[0]
                );
                worst = worst.max((x - y).abs());
            }
            rows += 1;
        }
        assert_eq!(rows, 2000, "{n}");
        println!("example rig, unit {n}: largest difference {worst:.2e}");
    }
}

/// A caller of the library that hands a rig's run the wrong number of writers gets an
/// error saying so, not a panic, and a builder without units is refused before any state.
#[test]
fn library_misuse_is_an_error() {
    let _rt = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let b = Simulation::builder()
        .scene_file(write_scene(dir.path(), TWO_UNITS))
        .unwrap();
    let run = Lockstep::rig(b, InputFormat::Csv).unwrap();
    assert_eq!(run.outputs(), 2);
    let mut one = Vec::new();
    let e = run
        .run_to(
            &mut receiver(&survey_csv(1.0)),
            &mut [&mut one],
            None,
            |_| (),
        )
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "1 outputs given for a run that writes 2",
        "{e}"
    );
    let e = Lockstep::rig(Simulation::builder(), InputFormat::Csv)
        .err()
        .unwrap();
    assert!(
        e.to_string().contains("a rig needs at least one unit"),
        "{e}"
    );
}
