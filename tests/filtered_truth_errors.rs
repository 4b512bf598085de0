//! The injected errors (`--truth-errors`) of a unit with an output filter: each stage kind's
//! internal-rate error through its own copy of the filter, plus the output quantization. The
//! filter is linear, so the columns add up to the output minus the filtered error-free signal
//! — which is the output of the same filter on an error-free unit.

use std::ops::ControlFlow;
use std::path::Path;
use std::process::Command;

use imu_emu::errors::template;
use imu_emu::errors::vibration::{Random, Sine, VibrationSpec};
use imu_emu::errors::{ImuModel, Sensor};
use imu_emu::sim::{SideOutputs, Simulation};

/// Every error term on both triads, an output LSB and range (quantization after the filter).
const FULL: &str =
    "order = [\"bias\", \"quantization\", \"misalignment\", \"scale_factor\", \"noise\"]
[gyro]
bias = \"20 deg/h\"
bias_instability = \"5 deg/h\"
bias_gm = { sigma = \"3 deg/h\", tau = \"2 s\" }
random_walk = \"100 deg/h/sqrt(h)\"
ramp = \"36 deg/h/h\"
scale_factor = \"500 ppm\"
misalignment = \"1 mrad\"
noise = \"0.5 deg/sqrt(h)\"
g_sensitivity = \"10 deg/h/g\"
quantization = \"1e-7 rad\"
[accel]
bias = \"2 mg\"
bias_instability = \"0.1 mg\"
random_walk = \"0.1 m/s/h/sqrt(h)\"
scale_factor = \"300 ppm\"
misalignment = \"1 mrad\"
noise = \"0.1 m/s/sqrt(h)\"
quantization = \"1e-6 m/s\"
range = \"10 g\"
";

/// The output filters tried: an FIR (CIC) and an IIR (Butterworth), internal rate 1600 Hz,
/// with the gain of their rounding (see [`components_sum_to_the_output_minus_the_filtered_truth`]).
const FILTERS: [(&str, f64); 2] = [
    ("kind = \"cic\"\norder = 2\ntaps = 8", 1.0),
    (
        "kind = \"butterworth\"\norder = 4\ncutoff = \"40 Hz\"",
        BUTTERWORTH_GAIN,
    ),
];

/// A rounding error δ left in a state of a second-order section 1/A(z) reaches the output with
/// DC gain 1/A(1); for the bilinear Butterworth biquad (`src/errors/output_filter.rs`)
/// A(1) = 4k²/(1 + k/Q + k²) with k = tan(π f_c/f_s) and 1/Q ≤ 2, so 1/A(1) ≤ (1 + k)²/(4k²):
/// ≈ 47 for 40 Hz at 1600 Hz, summed over the two sections of order 4.
const BUTTERWORTH_GAIN: f64 = {
    let k = 0.078_701_706_824_618_44; // tan(π·40/1600)
    2.0 * (1.0 + k) * (1.0 + k) / (4.0 * k * k)
};

const RATE: f64 = 200.0;

fn model(body: &str) -> ImuModel {
    template::parse(&format!("name = \"f\"\n{body}\n"), Path::new("f.toml")).unwrap()
}

fn filter(f: &str) -> String {
    format!("[output_filter]\ninternal_rate_hz = 1600\n{f}\n")
}

/// A sine above the output Nyquist frequency on the gyro and a random vibration on the
/// accelerometer, both generated at the internal rate.
fn vibration() -> VibrationSpec {
    VibrationSpec {
        sines: vec![Sine {
            sensor: Sensor::Gyro,
            axis: 0,
            amplitude: 0.01,
            freq_hz: 170.0,
            phase_rad: 0.3,
        }],
        randoms: vec![Random {
            sensor: Sensor::Accel,
            axis: 2,
            psd: vec![(20.0, 1e-3), (300.0, 1e-3)],
        }],
    }
}

/// A CSV file: its header and its rows of numbers.
type Csv = (Vec<String>, Vec<Vec<f64>>);

fn rows(text: &[u8]) -> Csv {
    let text = std::str::from_utf8(text).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (header, rows)
}

/// The output records and the injected-errors file of a 4 s circle run (the lever arm and the
/// vibration optional).
fn run(m: ImuModel, arm: bool, vib: bool) -> (Vec<Vec<f64>>, Csv) {
    let mut b = Simulation::builder()
        .scene("circle")
        .imu_model(m)
        .rate(RATE)
        .duration(4.0)
        .seed(7);
    if arm {
        b = b.lever_arm_m([0.3, -0.2, 0.1]);
    }
    if vib {
        b = b.vibration(vibration());
    }
    let (mut out, mut inj) = (Vec::new(), Vec::new());
    let side = SideOutputs {
        truth: None,
        injected: Some(&mut inj),
    };
    b.build()
        .unwrap()
        .write_with(&mut out, side, |_| ControlFlow::Continue(()))
        .unwrap();
    (rows(&out).1, rows(&inj))
}

/// Σ components == output − output of the error-free filtered unit, per record and channel,
/// with every error term, a lever arm and vibration, for an FIR and an IIR filter. Rounding:
/// the two sides differ by the filter's and the chain's rounding of the individual terms; the
/// filter carries its inputs' rounding over its memory (an IIR's for ever, decaying), and the
/// stages mix a triad's axes (misalignment), so the scale is the largest triad magnitude seen
/// in the run, |truth| + Σ|group| summed over the three axes (≈ 10 m/s² for the
/// accelerometer); an IIR filter also amplifies the rounding left in its states by its
/// rounding gain ([`BUTTERWORTH_GAIN`], ≈ 94). 16 ε of the scale times that gain bounds the
/// difference (the worst seen is printed: 2.3 ε·scale for the CIC, 53 for the Butterworth). Dropping the
/// components' filter (the internal error of the emitting sample instead), their priming, or
/// the output quantization's share breaks the sum by far more: the gyro noise alone is
/// ~6e-3 rad/s per internal sample, its LSB 2e-5 rad/s at 200 Hz.
#[test]
fn components_sum_to_the_output_minus_the_filtered_truth() {
    for (f, gain) in FILTERS {
        let (out, (header, comps)) = run(model(&format!("{FULL}{}", filter(f))), true, true);
        let (clean, (_, zero)) = run(model(&filter(f)), false, false);
        assert_eq!(header.len(), 43);
        assert_eq!(out.len(), 800);
        assert_eq!((comps.len(), clean.len()), (800, 800));
        assert!(zero.iter().all(|r| r[1..].iter().all(|v| *v == 0.0)));
        let magnitude = |c: &[f64], e: &[f64], ch: usize| {
            c[1 + ch].abs() + (0..7).map(|g| e[1 + g * 6 + ch].abs()).sum::<f64>()
        };
        let mut scale = [0.0_f64; 2];
        for (c, e) in clean.iter().zip(&comps) {
            for (s, sc) in scale.iter_mut().enumerate() {
                *sc = sc.max((0..3).map(|a| magnitude(c, e, 3 * s + a)).sum());
            }
        }
        let mut worst: f64 = 0.0;
        for ((o, c), e) in out.iter().zip(&clean).zip(&comps) {
            assert_eq!(o[0], e[0]);
            for ch in 0..6 {
                let sum: f64 = (0..7).map(|g| e[1 + g * 6 + ch]).sum();
                let diff = (o[1 + ch] - c[1 + ch] - sum).abs();
                let tol = f64::EPSILON * scale[ch / 3];
                worst = worst.max(diff / tol);
                assert!(
                    diff <= 16.0 * gain * tol,
                    "{f}: t {} channel {ch}: {} vs {sum}",
                    o[0],
                    o[1 + ch] - c[1 + ch]
                );
            }
        }
        eprintln!(
            "{f}: worst |output − filtered truth − Σ| = {worst:.2} ε·scale (scales {scale:?})"
        );
        // Every group that has a stage carries something on some channel.
        for g in 0..7 {
            let any = comps
                .iter()
                .any(|r| r[1 + g * 6..7 + g * 6].iter().any(|v| *v != 0.0));
            assert!(any, "{f}: group {} all zero", header[1 + g * 6]);
        }
    }
}

/// A stage switched off (no vibration, no lever arm) gives its columns exactly zero, while
/// the others still carry the run's errors; a model without quantization gives a zero
/// quantization group.
#[test]
fn a_stage_switched_off_gives_zero_columns() {
    let (_, (header, comps)) = run(
        model(&format!("{FULL}{}", filter(FILTERS[1].0))),
        false,
        false,
    );
    let zero = |g: usize| {
        comps
            .iter()
            .all(|r| r[1 + g * 6..7 + g * 6].iter().all(|v| *v == 0.0))
    };
    assert_eq!(header[1], "vibration_gyro_x");
    assert_eq!(header[7], "size_effect_gyro_x");
    assert!(zero(0) && zero(1));
    assert!((2..7).all(|g| !zero(g)));
    let no_lsb = FULL.replace("quantization = ", "# quantization = ");
    let (_, (header, comps)) = run(
        model(&format!("{no_lsb}{}", filter(FILTERS[0].0))),
        false,
        false,
    );
    let q = header
        .iter()
        .position(|h| h == "quantization_gyro_x")
        .unwrap();
    assert!(comps.iter().all(|r| r[q..q + 6].iter().all(|v| *v == 0.0)));
}

/// `imu-emu generate --truth-errors` on the example filtered template writes the file, and
/// `plot-errors` draws it.
#[test]
fn generate_writes_and_plot_errors_draws_a_filtered_run() {
    let dir = tempfile::tempdir().unwrap();
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/filtered.toml");
    let exe = env!("CARGO_BIN_EXE_imu-emu");
    let e = dir.path().join("e.csv");
    let png = dir.path().join("e.png");
    let out = Command::new(exe)
        .args(["generate", "--scene", "static", "--duration", "5", "--imu"])
        .arg(&example)
        .args(["-o", "/dev/null", "--truth-errors"])
        .arg(&e)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (header, comps) = rows(&std::fs::read(&e).unwrap());
    assert_eq!(header.len(), 43);
    assert_eq!(comps.len(), 1024);
    let out = Command::new(exe)
        .args(["plot-errors"])
        .arg(&e)
        .arg("-o")
        .arg(&png)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
}
