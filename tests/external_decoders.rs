//! Our frames decoded by decoders written by others: pymavlink for MAVLink 2 HIL_SENSOR and
//! NovAtel's EDIE for RAWIMUSXB (both from PyPI), through `scripts/cross_check.py`. They need
//! a Python with those packages, named by `IMU_EMU_PYTHON`; `.ci/run` builds one under
//! `target/` and runs these tests with `--ignored`.

use imu_emu::math::Vec3;
use imu_emu::protocol::faults::When;
use imu_emu::protocol::spec::Source;
use imu_emu::protocol::{self, EncoderState, FaultInjector, FaultKind, FaultSpec};
use imu_emu::record::Record;
use std::collections::HashMap;

/// One decoded frame: field name → value as the decoder printed it.
#[derive(Debug)]
struct Msg(HashMap<String, String>);

impl Msg {
    fn s(&self, k: &str) -> &str {
        self.0
            .get(k)
            .map(|v| v.trim_matches('\''))
            .unwrap_or_else(|| panic!("no `{k}` in {self:?}"))
    }
    fn f(&self, k: &str) -> f64 {
        self.s(k).parse().unwrap()
    }
    fn i(&self, k: &str) -> i64 {
        self.s(k).parse().unwrap()
    }
}

const NEEDS: &str = "IMU_EMU_PYTHON: a Python with pymavlink and novatel-edie (.ci/run)";

/// `n` records at `rate` Hz with varied values (a fixed xorshift sequence).
fn records(n: usize, rate: f64) -> Vec<Record> {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..n)
        .map(|k| {
            let gyro = Vec3::new(next(), next(), next());
            let accel = Vec3::new(5.0 * next(), 5.0 * next(), -9.8 + next());
            Record {
                t: (k + 1) as f64 / rate,
                gyro,
                accel,
                dtheta: gyro * (1.0 / rate),
                dv: accel * (1.0 / rate),
                flags: 0,
            }
        })
        .collect()
}

/// Encodes `recs` with `name`, corrupting the checks of frames `bad`; runs the external
/// decoder; returns its JSON objects.
fn cross_check(
    name: &str,
    kind: &str,
    recs: &[Record],
    bad: &[usize],
    st: EncoderState,
) -> Vec<Msg> {
    let python = std::env::var("IMU_EMU_PYTHON").expect(NEEDS);
    let (_, plan) = protocol::load(name).unwrap();
    let rate = plan.rate_hz.unwrap();
    let inj = FaultInjector::new(
        vec![FaultSpec {
            kind: FaultKind::CorruptCheck,
            when: When::At(bad.iter().map(|&k| (k + 1) as f64 / rate).collect()),
            duration_s: 0.0,
        }],
        rate,
        1,
    );
    let mut st = EncoderState {
        faults: Some(Box::new(inj)),
        ..st
    };
    let mut bytes = Vec::new();
    for r in recs {
        plan.encode(r, 25.0, &mut st, &mut bytes);
    }
    let path = std::env::temp_dir().join(format!("imu-emu-xcheck-{name}-{}", std::process::id()));
    std::fs::write(&path, &bytes).unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/cross_check.py");
    let out = std::process::Command::new(&python)
        .args([script, kind])
        .arg(&path)
        .output()
        .unwrap_or_else(|e| panic!("running {python}: {e}"));
    let _ = std::fs::remove_file(&path);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            Msg(l
                .split(';')
                .filter_map(|kv| kv.split_once('='))
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect())
        })
        .collect()
}

/// pymavlink accepts every intact HIL_SENSOR and HIGHRES_IMU frame (CRC with CRC_EXTRA,
/// truncated payload) and rejects the two with corrupted CRCs; its values are ours exactly:
/// the time in µs, accelerations and rates as single floats, temperature, sequence numbers.
#[test]
#[ignore = "needs IMU_EMU_PYTHON: a Python with pymavlink and novatel-edie (.ci/run)"]
fn pymavlink_decodes_our_frames() {
    for (name, kind) in [
        ("mavlink-hil-sensor", "HIL_SENSOR"),
        ("mavlink-highres-imu", "HIGHRES_IMU"),
    ] {
        pymavlink_check(name, kind);
    }
}

fn pymavlink_check(name: &str, kind: &str) {
    let recs = records(600, 250.0);
    let bad = [100, 333];
    let msgs = cross_check(name, "mavlink", &recs, &bad, EncoderState::default());
    let good: Vec<&Msg> = msgs
        .iter()
        .filter(|m| m.s("mavpackettype") == kind)
        .collect();
    assert_eq!(good.len(), recs.len() - bad.len());
    assert!(msgs.iter().any(|m| m.s("mavpackettype") == "BAD_DATA"));
    let kept = (0..recs.len()).filter(|k| !bad.contains(k));
    for (m, k) in good.iter().zip(kept) {
        let r = &recs[k];
        assert_eq!(m.i("seq"), k as i64 % 256);
        assert_eq!(m.i("time_usec"), (r.t * 1e6).round() as i64);
        for (i, a) in ["x", "y", "z"].iter().enumerate() {
            assert_eq!(m.f(&format!("{a}acc")), r.accel[i] as f32 as f64);
            assert_eq!(m.f(&format!("{a}gyro")), r.gyro[i] as f32 as f64);
        }
        assert_eq!(m.f("temperature"), 25.0);
        assert_eq!(m.i("fields_updated"), 0x103F);
    }
}

/// NovAtel EDIE accepts every intact RAWIMUSXB frame (NovAtel CRC-32) and drops the corrupted
/// ones; its counts are the record's values over the EG320N scale factors in NovAtel's order
/// z, −y, x, and its GPS week and seconds are the run's time reference plus the record time.
#[test]
#[ignore = "needs IMU_EMU_PYTHON: a Python with pymavlink and novatel-edie (.ci/run)"]
fn novatel_edie_decodes_our_rawimusx_frames() {
    let (_, plan) = protocol::load("novatel-rawimusx").unwrap();
    let rate = plan.rate_hz.unwrap();
    let recs = records(400, rate);
    let bad = [7, 250];
    let st = EncoderState {
        gps_week0: 2209,
        gps_sow0: 491_674.0,
        ..Default::default()
    };
    let msgs = cross_check("novatel-rawimusx", "novatel", &recs, &bad, st);
    let good: Vec<&Msg> = msgs.iter().filter(|m| m.s("name") == "RAWIMUSX").collect();
    assert_eq!(good.len(), recs.len() - bad.len());
    assert!(msgs.iter().any(|m| m.s("name") == "UnknownBytes"));
    let kept = (0..recs.len()).filter(|k| !bad.contains(k));
    let counts = |x: f64, s: Source| (x / plan.quantum(s).unwrap()).round() as i64;
    for (m, k) in good.iter().zip(kept) {
        let r = &recs[k];
        assert_eq!(m.i("gps_week"), 2209);
        assert!((m.f("gps_seconds") - (491_674.0 + r.t)).abs() < 1e-9);
        assert_eq!(m.i("imu_type"), 41);
        // NovAtel's field names say which axis and sign (z, −y, x); the spec's sources carry
        // the EG320N's rates and accelerations.
        for (key, s, sign) in [
            ("accel_z", Source::Accel(2), 1.0),
            ("accel_y", Source::Accel(1), -1.0),
            ("accel_x", Source::Accel(0), 1.0),
            ("gyro_z", Source::Gyro(2), 1.0),
            ("gyro_y", Source::Gyro(1), -1.0),
            ("gyro_x", Source::Gyro(0), 1.0),
        ] {
            let v = match s {
                Source::Accel(i) => r.accel[i],
                Source::Gyro(i) => r.gyro[i],
                _ => unreachable!(),
            };
            assert_eq!(m.i(key), counts(sign * v, s), "{key} of frame {k}");
        }
    }
}
