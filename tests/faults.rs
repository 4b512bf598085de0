//! Fault injection: for every protocol, N faults of each kind the protocol can show are
//! injected and `decode` reports exactly those; the scene file's `[faults]` and `--fault`
//! reach the encoder; saturation raises the status bits instead of wrapping.

use imu_emu::math::Vec3;
use imu_emu::protocol::faults::When;
use imu_emu::protocol::{
    self, EncoderState, FaultInjector, FaultKind, FaultSpec, StreamDecoder, StreamStats,
};
use imu_emu::record::Record;

/// 5 of each kind at separated times (every 37th frame, kinds in turn), 2000 frames of a slow
/// rotation: the decoder's tally equals the injector's, kind by kind, and every other frame
/// comes out.
#[test]
fn decode_reports_exactly_the_injected_faults() {
    for name in protocol::builtin_names() {
        let (_, plan) = protocol::load(name).unwrap();
        if plan.channels().is_some() {
            continue; // an N-channel frame takes no three-axis record: tests/skew_frames.rs
        }
        let kinds: Vec<FaultKind> = FaultKind::ALL
            .into_iter()
            .filter(|k| plan.supports(*k).is_ok())
            .collect();
        let rate = 100.0;
        let specs: Vec<FaultSpec> = kinds
            .iter()
            .enumerate()
            .map(|(i, k)| FaultSpec {
                kind: *k,
                when: When::At(
                    (0..5)
                        .map(|j| ((j * kinds.len() + i) * 37 + 11) as f64 / rate)
                        .collect(),
                ),
                duration_s: 0.0,
            })
            .collect();
        let inj = FaultInjector::new(specs, rate, 1);
        let tally = inj.tally();
        let mut st = EncoderState {
            faults: Some(Box::new(inj)),
            ..Default::default()
        };
        let mut bytes = Vec::new();
        let n = 2000u64;
        for k in 0..n {
            let t = k as f64 / rate;
            let w = Vec3::new(0.1 * t.sin(), 0.02, -0.3 * t.cos());
            let f = Vec3::new(0.5 * t.cos(), 0.1, -9.8);
            let r = Record {
                t,
                gyro: w,
                accel: f,
                dtheta: w * (1.0 / rate),
                dv: f * (1.0 / rate),
                flags: 0,
            };
            plan.encode(&r, 25.0, &mut st, &mut bytes);
        }
        let mut d = StreamDecoder::new(plan.clone());
        // Odd-sized chunks: frame boundaries fall anywhere in a read.
        for c in bytes.chunks(333) {
            d.feed(c, |_| {});
        }
        let got = |k| tally.get(k);
        for k in &kinds {
            assert_eq!(got(*k), 5, "{name}: {k:?} injected");
        }
        assert_eq!(
            d.stats(),
            StreamStats {
                frames: n - got(FaultKind::Drop) - got(FaultKind::CorruptCheck)
                    + got(FaultKind::Duplicate),
                check_failures: got(FaultKind::CorruptCheck),
                counter_gaps: got(FaultKind::Drop),
                duplicates: got(FaultKind::Duplicate),
                stale_counters: got(FaultKind::StaleCounter),
                status_flagged: got(FaultKind::Status),
                skipped_bytes: 0,
                framing_errors: 0,
                truncated: 0,
            },
            "{name}: kinds {kinds:?}"
        );
    }
}

/// Saturation: the error model's flags and values beyond a field's range set the status bits
/// the spec names, and the value sits at the field's limit rather than wrapping.
#[test]
fn saturation_sets_status_bits() {
    let (_, plan) = protocol::load("ln200").unwrap();
    let enc = |r: &Record| {
        let mut out = Vec::new();
        plan.encode(r, 25.0, &mut EncoderState::default(), &mut out);
        out
    };
    let word = |b: &[u8], i: usize| u16::from_le_bytes([b[2 * i], b[2 * i + 1]]);
    // ΔV z of 3 m/s is beyond ±2 m/s: word 2 at +32767, status bit 3 (accelerometer).
    let f = enc(&Record {
        dv: Vec3::new(0.0, 0.0, 3.0),
        ..Record::default()
    });
    assert_eq!(word(&f, 2), 0x7FFF);
    assert_eq!(word(&f, 6), 0x0008);
    let f = enc(&Record {
        dtheta: Vec3::new(-0.1, 0.0, 0.0),
        ..Record::default()
    });
    assert_eq!(word(&f, 3), 0x8000);
    assert_eq!(word(&f, 6), 0x0004);
    // The error chain's saturation flags (gyro = 1, accel = 2) raise the same bits.
    let f = enc(&Record {
        flags: 3,
        ..Record::default()
    });
    assert_eq!(word(&f, 6), 0x000C);
    let d = plan.decode(&f).unwrap();
    assert!(d.flagged);
    // KVH: a saturated gyro channel clears the three gyro valid bits of 0x77.
    let (_, kvh) = protocol::load("kvh1750").unwrap();
    let mut out = Vec::new();
    kvh.encode(
        &Record {
            flags: 1,
            ..Record::default()
        },
        25.0,
        &mut EncoderState::default(),
        &mut out,
    );
    assert_eq!(out[28], 0x70);
}

fn run(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(args)
        .output()
        .unwrap()
}

/// `[faults]` in a scene file plus `--fault` flags: `generate` reports what it injected and
/// `decode` finds exactly that; a bad entry is refused naming the file and key. The IMU is
/// noisy so that no two frames carry the same data: a stale counter on unchanged data would
/// read as a duplicate, to this decoder as to any receiver.
#[test]
fn scene_file_faults_reach_generate_and_decode() {
    let dir = std::env::temp_dir().join(format!("imu-emu-faults-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        r#"
[trajectory]
scene = "circle"
[imu]
model = "stim300"
[output]
format = "kvh1750"
duration_s = 2.0
[faults]
seed = 5
[[faults.event]]
kind = "drop"
at_s = [0.2, 0.9, 1.5]
[[faults.event]]
kind = "status"
at_s = [0.5]
duration_s = 0.0095
[[faults.event]]
kind = "duplicate"
rate_per_s = 4.0
"#,
    )
    .unwrap();
    let out_path = dir.join("out.bin");
    let g = run(&[
        "generate",
        scene.to_str().unwrap(),
        "--fault",
        "corrupt-check@0.3,1.1",
        "--fault",
        "stale-counter@0.7,1.8",
        "-o",
        out_path.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&g.stderr);
    assert!(g.status.success(), "{err}");
    // Injected: the three drops, ten status frames (0.5 s to 0.5095 s at 1 kHz), two
    // corruptions, and the seeded duplicates (seed 5: the count is fixed for the seed).
    let injected = err
        .lines()
        .find(|l| l.contains("faults injected"))
        .unwrap_or_else(|| panic!("{err}"));
    let count = |k: &str| -> u64 {
        let rest = &injected[injected.find(&format!("{k} ")).unwrap() + k.len() + 1..];
        rest.split(|c: char| !c.is_ascii_digit())
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    assert_eq!(count("drop"), 3, "{injected}");
    assert_eq!(count("corrupt-check"), 2, "{injected}");
    assert_eq!(count("status"), 10, "{injected}");
    assert_eq!(count("stale-counter"), 2, "{injected}");
    let dups = count("duplicate");
    assert!(dups > 0, "{injected}");
    let d = run(&[
        "decode",
        "--protocol",
        "kvh1750",
        out_path.to_str().unwrap(),
    ]);
    let derr = String::from_utf8_lossy(&d.stderr);
    assert!(d.status.success(), "{derr}");
    let frames = 2000 - 3 - 2 + dups;
    let want = format!(
        "{frames} frames, 2 check failures, 3 counter gaps, {dups} duplicates, 2 stale counters, 10 status flagged, 0 bytes skipped"
    );
    assert!(derr.contains(&want), "{derr}\nwanted {want}");
    // Reproducible: the same seed gives the same bytes.
    let again = dir.join("again.bin");
    let g2 = run(&[
        "generate",
        scene.to_str().unwrap(),
        "--fault",
        "corrupt-check@0.3,1.1",
        "--fault",
        "stale-counter@0.7,1.8",
        "-o",
        again.to_str().unwrap(),
    ]);
    assert!(g2.status.success());
    assert_eq!(
        std::fs::read(&out_path).unwrap(),
        std::fs::read(&again).unwrap()
    );

    // Errors name the file and key, or the flag.
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "[output]\nformat = \"kvh1750\"\n[[faults.event]]\nkind = \"melt\"\nat_s = [1.0]\n",
    )
    .unwrap();
    let e = run(&["generate", bad.to_str().unwrap(), "--duration", "0.1"]);
    let msg = String::from_utf8_lossy(&e.stderr);
    assert!(!e.status.success());
    assert!(
        msg.contains("bad.toml") && msg.contains("faults.event[0].kind") && msg.contains("melt"),
        "{msg}"
    );
    let e = run(&[
        "generate",
        "--scene",
        "static",
        "--duration",
        "0.1",
        "--format",
        "novatel-rawimusx",
        "--fault",
        "stale-counter@0.05",
    ]);
    let msg = String::from_utf8_lossy(&e.stderr);
    assert!(
        !e.status.success() && msg.contains("stale-counter") && msg.contains("no counter"),
        "{msg}"
    );
    let e = run(&[
        "generate",
        "--scene",
        "static",
        "--duration",
        "0.1",
        "--fault",
        "drop@0.05",
    ]);
    assert!(
        String::from_utf8_lossy(&e.stderr).contains("protocol frames"),
        "csv output with faults must be refused"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Ten minutes of the `survey` scene through the stim300 error model at each protocol's
/// nominal rate (400 Hz where none is given): every frame decodes, with no check failure,
/// counter gap, duplicate, stale counter, skipped byte or framing error.
#[test]
fn ten_minutes_of_survey_decode_cleanly() {
    use imu_emu::engine::{self, Encoding, SourceSpec};
    use imu_emu::motion::sampled::ModelSettings;
    use imu_emu::scenes::SceneParams;
    for name in protocol::builtin_names() {
        let (_, plan) = protocol::load(name).unwrap();
        if plan.channels().is_some() {
            continue; // an N-channel frame takes no three-axis record: tests/skew_frames.rs
        }
        let rate = plan.rate_hz.unwrap_or(400.0);
        let source = SourceSpec::Scene("survey".into(), SceneParams::defaults_for("survey"));
        let motion = engine::build_motion(&source, ModelSettings::default()).unwrap();
        let grid = engine::plan(&motion, rate, None, Some(600.0)).unwrap();
        let imu = imu_emu::errors::template::load("stim300").unwrap();
        let chain = imu_emu::errors::ErrorChain::new(&imu, rate, 1);
        let mut bytes = Vec::new();
        engine::run(
            motion,
            grid,
            3,
            Encoding::Frames {
                plan: Box::new(plan.clone()),
                state: EncoderState::default(),
                temperature: 25.0,
                side: imu_emu::output::Format::Csv,
            },
            Some(chain),
            &mut bytes,
            None,
            None,
            |_| {},
        )
        .unwrap();
        let mut d = StreamDecoder::new(plan);
        d.feed(&bytes, |_| {});
        assert_eq!(
            d.stats(),
            StreamStats {
                frames: grid.count,
                ..StreamStats::default()
            },
            "{name} at {rate} Hz"
        );
    }
}

/// A rate or duration out of range is named in a short message: 1e300 stays `1e300`, not a
/// 301-digit number.
#[test]
fn fault_values_are_named_compactly() {
    let spec = |when: When, duration_s: f64| FaultSpec {
        kind: FaultKind::Status,
        when,
        duration_s,
    };
    let e = spec(When::Rate(1e300), 0.0)
        .validate(1000.0)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("rate 1e300/s") && e.contains("1000/s") && e.len() < 80,
        "{e}"
    );
    let e = spec(When::At(vec![1.0]), -1e-300)
        .validate(1000.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("duration -1e-300 s") && e.len() < 80, "{e}");
}
