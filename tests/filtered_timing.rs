//! An output filter together with sampling-clock timing errors: the unit's clock ticks at
//! the filter's internal rate, output k is taken at internal tick k·D (or, under a host's
//! polled read, at the newest internal tick), and the truth covers the true output intervals. Checked against runs whose own behaviour is tested elsewhere:
//! the unfiltered timed run at the internal rate (its instants against the clock equation in
//! src/timing/sensor.rs, its increments in closed form in src/generator.rs) filtered by hand,
//! and the unfiltered timed run at the output rate for the truth.

use std::path::Path;

use imu_emu::errors::output_filter::Filter;
use imu_emu::errors::template;
use imu_emu::record::Record;
use imu_emu::sim::{SideOutputs, Simulation};
use imu_emu::timing::ReadRatio;

const FS: f64 = 1600.0;
const RATE: f64 = 200.0;
const MA: &str = "kind = \"moving_average\"\ntaps = 8";
const BW: &str = "kind = \"butterworth\"\norder = 4\ncutoff = \"40 Hz\"";

fn model(body: &str) -> imu_emu::errors::ImuModel {
    template::parse(&format!("name = \"f\"\n{body}\n"), Path::new("f.toml")).unwrap()
}

fn filtered(timing: &str, filter: &str) -> imu_emu::errors::ImuModel {
    model(&format!(
        "[timing]\n{timing}\n[output_filter]\ninternal_rate_hz = 1600\n{filter}"
    ))
}

fn builder(
    scene: &str,
    m: imu_emu::errors::ImuModel,
    rate: f64,
) -> imu_emu::sim::SimulationBuilder {
    Simulation::builder()
        .scene(scene)
        .imu_model(m)
        .rate(rate)
        .duration(3.0)
        .seed(5)
}

/// Records, truth and times (tov, tov_accel, emit, gaps) of a whole run.
struct Run {
    records: Vec<Record>,
    truth: Vec<Record>,
    times: Vec<(f64, f64, f64, u32)>,
}

fn run(b: imu_emu::sim::SimulationBuilder) -> Run {
    let mut p = b.build().unwrap().producer().unwrap();
    p.set_keep_truth(true);
    let mut out = Run {
        records: Vec::new(),
        truth: Vec::new(),
        times: Vec::new(),
    };
    while let Some(b) = p.next_records(97) {
        out.records.extend_from_slice(b.records);
        out.truth.extend_from_slice(b.truth);
        let t = b.times.expect("a timed run");
        for i in 0..b.records.len() {
            out.times.push((
                t.t0 + t.tov[i],
                t.t0 + t.tov_accel[i],
                t.t0 + t.emit[i],
                t.gaps[i],
            ));
        }
    }
    p.finished().unwrap();
    out
}

fn six(r: &Record) -> [f64; 6] {
    [
        r.gyro[0], r.gyro[1], r.gyro[2], r.accel[0], r.accel[1], r.accel[2],
    ]
}

fn scale(rs: &[Record]) -> f64 {
    rs.iter().flat_map(six).fold(0.0_f64, |a, x| a.max(x.abs()))
}

/// Under a clock 500 ppm fast with a drift and the accelerometers 40 µs late, the filtered
/// output equals the filter run by hand over the unfiltered run at the internal rate with the
/// same clock, decimated by 8 (to 1e-12 of the signal's scale, both filters); the truth is the
/// unfiltered run at the output rate with that clock (its increments over the true output
/// intervals), and the times of validity are the true output ticks kΔt/(1+y₀) + … less the
/// filter's validity offset. Were the clock applied per output sample only (nominal internal
/// intervals), the 1.5 ms phase it reaches in 3 s would move the coning scene's records by far
/// more than the tolerance.
#[test]
fn the_clock_ticks_at_the_internal_rate() {
    let clock = "clock_offset = \"500 ppm\"\nclock_drift = \"2 ppm/s\"\nskew = \"40 us\"";
    for scene in ["coning", "circle"] {
        let internal = run(builder(scene, model(&format!("[timing]\n{clock}")), FS));
        let at_rate = run(builder(scene, model(&format!("[timing]\n{clock}")), RATE));
        for f in [MA, BW] {
            let m = filtered(clock, f);
            let spec = m.output_filter.clone().unwrap();
            let offset = spec.validity_offset_s(RATE);
            let out = run(builder(scene, m, RATE));
            let mut filter = Filter::new(&spec, ReadRatio::integer(8));
            filter.prime(six(&internal.records[0]));
            let want: Vec<[f64; 6]> = (internal.records.iter())
                .filter_map(|r| filter.push(six(r)))
                .collect();
            assert_eq!(out.records.len(), want.len());
            assert_eq!(out.records.len(), at_rate.records.len());
            let s = scale(&out.records);
            for (k, (r, w)) in out.records.iter().zip(&want).enumerate() {
                assert_eq!(r.t, (k + 1) as f64 / RATE, "the sensor clock's reading");
                for (x, y) in six(r).iter().zip(w) {
                    assert!((x - y).abs() <= 1e-12 * s, "{scene} k {k}: {x} vs {y}");
                }
                let truth = &out.truth[k];
                for (x, y) in six(truth).iter().zip(six(&at_rate.truth[k])) {
                    assert!((x - y).abs() <= 1e-12 * s, "{scene} truth k {k}");
                }
                // Output k's instant is internal tick 8k's (its accelerometers' 40 µs later).
                let tick = internal.times[8 * k + 7];
                let (tov, tov_accel, emit, gap) = out.times[k];
                assert!((tov - (tick.0 - offset)).abs() < 1e-12, "k {k}");
                assert!((tov_accel - (tick.1 - offset)).abs() < 1e-12, "k {k}");
                assert!((emit - tick.0).abs() < 1e-12 && gap == 0, "k {k}");
                assert!((tick.0 - at_rate.times[k].0).abs() < 1e-12, "k {k}");
            }
            // The clock's phase at the end, so that the comparison above is not vacuous.
            let last = out.times.last().unwrap();
            assert!(3.0 - (last.0 + offset) > 1.4e-3, "{last:?}");
        }
    }
}

/// A host's polled read under the unit's clock (500 ppm fast, drifting, accelerometers 40 µs
/// late; a jitter of 2 µs per internal tick): the unit filters at 819.2 Hz on its own clock and
/// output k (read at 100 Hz) is the filtered value of internal sample n_k = ⌊k·8.192⌋, to
/// 1e-12 of the signal's scale against the filter run by hand over the unfiltered timed run at
/// 819.2 Hz with the same clock; its time of validity is that sample's true instant less the
/// filter's offset, its frame leaves the nominal wait k/100 − n_k/819.2 s after that instant,
/// and its truth covers (tick n_{k−1}, tick n_k]: the internal run's truth summed over those
/// samples (the increments, to 1e-12 of their scale). The internal bounds of a block run
/// from the last read sample to the newest, 8 or 9 per output.
#[test]
fn a_polled_read_under_the_units_clock() {
    use imu_emu::timing::{SensorTiming, TimedBlock, TimingModel};
    let fs = 819.2;
    let read = ReadRatio::from_rates(fs, 100.0).unwrap();
    let clock = "clock_offset = \"500 ppm\"\nclock_drift = \"2 ppm/s\"\nskew = \"40 us\"\njitter = \"2 us\"";
    let polled = |f: &str| {
        model(&format!(
            "[timing]\n{clock}\n[output_filter]\ninternal_rate_hz = 819.2\n{f}"
        ))
    };
    for scene in ["coning", "circle"] {
        let internal = run(builder(scene, model(&format!("[timing]\n{clock}")), fs));
        for f in [MA, BW] {
            let m = polled(f);
            let spec = m.output_filter.clone().unwrap();
            let offset = spec.validity_offset_s(100.0);
            let out = run(builder(scene, m, 100.0));
            assert_eq!(out.records.len(), 300);
            let mut filter = Filter::new(&spec, ReadRatio::integer(1));
            filter.prime(six(&internal.records[0]));
            let every: Vec<[f64; 6]> = (internal.records.iter())
                .filter_map(|r| filter.push(six(r)))
                .collect();
            let s = scale(&out.records);
            let ts = out
                .truth
                .iter()
                .flat_map(|r| [r.dtheta.norm(), r.dv.norm()]);
            let truth_scale = ts.fold(0.0_f64, f64::max);
            for (i, r) in out.records.iter().enumerate() {
                let k = i as u64 + 1;
                let n = read.index(k) as usize;
                assert_eq!(r.t, k as f64 / 100.0, "the host's reading");
                for (x, y) in six(r).iter().zip(every[n - 1]) {
                    assert!((x - y).abs() <= 1e-12 * s, "{scene} k {k}: {x} vs {y}");
                }
                let tick = internal.times[n - 1];
                let (tov, tov_accel, emit, gap) = out.times[i];
                assert!((tov - (tick.0 - offset)).abs() < 1e-12, "k {k}");
                assert!((tov_accel - (tick.1 - offset)).abs() < 1e-12, "k {k}");
                let wait = k as f64 / 100.0 - n as f64 / fs;
                assert!((emit - tick.0 - wait).abs() < 1e-12 && gap == 0, "k {k}");
                let from = read.index(k - 1) as usize;
                let (mut dtheta, mut dv) = (out.truth[i].dtheta * 0.0, out.truth[i].dv * 0.0);
                for t in &internal.truth[from..n] {
                    dtheta += t.dtheta;
                    dv += t.dv;
                }
                assert!(
                    (dtheta - out.truth[i].dtheta).norm() < 1e-12 * truth_scale,
                    "k {k}"
                );
                assert!((dv - out.truth[i].dv).norm() < 1e-12 * truth_scale, "k {k}");
            }
        }
    }
    let model = TimingModel {
        clock_offset: 100e-6,
        ..Default::default()
    };
    let mut s = SensorTiming::decimated(model, 100.0, read, 10.0, 1, (-1.0, 20.0)).unwrap();
    let mut b = TimedBlock::default();
    s.fill(1, 7, &mut b);
    assert_eq!(b.internal.0.len(), read.index(7) as usize + 1);
    s.fill(8, 118, &mut b);
    assert_eq!(
        b.internal.0.len(),
        (read.index(125) - read.index(7)) as usize + 1
    );
    for k in 8..=125u64 {
        let j = (read.index(k) - read.index(7)) as usize;
        assert_eq!(b.gyro[(k - 7) as usize], b.internal.0[j]);
    }
    let end = *b.gyro.last().unwrap();
    assert!((end - 1024.0 / fs / 1.0001).abs() < 1e-15, "{end}");
}

/// A constant angular acceleration seen through a moving average of 8 taps under a clock
/// offset y₀, in closed form: internal ticks t_j = jΔ/(1+y₀) (Δ = 1/1600 s); internal record
/// j is ∫ω over (t_{j−1}, t_j] over the nominal Δ, α(t_j + t_{j−1})/(2(1+y₀)) + c/(1+y₀) for
/// ω = c + αt; their mean over j = 8k−7 … 8k is (c + α(t_{8k} − 4Δ/(1+y₀)))/(1+y₀). The
/// coning scene has no such axis, so the check runs the filter and clock model directly on
/// the sampler's intervals the run uses, [`imu_emu::timing::SensorTiming::decimated`]. With
/// the ticks at the output rate only (internal ones nominal), the mean would miss by α·y₀·t.
#[test]
fn a_ramp_through_the_clock_and_the_filter_in_closed_form() {
    use imu_emu::timing::{SensorTiming, TimedBlock, TimingModel};
    let y0 = 800e-6;
    let model = TimingModel {
        clock_offset: y0,
        ..Default::default()
    };
    let mut s =
        SensorTiming::decimated(model, RATE, ReadRatio::integer(8), 10.0, 1, (-1.0, 20.0)).unwrap();
    let mut b = TimedBlock::default();
    s.fill(1, 2000, &mut b);
    assert_eq!(b.internal.0.len(), 16_001);
    let (c, alpha) = (0.02, 0.3);
    let d = 1.0 / FS;
    let spec = filtered("", MA).output_filter.unwrap();
    let mut filter = Filter::new(&spec, ReadRatio::integer(8));
    let g = &b.internal.0;
    let f = |t: f64| c * t + 0.5 * alpha * t * t;
    let rate = |j: usize| (f(g[j]) - f(g[j - 1])) / d;
    filter.prime([rate(1); 6]);
    let mut k = 0;
    for j in 1..g.len() {
        let Some(y) = filter.push([rate(j); 6]) else {
            continue;
        };
        k += 1;
        let tick = g[8 * k];
        assert!((tick - 8.0 * k as f64 * d / (1.0 + y0)).abs() < 1e-13 * tick.max(1.0));
        assert_eq!(b.gyro[k], tick, "output k's bound is internal tick 8k");
        if k > 1 {
            let want = (c + alpha * (tick - 4.0 * d / (1.0 + y0))) / (1.0 + y0);
            // Round-off: F(t) ≈ 15 at t = 10 s carries ulp 1.8e-15; 8 differences of two
            // evaluations (≤ 2 ulp each) over 8Δ are ≤ 32 · 1.8e-15 · 200 ≈ 1.2e-11.
            assert!((y[0] - want).abs() < 1.2e-11, "k {k}: {} vs {want}", y[0]);
        }
    }
    assert_eq!(k, 2000);
}

/// The internal sampler's jitter acts on every internal tick: with no clock terms, tick j
/// strays from jΔ by N(0, σ²). Over 16 000 ticks the sample standard deviation's own relative
/// scatter is 1/√(2·16 000) = 0.56 %, so 4σ allows 2.24 %; jitter drawn per output sample
/// only would leave 7 of every 8 internal ticks exact (a deviation 1/√8 as large). Frames are
/// still skipped and emitted per output sample: the draws are those of an unfiltered run at
/// the output rate with the same seed, whose emission follows its tick by the latency.
#[test]
fn jitter_is_per_internal_tick_and_emission_per_output() {
    use imu_emu::timing::{SensorTiming, TimedBlock, TimingModel};
    let sigma = 5e-6;
    let m = TimingModel {
        jitter: sigma,
        latency: 300e-6,
        latency_spread: 100e-6,
        missing_probability: 0.05,
        ..Default::default()
    };
    let span = (-1.0, 100.0);
    let mut s = SensorTiming::decimated(m, RATE, ReadRatio::integer(8), 10.0, 9, span).unwrap();
    let mut b = TimedBlock::default();
    s.fill(1, 2000, &mut b);
    let d = 1.0 / FS;
    let n = b.internal.0.len() - 1;
    let var = (1..=n)
        .map(|j| (b.internal.0[j] - j as f64 * d).powi(2))
        .sum::<f64>()
        / n as f64;
    let ratio = var.sqrt() / sigma;
    assert!((ratio - 1.0).abs() < 0.0224, "{ratio}");
    let mut plain = SensorTiming::new(m, RATE, 10.0, 9, span).unwrap();
    let mut p = TimedBlock::default();
    plain.fill(1, 2000, &mut p);
    assert_eq!(b.missing, p.missing);
    assert!(b.missing.iter().filter(|&&x| x).count() > 50);
    for k in 0..2000 {
        let lat = b.emit[k] - b.gyro[k + 1];
        let plain_lat = p.emit[k] - p.gyro[k + 1];
        // Frames leave in order, so a latency may grow past its draw; compare where neither did.
        if lat <= 400e-6 + 1e-12 && plain_lat <= 400e-6 + 1e-12 {
            assert!(
                (lat - plain_lat).abs() < 1e-12,
                "k {k}: {lat} vs {plain_lat}"
            );
        }
    }
    // Jitter above 1/20 of the internal interval is refused, though it is under the output's.
    let big = TimingModel {
        jitter: 50e-6,
        ..Default::default()
    };
    let e = SensorTiming::decimated(big, RATE, ReadRatio::integer(8), 10.0, 9, span).unwrap_err();
    assert!(e.contains("internal sample interval"), "{e}");
    assert!(SensorTiming::new(big, RATE, 10.0, 9, span).is_ok());
}

/// Skipped frames of a filtered unit fold into the next frame taken, as an unfiltered unit's
/// do: the increments summed over the run equal those of the same run with no frame skipped
/// (to round-off), the counter steps over them, and the injected-error columns stay one row
/// per frame (the noisy template writes them through the filter).
#[test]
fn skipped_frames_of_a_filtered_unit_keep_the_increments() {
    let base = "clock_offset = \"-200 ppm\"\njitter = \"3 us\"";
    let noisy = "[gyro]\nnoise = \"0.2 deg/sqrt(h)\"\n[accel]\nnoise = \"0.05 m/s/sqrt(h)\"\n";
    let m = |t: &str| {
        model(&format!(
            "{noisy}[timing]\n{t}\n[output_filter]\ninternal_rate_hz = 1600\n{BW}"
        ))
    };
    let all = run(builder("circle", m(base), RATE));
    let some = run(builder(
        "circle",
        m(&format!("{base}\nmissing_probability = 0.05")),
        RATE,
    ));
    let skipped: u32 = some.times.iter().map(|t| t.3).sum();
    assert!(skipped > 10, "{skipped}");
    // Frames skipped at the very end have no frame after them to carry them.
    let trailing = all.records.len() - some.records.len() - skipped as usize;
    assert!(trailing < 5, "{trailing}");
    let sum = |rs: &[Record]| {
        rs.iter().fold([0.0; 6], |mut a, r| {
            for i in 0..3 {
                a[i] += r.dtheta[i];
                a[i + 3] += r.dv[i];
            }
            a
        })
    };
    for (what, x, y) in [
        ("records", &some.records, &all.records),
        ("truth", &some.truth, &all.truth),
    ] {
        let (sx, sy) = (sum(x), sum(&y[..y.len() - trailing]));
        for i in 0..6 {
            assert!(
                (sx[i] - sy[i]).abs() <= 1e-12 * sy[i].abs().max(1.0),
                "{what} axis {i}: {} vs {}",
                sx[i],
                sy[i]
            );
        }
    }
    // The injected errors, written through the filter: a frame that follows no skipped one
    // carries the row of the same frame of the run that skips none.
    let injected = |t: &str| {
        let (mut frames, mut injected) = (Vec::new(), Vec::new());
        let side = SideOutputs {
            truth: None,
            injected: Some(&mut injected),
        };
        builder("circle", m(t), RATE)
            .format("csv")
            .build()
            .unwrap()
            .write_with(&mut frames, side, |_| std::ops::ControlFlow::Continue(()))
            .unwrap();
        let text = String::from_utf8(injected).unwrap();
        let rows: Vec<String> = text.lines().skip(1).map(String::from).collect();
        (rows, String::from_utf8(frames).unwrap().lines().count() - 1)
    };
    let (rows_all, _) = injected(base);
    let (rows, frames) = injected(&format!("{base}\nmissing_probability = 0.05"));
    assert_eq!(rows.len(), some.records.len());
    assert_eq!(frames, some.records.len());
    let first = |r: &str| r.split(',').next().unwrap().to_string();
    let mut compared = 0;
    for (row, t) in rows.iter().zip(&some.times) {
        if t.3 == 0 {
            let same = rows_all.iter().find(|r| first(r) == first(row)).unwrap();
            assert_eq!(row, same);
            compared += 1;
        }
    }
    assert!(
        compared > 500 && rows[0].split(',').count() > 7,
        "{compared}"
    );
}
