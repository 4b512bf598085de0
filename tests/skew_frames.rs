//! N-channel frames (`gyro[i]`, `dv[i]`, … fields; `protocols/skew6.toml`): a skew-redundant
//! rig unit writes them, `decode` and an independent Python decoder read them back, channel
//! values round-trip within an LSB (their running sums within half one), failure bits follow the failure truth, and bad specs
//! or mismatched units are refused naming the file, line and field.

use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "common/carry.rs"]
mod carry;

use imu_emu::protocol::spec::{Channel, Source};
use imu_emu::protocol::{self, Channels, Decoded, EncoderState, Plan, StreamDecoder};
use imu_emu::record::Record;

const EXE: &str = env!("CARGO_BIN_EXE_imu-emu");
/// skew6's LSBs: 2^-33 rad, 2^-27 m/s.
const LSB_DTHETA: f64 = 1.0 / 8_589_934_592.0;
const LSB_DV: f64 = 1.0 / 134_217_728.0;

fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("imu-emu-skew-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A rig scene: one skew-redundant unit of six gyros on the dodecahedron's face normals and
/// `accels` accelerometers, writing `format`, with a bias step on gyro 2 and a null on
/// accelerometer 4 (when it has one).
fn scene(format: &str, accels: usize) -> String {
    let p = 0.5257311121191336;
    let q = 0.85065080835204;
    let axes = [
        [0.0, p, q],
        [0.0, -p, q],
        [p, q, 0.0],
        [-p, q, 0.0],
        [q, 0.0, p],
        [q, 0.0, -p],
    ];
    let mut s = format!(
        "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 2.0\n[[imu]]\nname = \"skew\"\nformat = \"{format}\"\nseed = 11\nrate_hz = 200.0\nlever_arm_m = [0.5, 0.1, 0.0]\n"
    );
    for a in axes {
        s += &format!("[[imu.gyro]]\naxis = {a:?}\nnoise = \"0.01 deg/sqrt(h)\"\n");
    }
    for a in &axes[..accels] {
        s += &format!(
            "[[imu.accel]]\naxis = {a:?}\nposition_m = [0.02, 0.0, 0.0]\nnoise = \"0.05 m/s/sqrt(h)\"\n"
        );
    }
    s += "[[imu.failure]]\nkind = \"bias-step\"\nsensor = \"gyro_2\"\nat_s = 0.5\nduration_s = 0.3\nmagnitude = 0.01\n";
    if accels > 4 {
        s += "[[imu.failure]]\nkind = \"null\"\nsensor = \"accel_4\"\nat_s = 1.0\nduration_s = 0.5\n";
    }
    s
}

/// Runs `generate` on a scene file in `dir`; returns its stderr, panicking on failure.
fn generate(dir: &Path, name: &str, text: &str) -> String {
    let f = dir.join(format!("{name}.toml"));
    std::fs::write(&f, text).unwrap();
    let out = Command::new(EXE)
        .arg("generate")
        .arg(&f)
        .arg("-o")
        .arg(dir.join(name))
        .arg("--truth")
        .arg(dir.join(format!("{name}-truth")))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    err
}

fn csv_rows(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

fn decode_all(plan: &Plan, bytes: &[u8]) -> (Vec<Decoded>, protocol::StreamStats) {
    let mut d = StreamDecoder::new(plan.clone());
    let mut out = Vec::new();
    d.feed(bytes, |f| out.push(f.clone()));
    d.finish();
    (out, d.stats())
}

/// The same rig written as skew6 frames and as CSV (same seed, so the same readings): every
/// frame decodes, the counter runs 0, 1, …, the time tag is the record time to the µs, each
/// Δθ/ΔV channel is the CSV's to half an LSB, and the status word's low 12 bits are the truth
/// file's `failed` column (gyro 2 from 0.5 s, accelerometer 4 from 1 s). A frame that took
/// the wrong channel order, dropped the failure bits or scaled by the wrong LSB fails.
#[test]
fn rig_frames_carry_the_csv_values_and_failure_bits() {
    let dir = scratch("rig");
    generate(&dir, "frames", &scene("skew6", 6));
    generate(&dir, "csv", &scene("csv", 6));
    let bytes = std::fs::read(dir.join("frames/skew.bin")).unwrap();
    let rows = csv_rows(&dir.join("csv/skew.csv"));
    let truth = csv_rows(&dir.join("frames-truth/skew.csv"));
    let (_, plan) = protocol::load("skew6").unwrap();
    assert_eq!(plan.channels(), Some((6, 6)));
    let (frames, stats) = decode_all(&plan, &bytes);
    assert_eq!(bytes.len(), 64 * 400, "200 Hz (skew6's rate) for 2 s");
    assert_eq!(frames.len(), 400);
    assert_eq!(rows.len(), 400);
    assert_eq!(
        (
            stats.check_failures,
            stats.counter_gaps,
            stats.skipped_bytes
        ),
        (0, 0, 0)
    );
    assert_eq!(stats.status_flagged, 160);
    let (mut gyro_failed, mut accel_failed) = (0, 0);
    let mut running = Vec::new();
    for (k, ((d, row), tr)) in frames.iter().zip(&rows).zip(&truth).enumerate() {
        assert_eq!(d.get(Source::Counter), Some(k as f64));
        let t = d.get(Source::Time).unwrap();
        assert!((t - row[0]).abs() <= 0.5e-6 + 1e-12, "{t} vs {}", row[0]);
        for i in 0..6 {
            // CSV columns: t, gyro_0..5, accel_0..5, dtheta_0..5, dv_0..5.
            for (c, col, lsb) in [
                (Channel::DTheta, 13 + i, LSB_DTHETA),
                (Channel::Dv, 19 + i, LSB_DV),
            ] {
                let got = d.get(Source::Channel(c, i)).unwrap();
                assert_eq!(plan.quantum(Source::Channel(c, i)), Some(lsb));
                let s = (Source::Channel(c, i), k);
                assert!(carry::sums_within_half_a_step(
                    &mut running,
                    &plan,
                    s,
                    got,
                    row[col]
                ));
            }
        }
        let status = d.get(Source::Status).unwrap() as u64;
        let failed = *tr.last().unwrap() as u64;
        assert_eq!(status, failed, "frame {k} at t = {}", row[0]);
        assert_eq!(d.flagged, failed != 0);
        gyro_failed += usize::from(failed & (1 << 2) != 0);
        accel_failed += usize::from(failed & (1 << (6 + 4)) != 0);
    }
    // 0.3 s and 0.5 s at 200 Hz, records with t_k in [at, at + duration).
    assert_eq!((gyro_failed, accel_failed), (60, 100));
    // The command line reads them back too, under the spec's field names.
    let out = Command::new(EXE)
        .args(["decode", "--format", "skew6"])
        .arg(dir.join("frames/skew.bin"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "counter,t,dtheta_0,dtheta_1,dtheta_2,dtheta_3,dtheta_4,dtheta_5,dv_0,dv_1,dv_2,dv_3,dv_4,dv_5,status"
    );
    assert_eq!(lines.count(), 400);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("400 frames, 0 check failures"), "{err}");
    assert!(err.contains("160 status flagged"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A decoder written here with Python's `struct` and `zlib` (nothing of ours) reads the
/// frames: every CRC matches and every value equals ours to the bit (k·2^-33 and k·2^-27 are
/// exact in binary floating point), including the failure bits.
#[test]
fn python_struct_decoder_reads_the_frames() {
    let dir = scratch("py");
    generate(&dir, "frames", &scene("skew6", 6));
    let bin = dir.join("frames/skew.bin");
    let script = r#"
import struct, sys, zlib
data = open(sys.argv[1], 'rb').read()
assert len(data) % 64 == 0, len(data)
for o in range(0, len(data), 64):
    f = data[o:o + 64]
    sync, counter, t_us, *rest = struct.unpack('<IHI6i6iHI', f)
    dth, dv, status, crc = rest[:6], rest[6:12], rest[12], rest[13]
    assert sync == 0x36574B53 and f[:4] == b'SKW6'
    assert crc == zlib.crc32(f[:60]), o
    vals = [counter, t_us * 1e-6] + [k * 2.0**-33 for k in dth] + [k * 2.0**-27 for k in dv] + [status]
    print(','.join(repr(float(v)) for v in vals))
"#;
    let python = std::env::var("IMU_EMU_PYTHON").unwrap_or_else(|_| "python3".into());
    let out = Command::new(&python)
        .arg("-c")
        .arg(script)
        .arg(&bin)
        .output()
        .unwrap_or_else(|e| panic!("running {python} (Python 3 standard library): {e}"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (_, plan) = protocol::load("skew6").unwrap();
    let (frames, _) = decode_all(&plan, &std::fs::read(&bin).unwrap());
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), frames.len());
    let mut flagged = 0;
    for (line, d) in text.lines().zip(&frames) {
        let py: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let ours: Vec<f64> = d.values.iter().map(|v| v.1).collect();
        assert_eq!(py.len(), ours.len());
        // The time tag: Python's t_us·1e-6 and our t_us/1e6 may differ in the last bit.
        assert!((py[1] - ours[1]).abs() <= 2.0 * f64::EPSILON * py[1]);
        assert_eq!((py[0], &py[2..]), (ours[0], &ours[2..]));
        flagged += usize::from(py[14] != 0.0);
    }
    assert_eq!(flagged, 160);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Random channel values (inside ±0.25 rad and ±16 m/s per sample) and failure masks encode
/// and decode back: each channel within one LSB and its running sum within half one (the
/// encoder carries each count's remainder), the status word equal to the mask.
/// Wrong: the increments (value × dt) must be sent, not the means; the accelerometers come
/// after the gyros in `values`.
#[test]
fn channel_values_round_trip_within_half_an_lsb() {
    let (_, plan) = protocol::load("skew6").unwrap();
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let unit = |x: u64| (x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
    let mut st = EncoderState::default();
    let dt = 1.0 / 200.0;
    let mut running = Vec::new();
    for k in 0..2000 {
        let mut v = [0.0; 12];
        for (i, x) in v.iter_mut().enumerate() {
            // Means: ±49 rad/s and ±3000 m/s² times dt stay inside the fields' ranges.
            *x = unit(next()) * if i < 6 { 49.0 } else { 3000.0 };
        }
        let failed = next() & 0xFFF;
        let ch = Channels {
            values: &v,
            gyros: 6,
            dt,
            failed,
        };
        let r = Record {
            t: k as f64 * dt,
            ..Record::default()
        };
        let mut out = Vec::new();
        plan.encode_with(&r, Some(&ch), 25.0, &mut st, &mut out);
        let d = plan.decode(&out).unwrap();
        for i in 0..6 {
            for (c, want, lsb) in [
                (Channel::DTheta, v[i] * dt, LSB_DTHETA),
                (Channel::Dv, v[6 + i] * dt, LSB_DV),
            ] {
                let got = d.get(Source::Channel(c, i)).unwrap();
                assert_eq!(plan.quantum(Source::Channel(c, i)), Some(lsb));
                let s = (Source::Channel(c, i), k);
                assert!(carry::sums_within_half_a_step(
                    &mut running,
                    &plan,
                    s,
                    got,
                    want
                ));
            }
        }
        assert_eq!(d.get(Source::Status), Some(failed as f64));
        assert_eq!(d.get(Source::Counter), Some(k as f64));
    }
}

/// A frame of channels encoded without them (a three-axis record) is not a healthy frame:
/// its status word shows the failure bit (0x8000), never zeros passed off as readings.
#[test]
fn channels_missing_are_reported_as_a_failure() {
    let (_, plan) = protocol::load("skew6").unwrap();
    let mut out = Vec::new();
    plan.encode(
        &Record::default(),
        25.0,
        &mut EncoderState::default(),
        &mut out,
    );
    let d = plan.decode(&out).unwrap();
    assert_eq!(d.get(Source::Status), Some(f64::from(0x8000)));
    assert!(d.flagged);
    // Fewer channels than the frame carries: the missing ones fail the same way.
    let v = [0.1; 9];
    let ch = Channels {
        values: &v,
        gyros: 6,
        dt: 0.005,
        failed: 0,
    };
    out.clear();
    plan.encode_with(
        &Record::default(),
        Some(&ch),
        25.0,
        &mut EncoderState::default(),
        &mut out,
    );
    let d = plan.decode(&out).unwrap();
    assert_eq!(d.get(Source::Status), Some(f64::from(0x8000)));
    assert!((d.get(Source::Channel(Channel::Dv, 2)).unwrap() - 0.0005).abs() <= LSB_DV);
    assert_eq!(d.get(Source::Channel(Channel::Dv, 3)), Some(0.0));
}

/// A bad channel field is refused naming the file, the line of its `name` and the field.
#[test]
fn bad_channel_specs_name_file_line_and_field() {
    let head = "name = \"t\"\n[[field]]\nname = \"sync\"\ntype = \"u8\"\nvalue = 1\n";
    let status = |bit: u32| {
        format!(
            "[[field]]\nname = \"st\"\ntype = \"u8\"\nsource = \"status\"\n[field.status]\nok = 0\nfailed_channels = {bit}\n"
        )
    };
    let ch = |name: &str, src: &str| {
        format!("[[field]]\nname = \"{name}\"\ntype = \"i16\"\nsource = \"{src}\"\n")
    };
    let cases = [
        (ch("g", "gyro[64]"), ":7:", "`g`", "i < j ≤ 64"),
        (ch("g", "dv[3..1]"), ":7:", "`g`", "expected"),
        (ch("g", "gyro[2"), ":7:", "`g`", "expected"),
        (
            ch("a", "gyro[1]") + &ch("b", "gyro[0..3]"),
            ":11:",
            "`b_1`",
            "already carried by field `a`",
        ),
        (
            ch("g", "gyro[0..6]") + &ch("a", "accel[0..3]") + &status(0),
            ":15:",
            "`st`",
            "9 channel bits from bit 0 do not fit in U8",
        ),
        (status(0), ":7:", "`st`", "carries no channel"),
    ];
    for (body, line, field, problem) in cases {
        let text = format!("{head}{body}");
        let e = protocol::load::compile_text(&text, Path::new("bad.toml"))
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("bad.toml{line} field {field}")) && e.contains(problem),
            "{e}\n--- for ---\n{text}"
        );
    }
    let acc = "name = \"t\"\n[[message]]\nname = \"m\"\naccumulate = true\n[[message.field]]\nname = \"d\"\ntype = \"i32\"\nsource = \"dtheta[0]\"\n";
    let e = protocol::load::compile_text(acc, Path::new("bad.toml"))
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad.toml:6: field `d`") && e.contains("accumulating"),
        "{e}"
    );
}

/// A unit and a frame that do not match are refused before anything is written, naming the
/// scene file's key: a skew unit with 3 accelerometers for skew6's 6, a three-axis IMU with
/// skew6, a skew unit with a three-axis protocol; a single IMU's `--format skew6` too.
#[test]
fn units_and_frames_that_do_not_match_are_refused() {
    let dir = scratch("bad");
    let triad = "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 1.0\n[[imu]]\nname = \"nav\"\nmodel = \"ln200\"\nformat = \"skew6\"\n";
    for (name, text, want) in [
        (
            "few",
            scene("skew6", 3),
            "`imu[0].format`: `skew6`: carries 6 gyro and 6 accelerometer channels; the unit has 6 and 3",
        ),
        ("triad", triad.to_string(), "skew-redundant unit's frame"),
        ("kvh", scene("kvh1750", 6), "is a three-axis IMU's frame"),
    ] {
        let f = dir.join(format!("{name}.toml"));
        std::fs::write(&f, text).unwrap();
        let out_dir = dir.join(name);
        let out = Command::new(EXE)
            .arg("generate")
            .arg(&f)
            .arg("-o")
            .arg(&out_dir)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(want), "{name}: {err}");
        assert!(!out_dir.exists(), "{name}: output left behind");
    }
    let out = Command::new(EXE)
        .args(["generate", "--duration", "1", "--format", "skew6"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("frame of a skew-redundant unit"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
