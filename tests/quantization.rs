//! The quantization stage (paper eq. 9–10) through `ErrorChain`, for both kinds of LSB: on the
//! increment (`Lsb::Increment`, e.g. "2e-6 rad": Δθ and Δv are multiples of q) and on the rate
//! (`Lsb::Rate`, e.g. "0.05 deg/s": ω and f are multiples of q, as the `mpu6000` and
//! `adis16405` templates output), in each mode (truncate, round, carry). Fixed seeds.
//!
//! The measured figures are printed (`cargo test --release --test quantization -- --nocapture`).

mod common;

use common::{BLOCK, model, record, stream};
use imu_emu::analysis::allan;
use imu_emu::errors::process::QuantMode;
use imu_emu::errors::{ErrorChain, ImuModel, template};
use imu_emu::record::Record;
use imu_emu::rng::NormalStream;
use imu_emu::units::{G0, Lsb};

const RATES: [f64; 2] = [100.0, 1000.0];
const MODES: [&str; 3] = ["truncate", "round", "carry"];

/// A gyro and accelerometer LSB: on the increment (rad, m/s) or on the rate (rad/s, m/s²).
#[derive(Clone, Copy, Debug)]
enum Kind {
    Increment,
    Rate,
}

/// A template quantizing gyro and accelerometer with steps `q` (SI) of `kind`, in `mode`.
fn quantized(kind: Kind, q: [f64; 2], mode: &str) -> ImuModel {
    let (gu, au) = match kind {
        Kind::Increment => ("rad", "m/s"),
        Kind::Rate => ("rad/s", "m/s^2"),
    };
    let m = model(&format!(
        "quantization_mode = \"{mode}\"\n[gyro]\nquantization = \"{:e} {gu}\"\n\
         [accel]\nquantization = \"{:e} {au}\"\n",
        q[0], q[1]
    ));
    for (t, q) in [(&m.gyro, q[0]), (&m.accel, q[1])] {
        let expect = match kind {
            Kind::Increment => Lsb::Increment(q),
            Kind::Rate => Lsb::Rate(q),
        };
        assert_eq!(t.quantization, Some(expect));
    }
    m
}

/// The six values the LSB applies to, of a record: Δθ, Δv for an increment LSB; ω, f for a
/// rate LSB.
fn quantity(r: &Record, lsb: Lsb) -> [f64; 6] {
    let (g, a) = match lsb {
        Lsb::Increment(_) => (r.dtheta, r.dv),
        Lsb::Rate(_) => (r.gyro, r.accel),
    };
    [g[0], g[1], g[2], a[0], a[1], a[2]]
}

/// The step of an LSB.
fn step(lsb: Option<Lsb>) -> f64 {
    match lsb.expect("quantized") {
        Lsb::Increment(q) | Lsb::Rate(q) => q,
    }
}

/// A varying input of both signs spanning many LSBs, with a Gaussian part that spreads every
/// value's fraction of an LSB.
fn varying(k: usize, rate: f64, noise: [f64; 6]) -> Record {
    let t = k as f64 / rate;
    record(
        k,
        rate,
        [
            0.0123 + 0.02 * (0.37 * t).sin() + noise[0],
            -0.007 + 0.011 * (1.3 * t).cos() + noise[1],
            3.3e-3 * (0.05 * t).sin() + 1.0e-4 * (37.0 * t).sin() + noise[2],
        ],
        [
            0.3 * (0.21 * t).sin() + noise[3],
            -0.17 + 0.05 * (3.1 * t).cos() + noise[4],
            -G0 + 0.7 * (0.9 * t).sin() + noise[5],
        ],
    )
}

/// True when x is an exact integer multiple of q as the quantizer forms it (n·q, n integral):
/// x/q rounds to n for |n| < 2⁵⁰ and n·q reproduces x bit for bit.
fn on_grid(x: f64, q: f64) -> bool {
    (x / q).round() * q == x
}

/// Every output is an exact integer multiple of the LSB in the quantity the LSB applies to —
/// the increment for `Lsb::Increment`, the rate for `Lsb::Rate` — and the other quantity
/// follows from it exactly (ω = Δθ/Δt, or Δθ = ωΔt); each output is within the mode's bound
/// of its input: truncation toward zero by less than one LSB, rounding by at most half an
/// LSB, carry by at most one LSB (the carried residual is at most half an LSB). A quantizer
/// that does nothing, or applies the step to the wrong quantity, fails the grid check on
/// almost every sample.
#[test]
fn outputs_are_multiples_of_the_lsb() {
    let n = 20_000;
    for rate in RATES {
        let dt = 1.0 / rate;
        for kind in [Kind::Increment, Kind::Rate] {
            // About 1e-5 rad and 1e-4 m/s per increment at 100 Hz, and the same rate steps
            // (1e-3 rad/s, 1e-2 m/s²) for a rate LSB: the input spans tens of steps.
            let q = match kind {
                Kind::Increment => [1e-5 * 100.0 * dt, 1e-4 * 100.0 * dt],
                Kind::Rate => [1e-3, 1e-2],
            };
            for mode in MODES {
                let m = quantized(kind, q, mode);
                let lsb = [m.gyro.quantization.unwrap(), m.accel.quantization.unwrap()];
                let mut s = NormalStream::new(3, "test/quant-grid");
                let inputs: Vec<Record> = (0..n)
                    .map(|k| {
                        varying(
                            k,
                            rate,
                            std::array::from_fn(|i| [1e-3, 1e-2][i / 3] * s.draw()),
                        )
                    })
                    .collect();
                let mut out = inputs.clone();
                ErrorChain::new(&m, rate, 1).apply(&mut out);
                let mut moved = 0usize;
                for (o, inp) in out.iter().zip(&inputs) {
                    for i in 0..6 {
                        let l = lsb[i / 3];
                        let qi = step(Some(l));
                        let (y, x) = (quantity(o, l)[i], quantity(inp, l)[i]);
                        assert!(
                            on_grid(y, qi),
                            "{kind:?} {mode} {rate} Hz axis {i}: {y:e} is not a multiple of {qi:e}"
                        );
                        let err = (y - x) / qi;
                        let ok = match mode {
                            "truncate" => y.abs() <= x.abs() && err.abs() < 1.0,
                            "round" => err.abs() <= 0.5 + 1e-9,
                            _ => err.abs() <= 1.0 + 1e-9,
                        };
                        assert!(ok, "{kind:?} {mode} {rate} Hz axis {i}: {x:e} → {y:e}");
                        moved += usize::from(y != x);
                    }
                    // The other quantity is derived from the quantized one with the same Δt.
                    match kind {
                        Kind::Increment => {
                            for i in 0..3 {
                                assert_eq!(o.gyro[i], o.dtheta[i] / dt);
                                assert_eq!(o.accel[i], o.dv[i] / dt);
                            }
                        }
                        Kind::Rate => {
                            assert_eq!(o.dtheta, o.gyro * dt);
                            assert_eq!(o.dv, o.accel * dt);
                        }
                    }
                }
                assert!(
                    moved > 6 * n * 9 / 10,
                    "{kind:?} {mode}: only {moved} moved"
                );
            }
        }
    }
}

/// The built-in templates with a rate LSB (`mpu6000`: 1/131 deg/s and 1/16384 g; `adis16405`:
/// 0.05 deg/s and 3.333 mg) output rates on their LSB grid after every other error term,
/// at 100 Hz and 1 kHz, for a moving input within range.
#[test]
fn rate_lsb_templates_output_on_the_grid() {
    for name in ["mpu6000", "adis16405"] {
        let m = template::load(name).expect("built-in template");
        let q = [&m.gyro, &m.accel].map(|t| match t.quantization {
            Some(Lsb::Rate(q)) => q,
            other => panic!("{name}: expected a rate LSB, got {other:?}"),
        });
        for rate in RATES {
            let n = 10_000;
            let mut s = NormalStream::new(4, "test/quant-template");
            let inputs: Vec<Record> = (0..n)
                .map(|k| {
                    varying(
                        k,
                        rate,
                        std::array::from_fn(|i| [0.05, 0.2][i / 3] * s.draw()),
                    )
                })
                .collect();
            let mut out = inputs.clone();
            ErrorChain::new(&m, rate, 7).apply(&mut out);
            for (k, o) in out.iter().enumerate() {
                for i in 0..3 {
                    assert!(
                        on_grid(o.gyro[i], q[0]) && on_grid(o.accel[i], q[1]),
                        "{name} {rate} Hz record {k} axis {i}: {:e} {:e}",
                        o.gyro[i],
                        o.accel[i]
                    );
                }
                assert_eq!(o.dtheta, o.gyro * (1.0 / rate));
            }
            // Not a constant output: the noise moves it across LSBs.
            let distinct = out.windows(2).filter(|w| w[0].gyro != w[1].gyro).count();
            assert!(distinct > n / 2, "{name}: {distinct} changes");
        }
    }
}

/// x·2^shift as an exact integer (panics if it is not one).
fn fixed(x: f64, shift: i32) -> i128 {
    let s = x * 2f64.powi(shift);
    assert!(
        s.fract() == 0.0 && s.abs() < 2f64.powi(120),
        "{x:e} not exact at 2^{shift}"
    );
    s as i128
}

/// Carry mode (the default): over a long run with a varying, non-integer input of both signs,
/// the running sum of the outputs never differs from the running sum of the inputs by more
/// than one LSB, in the quantity the LSB applies to (increments for an increment LSB, rates
/// for a rate LSB) — checked exactly, every sample, in fixed point (every value here is an
/// integer multiple of 2^−115 for the gyro and 2^−110 for the accelerometer). The construction
/// promises half an LSB; a few ε of arithmetic in the carry are allowed on top.
#[test]
fn carry_keeps_the_running_sum() {
    let rate = 1000.0;
    let n = 1_000_000;
    let input = |k: usize, rate: f64| varying(k, rate, [0.0; 6]);
    let shift = [115, 115, 115, 110, 110, 110];
    for (kind, q) in [
        (Kind::Increment, [1.907e-6, 6.1e-5]),
        (Kind::Rate, [0.05f64.to_radians(), 3.333e-3 * G0]),
    ] {
        let m = quantized(kind, q, "carry");
        let lsb = m.gyro.quantization.unwrap();
        let q_fixed: Vec<f64> = (0..6).map(|i| fixed(q[i / 3], shift[i]) as f64).collect();
        let mut drift = [0i128; 6];
        let mut worst = [0.0f64; 6];
        let mut chain = ErrorChain::new(&m, rate, 1);
        stream(&mut chain, rate, n, BLOCK, input, |k0, block| {
            for (j, r) in block.iter().enumerate() {
                // The chain quantizes rate·Δt for an increment LSB, the rate itself otherwise.
                let (ins, outs) = (quantity(&input(k0 + j, rate), lsb), quantity(r, lsb));
                for i in 0..6 {
                    drift[i] += fixed(outs[i], shift[i]) - fixed(ins[i], shift[i]);
                    worst[i] = worst[i].max((drift[i] as f64 / q_fixed[i]).abs());
                }
            }
        });
        eprintln!("carry {kind:?}: max |Σout − Σin| in LSB per axis {worst:.6?}");
        for (i, w) in worst.iter().enumerate() {
            assert!(*w <= 1.0, "{kind:?} axis {i}: drift {w} LSB");
            assert!(
                *w <= 0.5 + 1e-9,
                "{kind:?} axis {i}: drift {w} LSB exceeds half an LSB"
            );
            // The sum moved through many LSBs, so the bound is not met by doing nothing.
            assert!(*w > 0.1, "{kind:?} axis {i}: drift {w} LSB");
        }
    }
}

/// The quantization error of the carry mode is a white error on the integrated angle, uniform
/// over one increment step q (q itself for an increment LSB, q_rate·Δt for a rate LSB): its
/// ADEV (of output − input increments, divided by Δt) is σ(τ) = √3·Q/τ with Q = q/√12, i.e.
/// exactly q/(2τ). The input carries Gaussian noise of 3 LSB per sample so that the carried
/// residual is uniform and independent (its deviation from uniform is ~e^{−2π²·9}).
///
/// 100 000 samples at 100 Hz and 1 kHz; at every octave m ≤ n/4 the white-phase edf
/// (N+1)(N−2m)/(2(N−m)) is ≥ 33 000, so each point's 1σ is ≤ 0.39 % and the bound is 4σ
/// of that point (≤ 1.6 %).
#[test]
fn carry_adev() {
    // Steps of the increment.
    let q = [2e-6, 1e-4];
    let n = 100_000usize;
    for rate in RATES {
        let dt = 1.0 / rate;
        for (kind, q_lsb) in [(Kind::Increment, q), (Kind::Rate, [q[0] / dt, q[1] / dt])] {
            let m = quantized(kind, q_lsb, "carry");
            let noise: Vec<[f64; 6]> = {
                let mut s = NormalStream::new(7, &format!("test/quant-input/{rate}"));
                (0..n)
                    .map(|_| std::array::from_fn(|i| 3.0 * q[i / 3] / dt * s.draw()))
                    .collect()
            };
            let input = |k: usize, rate: f64| {
                let v = noise[k];
                record(
                    k,
                    rate,
                    [0.01 + v[0], -0.02 + v[1], v[2]],
                    [0.1 + v[3], 0.2 + v[4], -G0 + v[5]],
                )
            };
            let mut err: [Vec<f64>; 6] = Default::default();
            let mut chain = ErrorChain::new(&m, rate, 1);
            stream(&mut chain, rate, n, BLOCK, input, |k0, block| {
                for (j, r) in block.iter().enumerate() {
                    // On the increments: (Δθ_out − Δθ_in)/Δt, (Δv_out − Δv_in)/Δt.
                    let inp = input(k0 + j, rate);
                    let d = [r.dtheta - inp.dtheta, r.dv - inp.dv];
                    for (i, v) in err.iter_mut().enumerate() {
                        v.push(d[i / 3][i % 3] / dt);
                    }
                }
            });
            let big_n = (n + 1) as f64;
            let mut worst = 0.0f64;
            for (i, y) in err.iter().enumerate() {
                for p in allan::overlapping(y, dt).iter().filter(|p| p.m <= n / 4) {
                    let expect = 3f64.sqrt() * (q[i / 3] / 12f64.sqrt()) / p.tau;
                    let mf = p.m as f64;
                    let edf = (big_n + 1.0) * (big_n - 2.0 * mf) / (2.0 * (big_n - mf));
                    let tol = 4.0 / (2.0 * edf).sqrt();
                    let r = p.adev / expect;
                    worst = worst.max((r - 1.0).abs());
                    assert!(
                        (r - 1.0).abs() <= tol,
                        "{kind:?} {rate} Hz axis {i} τ {}: σ/(q/2τ) = {r} (tol {tol})",
                        p.tau
                    );
                }
            }
            eprintln!(
                "carry ADEV {kind:?} {rate} Hz: max |σ/(√3Q/τ) − 1| = {worst:.4} over 6 axes"
            );
        }
    }
}

/// The paper's truncation (integer part, toward zero) is biased: for x > 0,
/// out − x = −q·frac(x/q), so when frac(x/q) is uniform on [0, 1) the mean error is −q/2
/// (+q/2 for x < 0), while rounding is unbiased. Here x ~ N(±20q, (3q)²) per sample: by
/// Poisson summation the density of frac(x/q) departs from uniform by at most
/// 2Σ_k e^{−2π²k²·9} ≈ 1e-77, so the closed forms hold exactly. Checked in the quantity the
/// LSB applies to, for both kinds.
///
/// Scatter: the per-sample error is uniform over one LSB (σ = q/√12), so over n = 100 000
/// samples the mean is known to 4·q/√12/√n = 0.0037 q.
#[test]
fn truncation_bias_and_unbiased_rounding() {
    let rate = 100.0;
    let dt = 1.0 / rate;
    let n = 100_000usize;
    let tol = 4.0 / 12f64.sqrt() / (n as f64).sqrt();
    for (kind, q) in [(Kind::Increment, 1e-6), (Kind::Rate, 1e-4)] {
        // The value the LSB applies to: q per LSB; as a rate for the record.
        let per_lsb = match kind {
            Kind::Increment => q / dt,
            Kind::Rate => q,
        };
        let mut s = NormalStream::new(8, "test/quant-input");
        // +20 ± 3 LSB (gyro) and −20 ± 3 LSB (accel): always of one sign.
        let inputs: Vec<Record> = (0..n)
            .map(|k| {
                let g: [f64; 3] = std::array::from_fn(|_| (20.0 + 3.0 * s.draw()) * per_lsb);
                let a: [f64; 3] = std::array::from_fn(|_| -(20.0 + 3.0 * s.draw()) * per_lsb);
                record(k, rate, g, a)
            })
            .collect();
        for (mode, expect) in [("truncate", [-0.5, 0.5]), ("round", [0.0, 0.0])] {
            let m = quantized(kind, [q, q], mode);
            let lsb = m.gyro.quantization.unwrap();
            assert_eq!(
                m.quantization_mode,
                if mode == "truncate" {
                    QuantMode::Truncate
                } else {
                    QuantMode::Round
                }
            );
            let mut out = inputs.clone();
            ErrorChain::new(&m, rate, 1).apply(&mut out);
            for i in 0..6 {
                let mean = out
                    .iter()
                    .zip(&inputs)
                    .map(|(o, r)| (quantity(o, lsb)[i] - quantity(r, lsb)[i]) / q)
                    .sum::<f64>()
                    / n as f64;
                eprintln!("{kind:?} {mode} axis {i}: mean (out − in) = {mean:+.4} LSB");
                assert!(
                    (mean - expect[i / 3]).abs() <= tol,
                    "{kind:?} {mode} axis {i}: mean error {mean} LSB, expected {}",
                    expect[i / 3]
                );
            }
        }
    }
}
