//! Output filters through the product (`generate`, the library's `Simulation`, the records
//! producer of `validate` and `compare`): the motion evaluated at the internal rate and
//! filtered equals the filter applied to an unfiltered run at the internal rate; a constant
//! signal passes unchanged; a ramp is valid at its stated time of validity; the truth and the
//! frames carry that time; white noise and a tone above the output Nyquist frequency come out
//! of `imu-emu generate` as the filter's response says.

use std::f64::consts::PI;
use std::ops::ControlFlow;
use std::path::Path;
use std::process::Command;

use imu_emu::analysis::psd::Welch;
use imu_emu::errors::filtered::FilteredChain;
use imu_emu::errors::output_filter::{Filter, FilterSpec};
use imu_emu::errors::template;
use imu_emu::record::Record;
use imu_emu::sim::{SideOutputs, Simulation};
use imu_emu::timing::ReadRatio;

const FS: f64 = 1600.0;
const RATE: f64 = 200.0;

/// The filters of these tests, as `[output_filter]` lines (internal rate 1600 Hz).
const FILTERS: [&str; 5] = [
    "kind = \"moving_average\"\ntaps = 8",
    "kind = \"cic\"\norder = 3\ntaps = 8",
    "kind = \"fir\"\ncoefficients = [1, 4, 6, 4, 1, 0.5]",
    "kind = \"butterworth\"\norder = 4\ncutoff = \"40 Hz\"",
    "kind = \"butterworth\"\norder = 3\ncutoff = \"150 Hz\"",
];

fn model(body: &str) -> imu_emu::errors::ImuModel {
    template::parse(&format!("name = \"f\"\n{body}\n"), Path::new("f.toml")).unwrap()
}

fn filtered(filter: &str) -> imu_emu::errors::ImuModel {
    model(&format!(
        "[output_filter]\ninternal_rate_hz = 1600\n{filter}"
    ))
}

/// Every record of an error-free run of `scene` at `rate` for `seconds` with `m`.
fn records(scene: &str, m: imu_emu::errors::ImuModel, rate: f64, seconds: f64) -> Vec<Record> {
    Simulation::builder()
        .scene(scene)
        .imu_model(m)
        .rate(rate)
        .duration(seconds)
        .build()
        .unwrap()
        .records()
        .unwrap()
        .flat_map(|b| b.unwrap())
        .collect()
}

fn six(r: &Record) -> [f64; 6] {
    [
        r.gyro[0], r.gyro[1], r.gyro[2], r.accel[0], r.accel[1], r.accel[2],
    ]
}

/// A constant signal (the static scene: Earth rate and gravity) passes every unit-DC-gain
/// filter unchanged from the first record on (the filter starts in its steady state, as a
/// unit's has run since power-on), to 1e-13 relative: the records equal the unfiltered run's,
/// time tags bit for bit. Without the start-up priming the first records would be far off
/// (a zero-state FIR of 8 taps gives 1/8 of gravity first).
#[test]
fn a_constant_signal_passes_unchanged() {
    let plain = records("static", model(""), RATE, 2.0);
    for f in FILTERS {
        let out = records("static", filtered(f), RATE, 2.0);
        assert_eq!(out.len(), plain.len());
        for (a, b) in out.iter().zip(&plain) {
            assert_eq!(a.t, b.t);
            for (x, y) in a.values().iter().zip(b.values()) {
                assert!(
                    (x - y).abs() <= 1e-13 * y.abs().max(1e-3),
                    "{f}: {x} vs {y}"
                );
            }
        }
    }
}

/// `spec` run by hand over the `internal` records from its steady state, decimated by 8, with
/// the largest value it puts out.
fn by_hand(spec: &FilterSpec, internal: &[Record]) -> (Vec<[f64; 6]>, f64) {
    let mut filter = Filter::new(spec, ReadRatio::integer(8));
    filter.prime(six(&internal[0]));
    let want: Vec<[f64; 6]> = internal
        .iter()
        .filter_map(|r| filter.push(six(r)))
        .collect();
    let scale = want.iter().flatten().fold(0.0_f64, |a, x| a.max(x.abs()));
    (want, scale)
}

/// The filtered error-free output of a moving scene (`coning`, `circle`) equals the filter,
/// started at the first internal record, run over an unfiltered error-free run at the internal
/// rate (the same generator) and decimated by 8 — to 1e-12 of the signal's scale: the product
/// evaluates the motion over the internal intervals and keeps the last internal sample of each
/// output interval. Off by one internal sample, the coning scene's 8 Hz-class motion would
/// differ by far more.
#[test]
fn the_output_is_the_filter_of_the_internal_run() {
    for scene in ["coning", "circle"] {
        let internal = records(scene, model(""), FS, 4.0);
        for f in FILTERS {
            let m = filtered(f);
            let spec = m.output_filter.clone().unwrap();
            let out = records(scene, m, RATE, 4.0);
            let (want, scale) = by_hand(&spec, &internal);
            assert_eq!(out.len(), want.len());
            for (k, (r, w)) in out.iter().zip(&want).enumerate() {
                assert_eq!(r.t, (k + 1) as f64 / RATE);
                for (x, y) in six(r).iter().zip(w) {
                    assert!(
                        (x - y).abs() <= 1e-12 * scale,
                        "{scene} {f} k {k}: {x} vs {y}"
                    );
                }
                assert!((r.dtheta[0] - r.gyro[0] / RATE).abs() <= 1e-15 * scale);
            }
        }
    }
}

/// With `[output_filter.accel]` each sensor's channels are their own filter of the internal
/// run: the gyros' through the top-level kind alone, the accelerometers' through theirs alone,
/// each checked against a single-kind filter by hand to 1e-12 of the scale. Running the
/// accelerometers through the gyros' filter (the table ignored) fails it on every pair of
/// different kinds below.
#[test]
fn each_sensor_is_its_own_filter_of_the_internal_run() {
    let internal = records("coning", model(""), FS, 4.0);
    for (g, a) in [(FILTERS[3], FILTERS[0]), (FILTERS[0], FILTERS[1])] {
        let m = filtered(&format!(
            "{g}
[output_filter.accel]
{a}"
        ));
        let spec = m.output_filter.clone().unwrap();
        assert!(spec.accel.is_some());
        let out = records("coning", m, RATE, 4.0);
        for (sensor, chans) in [(false, 0..3), (true, 3..6)] {
            let (want, scale) = by_hand(&spec.sensor(sensor), &internal);
            assert_eq!(out.len(), want.len());
            for (k, (r, w)) in out.iter().zip(&want).enumerate() {
                for i in chans.clone() {
                    let (x, y) = (six(r)[i], w[i]);
                    assert!(
                        (x - y).abs() <= 1e-12 * scale,
                        "{g} / {a}: channel {i}, k {k}: {x} vs {y}"
                    );
                }
            }
        }
    }
}

/// `n` internal records at `fs` of the ramp ω = a + b·t, each its exact interval mean
/// a + b(t_j − Δt_in/2), on gyro x and (negated) accel z.
fn ramp(a: f64, b: f64, fs: f64, n: u32) -> Vec<Record> {
    (1..=n)
        .map(|j| {
            let t = j as f64 / fs;
            let w = a + b * (t - 0.5 / fs);
            let mut r = Record {
                t,
                ..Default::default()
            };
            r.gyro[0] = w;
            r.accel[2] = -w;
            r
        })
        .collect()
}

/// A ramp ω = a + b·t through the filtered chain, its internal records the exact interval
/// means a + b(t_j − Δt_in/2): after the transient each output equals the ramp's mean over
/// the output interval ending at t_k − L, L = `validity_offset_s` (g + Δt_in/2 − Δt_out/2),
/// to 1e-9 relative — the time the truth file gives as the record's time of validity. For a
/// moving average of exactly D = 8 taps (a unit that sums its internal samples) L is 0.
#[test]
fn a_ramp_is_valid_at_the_offset_time() {
    let (a, b) = (0.3, 0.05);
    for f in FILTERS {
        let m = filtered(f);
        let spec = m.output_filter.clone().unwrap();
        let offset = spec.validity_offset_s(RATE);
        let mut chain = FilteredChain::new(&m, RATE, 1).unwrap();
        let input = ramp(a, b, FS, 80_000);
        let mut out = Vec::new();
        chain.apply(&input, &mut out);
        for r in &out[5000..] {
            let want = a + b * (r.t - offset - 0.5 / RATE);
            assert!(
                (r.gyro[0] - want).abs() < 1e-9 * want,
                "{f}: {} vs {want}",
                r.gyro[0]
            );
            assert!((r.accel[2] + want).abs() < 1e-9 * want);
        }
    }
    let ma = filtered(FILTERS[0]).output_filter.unwrap();
    assert!(ma.validity_offset_s(RATE).abs() < 1e-15);
    // Butterworth 4th order at 40 Hz: its DC group delay plus ½(1/1600 − 1/200) s.
    let bw = filtered(FILTERS[3]).output_filter.unwrap();
    let want = bw.latency_s() + 0.5 / FS - 0.5 / RATE;
    assert!((bw.validity_offset_s(RATE) - want).abs() < 1e-15);
}

/// The truth of a filtered run has the time columns: `tov` = `tov_accel` = t − L and, with no
/// `[timing]`, `emit` = t (the frame leaves at the end of its interval); with a template
/// latency of 400 µs, `emit` = t + 400 µs, so emit − tov = latency + L. The records producer
/// `run` paces by gives the same times.
#[test]
fn the_truth_and_the_frames_carry_the_filter_delay() {
    let bw = FILTERS[3];
    // The third case gives the accelerometers a moving average of 8 taps (no offset: it sums
    // its output interval exactly), so `tov_accel` leads `tov` by the Butterworth's offset.
    let own = format!("\n[output_filter.accel]\n{}", FILTERS[0]);
    for (timing, latency, accel) in [
        ("", 0.0, ""),
        ("[timing]\nlatency = \"400 us\"\n", 400e-6, ""),
        ("", 0.0, own.as_str()),
    ] {
        let m = model(&format!(
            "{timing}[output_filter]\ninternal_rate_hz = 1600\n{bw}{accel}"
        ));
        let spec = m.output_filter.as_ref().unwrap();
        let offset = spec.validity_offset_s(RATE);
        let offset_accel = spec.sensor(true).validity_offset_s(RATE);
        assert_eq!(accel.is_empty(), offset_accel == offset);
        let sim = || {
            Simulation::builder()
                .scene("circle")
                .imu_model(m.clone())
                .rate(RATE)
                .duration(1.0)
                .format("kvh1750")
                .build()
                .unwrap()
        };
        let (mut frames, mut truth) = (Vec::new(), Vec::new());
        let side = SideOutputs {
            truth: Some(&mut truth),
            injected: None,
        };
        sim()
            .write_with(&mut frames, side, |_| ControlFlow::Continue(()))
            .unwrap();
        let text = String::from_utf8(truth).unwrap();
        let mut lines = text.lines();
        assert!(lines.next().unwrap().ends_with(",tov,tov_accel,emit"));
        let mut n = 0;
        for l in lines {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            let t = v[0];
            assert!((v[13] - (t - offset)).abs() < 1e-12, "{l}");
            assert!((v[14] - (t - offset_accel)).abs() < 1e-12, "{l}");
            assert!((v[15] - (t + latency)).abs() < 1e-12, "{l}");
            n += 1;
        }
        assert_eq!(n, 200);
        let mut p = sim().producer().unwrap();
        let b = p.next_records(50).unwrap();
        let times = b.times.expect("a filtered run is timed");
        for (i, r) in b.records.iter().enumerate() {
            let emit = times.t0 + times.emit[i];
            let tov = times.t0 + times.tov[i];
            assert!((emit - tov - latency - offset).abs() < 1e-12);
            assert!((emit - r.t - latency).abs() < 1e-12);
        }
    }
}

/// The polled read tests' unit: a Bartlett window of 2 × 16 taps (the ADIS164xx data sheets'
/// filter) or a 4th-order Butterworth at 819.2 Hz, read by a host at 100 Hz.
const POLLED_FILTERS: [&str; 2] = [
    "kind = \"cic\"\norder = 2\ntaps = 16",
    "kind = \"butterworth\"\norder = 4\ncutoff = \"50 Hz\"",
];

fn polled(filter: &str) -> imu_emu::errors::ImuModel {
    model(&format!(
        "[output_filter]\ninternal_rate_hz = 819.2\n{filter}"
    ))
}

/// A host polling at 100 Hz a unit that filters at 819.2 Hz reads the newest complete internal
/// sample: output k is the filter's value at internal sample n_k = ⌊k·8.192⌋ (8 or 9 apart),
/// to 1e-12 of the signal's scale, against the filter run by hand over every sample of an
/// unfiltered run at 819.2 Hz; time tags k/100 s. Reading ⌈k·8.192⌉ or the sample before
/// (off by one internal sample) moves the coning scene's records by far more.
#[test]
fn a_polled_read_takes_the_newest_internal_sample() {
    let read = ReadRatio::from_rates(819.2, 100.0).unwrap();
    for scene in ["coning", "circle"] {
        let internal = records(scene, model(""), 819.2, 4.0);
        for f in POLLED_FILTERS {
            let m = polled(f);
            let spec = m.output_filter.clone().unwrap();
            let out = records(scene, m, 100.0, 4.0);
            assert_eq!(out.len(), 400);
            let mut filter = Filter::new(&spec, ReadRatio::integer(1));
            filter.prime(six(&internal[0]));
            let every: Vec<[f64; 6]> = internal
                .iter()
                .filter_map(|r| filter.push(six(r)))
                .collect();
            let scale = every.iter().flatten().fold(0.0_f64, |a, x| a.max(x.abs()));
            for (i, r) in out.iter().enumerate() {
                let k = i as u64 + 1;
                assert_eq!(r.t, k as f64 / 100.0);
                let want = every[read.index(k) as usize - 1];
                for (x, y) in six(r).iter().zip(want) {
                    assert!(
                        (x - y).abs() <= 1e-12 * scale,
                        "{scene} {f} k {k}: {x} vs {y}"
                    );
                }
            }
        }
    }
}

/// Under a polled read each record is valid at its own time: a ramp's output k equals the
/// ramp's mean over the 10 ms ending L before internal sample n_k's end (L =
/// `validity_offset_s`, the filter's delay less ½(Δt_out − Δt_in)), to 1e-9 relative; that
/// time moves by up to one internal interval (1.22 ms) from record to record, so a constant
/// offset from the time tag misses by up to b·1.22 ms. The truth file's `tov` column is
/// n_k/819.2 − L to 1e-12 s.
#[test]
fn a_polled_record_is_valid_at_its_own_time() {
    let (a, b) = (0.3, 0.05);
    let fs = 819.2;
    let read = ReadRatio::from_rates(fs, 100.0).unwrap();
    for f in POLLED_FILTERS {
        let m = polled(f);
        let offset = m.output_filter.as_ref().unwrap().validity_offset_s(100.0);
        let mut chain = FilteredChain::new(&m, 100.0, 1).unwrap();
        let input = ramp(a, b, fs, 40_960);
        let mut out = Vec::new();
        chain.apply(&input, &mut out);
        assert_eq!(out.len(), 5000);
        let mut worst_constant: f64 = 0.0;
        for (i, r) in out.iter().enumerate().skip(1000) {
            let tov = read.index(i as u64 + 1) as f64 / fs - offset;
            let want = a + b * (tov - 0.5 / 100.0);
            assert!(
                (r.gyro[0] - want).abs() < 1e-9 * want,
                "{f}: {} vs {want}",
                r.gyro[0]
            );
            assert!((r.accel[2] + want).abs() < 1e-9 * want);
            let tag = (i + 1) as f64 / 100.0;
            worst_constant =
                worst_constant.max((r.gyro[0] - (a + b * (tag - offset - 0.005))).abs());
        }
        assert!(worst_constant > 0.9 * b / fs, "{worst_constant}");
        let sim = Simulation::builder()
            .scene("circle")
            .imu_model(m)
            .rate(100.0)
            .duration(2.0)
            .build()
            .unwrap();
        let mut truth = Vec::new();
        let side = SideOutputs {
            truth: Some(&mut truth),
            injected: None,
        };
        sim.write_with(&mut Vec::new(), side, |_| ControlFlow::Continue(()))
            .unwrap();
        let text = String::from_utf8(truth).unwrap();
        let rows: Vec<Vec<f64>> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 200);
        for (i, v) in rows.iter().enumerate() {
            let k = i as u64 + 1;
            let tov = read.index(k) as f64 / fs - offset;
            assert!((v[13] - tov).abs() < 1e-12, "{k}: {} vs {tov}", v[13]);
            assert!((v[15] - k as f64 / 100.0).abs() < 1e-12);
        }
    }
}

/// What a filtered run cannot do is refused with a message naming it: a jitter above 1/20 of
/// the internal sample interval (its sampler ticks at the internal rate, though 50 µs is
/// within 1/20 of the output's 5 ms; sampling-clock errors with a filter work:
/// tests/filtered_timing.rs), an output rate above the internal rate. (Its injected errors are
/// written: `tests/filtered_truth_errors.rs`.) An output rate the internal rate is no multiple
/// of is a host's polled read (above).
#[test]
fn filtered_runs_refuse_what_they_cannot_do() {
    let bw = FILTERS[3];
    let build = |body: &str, rate: f64| {
        Simulation::builder()
            .scene("static")
            .imu_model(model(body))
            .rate(rate)
            .duration(1.0)
            .build()
    };
    let body = format!("[output_filter]\ninternal_rate_hz = 1600\n{bw}");
    let e = build(&format!("[timing]\njitter = \"50 us\"\n{body}"), RATE)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("`f`") && e.contains("internal sample interval"),
        "{e}"
    );
    assert!(build("[timing]\njitter = \"50 us\"", RATE).is_ok());
    let e = build(&body, 3200.0).err().unwrap().to_string();
    assert!(
        e.contains("`f`") && e.contains("below the output rate"),
        "{e}"
    );
    assert!(build(&body, 300.0).is_ok());
}

/// Runs `imu-emu` with `args` in `dir`; panics with its stderr on failure.
fn imu_emu(dir: &Path, args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The 104-byte binary records of `path` as (t, gyro, accel) rows.
fn read_bin(path: &Path) -> Vec<[f64; 7]> {
    let bytes = std::fs::read(path).unwrap();
    bytes
        .chunks_exact(104)
        .map(|c| {
            std::array::from_fn(|i| f64::from_le_bytes(c[8 * i..8 * i + 8].try_into().unwrap()))
        })
        .collect()
}

/// `imu-emu generate` of a noisy filtered template (white gyro and accelerometer noise at the
/// internal rate, 4th-order Butterworth at 40 Hz, 1600 → 200 Hz, 2000 s): the output PSD over
/// the input density 2N² (one-sided) equals |H(f)|² within 0.5 dB up to 0.8 of the cut-off.
/// Scatter (as in tests/output_filter.rs): 4·10⁵ samples in Welch segments of 256 at 50 %
/// overlap, pooled over three axes, leave a bin's 1σ at ≈ 1.1 % (0.05 dB); aliasing adds −50 dB
/// at 0.8·f_c. Unfiltered (the noise decimated) the ratio would be 8 (+9 dB).
#[test]
fn generate_filters_the_noise() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("noisy.toml"),
        format!(
            "name = \"noisy\"\n[gyro]\nnoise = \"0.5 deg/sqrt(h)\"\n[accel]\nnoise = \"0.1 m/s/sqrt(h)\"\n\
             [output_filter]\ninternal_rate_hz = 1600\n{}\n",
            FILTERS[3]
        ),
    )
    .unwrap();
    imu_emu(
        dir.path(),
        &[
            "generate",
            "--scene",
            "static",
            "--imu",
            "noisy.toml",
            "--rate",
            "200",
            "--duration",
            "2000",
            "--format",
            "bin",
            "-o",
            "noisy.bin",
        ],
    );
    let rows = read_bin(&dir.path().join("noisy.bin"));
    assert_eq!(rows.len(), 400_000);
    let m = template::load(dir.path().join("noisy.toml").to_str().unwrap()).unwrap();
    let s = m.output_filter.clone().unwrap();
    for (sensor, cols, n) in [
        ("gyro", 1..4, m.gyro.noise[0]),
        ("accel", 4..7, m.accel.noise[0]),
    ] {
        let psds: Vec<_> = cols
            .map(|c| {
                let mut w = Welch::new(256);
                rows.iter().for_each(|r| w.push(r[c]));
                w.finish(1.0 / RATE)
            })
            .collect();
        let mut worst: f64 = 0.0;
        for (k, &f) in psds[0].freq.iter().enumerate() {
            // Bins 0 and 1 are the Welch estimator's own mean removal (see output_filter.rs).
            if k < 2 || f > 0.8 * 40.0 {
                continue;
            }
            let mean = psds.iter().map(|p| p.density[k]).sum::<f64>() / 3.0;
            let db = 10.0 * (mean / (2.0 * n * n) / s.magnitude(f).powi(2)).log10();
            worst = worst.max(db.abs());
            assert!(db.abs() < 0.5, "{sensor} f {f}: {db} dB");
        }
        eprintln!("generate, {sensor}: worst |PSD ratio / |H|²| = {worst:.3} dB");
    }
}

/// `imu-emu generate` with a 0.3 deg/s gyro-x vibration tone at 170 Hz, above the 100 Hz output
/// Nyquist frequency: it comes out at its 30 Hz alias with amplitude A·sinc(π·170/1600)·|H(170)|
/// (the internal records' interval mean, then the filter) — 0.17·A through an 8-tap average,
/// equal to an unfiltered 200 Hz unit's A·sinc(π·170/200) (an 8-tap average of 8 internal
/// samples is the output interval's mean), and ≈ 6·10⁻⁶·A through an 8th-order 40 Hz
/// Butterworth. Deterministic: to 1e-9·A, projected on 900 whole periods after the transient.
#[test]
fn generate_aliases_or_removes_a_tone_above_nyquist() {
    let a = 0.3_f64.to_radians();
    let sinc = |x: f64| x.sin() / x;
    for (filter, name) in [
        (FILTERS[0].to_string(), "average"),
        (
            "kind = \"butterworth\"\norder = 8\ncutoff = \"40 Hz\"".to_string(),
            "butterworth",
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("unit.toml"),
            format!("name = \"unit\"\n[output_filter]\ninternal_rate_hz = 1600\n{filter}\n"),
        )
        .unwrap();
        std::fs::write(
            dir.path().join("scene.toml"),
            "[trajectory]\nscene = \"static\"\n[imu]\nmodel = \"unit.toml\"\nrate_hz = 200.0\n\
             [[vibration.sine]]\nsensor = \"gyro\"\naxis = \"x\"\namplitude = \"0.3 deg/s\"\nfrequency = \"170 Hz\"\n",
        )
        .unwrap();
        imu_emu(
            dir.path(),
            &[
                "generate",
                "scene.toml",
                "--duration",
                "40",
                "--format",
                "bin",
                "-o",
                "tone.bin",
            ],
        );
        let rows = read_bin(&dir.path().join("tone.bin"));
        assert_eq!(rows.len(), 8000);
        let tail = &rows[2000..];
        let (mut re, mut im) = (0.0, 0.0);
        for r in tail {
            let w = 2.0 * PI * 30.0 * r[0];
            re += r[1] * w.cos();
            im += r[1] * w.sin();
        }
        let amp = 2.0 * (re * re + im * im).sqrt() / tail.len() as f64;
        let spec = template::load(dir.path().join("unit.toml").to_str().unwrap())
            .unwrap()
            .output_filter
            .unwrap();
        let want = a * sinc(PI * 170.0 / FS) * spec.magnitude(170.0);
        eprintln!("{name}: alias amplitude {amp:.4e} rad/s, theory {want:.4e}");
        assert!((amp - want).abs() < 1e-9 * a, "{name}: {amp} vs {want}");
        if name == "average" {
            assert!((want - a * sinc(PI * 170.0 / RATE)).abs() < 1e-12 * a);
        }
    }
}

/// The records producer of `validate` and `compare` (`Producer::for_model`) gives a noisy
/// filtered template the same records as `generate`'s `Simulation`, bit for bit (same motion,
/// internal rate, chain seed and filter), and refuses an output rate above the internal
/// rate.
#[test]
fn validate_and_compare_produce_what_generate_does() {
    let m = model(&format!(
        "[gyro]\nnoise = \"0.5 deg/sqrt(h)\"\nbias_instability = \"3 deg/h\"\n[accel]\nnoise = \"0.1 m/s/sqrt(h)\"\n\
         [output_filter]\ninternal_rate_hz = 1600\n{}",
        FILTERS[3]
    ));
    let sim = Simulation::builder()
        .scene("circle")
        .imu_model(m.clone())
        .rate(RATE)
        .duration(5.0)
        .seed(7)
        .build()
        .unwrap();
    let grid = sim.grid();
    let motion = sim.motion().clone();
    let want: Vec<Record> = sim.records().unwrap().flat_map(|b| b.unwrap()).collect();
    let mut p = imu_emu::engine::Producer::for_model(motion.clone(), grid, &m, 7).unwrap();
    let mut got = Vec::new();
    while let Some(b) = p.next_records(300) {
        got.extend_from_slice(b.records);
    }
    p.finished().unwrap();
    assert_eq!(got.len(), 1000);
    assert_eq!(got, want);
    let bad = imu_emu::engine::Grid {
        rate_hz: 3200.0,
        ..grid
    };
    let e = imu_emu::engine::Producer::for_model(motion, bad, &m, 7)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("below the output rate"), "{e}");
}

/// A rig unit whose template has an output filter runs its filter (it was refused before
/// rigs ran filters): a one-unit rig at the reference point with the single IMU's seed
/// writes the single IMU's filtered records (tests/rig_units.rs checks more).
#[test]
fn a_rig_runs_a_filtered_unit() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("unit.toml");
    std::fs::write(
        &file,
        format!(
            "name = \"unit\"\n[gyro]\nnoise = \"0.1 deg/sqrt(h)\"\n[output_filter]\ninternal_rate_hz = 1600\n{}\n",
            FILTERS[0]
        ),
    )
    .unwrap();
    let path = file.to_str().unwrap();
    let base = || {
        Simulation::builder()
            .scene("circle")
            .rate(RATE)
            .duration(1.0)
            .seed(3)
    };
    let mut unit = imu_emu::rig::UnitSpec::imu("a", path);
    unit.seed = Some(3);
    let rig = base().unit(unit).build_rig().unwrap();
    let mut main = Vec::new();
    let mut outs = [imu_emu::rig::UnitOutputs {
        main: &mut main,
        truth: None,
        failures: None,
    }];
    rig.write(&mut outs, |_| std::ops::ControlFlow::Continue(()))
        .unwrap();
    let mut one = Vec::new();
    base()
        .imu(path)
        .format("csv")
        .build()
        .unwrap()
        .write(&mut one)
        .unwrap();
    assert!(main.len() > 1000 && main == one);
}
