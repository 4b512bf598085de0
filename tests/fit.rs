//! `imu-emu fit` closure: a recording simulated from a template with every stochastic term the
//! template can hold → the fit recovers each term within its stated 99 % interval; a record
//! simulated from the fitted template has an Allan deviation inside the recording's band at
//! every octave from Δt to T/8. And the command end to end: template that loads, report, plot,
//! spectral lines as vibration sines, bad input named.

mod common;

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use common::cli::{err, imu_emu, ok};
use imu_emu::errors::template::{self, ImuModel};
use imu_emu::fit::closure;
use imu_emu::fit::compare::{fit_all, fit_all_with_filter, triad_lsbs};
use imu_emu::fit::gmwm::{COMPONENTS, Component};
use imu_emu::fit::template::{Provenance, template_toml};
use tempfile::TempDir;

/// Every stochastic term, each dominating its own stretch of τ at 20 Hz so that a 29 h record
/// (2^21 samples) separates them: quantization at τ = Δt (23 % of σ²), white noise from 0.1
/// to 2 s, the Gauss–Markov bump near 6 s (T = 3 s), the bias-instability floor from 30 s to
/// 1000 s (above the GM tail 2σ²T/τ from 100 s), the random walk beyond 2000 s, so that
/// T/8 = 13 000 s leaves three octaves where K holds most of σ². 20 Hz rather than a typical
/// 100–400 Hz: the octaves above τ = 1 s, where B, K and the GM component are read, are the
/// same for any rate of the same duration, and 2^21 samples keep the test near a minute on two
/// shared cores. The accelerometer triad has the same structure at other magnitudes.
///
/// The band edges lie on the fit's half-decade grid: an edge off the grid is fitted at a
/// neighbouring grid value and the terms next to it absorb the difference (docs/fit.md shows
/// σ_GM 9 % high for an edge at 30 s).
///
/// K is the term the record knows least: it holds most of σ² only in the last three octaves
/// before T/8, where the edf are a few tens, so its Δχ² is 16–35 against the gate's 6.6 and
/// the gate sometimes leaves it out — legitimately: the record is at the edge of resolving it.
/// Over seeds 11–18 (48 channel fits) K was left out 3 times (accel x seed 11, accel z seeds 15
/// and 17), once per seed at most, and every one of the 285 other figures kept lay inside its
/// 99 % interval. The test runs two seeds and allows K to be left out on at most one channel
/// per seed (for a per-channel miss rate of 1/16, two or more of six has probability 5 %);
/// every other term must be kept, and every kept figure must be inside its interval.
const TRUTH: &str = r#"
name = "truth"
rate_hz = 20
[gyro]
noise = "0.15 deg/sqrt(h)"
bias_gm = { sigma = "14.6 deg/h", tau = "3 s" }
bias_instability = "9.9 deg/h"
bias_instability_band = ["31.6227766 s", "1000 s"]
random_walk = "15.1 deg/h/sqrt(h)"
quantization = "10.7 urad"
[accel]
noise = "0.07 m/s/sqrt(h)"
bias_gm = { sigma = "193 ug", tau = "3 s" }
bias_instability = "131 ug"
bias_instability_band = ["31.6227766 s", "1000 s"]
random_walk = "3.33 ug/sqrt(s)"
quantization = "0.287 mm/s"
"#;

const DT: f64 = 0.05;
const SAMPLES: u64 = 1 << 21;

fn truth() -> ImuModel {
    template::parse(TRUTH, Path::new("truth.toml")).unwrap()
}

/// The true value of component k on an axis of the triad `t` (SI, as the fit reports it).
fn true_value(t: &imu_emu::errors::template::TriadModel, k: Component) -> f64 {
    match k {
        Component::Quantization => match t.quantization {
            Some(imu_emu::units::Lsb::Increment(q)) => q / 12f64.sqrt(),
            _ => unreachable!(),
        },
        Component::WhiteNoise => t.noise[0],
        Component::BiasInstability => t.bias_instability[0],
        Component::RandomWalk => t.random_walk[0],
        Component::Ramp => 0.0,
        Component::GaussMarkov => t.bias_gm.unwrap().0[0],
    }
}

#[test]
fn closure_recovers_every_term_and_reproduces_the_adev() {
    for seed in [11, 12] {
        closure_at(seed);
    }
}

fn closure_at(seed: u64) {
    let m = truth();
    let rec = closure::simulate(m.clone(), DT, SAMPLES, seed, 1 << 14).unwrap();
    let n = rec.samples as usize;
    let c = &rec.channels;
    // As `fit` does: the triads fitted, then each channel's slope tested on its time series.
    // The carry quantizer's outputs sit on the rate grid q/Δt: Q is read from it (the LSB to
    // 1e-9) and the carry mode chosen over rounding, so Q is known rather than fitted.
    let fitted = fit_all_with_filter(&rec);
    assert!(fitted.carry && fitted.filter.is_none(), "seed {seed}");
    let lsb = triad_lsbs(&rec);
    for (s, t) in [&m.gyro, &m.accel].into_iter().enumerate() {
        let Some(imu_emu::units::Lsb::Increment(q)) = t.quantization else {
            panic!("{:?}", t.quantization)
        };
        let got = lsb[s].unwrap() * DT;
        assert!(
            (got / q - 1.0).abs() < 1e-9,
            "seed {seed}: {got:e} vs {q:e}"
        );
    }
    let fits = fitted.fits;
    let mut missed = Vec::new();
    let mut k_left_out = Vec::new();
    for (ch, f) in fits.iter().enumerate() {
        let f = f.as_ref().unwrap();
        let triad = if ch < 3 { &m.gyro } else { &m.accel };
        for k in [
            Component::WhiteNoise,
            Component::BiasInstability,
            Component::RandomWalk,
            Component::GaussMarkov,
        ] {
            let want = true_value(triad, k);
            match f.estimate(k) {
                Some(e) if e.lo <= want && want <= e.hi => {}
                None if k == Component::RandomWalk => k_left_out.push(ch),
                e => missed.push(format!("channel {ch} {k:?}: true {want:e}, fitted {e:?}")),
            }
        }
        // The gain printed beside each kept figure clears the gate it printed: kept exactly
        // when the penalised search kept it.
        for k in COMPONENTS {
            if let Some(e) = f.estimate(k) {
                assert!(e.gain > k.penalty(), "channel {ch} {k:?}: {e:?}");
            }
        }
        let (lo, hi) = f.gm_tau_interval.unwrap();
        if !(lo <= 3.0 && 3.0 <= hi) {
            missed.push(format!("channel {ch} T: [{lo}, {hi}]"));
        }
        // No ramp was simulated: none is kept (the time-domain test ran on every channel).
        assert!(f.estimate(Component::Ramp).is_none());
        let t = f
            .ramp
            .expect("a recording's channels are tested for a ramp");
        assert!(!t.kept, "seed {seed} channel {ch}: {t:?}");
    }
    assert!(missed.is_empty(), "seed {seed}:\n{}", missed.join("\n"));
    assert!(
        k_left_out.len() <= 1,
        "seed {seed}: K left out on {k_left_out:?}"
    );

    // The fitted template, as written and loaded, simulated with another seed.
    let prov = Provenance {
        name: "fitted".into(),
        source: "closure".into(),
        samples: rec.samples,
        dt: DT,
        lsb,
        filter: None,
        carry: true,
        resonances: Vec::new(),
        table: false,
        missing: [false; 6],
    };
    let text = template_toml(&prov, &fits, &vec![Vec::new(); 6]);
    let fitted = template::parse(&text, Path::new("fitted.toml")).unwrap();
    let sim = closure::simulate(fitted, DT, SAMPLES, seed + 100, 1 << 14).unwrap();
    for ch in 0..6 {
        let model = &fits[ch].as_ref().unwrap().model;
        let pts = closure::compare(&c[ch].adev, &sim.channels[ch].adev, model, n);
        // Octaves m = 1 … 2^18 (τ = 0.05 s … 13 107 s = T/8).
        assert_eq!(pts.len(), 19);
        for p in &pts {
            assert!(p.inside(), "seed {seed} channel {ch}: {p:?}");
        }
    }
}

/// The check can fail: the same closure against a template whose gyro white noise is 20 %
/// high leaves the short-τ octaves (white-noise dominated, edf in the 10⁵–10⁶) far outside.
#[test]
fn closure_catches_a_wrong_template() {
    let rec = closure::simulate(truth(), DT, 1 << 16, 11, 1 << 12).unwrap();
    let wrong = template::parse(
        &TRUTH.replace("0.15 deg/sqrt(h)", "0.18 deg/sqrt(h)"),
        Path::new("wrong.toml"),
    )
    .unwrap();
    let sim = closure::simulate(wrong, DT, 1 << 16, 12, 1 << 12).unwrap();
    let c = &rec.channels[0];
    let f = imu_emu::fit::gmwm::fit_axis(&c.adev, rec.samples as usize, DT).unwrap();
    let pts = closure::compare(
        &c.adev,
        &sim.channels[0].adev,
        &f.model,
        rec.samples as usize,
    );
    assert!(!pts[1].inside() && !pts[2].inside(), "{pts:?}");
}

/// A CSV recording with a 0.5 Hz line on gyro x: `fit` writes a template that loads and
/// simulates, a report with the closure check, a PNG, and the line as a vibration sine at its
/// frequency (within one PSD bin, 20/16384 Hz) and amplitude (±5 %: the line stands about
/// 1500× above the background, 15 segments).
#[test]
fn fit_command_end_to_end() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    std::fs::write(d.join("truth.toml"), TRUTH).unwrap();
    std::fs::write(
        d.join("scene.toml"),
        "[trajectory]\nscene = \"static\"\n[[vibration.sine]]\nsensor = \"gyro\"\naxis = \"x\"\n\
         amplitude = \"0.01 deg/s\"\nfrequency = \"0.5 Hz\"\n",
    )
    .unwrap();
    let rec = d.join("rec.csv");
    ok(imu_emu([
        OsStr::new("generate"),
        d.join("scene.toml").as_os_str(),
        OsStr::new("--imu"),
        d.join("truth.toml").as_os_str(),
        OsStr::new("--rate"),
        OsStr::new("20"),
        OsStr::new("--duration"),
        OsStr::new("6553.6"),
        OsStr::new("-o"),
        rec.as_os_str(),
    ]));
    let unit = d.join("unit.toml");
    let out = ok(imu_emu([
        OsStr::new("fit"),
        rec.as_os_str(),
        OsStr::new("-o"),
        unit.as_os_str(),
        OsStr::new("--report"),
        d.join("r.md").as_os_str(),
        OsStr::new("--plot"),
        d.join("r.png").as_os_str(),
        OsStr::new("--sines"),
        d.join("lines.toml").as_os_str(),
    ]));
    assert!(out.contains("| gyro x | white noise |"), "{out}");
    let m = template::load(unit.to_str().unwrap()).unwrap();
    assert_eq!(m.name, "unit");
    // No ramp simulated: the time-domain test ran on every channel and kept none.
    let text = std::fs::read_to_string(&unit).unwrap();
    assert_eq!(
        text.matches("# rate ramp: not kept on any axis").count(),
        2,
        "{text}"
    );
    assert!(
        out.contains("## Rate ramp") && !out.contains("| yes |"),
        "{out}"
    );
    // Gyro y (gyro x carries the line, which the Allan-variance fit sees as noise near
    // τ = 1/(2f)): N within 2 % (its 99 % interval here is ±1.5 %).
    let n = m.gyro.noise[1] / (0.15f64.to_radians() / 60.0);
    assert!((n - 1.0).abs() < 0.02, "{n}");
    let report = std::fs::read_to_string(d.join("r.md")).unwrap();
    assert!(
        report.contains("## Closure")
            && report.contains("gyro y: Allan deviation 15 of 15 octaves inside"),
        "{report}"
    );
    let png = std::fs::read(d.join("r.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let lines = std::fs::read_to_string(d.join("lines.toml")).unwrap();
    let scene: toml::Table = lines.parse().unwrap();
    let sines = scene["vibration"]["sine"].as_array().unwrap();
    assert_eq!(sines.len(), 1, "{lines}");
    let s = &sines[0];
    assert_eq!(s["sensor"].as_str(), Some("gyro"));
    assert_eq!(s["axis"].as_str(), Some("x"));
    let f: f64 = s["frequency"]
        .as_str()
        .unwrap()
        .trim_end_matches(" Hz")
        .parse()
        .unwrap();
    assert!((f - 0.5).abs() < 20.0 / 16384.0, "{f}");
    let a: f64 = s["amplitude"]
        .as_str()
        .unwrap()
        .trim_end_matches(" deg/s")
        .parse()
        .unwrap();
    assert!((a / 0.01 - 1.0).abs() < 0.05, "{a}");
    // The scene of lines and the fitted template run together.
    ok(imu_emu([
        OsStr::new("generate"),
        d.join("lines.toml").as_os_str(),
        OsStr::new("--imu"),
        unit.as_os_str(),
        OsStr::new("--duration"),
        OsStr::new("1"),
        OsStr::new("-o"),
        d.join("again.csv").as_os_str(),
    ]));
}

/// Bad input is named (file, line, column) and leaves no output file behind.
#[test]
fn fit_bad_input_is_named_and_writes_nothing() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let f = d.join("bad.csv");
    std::fs::write(
        &f,
        "t,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n0.01,1,2,3,4,5,6\n0.02,1,2,x,4,5,6\n",
    )
    .unwrap();
    let unit = d.join("unit.toml");
    let path = f.to_str().unwrap();
    let e = err(imu_emu(["fit", path, "-o", unit.to_str().unwrap()]));
    assert!(
        e.contains(&format!(
            "{path}:3: column 4 (`gyro_z`): `x` is not a number"
        )),
        "{e}"
    );
    assert!(!unit.exists());
    let e = err(imu_emu(["fit", "no-such-file.csv"]));
    assert!(e.contains("no-such-file.csv"), "{e}");
    let e = err(imu_emu(["fit", path, "--plot", "x.jpg"]));
    assert!(e.contains("x.jpg") && e.contains(".png or .svg"), "{e}");
}

/// A rate ramp (template key `ramp`) simulated on top of white noise, ±50 deg/h/h on the
/// gyros, T = 2^17 × 0.05 s = 6554 s: the time-domain test keeps it on every gyro axis with
/// its sign, the true R inside its 99 % interval, and none on the accelerometers; the other
/// figures are fitted around the line (N inside its interval, no random walk from the
/// ramp); the template carries `ramp` as a real key that loads as the fitted slope to its
/// 4 written digits.
///
/// Power. Under white noise alone σ(b̂) = √(12N²/T³) = 1.6e-8 deg/s² against R = 3.9e-6
/// deg/s²: z ≈ 240. But the gate's σ comes from the fit without a ramp, where a random walk
/// takes the ramp's rise R²τ²/2: matched at τ, K² = 3R²τ/2, and σ(b̂) = √(6K²/(5T)) gives
/// z = √(T/(1.8τ)), scale-free — 2.1 if K were matched at T/8. The Allan-variance fit
/// cannot match a τ² rise over the octaves with a τ term and weighs the short octaves
/// most, so K comes out far lower: the z printed on failure shows the margin.
#[test]
fn a_ramp_is_fitted_and_written_as_a_key() {
    let truth = template::parse(
        "name = \"ramp\"\n[gyro]\nnoise = \"0.15 deg/sqrt(h)\"\nramp = [\"50 deg/h/h\", \"-50 deg/h/h\", \"50 deg/h/h\"]\n\
         [accel]\nnoise = \"0.07 m/s/sqrt(h)\"\n",
        Path::new("ramp.toml"),
    )
    .unwrap();
    let samples = 1 << 17;
    let rec = closure::simulate(truth.clone(), DT, samples, 12, 1 << 12).unwrap();
    let fits = fit_all(&rec);
    let mut fitted = Vec::new();
    for (ch, f) in fits.iter().enumerate() {
        let f = f.as_ref().unwrap();
        let t = f.ramp.unwrap();
        if ch >= 3 {
            assert!(!t.kept, "accel {ch}: {t:?}");
            continue;
        }
        let r = truth.gyro.ramp[ch];
        let (lo, hi) = t
            .interval
            .unwrap_or_else(|| panic!("axis {ch} not kept: {t:?}"));
        assert!(lo <= r && r <= hi, "axis {ch}: R {r:e} vs {t:?}");
        let n = f.estimate(Component::WhiteNoise).unwrap();
        let want = truth.gyro.noise[ch];
        assert!(
            n.lo <= want && want <= n.hi,
            "axis {ch}: N {want:e} vs {n:?}"
        );
        assert!(
            f.estimate(Component::RandomWalk).is_none(),
            "axis {ch}: {f:?}"
        );
        fitted.push(t.slope);
    }
    let prov = Provenance {
        name: "fitted".into(),
        source: "ramp".into(),
        samples,
        dt: DT,
        lsb: [None; 2],
        filter: None,
        carry: false,
        resonances: Vec::new(),
        table: false,
        missing: [false; 6],
    };
    let text = template_toml(&prov, &fits, &vec![Vec::new(); 6]);
    let m = template::parse(&text, Path::new("fitted.toml")).unwrap();
    for (axis, want) in fitted.iter().enumerate() {
        let got = m.gyro.ramp[axis];
        assert!(
            (got - want).abs() <= 1e-3 * want.abs(),
            "axis {axis}: {got:e} vs {want:e}\n{text}"
        );
    }
    assert!(m.accel.ramp.iter().all(|&r| r == 0.0), "{text}");
}

/// A static record (CSV, in `d`) of white noise of densities `gyro` and `accel` at `rate` Hz
/// for `duration` s.
fn white_static(d: &Path, gyro: &str, accel: &str, rate: &str, duration: &str) -> PathBuf {
    std::fs::write(
        d.join("truth.toml"),
        format!("name = \"t\"\n[gyro]\nnoise = \"{gyro}\"\n[accel]\nnoise = \"{accel}\"\n"),
    )
    .unwrap();
    std::fs::write(d.join("scene.toml"), "[trajectory]\nscene = \"static\"\n").unwrap();
    let out = d.join("white.csv");
    ok(imu_emu([
        OsStr::new("generate"),
        d.join("scene.toml").as_os_str(),
        OsStr::new("--imu"),
        d.join("truth.toml").as_os_str(),
        OsStr::new("--rate"),
        OsStr::new(rate),
        OsStr::new("--duration"),
        OsStr::new(duration),
        OsStr::new("-o"),
        out.as_os_str(),
    ]));
    out
}

/// A recording of some axes only (a CSV with gyro x and accel z, as a single-axis test
/// gives): `fit` fits those, says which channels the input lacks in the report and the
/// template (written error-free there, with a comment), checks the closure on the two it has,
/// and draws a panel per channel it has. White noise at 20 Hz, 2^16 samples: N inside its
/// 99 % interval, the closure inside everywhere.
#[test]
fn a_recording_of_some_axes_is_fitted_on_those() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let full = white_static(d, "0.15 deg/sqrt(h)", "0.07 m/s/sqrt(h)", "20", "3276.8");
    // Keep t, gyro_x and accel_z, by header name.
    let text = std::fs::read_to_string(&full).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let keep = [col("t"), col("gyro_x"), col("accel_z")];
    let mut sub = String::from("t,gyro_x,accel_z\n");
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        sub.push_str(&keep.map(|i| f[i]).join(","));
        sub.push('\n');
    }
    let rec = d.join("two.csv");
    std::fs::write(&rec, sub).unwrap();
    let unit = d.join("unit.toml");
    let out = ok(imu_emu([
        OsStr::new("fit"),
        rec.as_os_str(),
        OsStr::new("-o"),
        unit.as_os_str(),
        OsStr::new("--plot"),
        d.join("r.svg").as_os_str(),
    ]));
    assert!(
        out.contains("| gyro y | (not in the input) |")
            && out.contains("Not in the input: gyro y, gyro z, accel x, accel y.")
            && out.contains(
                "- gyro x: Allan deviation 14 of 14 octaves inside; PSD 15 of 15 bands inside"
            )
            && out.contains(
                "- accel z: Allan deviation 14 of 14 octaves inside; PSD 15 of 15 bands inside"
            )
            && !out.contains("- gyro y:")
            && !out.contains("### accel x"),
        "{out}"
    );
    let toml = std::fs::read_to_string(&unit).unwrap();
    assert!(
        toml.contains("# not in the input: y, z (written error-free")
            && toml.contains("# not in the input: x, y (written error-free"),
        "{toml}"
    );
    let m = template::load(unit.to_str().unwrap()).unwrap();
    assert_eq!((m.gyro.noise[1], m.gyro.noise[2]), (0.0, 0.0));
    assert_eq!((m.accel.noise[0], m.accel.noise[1]), (0.0, 0.0));
    // N's 99 % interval at 2^16 samples is about ±1 % (2.58/√(2^16)·…); 3 % leaves room.
    let n = m.gyro.noise[0] / (0.15f64.to_radians() / 60.0);
    assert!((n - 1.0).abs() < 0.03, "{n}");
    let a = m.accel.noise[2] / (0.07 / 60.0);
    assert!((a - 1.0).abs() < 0.03, "{a}");
    // Two rows (gyro, accel) of two panels each: the channel's ADEV and its sensor's PSD.
    let svg = std::fs::read_to_string(d.join("r.svg")).unwrap();
    assert_eq!(svg.matches("two.csv: ").count(), 4, "panel titles");
}

/// A knock on the bench in a static record: a damped 15 Hz ring (decay 0.2 s) of 50 noise σ
/// on gyro x and accel z at t = 600 s of a 100 Hz, 2^17-sample record of white noise.
/// `fit` finds it (one transient, at 600 s), leaves it out with a second on each side, and
/// the fit is that of the clean record: N inside 2 %, no broad resonance, the closure inside
/// everywhere. Kept (`--keep-transients`), its energy (≈ 12 500 σ² against the record's
/// 131 072 σ²) is read as a unit's broad resonance at 9–20 Hz on both channels (2.5× the
/// floor): a vibration the unit does not have.
#[test]
fn a_knock_is_found_and_left_out() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let clean = white_static(d, "0.3 deg/sqrt(h)", "0.1 m/s/sqrt(h)", "100", "1310.72");
    // σ per sample of each: N/√Δt.
    let (sg, sa) = (0.3f64.to_radians() / 60.0 / 0.1, 0.1 / 60.0 / 0.1);
    let text = std::fs::read_to_string(&clean).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let cols: Vec<&str> = header.split(',').collect();
    let (gx, az) = (
        cols.iter().position(|c| *c == "gyro_x").unwrap(),
        cols.iter().position(|c| *c == "accel_z").unwrap(),
    );
    let mut knocked = format!("{header}\n");
    for (k, l) in lines.enumerate() {
        let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
        let t = k as f64 * 0.01 - 600.0;
        if t >= 0.0 {
            let ring = (-t / 0.2).exp() * (2.0 * std::f64::consts::PI * 15.0 * t).sin() * 50.0;
            for (c, s) in [(gx, sg), (az, sa)] {
                let v: f64 = f[c].parse().unwrap();
                f[c] = format!("{}", v + ring * s);
            }
        }
        knocked.push_str(&f.join(","));
        knocked.push('\n');
    }
    let rec = d.join("knocked.csv");
    std::fs::write(&rec, knocked).unwrap();
    let report_path = d.join("r.md");
    let fit = |extra: &[&str]| {
        let mut args: Vec<&OsStr> = vec![
            OsStr::new("fit"),
            rec.as_os_str(),
            OsStr::new("--report"),
            report_path.as_os_str(),
        ];
        args.extend(extra.iter().map(OsStr::new));
        let out = imu_emu(args);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        let toml = String::from_utf8(out.stdout).unwrap();
        let m = template::parse(&toml, Path::new("fitted.toml")).unwrap();
        let report = std::fs::read_to_string(d.join("r.md")).unwrap();
        (stderr, m, report)
    };
    let (stderr, m, report) = fit(&[]);
    assert!(
        stderr.contains("1 transient (a knock or a spike)")
            && stderr.contains("at t = 600.0")
            && stderr.contains("left out of the statistics"),
        "{stderr}"
    );
    assert!(report.contains("| 60001–"), "{report}");
    assert!(
        !report.contains("OUTSIDE") && report.contains("## Broad resonances\n\nNone"),
        "{report}"
    );
    let n_az = m.accel.noise[2] / (0.1 / 60.0);
    let n_gx = m.gyro.noise[0] / (0.3f64.to_radians() / 60.0);
    assert!(
        (n_az - 1.0).abs() < 0.02 && (n_gx - 1.0).abs() < 0.02,
        "{n_az} {n_gx}"
    );
    let (stderr, _, report) = fit(&["--keep-transients"]);
    assert!(stderr.contains("kept (--keep-transients)"), "{stderr}");
    assert!(
        report.contains("- gyro x: broad resonance")
            && report.contains("- accel z: broad resonance"),
        "{report}"
    );
}

/// Spikes all through a record (40σ on gyro y at about 1 sample in 500, at pseudo-random
/// places, in 2^15 samples): leaving each out with a second on each side would take about 40 %
/// of the record, so they are the noise's own tails — kept, and `fit` says so. The template's
/// Gaussian white noise then carries their variance (n·1600σ² over 32 768 samples: with
/// n ≈ 65, N ≈ 2× on gyro y).
#[test]
fn spikes_all_through_a_record_are_kept_as_heavy_tails() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let clean = white_static(d, "0.3 deg/sqrt(h)", "0.1 m/s/sqrt(h)", "100", "327.68");
    let sg = 0.3f64.to_radians() / 60.0 / 0.1;
    let text = std::fs::read_to_string(&clean).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let gy = header.split(',').position(|c| c == "gyro_y").unwrap();
    let mut spiked = format!("{header}\n");
    let (mut state, mut spikes) = (12345u64, 0);
    for l in lines {
        let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
        // A 64-bit LCG (Knuth's MMIX constants); its top bits pick 1 sample in 512.
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        if state >> 55 == 0 {
            let v: f64 = f[gy].parse().unwrap();
            f[gy] = format!("{}", v + 40.0 * sg);
            spikes += 1;
        }
        spiked.push_str(&f.join(","));
        spiked.push('\n');
    }
    assert!((40..100).contains(&spikes), "{spikes}");
    let rec = d.join("spiked.csv");
    std::fs::write(&rec, spiked).unwrap();
    let out = imu_emu([OsStr::new("fit"), rec.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    // Two spikes closer than 2 s are one transient.
    assert!(
        stderr.contains("transients (knocks or spikes)")
            && stderr.contains("on gyro y")
            && stderr.contains("the noise is heavy-tailed; kept"),
        "{stderr}"
    );
    let m = template::parse(
        &String::from_utf8(out.stdout).unwrap(),
        Path::new("fitted.toml"),
    )
    .unwrap();
    let n = m.gyro.noise[1] / (0.3f64.to_radians() / 60.0);
    assert!(n > 1.3, "{n}");
}

/// Samples a logger dropped (time steps of 2Δt and 5Δt in a CSV) are put back on the time
/// grid and left out of every statistic: `fit` accepts the record, says where they were, and
/// fits and closes as on the whole record; a record that lost more than 1 % is refused as not
/// uniformly sampled, as before.
#[test]
fn dropped_samples_are_put_back_and_left_out() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let whole = white_static(d, "0.3 deg/sqrt(h)", "0.1 m/s/sqrt(h)", "100", "655.36");
    let text = std::fs::read_to_string(&whole).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let rows: Vec<&str> = lines.collect();
    let write = |name: &str, keep: &dyn Fn(usize) -> bool| {
        let mut s = format!("{header}\n");
        for (k, l) in rows.iter().enumerate().filter(|(k, _)| keep(*k)) {
            let _ = k;
            s.push_str(l);
            s.push('\n');
        }
        let p = d.join(name);
        std::fs::write(&p, s).unwrap();
        p
    };
    let gone = [10_000, 30_000, 30_001, 30_002, 30_003, 50_000];
    let rec = write("dropped.csv", &|k| !gone.contains(&k));
    let report = d.join("r.md");
    let out = imu_emu([
        OsStr::new("fit"),
        rec.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("6 samples dropped in 3 gaps (the longest 4 at t = 300.04 s"),
        "{stderr}"
    );
    let report = std::fs::read_to_string(&report).unwrap();
    assert!(
        report.contains("## Dropped samples") && report.contains("65536 samples at 100.0 Hz"),
        "{report}"
    );
    assert!(!report.contains("OUTSIDE"), "{report}");
    let m = template::parse(&String::from_utf8(out.stdout).unwrap(), Path::new("t.toml")).unwrap();
    let n_gx = m.gyro.noise[0] / (0.3f64.to_radians() / 60.0);
    assert!((n_gx - 1.0).abs() < 0.02, "{n_gx}");
    // One sample in 80 lost (1.25 %): not a few drops; refused as before.
    let sparse = write("sparse.csv", &|k| k % 80 != 40);
    let out = imu_emu([OsStr::new("fit"), sparse.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("needs uniformly sampled data"),
        "{stderr}"
    );
}
