//! Every protocol specification in `protocols/`: it loads, compiles, its golden vectors decode
//! to the stated values, and re-encoding those values gives the same bytes; encode→decode
//! round trips for random records stay within one LSB (exact for floats to their precision).

use std::path::Path;

use imu_emu::math::Vec3;
use imu_emu::protocol::spec::Source;
use imu_emu::protocol::{
    self, Decoded, EncoderState, FrameSpec, Plan, StreamDecoder, StreamStats, Transport,
};
use imu_emu::record::Record;

#[path = "common/carry.rs"]
mod carry;
use carry::sums_within_half_a_step;

/// Every frame of a byte stream, through the protocol's transport, and the decoder's tally.
fn decode_stream(plan: &Plan, bytes: &[u8]) -> (Vec<Decoded>, StreamStats) {
    let mut d = StreamDecoder::new(plan.clone());
    let mut out = Vec::new();
    d.feed(bytes, |f| out.push(f.clone()));
    (out, d.stats())
}

fn hex(s: &str) -> Vec<u8> {
    let s: String = s.chars().filter(|c| !c.is_whitespace()).collect();
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

/// Every file in protocols/ is a built-in protocol, and every built-in one compiles.
#[test]
fn every_spec_file_is_built_in() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("protocols");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    files.sort();
    let mut names: Vec<String> = protocol::builtin_names()
        .iter()
        .map(|s| s.to_string())
        .collect();
    names.sort();
    assert_eq!(files, names);
    for n in protocol::builtin_names() {
        protocol::load(n).unwrap_or_else(|e| panic!("{n}: {e}"));
    }
}

/// Golden vectors: decode to the stated values; re-encoding them reproduces the bytes.
#[test]
fn golden_vectors_decode_and_reencode() {
    for name in protocol::builtin_names() {
        let (spec, plan): (FrameSpec, Plan) = protocol::load(name).unwrap();
        assert!(!spec.test_vector.is_empty(), "{name} has no golden vector");
        for tv in &spec.test_vector {
            let bytes = hex(&tv.hex);
            let d = if matches!(plan.transport, Transport::Plain) {
                let d = plan
                    .decode(&bytes)
                    .unwrap_or_else(|e| panic!("{name}: {e}"));
                assert_eq!(bytes.len(), d.len, "{name}: vector length");
                d
            } else {
                let (mut frames, stats) = decode_stream(&plan, &bytes);
                assert_eq!(stats.frames, 1, "{name}: {stats:?}");
                frames.remove(0)
            };
            let tol = tv.tolerance.unwrap_or(1e-6);
            let mut rec = Record::default();
            let (mut counter, mut temperature) = (0u64, 0.0);
            // Single-axis channels (skew6), re-encoded with dt = 1: value = increment.
            let mut channels = [[0.0; 64]; 2];
            let (mut gyros, mut accels) = (0, 0);
            // GPS fields rebuild the time tag from the most precise of them: week·604800 +
            // seconds of week, else whole seconds + µs, else ms.
            let (mut week, mut secs, mut whole, mut micros, mut millis) =
                (0.0, None, None, 0.0, None);
            for (k, v) in &tv.values {
                let want = v.as_float().or(v.as_integer().map(|i| i as f64)).unwrap();
                let s =
                    Source::from_name(k).unwrap_or_else(|| panic!("{name}: unknown source {k}"));
                let got = d
                    .get(s)
                    .unwrap_or_else(|| panic!("{name}: frame lacks {k}"));
                assert!(
                    (got - want).abs() <= tol * want.abs().max(1e-30),
                    "{name} {k}: {got} vs {want}"
                );
                match s {
                    Source::Gyro(i) => rec.gyro[i] = got,
                    Source::Accel(i) => rec.accel[i] = got,
                    Source::DTheta(i) => rec.dtheta[i] = got,
                    Source::Dv(i) => rec.dv[i] = got,
                    Source::Time => rec.t = got,
                    Source::Counter => counter = got as u64,
                    // Re-encoding without flags or faults gives the healthy value.
                    Source::Status => assert!(!d.flagged, "{name}: status flagged"),
                    Source::Temperature => temperature = got,
                    // Encoders send 0 (no magnetometer): a vector's field must be 0.
                    Source::Mag(_) => {}
                    Source::GpsWeek => week = got,
                    Source::GpsSeconds => secs = Some(got),
                    Source::GpsWholeSeconds => whole = Some(got),
                    Source::GpsMicros => micros = got,
                    Source::GpsMillis => millis = Some(got),
                    // Only in live-input specs (protocols/live/), which have no vectors here.
                    Source::State(_) | Source::Raw => {}
                    Source::Channel(c, i) => {
                        let n = if c.is_gyro() { &mut gyros } else { &mut accels };
                        *n = (*n).max(i + 1);
                        channels[usize::from(!c.is_gyro())][i] = got;
                    }
                }
            }
            let ch_values: Vec<f64> = channels[0][..gyros]
                .iter()
                .chain(&channels[1][..accels])
                .copied()
                .collect();
            let ch = protocol::Channels {
                values: &ch_values,
                gyros,
                dt: 1.0,
                failed: 0,
            };
            let sow = secs
                .or(whole.map(|w| w + micros * 1e-6))
                .or(millis.map(|m| m * 1e-3));
            let mut state = EncoderState {
                frames: tv.frame.unwrap_or(counter),
                ..Default::default()
            };
            if let Some(sow) = sow {
                // The frame's GPS time becomes the run's reference, at record time 0.
                state.gps_week0 = week as u32;
                state.gps_sow0 = sow;
            }
            let mut out = Vec::new();
            let ch = plan.channels().is_some().then_some(&ch);
            plan.encode_with(&rec, ch, temperature, &mut state, &mut out);
            assert_eq!(out, bytes, "{name}: re-encoded frame");
        }
    }
}

/// Random records round-trip through every protocol; a corrupted byte is caught by the check.
#[test]
fn random_round_trips_and_corruption() {
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    for name in protocol::builtin_names() {
        let (_, plan) = protocol::load(name).unwrap();
        if plan.channels().is_some() {
            continue; // an N-channel frame takes no three-axis record: tests/skew_frames.rs
        }
        let mut state = EncoderState::default();
        let mut sums = [Vec3::default(); 2];
        // Running sums of each increment field as sent and as meant.
        let mut running: Vec<(Source, usize, f64, f64)> = Vec::new();
        for i in 0..1000 {
            let r = Record {
                t: i as f64 * 1e-3,
                gyro: Vec3::new(next(), next(), next()),
                accel: Vec3::new(next() * 15.0, next() * 15.0, next() * 15.0), // inside every range (STIM300 inclinometers: ±2 g)
                dtheta: Vec3::new(next() * 1e-3, next() * 1e-3, next() * 1e-3),
                dv: Vec3::new(next() * 0.05, next() * 0.05, next() * 0.05),
                flags: 0,
            };
            let mut out = Vec::new();
            plan.encode(&r, 25.0, &mut state, &mut out);
            let (frames, stats) = decode_stream(&plan, &out);
            assert_eq!(stats.frames, 1, "{name}: {stats:?}");
            let d = &frames[0];
            assert!(!d.flagged, "{name}: status flagged without saturation");
            // An accumulating message carries the sums since it was last sent.
            sums = [sums[0] + r.dtheta, sums[1] + r.dv];
            let (dtheta, dv) = if plan.accumulates(d.message) {
                let s = sums;
                sums = [Vec3::default(); 2];
                (s[0], s[1])
            } else {
                (r.dtheta, r.dv)
            };
            for (s, v) in &d.values {
                let want = match *s {
                    Source::Gyro(i) => r.gyro[i],
                    Source::Accel(i) => r.accel[i],
                    Source::DTheta(i) => dtheta[i],
                    Source::Dv(i) => dv[i],
                    Source::Time => r.t,
                    // Counters are checked by the golden vectors and the stream tests.
                    Source::Counter | Source::Status => continue,
                    Source::Temperature => 25.0,
                    Source::Mag(_) => 0.0,
                    // Time fields are checked by the golden vectors.
                    _ => continue,
                };
                // Single floats keep 24 bits (a relative 6e-8); integer fields half their step.
                let tol = plan.quantum(*s).map_or(1.2e-7 * want.abs() + 1e-30, |q| {
                    0.5 * q + 4.0 * f64::EPSILON * want.abs()
                });
                if !sums_within_half_a_step(&mut running, &plan, (*s, i), *v, want) {
                    assert!((v - want).abs() <= tol, "{name} {s:?}: {v} vs {want}");
                }
            }
            let mut bad = out.clone();
            // SDLC: the last two bytes hold the closing flag and idle marks, outside the frame.
            let k = match plan.transport {
                Transport::Plain => i % bad.len(),
                _ => i % (bad.len() - 2),
            };
            bad[k] ^= 0x10;
            assert_eq!(
                decode_stream(&plan, &bad).1.frames,
                0,
                "{name}: flipped bit in byte {k} not caught"
            );
        }
    }
}

/// A bad specification is refused naming the file, the field and the problem.
#[test]
fn bad_specs_name_file_field_and_problem() {
    let head = "name = \"t\"\n";
    let field = |body: &str| format!("{head}[[field]]\nname = \"f\"\n{body}\n");
    let cases = [
        (
            field("type = \"u16\"\nsource = \"gyro.w\""),
            "field `f`",
            "unknown source quantity `gyro.w`",
        ),
        (
            field("type = \"u8\"\nvalue = 300"),
            "field `f`",
            "does not fit",
        ),
        (field("type = \"u8\""), "field `f`", "needs a `value`"),
        (
            field("type = \"u8\"\nvalue = 1")
                + "[check]\nkind = \"crc-16/xmodem\"\ntype = \"u16\"\nfrom = 5\n",
            "`check`",
            "outside",
        ),
        (
            field("type = \"u8\"\nvalue = 1")
                + "[check]\ntype = \"u16\"\nkind = { width = 16, poly = 0x1021, init = 0xFFFF, refin = false, refout = false, xorout = 0, check = 0x1234 }\n",
            "`check`",
            "0x29b1",
        ),
        (
            field("type = \"u8\"\nvalue = 1")
                + "[check]\nkind = \"crc-99/nothing\"\ntype = \"u16\"\n",
            "`check`",
            "crc-99/nothing",
        ),
    ];
    for (text, place, problem) in cases {
        let p = Path::new("bad.toml");
        let e = FrameSpec::parse(&text, p)
            .and_then(|s| Plan::compile(&s, p).map(|_| ()))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bad.toml")
                && e.contains(place)
                && e.to_lowercase().contains(&problem.to_lowercase()),
            "{e}"
        );
    }
}

/// `generate --format NAME` writes the protocol's frames: one per record at the protocol's
/// nominal rate, every frame decodes (check and constants), counters run without gaps, and
/// the values are the records `generate --format bin` writes for the same run.
#[test]
fn generate_writes_frames_that_decode() {
    let exe = env!("CARGO_BIN_EXE_imu-emu");
    for name in protocol::builtin_names() {
        let (_, plan) = protocol::load(name).unwrap();
        if plan.channels().is_some() {
            continue; // an N-channel frame takes no three-axis record: tests/skew_frames.rs
        }
        let args = [
            "generate",
            "--scene",
            "circle",
            "--duration",
            "0.5",
            "--imu",
            "stim300",
            "--seed",
            "3",
        ];
        let rate = plan.rate_hz.unwrap_or(400.0);
        let frames = std::process::Command::new(exe)
            .args(args)
            .args(["--format", name, "--rate", &rate.to_string()])
            .output()
            .unwrap();
        assert!(
            frames.status.success(),
            "{}",
            String::from_utf8_lossy(&frames.stderr)
        );
        let bin = std::process::Command::new(exe)
            .args(args)
            .args(["--format", "bin", "--rate", &rate.to_string()])
            .output()
            .unwrap();
        assert!(bin.status.success());
        let n = (0.5 * rate) as usize;
        let (decoded, stats) = decode_stream(&plan, &frames.stdout);
        assert_eq!(
            stats,
            StreamStats {
                frames: n as u64,
                ..StreamStats::default()
            },
            "{name}"
        );
        if let Some(len) = plan.fixed_len() {
            assert_eq!(frames.stdout.len(), n * len, "{name}");
        }
        assert_eq!(bin.stdout.len(), n * 104);
        let mut last: Option<f64> = None;
        let mut sums = [0.0f64; 6];
        let mut running: Vec<(Source, usize, f64, f64)> = Vec::new();
        for (i, (d, b)) in decoded.iter().zip(bin.stdout.chunks(104)).enumerate() {
            let mut v: Vec<f64> = b
                .chunks(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect();
            // An accumulating message carries Δθ, ΔV summed since it was last sent.
            for (s, x) in sums.iter_mut().zip(&v[7..13]) {
                *s += x;
            }
            if plan.accumulates(d.message) {
                v[7..13].copy_from_slice(&sums);
                sums = [0.0; 6];
            }
            for (s, x) in &d.values {
                let want = match *s {
                    Source::Gyro(a) => v[1 + a],
                    Source::Accel(a) => v[4 + a],
                    Source::DTheta(a) => v[7 + a],
                    Source::Dv(a) => v[10 + a],
                    Source::Counter => {
                        if let Some(l) = last {
                            assert!(*x == l + 1.0 || *x == 0.0, "{name}: counter {l} then {x}");
                        }
                        last = Some(*x);
                        continue;
                    }
                    Source::Status => {
                        assert!(!d.flagged, "{name} frame {i}: status flagged");
                        continue;
                    }
                    _ => continue,
                };
                // Floats keep 24 bits; integer fields round to half their step.
                let tol = plan.quantum(*s).map_or(1.2e-7 * want.abs() + 1e-30, |q| {
                    0.5 * q + 4.0 * f64::EPSILON * want.abs()
                });
                if !sums_within_half_a_step(&mut running, &plan, (*s, i), *x, want) {
                    assert!(
                        (x - want).abs() <= tol,
                        "{name} frame {i} {s:?}: {x} vs {want}"
                    );
                }
            }
        }
    }
}

/// `imu-emu decode` reads a frame stream back to CSV and reports exactly the damage done to
/// it: garbage skipped, a corrupted frame as a check failure, a dropped frame as a gap.
#[test]
fn decode_command_reports_damage() {
    let exe = env!("CARGO_BIN_EXE_imu-emu");
    let dir = std::env::temp_dir().join(format!("imu-emu-decode-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = std::process::Command::new(exe)
        .args([
            "generate",
            "--scene",
            "circle",
            "--duration",
            "0.02",
            "--format",
            "kvh1750",
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    let frames: Vec<&[u8]> = out.stdout.chunks(36).collect();
    assert_eq!(frames.len(), 20);
    let mut damaged = b"junk".to_vec();
    for (i, f) in frames.iter().enumerate() {
        match i {
            5 => continue,
            9 => {
                let mut bad = f.to_vec();
                bad[20] ^= 0x40;
                damaged.extend_from_slice(&bad);
            }
            _ => damaged.extend_from_slice(f),
        }
    }
    let path = dir.join("stream.bin");
    std::fs::write(&path, &damaged).unwrap();
    let dec = std::process::Command::new(exe)
        .args(["decode", "--protocol", "kvh1750"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(dec.status.success());
    let text = String::from_utf8(dec.stdout).unwrap();
    // The record contract, then the frame's own other fields.
    assert_eq!(
        text.lines().next().unwrap(),
        "t,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z,dtheta_x,dtheta_y,dtheta_z,dv_x,dv_y,dv_z,status,sequence,temperature"
    );
    assert_eq!(text.lines().count(), 1 + 18);
    let err = String::from_utf8(dec.stderr).unwrap();
    // The corrupted frame took its counter value: only the dropped frame is a gap.
    assert!(
        err.contains("18 frames, 1 check failures, 1 counter gaps, 0 duplicates, 0 stale counters, 0 status flagged, 4 bytes skipped"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Values beyond a field's range saturate instead of wrapping (STIM300 inclinometer: 24-bit
/// at 2^22 counts per g, so ±2 g).
#[test]
fn out_of_range_values_saturate() {
    let (_, plan) = protocol::load("stim300").unwrap();
    let r = Record {
        accel: Vec3::new(0.0, 0.0, 40.0),
        ..Record::default()
    };
    let mut out = Vec::new();
    plan.encode(&r, 25.0, &mut EncoderState::default(), &mut out);
    assert_eq!(
        &out[27..30],
        &[0x7F, 0xFF, 0xFF],
        "incl z at the positive limit"
    );
    // The 10 g accelerometer channel carries 40 m/s² unsaturated (to its 2^-19 g step).
    let lsb = 1.8704700469970702e-05;
    let d = plan.decode(&out).unwrap();
    assert_eq!(d.get(Source::Accel(2)), Some((40.0f64 / lsb).round() * lsb));
}

/// STIM300 counts internal 2000 Hz samples: at 125 datagrams/s the counter advances by 16.
/// `decode --rate 125` expects that step (no gaps); at the nominal 2000 Hz every datagram
/// looks like a gap; a rate that does not divide 2000 is refused.
#[test]
fn stim300_counter_follows_the_run_rate() {
    let exe = env!("CARGO_BIN_EXE_imu-emu");
    let out = std::process::Command::new(exe)
        .args(["generate", "--scene", "static", "--duration", "0.2"])
        .args(["--format", "stim300-91", "--rate", "125"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let frames: Vec<&[u8]> = out.stdout.chunks(28).collect();
    assert_eq!(frames.len(), 25);
    let counters: Vec<u8> = frames.iter().map(|f| f[21]).collect();
    assert_eq!(&counters[..4], &[0, 16, 32, 48]);
    assert_eq!(counters[24], (24 * 16 % 256) as u8);
    let decode = |rate: Option<&str>| {
        let mut c = std::process::Command::new(exe);
        c.args(["decode", "--protocol", "stim300-91"]);
        if let Some(r) = rate {
            c.args(["--rate", r]);
        }
        let mut child = c
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        use std::io::Write;
        child.stdin.take().unwrap().write_all(&out.stdout).unwrap();
        String::from_utf8(child.wait_with_output().unwrap().stderr).unwrap()
    };
    assert!(decode(Some("125")).contains("25 frames, 0 check failures, 0 counter gaps"));
    assert!(decode(None).contains("25 frames, 0 check failures, 24 counter gaps"));
    let bad = std::process::Command::new(exe)
        .args(["generate", "--scene", "static", "--duration", "0.1"])
        .args(["--format", "stim300", "--rate", "300"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("must divide 2000") && err.contains("300"),
        "{err}"
    );
}

/// `decode --help` names every built-in protocol.
#[test]
fn decode_help_lists_every_built_in() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(["decode", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8(out.stdout).unwrap();
    for name in protocol::builtin_names() {
        assert!(help.contains(name), "decode --help lacks {name}");
    }
}

/// A `wrap = true` field (KVH Format B's µs timestamp) wraps at its type's range like the
/// unit's free-running clock, instead of saturating.
#[test]
fn timestamps_wrap() {
    let (_, plan) = protocol::load("kvh1750-b").unwrap();
    let t = 4_294.967_296 + 1.5; // 2^32 µs + 1.5 s
    let mut out = Vec::new();
    plan.encode(
        &Record {
            t,
            ..Record::default()
        },
        25.0,
        &mut EncoderState::default(),
        &mut out,
    );
    assert_eq!(
        u32::from_be_bytes(out[28..32].try_into().unwrap()),
        1_500_000
    );
    assert_eq!(out[32], 0x77, "wrapping is not an overrange");
}

/// `decode` prints the record contract: the rates and increments of each frame equal the
/// records `generate` writes for the same run (to the f32 precision of KVH floats), the
/// rates KVH does not carry derived from its increments over the Δt of `--rate`.
#[test]
fn decode_prints_the_record_contract() {
    let exe = env!("CARGO_BIN_EXE_imu-emu");
    let run = |args: &[&str], input: Option<&[u8]>| {
        let mut c = std::process::Command::new(exe);
        c.args(args)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped());
        let mut child = c.spawn().unwrap();
        if let Some(bytes) = input {
            use std::io::Write;
            child.stdin.take().unwrap().write_all(bytes).unwrap();
        }
        let out = child.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        out.stdout
    };
    let common = ["--scene", "circle", "--duration", "0.05", "--rate", "1000"];
    let csv = run(
        &[&["generate", "--format", "csv"], &common[..]].concat(),
        None,
    );
    let frames = run(
        &[&["generate", "--format", "kvh1750"], &common[..]].concat(),
        None,
    );
    let decoded = run(
        &["decode", "--protocol", "kvh1750", "--rate", "1000"],
        Some(&frames),
    );
    let rows = |b: &[u8]| -> Vec<Vec<String>> {
        String::from_utf8(b.to_vec())
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect()
    };
    let (want, got) = (rows(&csv), rows(&decoded));
    assert_eq!(want.len(), 50);
    assert_eq!(got.len(), 50);
    for (w, g) in want.iter().zip(&got) {
        assert_eq!(g[0], "", "KVH frames carry no time tag");
        for c in 1..13 {
            let (w, g): (f64, f64) = (w[c].parse().unwrap(), g[c].parse().unwrap());
            assert!(
                (w - g).abs() <= 1.2e-7 * w.abs() + 1e-30,
                "column {c}: {g} vs {w}"
            );
        }
    }
}

/// KVH Format C: the sequence number picks the multiplexed word's slot (temperature, mag X, Y,
/// Z, assumed order) when encoding and decoding; a stale counter keeps the slot of the
/// counter it repeats; a real unit's non-zero field decodes in its slot. Frame bytes built by
/// an independent Python script (CRC-32/MPEG-2 bitwise).
#[test]
fn kvh_format_c_slots_follow_the_sequence_number() {
    let (_, plan) = protocol::load("kvh1750-c").unwrap();
    assert_eq!(plan.fixed_len(), Some(38));
    // A unit's frame: sequence 106 (slot 2, mag Y) carrying 0.25 gauss = 2.5e-5 T.
    let f = hex(
        "FE81FF57 B3D0BBE7 32193EF4 30AC19A5 BA8F78D6 3A290594 3F7ECBD4 3E800000 77 6A CBC6C54B",
    );
    let d = plan.decode(&f).unwrap();
    assert_eq!(plan.message_name(d.message), "mag_y");
    let mag = d.get(Source::Mag(1)).unwrap();
    assert!((mag - 2.5e-5).abs() <= 1e-15 * 2.5e-5, "{mag}");
    assert_eq!(d.get(Source::Temperature), None);
    assert_eq!(d.get(Source::Counter), Some(106.0));
    // Encoding: frame k carries sequence k mod 128 and the slot k mod 4; its word is the
    // temperature (f32 °C) in slot 0 and 0 (no magnetometer) otherwise.
    let mut st = EncoderState::default();
    let mut out = Vec::new();
    for _ in 0..130 {
        plan.encode(&Record::default(), 31.5, &mut st, &mut out);
    }
    for (k, fr) in out.chunks(38).enumerate() {
        let seq = fr[33] as usize;
        assert_eq!(seq, k % 128);
        let word = f32::from_be_bytes(fr[28..32].try_into().unwrap());
        assert_eq!(
            word,
            if seq.is_multiple_of(4) { 31.5 } else { 0.0 },
            "frame {k}"
        );
        let d = plan.decode(fr).unwrap();
        let names = ["temperature", "mag_x", "mag_y", "mag_z"];
        assert_eq!(plan.message_name(d.message), names[seq % 4], "frame {k}");
    }
    // A stale counter: the frame repeats sequence 2 and so slot 2 (mag Y).
    use imu_emu::protocol::faults::When;
    use imu_emu::protocol::{FaultInjector, FaultKind, FaultSpec};
    let inj = FaultInjector::new(
        vec![FaultSpec {
            kind: FaultKind::StaleCounter,
            when: When::At(vec![0.03]),
            duration_s: 0.0,
        }],
        100.0,
        1,
    );
    let mut st = EncoderState {
        faults: Some(Box::new(inj)),
        ..Default::default()
    };
    let mut out = Vec::new();
    for k in 0..5 {
        let r = Record {
            t: k as f64 / 100.0,
            ..Record::default()
        };
        plan.encode(&r, 25.0, &mut st, &mut out);
    }
    let seqs: Vec<u8> = out.chunks(38).map(|f| f[33]).collect();
    assert_eq!(seqs, [0, 1, 2, 2, 3]);
    let slots: Vec<&str> = out
        .chunks(38)
        .map(|f| plan.message_name(plan.decode(f).unwrap().message))
        .collect();
    assert_eq!(slots, ["temperature", "mag_x", "mag_y", "mag_y", "mag_z"]);
}

/// `schedule_by = "counter"` is refused without a counter, or with a counter whose modulo the
/// schedule does not divide, naming the problem.
#[test]
fn counter_schedule_needs_a_fitting_counter() {
    let text = protocol::BUILTIN
        .iter()
        .find(|b| b.0 == "kvh1750-c")
        .unwrap()
        .1;
    let path = Path::new("bad.toml");
    let compile = |t: &str| {
        let spec = FrameSpec::parse(t, path).unwrap();
        Plan::compile(&spec, path).err().map(|e| e.to_string())
    };
    assert_eq!(compile(text), None);
    let e = compile(&text.replace("modulo = 128", "modulo = 126")).unwrap();
    assert!(e.contains("bad.toml") && e.contains("modulo 126"), "{e}");
    let e = compile(&text.replace("source = \"counter\"", "value = 0")).unwrap();
    assert!(e.contains("needs a counter"), "{e}");
}

/// The output of a command run with `input` on stdin.
fn run_with(args: &[&str], input: &[u8]) -> std::process::Output {
    use std::io::Write;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(args)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input).unwrap();
    child.wait_with_output().unwrap()
}

/// Frames of a built-in protocol from `generate` (static scene, ideal IMU).
fn generated(format: &str, rate: &str, duration: &str) -> Vec<u8> {
    let out = run_with(
        &[
            "generate",
            "--scene",
            "static",
            "--format",
            format,
            "--rate",
            rate,
            "--duration",
            duration,
        ],
        b"",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// `decode --protocol` of a name that is neither a built-in nor a file says "unknown protocol"
/// and lists the built-ins (not "cannot read"); a file that exists but is no spec gives the
/// spec's own error; a missing `--protocol-file` cannot be read, its cause said once.
#[test]
fn decode_names_an_unknown_protocol() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nosuch.toml");
    for name in ["nosuch", missing.to_str().unwrap()] {
        let out = run_with(&["decode", "--protocol", name], b"");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{err}");
        assert!(
            err.contains(&format!("unknown protocol `{name}`"))
                && err.contains("kvh1750")
                && err.contains("stim300-a7")
                && !err.contains("cannot read"),
            "{err}"
        );
    }
    let bad = dir.path().join("bad.toml");
    std::fs::write(
        &bad,
        "name = \"b\"\n[[field]]\nname = \"x\"\ntype = \"u9\"\n",
    )
    .unwrap();
    let out = run_with(&["decode", "--protocol", bad.to_str().unwrap()], b"");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("bad.toml") && err.contains("u9"),
        "{err}"
    );
    let out = run_with(
        &["decode", "--protocol-file", missing.to_str().unwrap()],
        b"",
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("nosuch.toml: cannot read"),
        "{err}"
    );
    assert_eq!(
        err.matches("os error 2").count(),
        1,
        "cause said once: {err}"
    );
}

/// Input with no valid frame is a failure (exit status non-zero) that still prints the tally.
#[test]
fn decode_of_no_valid_frame_fails() {
    let mut junk = b"this is not a KVH stream at all, only text\n".repeat(3);
    let out = run_with(&["decode", "--protocol", "kvh1750"], &junk);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("0 frames") && err.contains(&format!("{} bytes skipped", junk.len())),
        "{err}"
    );
    assert!(err.contains("no valid `kvh1750` frame"), "{err}");
    // Empty input too.
    junk.clear();
    let out = run_with(&["decode", "--protocol", "ln200"], &junk);
    assert!(!out.status.success());
}

/// A stream cut inside its last frame: the whole frames decode, the cut one is reported as cut
/// short (not as skipped bytes), plain and SDLC, and on the command line.
#[test]
fn a_truncated_last_frame_is_counted() {
    // KVH frames in asynchronous HDLC (byte stuffing) too: no built-in protocol uses it.
    let kvh = protocol::BUILTIN
        .iter()
        .find(|b| b.0 == "kvh1750")
        .unwrap()
        .1;
    let kvh_hdlc = protocol::load::compile_text(
        &kvh.replace("[check]", "[hdlc]\nfcs = \"fcs-16\"\n\n[check]"),
        Path::new("kvh-hdlc.toml"),
    )
    .unwrap()
    .1;
    assert!(matches!(kvh_hdlc.transport, Transport::Hdlc(_)));
    for name in [
        "kvh1750",
        "ln200",
        "mavlink-hil-sensor",
        "ln200-sdlc",
        "hg1700-sdlc",
        "kvh-hdlc",
    ] {
        let plan = match name {
            "kvh-hdlc" => kvh_hdlc.clone(),
            _ => protocol::load(name).unwrap().1,
        };
        let mut st = EncoderState::default();
        let mut bytes = Vec::new();
        let mut ends = Vec::new();
        for k in 0..5 {
            let r = Record {
                t: k as f64 * 0.01,
                gyro: Vec3::new(0.1, -0.2, 0.3),
                dtheta: Vec3::new(1e-3, -2e-3, 3e-3),
                ..Record::default()
            };
            plan.encode(&r, 25.0, &mut st, &mut bytes);
            ends.push(bytes.len());
        }
        // Cut half-way into the last frame.
        let cut = ends[3] + (ends[4] - ends[3]) / 2;
        let mut d = StreamDecoder::new(plan.clone());
        let mut n = 0;
        d.feed(&bytes[..cut], |_| n += 1);
        d.finish();
        assert_eq!(n, 4, "{name}");
        let s = d.stats();
        assert_eq!(
            (s.frames, s.truncated, s.skipped_bytes),
            (4, 1, 0),
            "{name}: {s:?}"
        );
        // The whole stream: nothing cut short.
        let mut d = StreamDecoder::new(plan);
        d.feed(&bytes, |_| {});
        d.finish();
        assert_eq!((d.stats().frames, d.stats().truncated), (5, 0), "{name}");
    }
    let frames = generated("kvh1750", "1000", "0.01");
    let out = run_with(
        &["decode", "--protocol", "kvh1750", "--tally-only"],
        &frames[..frames.len() - 7],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("9 frames,")
            && err.contains("0 bytes skipped")
            && err.contains("1 frame cut short at the end"),
        "{err}"
    );
}

/// Frames that carry only increments (LN-200) or only rates (MAVLink): without `--rate` the
/// missing columns are not made up from the nominal rate. LN-200 frames have no time tag, so
/// the rate columns stay empty (and stderr says why); MAVLink frames do, so the increments
/// are the rates over the interval of their time stamps. With `--rate` both derive from it.
#[test]
fn decode_takes_the_interval_from_rate_or_time_tags() {
    // 100 Hz, a quarter of LN-200's nominal 400 Hz: the nominal Δt would scale rates by 4.
    let frames = generated("ln200", "100", "0.05");
    let rows = |out: &std::process::Output| -> Vec<Vec<String>> {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect()
    };
    let out = run_with(&["decode", "--protocol", "ln200"], &frames);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    let got = rows(&out);
    assert_eq!(got.len(), 5);
    assert!(err.contains("--rate"), "{err}");
    for r in &got {
        assert!(
            r[1..7].iter().all(String::is_empty),
            "rates without a rate: {r:?}"
        );
        assert!(r[7..13].iter().all(|c| !c.is_empty()), "{r:?}");
    }
    let got = rows(&run_with(
        &["decode", "--protocol", "ln200", "--rate", "100"],
        &frames,
    ));
    for r in &got {
        for a in 0..6 {
            let (rate, inc): (f64, f64) = (r[1 + a].parse().unwrap(), r[7 + a].parse().unwrap());
            assert!((rate - inc * 100.0).abs() <= 1e-12 * rate.abs(), "{r:?}");
        }
    }
    // MAVLink at 100 Hz (nominal 250): Δt from time_usec, known from the second frame on.
    let frames = generated("mavlink-highres-imu", "100", "0.05");
    let got = rows(&run_with(
        &["decode", "--protocol", "mavlink-highres-imu"],
        &frames,
    ));
    assert_eq!(got.len(), 5);
    assert!(got[0][7..13].iter().all(String::is_empty), "{:?}", got[0]);
    for r in &got[1..] {
        for a in 0..6 {
            let (rate, inc): (f64, f64) = (r[1 + a].parse().unwrap(), r[7 + a].parse().unwrap());
            // The time stamps are whole µs: 10 000 µs exactly.
            assert!((inc - rate * 0.01).abs() <= 1e-12 * rate.abs(), "{r:?}");
        }
    }
}

/// Sanity bounds: duplicate field names, an LSB that is zero, negative or not finite, a
/// non-finite sign, more fields or bytes than any real frame, a bad `rate_hz` or `baud` are
/// refused naming the file and the field; numbers in messages stay short.
#[test]
fn spec_sanity_bounds() {
    let q = |lsb: &str| {
        format!("[[field]]\nname = \"g\"\ntype = \"i16\"\nsource = \"gyro.x\"\nlsb = {lsb}\n")
    };
    let head = "name = \"t\"\n[[field]]\nname = \"sync\"\ntype = \"u8\"\nvalue = 1\n";
    let cases: Vec<(String, &str, &str)> = vec![
        (
            format!("{head}{}{}", q("1e-3"), q("2e-3")),
            "field `g`",
            "a second field of this name",
        ),
        (format!("{head}{}", q("0.0")), "field `g`", "lsb = 0:"),
        (
            format!("{head}{}", q("-1e-3")),
            "field `g`",
            "lsb = -0.001:",
        ),
        (format!("{head}{}", q("nan")), "field `g`", "lsb = NaN:"),
        (format!("{head}{}", q("inf")), "field `g`", "lsb = inf:"),
        (
            format!("{head}{}", q("-1e300")),
            "field `g`",
            "lsb = -1e300:",
        ),
        (
            format!("{head}{}sign = nan\n", q("1.0")),
            "field `g`",
            "sign = NaN",
        ),
        (
            format!("rate_hz = 0\n{head}"),
            "`rate_hz` = 0",
            "expected a rate",
        ),
        (
            format!("rate_hz = 1e300\n{head}"),
            "`rate_hz` = 1e300",
            "expected a rate",
        ),
        (format!("baud = 0\n{head}"), "`baud` = 0", "bit/s"),
        (
            format!(
                "{head}{}",
                (0..300)
                    .map(|i| format!("[[field]]\nname = \"w{i}\"\ntype = \"u64\"\nvalue = 0\n"))
                    .collect::<String>()
            ),
            "field `w255`",
            "at most 2048 bytes",
        ),
        (
            format!(
                "{head}{}",
                (0..600)
                    .map(|i| format!("[[field]]\nname = \"w{i}\"\ntype = \"u8\"\nvalue = 0\n"))
                    .collect::<String>()
            ),
            "601 fields",
            "at most 512",
        ),
    ];
    for (text, place, problem) in cases {
        let p = Path::new("bad.toml");
        let e = FrameSpec::parse(&text, p)
            .and_then(|s| Plan::compile(&s, p).map(|_| ()))
            .expect_err(place)
            .to_string();
        assert!(
            e.starts_with("bad.toml: ") && e.contains(place) && e.contains(problem),
            "{e}\nwanted {place} … {problem}"
        );
        assert!(e.len() < 300, "{e}");
    }
    // A spec file of 200 000 fields is refused by its size, naming it, before it is parsed.
    let dir = tempfile::tempdir().unwrap();
    let huge = dir.path().join("huge.toml");
    let text = format!(
        "name = \"h\"\n{}",
        (0..200_000)
            .map(|i| format!("[[field]]\nname = \"w{i}\"\ntype = \"u8\"\nvalue = 0\n"))
            .collect::<String>()
    );
    std::fs::write(&huge, text).unwrap();
    let e = protocol::load_file(&huge).unwrap_err().to_string();
    assert!(e.contains("huge.toml") && e.contains("at most"), "{e}");
    // The same bounds hold for `--protocol-file` on the command line, naming the file.
    let out = run_with(&["decode", "--protocol-file", huge.to_str().unwrap()], b"");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("huge.toml"));
}

/// A record with a non-finite value: no frame carries a non-finite value or looks healthy.
/// A protocol whose status word has a failure model sends the frame with the failure bits set
/// (as a real unit's built-in test reports a failed sensor); one without (MAVLink, NovAtel)
/// withholds the frame, its counter value skipped, so a receiver sees the gap. The record's
/// own `FLAG_INVALID` does the same with finite values.
#[test]
fn non_finite_values_never_reach_a_healthy_frame() {
    let bad = [
        Record {
            gyro: Vec3::new(f64::NAN, 0.0, 0.0),
            dtheta: Vec3::new(f64::NAN, 0.0, 0.0),
            ..Record::default()
        },
        Record {
            accel: Vec3::new(0.0, f64::INFINITY, 0.0),
            dv: Vec3::new(0.0, f64::INFINITY, 0.0),
            ..Record::default()
        },
        Record {
            t: f64::NAN,
            ..Record::default()
        },
        Record {
            flags: imu_emu::record::FLAG_INVALID,
            ..Record::default()
        },
    ];
    for name in protocol::builtin_names() {
        let (_, plan) = protocol::load(name).unwrap();
        if plan.channels().is_some() {
            continue; // an N-channel frame takes no three-axis record: tests/skew_frames.rs
        }
        for (i, r) in bad.iter().enumerate() {
            // Which non-finite quantities this protocol carries at all.
            let sources = plan.value_sources().concat();
            let carried = match i {
                0 => sources.contains(&Source::Gyro(0)) || sources.contains(&Source::DTheta(0)),
                1 => sources.contains(&Source::Accel(1)) || sources.contains(&Source::Dv(1)),
                2 => sources.iter().any(|s| {
                    matches!(
                        s,
                        Source::Time
                            | Source::GpsSeconds
                            | Source::GpsWeek
                            | Source::GpsMillis
                            | Source::GpsWholeSeconds
                            | Source::GpsMicros
                    )
                }),
                _ => true,
            };
            // A healthy frame first so that a withheld one shows as a counter gap.
            let mut st = EncoderState::default();
            let mut bytes = Vec::new();
            for (k, rec) in [&Record::default(), r, &Record::default()]
                .into_iter()
                .enumerate()
            {
                let mut rec = *rec;
                if !rec.t.is_nan() {
                    rec.t = 1.0 + 0.01 * k as f64;
                }
                plan.encode(&rec, 25.0, &mut st, &mut bytes);
            }
            let (frames, stats) = decode_stream(&plan, &bytes);
            for f in &frames {
                assert!(
                    f.values.iter().all(|v| v.1.is_finite()),
                    "{name} case {i}: {f:?}"
                );
            }
            if !carried {
                assert_eq!(
                    (frames.len(), stats.status_flagged),
                    (3, 0),
                    "{name} case {i}"
                );
            } else if st.withheld == 1 {
                assert_eq!(frames.len(), 2, "{name} case {i}");
                if plan.counter().is_some() {
                    assert_eq!(stats.counter_gaps, 1, "{name} case {i}: {stats:?}");
                }
            } else {
                assert_eq!(st.withheld, 0, "{name} case {i}");
                assert_eq!(frames.len(), 3, "{name} case {i}");
                assert!(
                    frames[1].flagged && !frames[0].flagged,
                    "{name} case {i}: failure bits"
                );
            }
        }
        let mavlink_or_novatel = name.starts_with("mavlink") || name.starts_with("novatel");
        let mut st = EncoderState::default();
        plan.encode(&bad[3], 25.0, &mut st, &mut Vec::new());
        assert_eq!(st.withheld == 1, mavlink_or_novatel, "{name}");
    }
}

/// An error with a cause prints the cause once: the cause is the error's `source()`, not
/// repeated in its message.
#[test]
fn spec_errors_do_not_repeat_their_cause() {
    let e = protocol::load_file(Path::new("/nonexistent/imu-emu/x.toml")).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("x.toml") && !text.contains("os error"),
        "{text}"
    );
    let source = std::error::Error::source(&e)
        .expect("the I/O error is the source")
        .to_string();
    assert!(source.contains("os error 2"), "{source}");
}

/// A value clipped at its field's range (or at f32's largest) is counted as unreported where
/// no status bit of the message reports it (NovAtel's integer fields, MAVLink's floats), and
/// not where one does (STIM300, LN-200, KVH 1750): Python's `encode` refuses the former.
#[test]
fn clipping_without_a_status_bit_is_counted() {
    for (name, want) in [
        ("novatel-rawimusx", 1),
        ("mavlink-hil-sensor", 1),
        ("stim300", 0),
        ("ln200", 0),
        ("kvh1750", 0),
    ] {
        let (_, plan) = imu_emu::protocol::load(name).unwrap();
        let mut st = EncoderState::default();
        let mut out = Vec::new();
        let mut v = [0.0; 13];
        v[0] = 0.001;
        plan.encode(&Record::from_values(&v), 25.0, &mut st, &mut out);
        assert_eq!(st.unreported, 0, "{name}");
        v[1] = 1e300;
        v[7] = 1e297;
        plan.encode(&Record::from_values(&v), 25.0, &mut st, &mut out);
        assert_eq!(st.unreported, want, "{name}");
    }
}
