//! `fit` on what real recordings carry (issue 24): an output LSB (values on a lattice), an
//! output filter (a PSD that rolls off before the Nyquist frequency), Gauss–Markov terms with
//! T near or below Δt; every term's theory is what the generator produces at the record's
//! rate, so a record simulated from known templates, fitted and simulated again closes at every
//! octave and PSD band. What `fit` refuses: records too short for its terms, non-uniform time
//! steps, records that are not static. And public recordings of real units: the ADIS16448's
//! and the BMI160's Allan deviation tables (gaowenliang/imu_utils, MIT) and an MPU-6050's
//! static and moving records (sunsided/sensor-fusion, EUPL-1.2), read from the public data
//! sets outside the repository (tests/common/public_data.rs, docs/testing.md).

mod common;
#[path = "common/public_data.rs"]
mod public_data;

use std::path::Path;

use common::cli::{err, imu_emu, ok, p};
use imu_emu::analysis::analyzer::Analysis;
use imu_emu::analysis::confidence::{NoiseType, edf};
use imu_emu::analysis::theory;
use imu_emu::errors::filter_allan::SensorAllan;
use imu_emu::errors::template::{self, ImuModel};
use imu_emu::fit::checks;
use imu_emu::fit::closure::{self, ClosurePoint, PsdPoint};
use imu_emu::fit::compare::{fit_all_with_filter, triad_lsbs};
use imu_emu::fit::filter::FittedFilter;
use imu_emu::fit::gmwm::AxisFit;
use imu_emu::fit::template::{Provenance, template_toml};
use imu_emu::timing::ReadRatio;
use tempfile::TempDir;

const DT: f64 = 0.01;

/// `imu-emu generate` of the built-in `scene` with the stim300 at 100 Hz for `seconds`, to
/// `out` (binary when it ends in .bin).
fn generate(scene: &str, seconds: &str, out: &Path) {
    let bin = out.extension().is_some_and(|e| e == "bin");
    let mut args = vec![
        "generate",
        "--scene",
        scene,
        "--imu",
        "stim300",
        "--rate",
        "100",
        "--duration",
        seconds,
    ];
    if bin {
        args.extend(["--format", "bin"]);
    }
    args.extend(["-o", p(out)]);
    ok(imu_emu(args));
}

/// A static record of `model`, fitted as `fit` does; the fitted template written and loaded
/// back; a record of the same length simulated from it (another seed); the closure of every
/// channel (Allan deviation per octave to T/8, PSD per band from 0.01 Hz).
struct Closed {
    rec: Analysis,
    fits: Vec<Option<AxisFit>>,
    filter: Option<FittedFilter>,
    toml: String,
    adev: Vec<Vec<ClosurePoint>>,
    psd: Vec<Vec<PsdPoint>>,
}

fn close(model: &ImuModel, samples: u64, seed: u64) -> Closed {
    let rec = closure::simulate(model.clone(), DT, samples, seed, 1 << 12).unwrap();
    checks::check(&rec).unwrap();
    let fitted = fit_all_with_filter(&rec);
    let (fits, filter) = (fitted.fits, fitted.filter);
    let prov = Provenance {
        name: "fitted".into(),
        source: "closure".into(),
        samples,
        dt: DT,
        lsb: triad_lsbs(&rec),
        filter: filter.clone(),
        carry: fitted.carry,
        resonances: Vec::new(),
        table: false,
        missing: [false; 6],
    };
    let toml = template_toml(&prov, &fits, &vec![Vec::new(); 6]);
    let fitted = template::parse(&toml, Path::new("fitted.toml")).unwrap();
    let sim = closure::simulate(fitted, DT, samples, seed + 100, 1 << 12).unwrap();
    let adev = (0..6)
        .map(|ch| {
            let f = fits[ch].as_ref().unwrap();
            closure::compare(
                &rec.channels[ch].adev,
                &sim.channels[ch].adev,
                &f.model,
                samples as usize,
            )
        })
        .collect();
    let psd = (0..6)
        .map(|ch| closure::compare_psd(&rec.channels[ch].psd, &sim.channels[ch].psd))
        .collect();
    Closed {
        rec,
        fits,
        filter,
        toml,
        adev,
        psd,
    }
}

fn all_inside(c: &Closed, what: &str) {
    for ch in 0..6 {
        for q in &c.adev[ch] {
            assert!(q.inside(), "{what}: channel {ch}: {q:?}\n{}", c.toml);
        }
        assert!(!c.psd[ch].is_empty());
        for q in &c.psd[ch] {
            assert!(q.inside(), "{what}: channel {ch} PSD: {q:?}\n{}", c.toml);
        }
    }
}

/// A white-noise + Gauss–Markov unit at 100 Hz with Δt/T = `x`, each rate sample rounded to
/// an LSB equal to the white noise's per-sample σ (σ/q = 1: the rounding error is uniform and
/// independent of the signal to e^{−2π²σ²/q²} ≈ 3e-9, Widrow & Kollár 2008, ch. 4; its
/// q²/12 is 1/12 of the white variance, enough for the fit to tell rounding from a carry
/// quantizer's 3Q²/τ², which is 3× larger at τ = Δt and falls as 1/τ²). The GM
/// σ is twice the white noise's per-sample σ, so it dominates σ² around τ ≈ T (or, for T ≪
/// Δt, makes up 80 % of the white noise it then is).
fn gm_unit(x: f64) -> ImuModel {
    let t = DT / x;
    let (ng, na) = (1e-4, 2e-3); // rad/√s, m/s/√s
    let text = format!(
        "name = \"gm\"\nrate_hz = 100\nquantization_mode = \"round\"\n\
         [gyro]\nnoise = \"{ng} rad/s/sqrt(Hz)\"\nbias_gm = {{ sigma = \"{} rad/s\", tau = \"{t} s\" }}\nquantization = \"{} rad/s\"\n\
         [accel]\nnoise = \"{na} m/s^2/sqrt(Hz)\"\nbias_gm = {{ sigma = \"{} m/s^2\", tau = \"{t} s\" }}\nquantization = \"{} m/s^2\"\n",
        2.0 * ng / DT.sqrt(),
        ng / DT.sqrt(),
        2.0 * na / DT.sqrt(),
        na / DT.sqrt(),
    );
    template::parse(&text, Path::new("gm.toml")).unwrap()
}

/// The generator against the exact theory, and the fit closing, for Gauss–Markov terms from
/// T = 10Δt to T = Δt/100 with the output LSB's rounding. 2^16 samples at 100 Hz per case.
///
/// (a) The record's Allan deviation at every octave to T/8 lies within 4σ of the exact theory
/// (`theory::triad`: the sampled AR(1) curve plus the rounding's q²/(12m)); σ of ln σ̂ is
/// 1/√(2ν) with ν the smallest edf of the white, flicker and random-walk types (the
/// conservative one). The continuous curve σ²g(τ/T) the theory used before is off by the
/// factor Δt/(2T) at T ≪ Δt (5× at Δt/T = 10, 50× at 100), far outside.
/// (b) The fit finds the LSB exactly (to 1e-9) and closes: the record simulated from the
/// fitted template lies inside the closure bands at every octave and PSD band. Which
/// quantizer the fit takes (rounding or carry) is not asserted: at Δt/T = 1 a Gauss–Markov
/// term with T ≈ Δt trades with the carry quantizer's 3Q²/τ² at the shortest τ, and the
/// cheaper of the two fits was the carry one, which closes as well.
#[test]
fn sampled_gauss_markov_closes_across_dt_over_t() {
    let n: u64 = 1 << 16;
    for (i, x) in [0.1, 1.0, 10.0, 100.0].into_iter().enumerate() {
        let model = gm_unit(x);
        let c = close(&model, n, 40 + i as u64);
        let th: Vec<theory::AxisTheory> = theory::triad(&model.gyro, model.quantization_mode, DT)
            .into_iter()
            .chain(theory::triad(&model.accel, model.quantization_mode, DT))
            .collect();
        for (ch, (t, chan)) in th.iter().zip(&c.rec.channels).enumerate() {
            for pt in chan.adev.iter().filter(|p| p.m as u64 <= n / 8) {
                let nu = [
                    NoiseType::WhiteRate,
                    NoiseType::FlickerRate,
                    NoiseType::RandomWalkRate,
                ]
                .map(|k| edf(k, n as usize + 1, pt.m))
                .into_iter()
                .fold(f64::INFINITY, f64::min);
                let want = t.avar(pt.m, DT).sqrt();
                let z = (pt.adev / want).ln() * (2.0 * nu).sqrt();
                assert!(z.abs() < 4.0, "Δt/T {x}, channel {ch}, m {}: z = {z}", pt.m);
            }
        }
        let q = [model.gyro.quantization, model.accel.quantization].map(|q| match q {
            Some(imu_emu::units::Lsb::Rate(q)) => q,
            other => panic!("{other:?}"),
        });
        let found = triad_lsbs(&c.rec);
        for s in 0..2 {
            let f = found[s].unwrap();
            assert!((f / q[s] - 1.0).abs() < 1e-9, "{f} vs {}", q[s]);
        }
        // The GM's own roll-off at T = 10Δt is no output filter (the ADEV fit decides).
        assert!(c.filter.is_none(), "Δt/T {x}: {:?} {}", c.filter, c.toml);
        all_inside(&c, &format!("Δt/T = {x}"));
    }
}

/// Every channel's fitted white noise N holds the template's in its 99 % interval.
fn white_noise_inside(c: &Closed, model: &ImuModel) {
    white_noise_inside_scaled(c, model, |_| 1.0);
}

/// Every channel's fitted white noise N holds the template's times `scale(accel)` in its 99 %
/// interval.
fn white_noise_inside_scaled(c: &Closed, model: &ImuModel, scale: impl Fn(bool) -> f64) {
    for ch in 0..6 {
        let e = c.fits[ch]
            .as_ref()
            .unwrap()
            .estimate(imu_emu::fit::gmwm::Component::WhiteNoise)
            .unwrap();
        let accel = ch >= 3;
        let sensor = if accel { &model.accel } else { &model.gyro };
        let truth = sensor.noise[0] * scale(accel);
        assert!(
            e.lo <= truth && truth <= e.hi,
            "channel {ch}: {e:?} vs {truth}"
        );
    }
}

/// White noise of 2.5 deg/√h and 0.25 m/s/√h rounded to 0.05 deg/s and 3.33 mg (an ADIS16405's
/// LSBs) at 100 Hz, under the output filter `filter` (template tables).
fn adis_like(filter: &str) -> ImuModel {
    let text = format!(
        "name = \"adis-like\"\nrate_hz = 100\nquantization_mode = \"round\"\n\
         [gyro]\nnoise = \"2.5 deg/sqrt(h)\"\nquantization = \"0.05 deg/s\"\n\
         [accel]\nnoise = \"0.25 m/s/sqrt(h)\"\nquantization = \"3.33 mg\"\n{filter}"
    );
    template::parse(&text, Path::new("adis-like.toml")).unwrap()
}

/// A unit with the ADIS164xx family's output stage (samples at 4× the output rate, a Bartlett
/// window — two cascaded 4-tap averages — and decimation; Analog Devices ADIS16448 data sheet,
/// "Digital filtering"), rate samples rounded to 0.05 deg/s and 3.33 mg, white noise only:
/// the fit reads the filter from the PSD roll-off (the exact candidate, CIC order 2, 4 taps, at
/// 400 Hz), the LSBs from the lattice, N inside its 99 % interval, and closes at every octave
/// and PSD band. 2^17 samples at 100 Hz.
#[test]
fn output_filter_and_lsb_are_read_and_close() {
    let model =
        adis_like("[output_filter]\ninternal_rate_hz = 400\nkind = \"cic\"\norder = 2\ntaps = 4\n");
    let c = close(&model, 1 << 17, 7);
    let f = c.filter.clone().expect("a filter");
    assert_eq!(f.spec.internal_rate_hz, 400.0, "{:?}", f);
    assert_eq!(
        f.spec.kind,
        imu_emu::errors::output_filter::FilterKind::Cic { order: 2, taps: 4 }
    );
    assert!(
        c.toml.contains(
            "[output_filter]\ninternal_rate_hz = 400\nkind = \"cic\"\norder = 2\ntaps = 4"
        )
    );
    white_noise_inside(&c, &model);
    all_inside(&c, "filtered unit");
}

/// A unit whose gyros and accelerometers have their own filters at the same internal rate
/// (1600 Hz, 16× the output rate: a moving average of 20 taps on the gyros, a CIC of order 3
/// and 12 taps on the accelerometers, the kinds `fit` read from the ADIS16405 recordings of
/// docs/fit.md), and an accelerometer LSB whose rounding noise is 8 % of the Allan variance at
/// τ = Δt (3.33 mg, as on the ADIS16405, where it is 7–12 %). The fit reads each sensor's
/// filter to within 1 % of its folded PSD shape, the accelerometers' as
/// `[output_filter.accel]`, the output white density inside its 99 % interval, and closes at
/// every octave and PSD band. Each of three parts is needed, and this test fails without it:
/// the LSB's flat floor under the roll-off in the filter fit (without it the accelerometers'
/// roll-off looks shallower than their filter's), the second filter, and the fitted model's
/// PSD misfit in the choice of quantizer (`fit::compare`). 2^17 samples at 100 Hz.
#[test]
fn a_filter_per_sensor_and_a_coarse_lsb_are_read_and_close() {
    let model = adis_like(
        "[output_filter]\ninternal_rate_hz = 1600\nkind = \"moving_average\"\ntaps = 20\n\
         [output_filter.accel]\nkind = \"cic\"\norder = 3\ntaps = 12\n",
    );
    let c = close(&model, 1 << 17, 13);
    let f = c.filter.clone().expect("a filter");
    // Each sensor's filter as the output sees it: the folded PSD shape, within 1 % of the
    // truth's up to the Nyquist frequency (at 2^17 samples a neighbour of the same folded
    // shape, a CIC 2 × 15 for the moving average of 20, cannot be told apart). The fit weighs
    // about 60 points per sensor (`FittedFilter::bands` is 120: PSD bands of the top decade
    // and Allan variances at m ≤ 64), each ±1.6 % at 1σ, which pin the shape to about 0.2 %:
    // 1 % is 5σ of that.
    let truth = model.output_filter.clone().unwrap();
    let (want, got) = (SensorAllan::new(&truth, ReadRatio::integer(16)), f.white());
    for accel in [false, true] {
        for k in 0..=50 {
            let hz = k as f64;
            let (w, g) = (
                want.sensor(accel).psd_ratio(hz, DT),
                got.sensor(accel).psd_ratio(hz, DT),
            );
            assert!(
                (g / w - 1.0).abs() < 0.01,
                "accel {accel}, {hz} Hz: {g} vs {w}\n{}",
                c.toml
            );
        }
    }
    assert!(f.spec.accel.is_some(), "{}", c.toml);
    assert!(c.toml.contains("[output_filter.accel]"), "{}", c.toml);
    // What the output shows of N is its density N²·r_∞ (r_∞ the filter's aliasing gain, 1.07
    // for the moving average of 20 and 1.01 for the CIC 2 × 15: the two put out the same
    // shape with different N), so that is what must lie inside the interval.
    let gain = |s: &SensorAllan, accel: bool| s.sensor(accel).long_tau().sqrt();
    white_noise_inside_scaled(&c, &model, |accel| gain(&want, accel) / gain(&got, accel));
    all_inside(&c, "filter per sensor");
}

/// The same filter and LSBs with the z axes keeping a white floor the filter did not shape
/// (`post_filter_noise`, P²/N² = 0.0576 on gyro z and accel z; the ADIS16405's z axes show
/// floors of 0.02–0.08). The fit reads each floor from the top decade of its axis's PSD within
/// 4σ of its own scatter (the σ it reports, from the χ²'s curvature: 0.0064 and 0.0066 here),
/// finds none on x and y (a false floor passes the 99.9 % threshold once in a thousand axes),
/// writes `post_filter_noise`, and closes everywhere. 2^19 samples: at 2^17 the fit without
/// floors still closed (another filter, N and the bands' ±6 % absorb them); here, with the
/// floors left out of the fit, gyro z's top band (45 Hz) comes out 4.3 % low against a band of
/// ±3.1 %.
#[test]
fn a_floor_above_the_roll_off_is_read_per_axis_and_closes() {
    let mut model = adis_like(
        "[output_filter]\ninternal_rate_hz = 1600\nkind = \"moving_average\"\ntaps = 20\n",
    );
    let ratio: f64 = 0.0576;
    model.gyro.post_filter_noise = [0.0, 0.0, model.gyro.noise[2] * ratio.sqrt()];
    model.accel.post_filter_noise = [0.0, 0.0, model.accel.noise[2] * ratio.sqrt()];
    let c = close(&model, 1 << 19, 17);
    let f = c.filter.clone().expect("a filter");
    for (ch, floor) in f.floors.iter().enumerate() {
        if ch % 3 == 2 {
            assert!(
                floor.ratio > 0.0 && (floor.ratio - ratio).abs() < 4.0 * floor.sd,
                "channel {ch}: {floor:?}\n{}",
                c.toml
            );
        } else {
            assert_eq!(floor.ratio, 0.0, "channel {ch}: {floor:?}\n{}", c.toml);
        }
    }
    assert!(c.toml.contains("post_filter_noise = "), "{}", c.toml);
    all_inside(&c, "floor above the roll-off");
}

/// The same unit as a host sees it when it polls at 100 Hz a unit that filters at 819.2 Hz
/// (the ADIS164xx family's internal rate, its Bartlett window of 2 × 16 taps): each output is
/// the newest filtered sample, 8 or 9 internal samples apart. The fit reads that filter from
/// the PSD roll-off among the polled candidates (819.2 Hz, CIC order 2, 16 taps), N inside its
/// 99 % interval, and closes at every octave and PSD band. 2^17 samples at 100 Hz.
#[test]
fn a_polled_unit_is_read_and_closes() {
    let (ng, na) = (2.5, 0.25); // deg/√h, m/s/√h
    let text = format!(
        "name = \"adis-polled\"\nrate_hz = 100\n\
         [gyro]\nnoise = \"{ng} deg/sqrt(h)\"\n[accel]\nnoise = \"{na} m/s/sqrt(h)\"\n\
         [output_filter]\ninternal_rate_hz = 819.2\nkind = \"cic\"\norder = 2\ntaps = 16\n"
    );
    let model = template::parse(&text, Path::new("adis-polled.toml")).unwrap();
    let c = close(&model, 1 << 17, 11);
    let f = c.filter.clone().expect("a filter");
    assert_eq!(
        (f.spec.internal_rate_hz, &f.spec.kind),
        (
            819.2,
            &imu_emu::errors::output_filter::FilterKind::Cic { order: 2, taps: 16 }
        )
    );
    assert!(
        c.toml
            .contains("# Output filter read from the PSD roll-off")
    );
    assert!(
        c.toml
            .contains("polling host: output k is internal sample ⌊k·1024/125⌋"),
        "{}",
        c.toml
    );
    white_noise_inside(&c, &model);
    all_inside(&c, "polled unit");
}

/// A record too short for the terms `fit` reports is refused with the count it needs, and no
/// template is written — 10 samples (issue 23, item 6) and one sample short of
/// `checks::MIN_SAMPLES`; at `MIN_SAMPLES` it fits.
#[test]
fn too_short_records_are_refused() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    for (samples, refused) in [
        (10, true),
        (checks::MIN_SAMPLES - 1, true),
        (checks::MIN_SAMPLES, false),
    ] {
        let rec = d.join(format!("r{samples}.csv"));
        let duration = format!("{}", samples as f64 * DT);
        generate("static", &duration, &rec);
        let unit = d.join(format!("u{samples}.toml"));
        let out = imu_emu(["fit", p(&rec), "-o", p(&unit)]);
        if refused {
            let e = err(out);
            assert!(
                e.contains(&format!("{samples} samples are too few"))
                    && e.contains(&format!("at least {}", checks::MIN_SAMPLES))
                    && e.contains(p(&rec)),
                "{e}"
            );
            assert!(!unit.exists());
        } else {
            ok(out);
            assert!(unit.exists());
        }
    }
}

/// A time step that is not a whole number of Δt (a jump of the time tags by half a step, as a
/// host's buffered reads give) is refused, naming the sample after it and its time; nothing
/// is written. Without the time column and with --rate (the samples themselves uniform) it
/// fits. (A step of a whole number of Δt is a dropped sample: `tests/fit.rs`,
/// `dropped_samples_are_put_back_and_left_out`.)
#[test]
fn non_uniform_time_steps_are_refused() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let rec = d.join("r.csv");
    generate("static", "10", &rec);
    let text = std::fs::read_to_string(&rec).unwrap();
    assert!(text.starts_with("t,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z"));
    // Line 1 is the header, line k + 1 sample k (counted from 1, as messages count them; t =
    // k·Δt): from sample 501 on, the time tags are late by Δt/2, so sample 501 (t = 5.015 s)
    // comes 1.5Δt after sample 500.
    let mut out = String::new();
    for (i, l) in text.lines().enumerate() {
        match l.split_once(',') {
            Some((t, rest)) if i >= 501 => {
                let t: f64 = t.parse().unwrap();
                out.push_str(&format!("{},{rest}\n", t + 0.005));
            }
            _ => out.push_str(&format!("{l}\n")),
        }
    }
    let jump = d.join("jump.csv");
    std::fs::write(&jump, out).unwrap();
    let unit = d.join("u.toml");
    let e = err(imu_emu(["fit", p(&jump), "-o", p(&unit)]));
    assert!(
        e.contains(&format!("{}: sample 501 (t = 5.015", p(&jump)))
            && e.contains("needs uniformly sampled data"),
        "{e}"
    );
    assert!(!unit.exists());
    let columns = "--columns=-,gx,gy,gz,ax,ay,az";
    ok(imu_emu([
        "fit",
        p(&jump),
        columns,
        "--rate",
        "100",
        "-o",
        p(&unit),
    ]));
    assert!(unit.exists());
}

/// A moving record (the built-in survey flight: turns, banks, climbs) is refused as not
/// static, naming the channel and the stretch of samples; the same unit at rest is fitted.
#[test]
fn a_moving_record_is_refused() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let moving = d.join("moving.bin");
    generate("survey", "120", &moving);
    let unit = d.join("u.toml");
    let e = err(imu_emu(["fit", p(&moving), "-o", p(&unit)]));
    assert!(
        e.contains(&format!("{}: not a static recording", p(&moving))) && e.contains("samples "),
        "{e}"
    );
    assert!(!unit.exists());
}

/// Every τ of a real unit's Allan deviation closes to T/8 from 15 ms (3Δt) or 25 ms (5Δt):
/// the tables of gaowenliang/imu_utils (MIT; the public data set `imu_utils`): an ADIS16448 (2 h at
/// 200 Hz) and a BMI160 (200 min at 196.4 Hz), 83 τ each to T/8. `fit` reads their output
/// filters from the tables' shortest τ: for the ADIS16448 a CIC of order 2 and 4 taps at
/// 819.2 Hz read by the host at 200 Hz — the data sheet's internal rate and Bartlett window
/// (Analog Devices ADIS16448 data sheet, "Digital filtering"; the table's 199.999861 Hz is
/// 512/125 of 819.2 Hz within 0.7 ppm) — and gyro z's resonance from the Allan deviation
/// (`fit::resonance_adev`, 10–54 Hz), which close from 3Δt on every channel; for the BMI160 a
/// low-pass (a 4th-order Butterworth at 0.4× its output rate) and a weak resonance (1.1–1.3×
/// the floor) on every channel but accel z, from 5Δt. Below, the filter's exact shape decides
/// σ within bands of ±0.5 % (docs/fit.md): 4 of the ADIS16448's points (at 5 or 10 ms) and 6 of
/// the BMI160's (10–20 ms) fall outside. Without the resonances gyro z of the ADIS16448 closed
/// from 0.15 s only (15 of its points below it outside), and the BMI160 from 0.15 s.
#[test]
fn real_unit_tables_close_above_thirty_samples() {
    let Some(tables) = public_data::set("imu_utils", "real_unit_tables_close_above_thirty_samples")
    else {
        return;
    };
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    for (unit, filter, from) in [
        ("adis16448", "internal_rate_hz = 819.19943", [0.015; 6]),
        ("bmi160", "kind = \"butterworth\"\norder = 4", [0.025; 6]),
    ] {
        let table = tables.join(format!("{unit}-adev.csv"));
        let out = d.join(format!("{unit}.toml"));
        let report = d.join(format!("{unit}.md"));
        ok(imu_emu([
            "fit",
            p(&table),
            "-o",
            p(&out),
            "--report",
            p(&report),
        ]));
        let toml = std::fs::read_to_string(&out).unwrap();
        assert!(toml.contains(filter), "{unit}: {toml}");
        if unit == "adis16448" {
            assert!(
                toml.contains("kind = \"cic\"\norder = 2\ntaps = 4"),
                "{toml}"
            );
            assert!(toml.contains("polling host: output k is internal sample ⌊k·512/125⌋"));
        }
        assert!(toml.contains("# Output filter read from the Allan deviation at m ≤ 64"));
        let md = std::fs::read_to_string(&report).unwrap();
        let mut rows = 0;
        let mut channel = None;
        for line in md.lines() {
            if let Some(name) = line.strip_prefix("### ") {
                let names = [
                    "gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z",
                ];
                channel = names.iter().position(|n| *n == name);
                continue;
            }
            if !(line.ends_with("inside |") || line.ends_with("**OUTSIDE** |")) {
                continue;
            }
            let tau: f64 = line.split('|').nth(1).unwrap().trim().parse().unwrap();
            // The PSD rows (a table has none) would start with a frequency.
            let ch = channel.expect("a row under a channel's heading");
            if tau >= from[ch] - 1e-9 {
                rows += 1;
                assert!(
                    line.ends_with("inside |"),
                    "{unit} channel {ch}: {line}\n{md}"
                );
            }
        }
        // 6 channels × the table's τ from 3Δt or 5Δt to T/8 (900 s, 1500 s): 81 and 79.
        assert!(rows >= 6 * 79, "{unit}: {rows}");
        if unit == "adis16448" {
            let bumps: Vec<&str> = md
                .lines()
                .filter(|l| l.contains(": broad resonance "))
                .collect();
            assert!(
                bumps.len() == 1 && bumps[0].starts_with("- gyro z: "),
                "{bumps:?}"
            );
        }
    }
}

/// A recording of the sensor-fusion data set in the folder `set` (its README), its register
/// counts written as the CSV a user has: deg/s and g, no time column.
fn mpu6050_csv(set: &Path, name: &str, dir: &Path) -> std::path::PathBuf {
    let src = set.join(format!("mpu6050-{name}-counts.csv"));
    let text = std::fs::read_to_string(&src).unwrap();
    let mut csv = String::from("gx,gy,gz,ax,ay,az\n");
    for line in text.lines().skip(1) {
        let row: Vec<String> = line
            .split(',')
            .enumerate()
            .map(|(i, c)| {
                let count: f64 = c.parse().unwrap();
                format!("{}", count / if i < 3 { 131.0 } else { 4096.0 })
            })
            .collect();
        csv.push_str(&row.join(","));
        csv.push('\n');
    }
    let out = dir.join(format!("mpu6050-{name}.csv"));
    std::fs::write(&out, csv).unwrap();
    out
}

/// The real MPU-6050's 655 s static recording, whole (65 067 samples; sunsided/sensor-fusion,
/// EUPL-1.2), fitted as a user fits it: without the host's time tags (bursts of reads, which
/// `fit` refuses; the script `scripts/fit_real.sh` shows that) at its mean rate of 99.32 Hz. The
/// LSBs of its ±250 deg/s and ±8 g ranges, 1/131 deg/s and 1/4096 g, are read from the lattice
/// to the template's eight digits, and a record simulated from the template closes at every
/// octave from Δt to T/8 (13) and every PSD band from 0.01 Hz to the Nyquist frequency (19) on
/// every channel. Its record of a turn about z is refused as not static, and leaves no file.
#[test]
fn a_real_mpu6050_recording_closes_and_a_moving_one_is_refused() {
    let test = "a_real_mpu6050_recording_closes_and_a_moving_one_is_refused";
    let Some(set) = public_data::set("sensor-fusion", test) else {
        return;
    };
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let rate = 99.32;
    let csv = mpu6050_csv(&set, "static", d);
    let (out, report) = (d.join("mpu6050.toml"), d.join("mpu6050.md"));
    let flags = [
        "--rate",
        "99.32",
        "--gyro-unit",
        "deg/s",
        "--accel-unit",
        "g",
    ];
    let mut args = vec!["fit", p(&csv), "-o", p(&out), "--report", p(&report)];
    args.extend(flags);
    ok(imu_emu(&args));
    let m = template::load(out.to_str().unwrap()).unwrap();
    for (sensor, lsb) in [
        (&m.gyro, 1f64.to_radians() / 131.0),
        (&m.accel, imu_emu::units::G0 / 4096.0),
    ] {
        let rate_lsb = match sensor.quantization {
            Some(imu_emu::units::Lsb::Rate(q)) => q,
            Some(imu_emu::units::Lsb::Increment(q)) => q * rate,
            None => panic!("no LSB read: {m:?}"),
        };
        // Eight significant digits written: half a unit of the last is 5e-8 of the value.
        assert!((rate_lsb / lsb - 1.0).abs() < 5e-8, "{rate_lsb} vs {lsb}");
    }
    let md = std::fs::read_to_string(&report).unwrap();
    let names = [
        "gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z",
    ];
    for name in names {
        let want =
            format!("- {name}: Allan deviation 13 of 13 octaves inside; PSD 19 of 19 bands inside");
        assert!(md.contains(&want), "{want}\n{md}");
    }
    // No knock or spike in it: nothing is left out.
    assert!(md.contains("## Transients\n\nNone"), "{md}");
    // Every kept figure's printed gain clears the gate printed beside it (it once did not:
    // B on gyro x with "Δχ² = -4.205 (> 11.3 to be kept)", a plain χ² difference against a
    // fit without it that took two other terms).
    let toml = std::fs::read_to_string(&out).unwrap();
    let mut gates = 0;
    for line in toml
        .lines()
        .filter(|l| l.contains("to be kept)") && l.contains("Δχ² = "))
    {
        // The number written right after `marker`.
        let after = |marker: &str| -> f64 {
            let rest = line.split(marker).nth(1).unwrap();
            rest.split(' ').next().unwrap().parse().unwrap()
        };
        let (gain, gate) = (after("Δχ² = "), after("(> "));
        assert!(gain > gate, "{line}");
        gates += 1;
    }
    assert!(gates >= 8, "{toml}");

    let moving = mpu6050_csv(&set, "moving", d);
    let refused = d.join("moving.toml");
    let mut args = vec!["fit", p(&moving), "-o", p(&refused), "--rate", "100"];
    args.extend(&flags[2..]);
    let e = err(imu_emu(&args));
    assert!(e.contains("not a static recording"), "{e}");
    assert!(!refused.exists());
}
