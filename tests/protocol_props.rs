//! Property tests over every built-in protocol (fixed proptest seed, so a run is
//! reproducible): random records round-trip to within half an LSB; decoders never panic on
//! random bytes; after garbage they find the frames again.

use imu_emu::math::Vec3;
use imu_emu::protocol::spec::Source;
use imu_emu::protocol::{self, Decoded, EncoderState, Plan, StreamDecoder};
use imu_emu::record::Record;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

#[path = "common/carry.rs"]
mod carry;

fn config(cases: u32) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(20_261_124),
        failure_persistence: None,
        ..Config::default()
    }
}

fn plans() -> Vec<Plan> {
    // N-channel frames take no three-axis record: tests/skew_frames.rs.
    protocol::builtin_names()
        .into_iter()
        .map(|n| protocol::load(n).unwrap().1)
        .filter(|p| p.channels().is_none())
        .collect()
}

fn vec3(r: f64) -> impl Strategy<Value = Vec3> {
    prop::array::uniform3(-r..r).prop_map(Vec3::from)
}

/// Records inside every protocol's range: rates ±3 rad/s, specific force ±15 m/s² (STIM300
/// inclinometers: ±2 g), Δθ ±0.04 rad and ΔV ±0.75 m/s (LN-200: ±0.0625 rad, ±2 m/s; HG4930
/// inertial sums of six: ±0.25 rad, ±4.9 m/s).
fn record() -> impl Strategy<Value = Record> {
    (0.0..1e6f64, vec3(3.0), vec3(15.0), vec3(0.04), vec3(0.75)).prop_map(
        |(t, gyro, accel, dtheta, dv)| Record {
            t,
            gyro,
            accel,
            dtheta,
            dv,
            flags: 0,
        },
    )
}

fn decode_all(plan: &Plan, bytes: &[u8], chunk: usize) -> Vec<Decoded> {
    let mut d = StreamDecoder::new(plan.clone());
    let mut out = Vec::new();
    for c in bytes.chunks(chunk.max(1)) {
        d.feed(c, |f| out.push(f.clone()));
    }
    out
}

proptest! {
    #![proptest_config(config(64))]

    /// encode → decode gives every quantity back to within half its field's LSB (integers:
    /// the encoder rounds once) or to single-float precision — increments in integer fields
    /// within one LSB a frame and half an LSB in their running sum (the encoder carries the
    /// remainder); the counter and status are the encoder's.
    #[test]
    fn round_trip_within_half_an_lsb(recs in prop::collection::vec(record(), 1..8)) {
        for plan in plans() {
            let mut st = EncoderState::default();
            let mut bytes = Vec::new();
            for r in &recs {
                plan.encode(r, 25.0, &mut st, &mut bytes);
            }
            let got = decode_all(&plan, &bytes, 4096);
            prop_assert_eq!(got.len(), recs.len(), "{}", plan.name);
            let mut sums = [Vec3::default(); 2];
            let mut running = Vec::new();
            for (k, (d, r)) in got.iter().zip(&recs).enumerate() {
                prop_assert!(!d.flagged, "{}: status flagged", plan.name);
                // An accumulating message carries Δθ, ΔV summed since it was last sent.
                sums = [sums[0] + r.dtheta, sums[1] + r.dv];
                let [dtheta, dv] = if plan.accumulates(d.message) {
                    std::mem::take(&mut sums)
                } else {
                    [r.dtheta, r.dv]
                };
                for (s, v) in &d.values {
                    let want = match *s {
                        Source::Gyro(i) => r.gyro[i],
                        Source::Accel(i) => r.accel[i],
                        Source::DTheta(i) => dtheta[i],
                        Source::Dv(i) => dv[i],
                        Source::Temperature => 25.0,
                        // No magnetometer is simulated (KVH Format C).
                        Source::Mag(_) => 0.0,
                        Source::Counter => {
                            let (modulo, step) = plan.counter().unwrap();
                            prop_assert_eq!(*v as u64, (k as u64 * step) % modulo);
                            continue;
                        }
                        _ => continue,
                    };
                    let tol = plan.quantum(*s).map_or(6e-8 * want.abs() + 1e-30, |q| {
                        0.5 * q + 4.0 * f64::EPSILON * want.abs()
                    });
                    if !carry::sums_within_half_a_step(&mut running, &plan, (*s, k), *v, want) {
                        prop_assert!((v - want).abs() <= tol, "{} {:?}: {} vs {}", plan.name, s, v, want);
                    }
                }
            }
        }
    }

    /// Random bytes, fed in random-sized reads, never panic any decoder; neither does a single
    /// frame decode of them.
    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..3000), chunk in 1usize..200) {
        for plan in plans() {
            let _ = decode_all(&plan, &bytes, chunk);
            let _ = plan.decode(&bytes);
        }
    }
}

proptest! {
    #![proptest_config(config(48))]

    /// Blocks of six consecutive frames, each after random garbage: the decoder finds the
    /// frames again. Garbage can hide at most the first two frames of a block (a false frame
    /// start in the garbage that runs into the block, and the hunt after it); the last four
    /// always come out, in order and exact.
    #[test]
    fn resynchronises_after_garbage(
        garbage in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..120), 3),
        recs in prop::collection::vec(record(), 18),
        chunk in 1usize..300,
    ) {
        for plan in plans() {
            let mut st = EncoderState::default();
            let mut bytes = Vec::new();
            let mut want: Vec<Vec<u8>> = Vec::new();
            for (b, g) in garbage.iter().enumerate() {
                bytes.extend_from_slice(g);
                for r in &recs[6 * b..6 * b + 6] {
                    let start = bytes.len();
                    plan.encode(r, 25.0, &mut st, &mut bytes);
                    want.push(bytes[start..].to_vec());
                }
            }
            let got = decode_all(&plan, &bytes, chunk);
            let expected: Vec<Decoded> = want
                .iter()
                .map(|f| decode_all(&plan, f, 4096).remove(0))
                .collect();
            for b in 0..3 {
                let tail = &expected[6 * b + 2..6 * b + 6];
                let found = got.windows(4).any(|w| w == tail);
                prop_assert!(found, "{}: block {} not found after garbage", plan.name, b);
            }
        }
    }
}
