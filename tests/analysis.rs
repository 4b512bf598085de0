//! The analysis against closed forms (Allan deviation of white noise, random walk and a
//! quantized ramp; Welch PSD of a sinusoid in white noise), the IEEE term fit against known
//! synthetic terms, and `imu-emu analyze` end to end: LN-200 terms within their bands, a
//! wrong template caught, plots valid, foreign CSV columns and units, bad input named.

mod common;

use common::cli::{err, imu_emu, ok, p};
use imu_emu::analysis::analyzer::Analyzer;
use imu_emu::analysis::confidence::{NoiseType, edf};
use imu_emu::analysis::conformance::term_rows;
use imu_emu::analysis::fit::Term;
use imu_emu::analysis::octave_adev::OctaveAdev;
use imu_emu::analysis::psd::Welch;
use imu_emu::errors::process::{Flicker, QuantMode, Quantizer, RandomWalk};
use imu_emu::rng::NormalStream;
use tempfile::TempDir;

// ---------------------------------------------------------------------------------------------
// Closed forms.

/// White rate noise of density N: σ(τ) = N/√τ. 200 000 samples; every octave with m ≤ n/50
/// (edf ≥ 66) within 4 of its own 68 % half-widths (≈ 1σ).
#[test]
fn adev_of_white_noise() {
    let (density, dt, n) = (2.0e-3, 0.01f64, 200_000);
    let mut s = NormalStream::new(101, "analysis/white");
    let mut acc = OctaveAdev::new();
    (0..n).for_each(|_| acc.push(7.0 + density / dt.sqrt() * s.draw()));
    let pts = acc.points(dt, |_| NoiseType::WhiteRate);
    assert_eq!(pts.len(), 17); // m = 1 … 2^16 < n/2
    for p in pts.iter().filter(|p| p.m <= n / 50) {
        let expect = density / p.tau.sqrt();
        assert!(p.lo < p.adev && p.adev < p.hi);
        assert!(
            (p.adev - expect).abs() <= 4.0 * (p.hi - p.lo) / 2.0,
            "τ {}: {:e} vs {expect:e} [{:e}, {:e}]",
            p.tau,
            p.adev,
            p.lo,
            p.hi
        );
    }
}

/// Random walk b⁺ = b + K√Δt n: exactly σ² = K²τ/3·(1 + 1/(2m²)) for the discrete walk.
/// Mean σ² over 8 records of 2^17 samples; tolerance 4σ of that mean with the random-walk
/// edf of NIST SP 1065 (from ±4.4 % at m = 64 to ±18 % at m = 1024).
#[test]
fn adev_of_random_walk() {
    let (k, dt, n, records) = (3.0e-4, 0.01f64, 1usize << 17, 8);
    let ms = [64usize, 256, 1024];
    let mut mean_var = [0.0; 3];
    for r in 0..records {
        let mut w = RandomWalk::new(k, dt, NormalStream::new(r, "analysis/rw"));
        let mut acc = OctaveAdev::new();
        (0..n).for_each(|_| acc.push(w.step()));
        let pts = acc.points(dt, |_| NoiseType::RandomWalkRate);
        for (v, &m) in mean_var.iter_mut().zip(&ms) {
            let p = pts.iter().find(|p| p.m == m).unwrap();
            *v += p.adev * p.adev / records as f64;
        }
    }
    for (&m, &var) in ms.iter().zip(&mean_var) {
        let tau = m as f64 * dt;
        let mf = m as f64;
        let exact = k * k * tau / 3.0 * (1.0 + 1.0 / (2.0 * mf * mf));
        let nu = edf(NoiseType::RandomWalkRate, n + 1, m);
        let tol = 4.0 * (2.0 / (nu * records as f64)).sqrt();
        assert!(
            (var / exact - 1.0).abs() < tol,
            "m {m}: ratio {} tol {tol}",
            var / exact
        );
    }
}

/// A rate ramp R integrated into increments and quantized with carry to an LSB q. The
/// carried angle error stays within ±q/2, so each second difference is off by at most 2q and
/// |σ(τ) − Rτ/√2| ≤ 2q/(√2·τ) at every τ — a deterministic bound, tight at long τ.
#[test]
fn adev_of_quantized_ramp() {
    let (r, dt, n, q) = (1.0e-3, 0.01f64, 100_000u64, 1.0e-6);
    let mut quant = Quantizer::new(q, QuantMode::Carry);
    let mut acc = OctaveAdev::new();
    for k in 0..n {
        // ∫ R t dt over (kΔt, (k+1)Δt] = R Δt² (k + ½).
        let inc = quant.apply(r * dt * dt * (k as f64 + 0.5));
        acc.push(inc / dt);
    }
    let pts = acc.points(dt, |_| NoiseType::RandomWalkRate);
    assert_eq!(pts.len(), 16);
    for p in &pts {
        let ramp = r * p.tau / std::f64::consts::SQRT_2;
        let bound = 2.0 * q / (std::f64::consts::SQRT_2 * p.tau);
        assert!(
            (p.adev - ramp).abs() <= bound * (1.0 + 1e-9),
            "τ {}: {:e} vs {ramp:e} ± {bound:e}",
            p.tau,
            p.adev
        );
    }
    // The quantization shows at short τ: the curve is well above the bare ramp there.
    assert!(pts[0].adev > 3.0 * r * pts[0].tau / std::f64::consts::SQRT_2);
}

/// A sinusoid of amplitude A = 1 at 12.5 Hz (on a bin) in white noise σ = 0.1 at 100 Hz:
/// the peak sits on 12.5 Hz, the power within ±3 bins (Hann main lobe ±2) integrates to A²/2,
/// and the floor is 2σ²/f_s. 2^18 samples, segments of 4096: 127 segments × ~1900 bins
/// averaged put the floor's relative 1σ below 0.2 %; the 2 % tolerance also covers the
/// peak's leakage that is left out (< 1e-4 of A²/2 beyond ±3 bins for a periodic Hann).
#[test]
fn psd_of_sinusoid_in_white_noise() {
    let (fs, n, f0, sigma) = (100.0, 1usize << 18, 12.5, 0.1);
    let dt = 1.0 / fs;
    let mut s = NormalStream::new(102, "analysis/psd");
    let mut w = Welch::new(4096);
    for k in 0..n {
        let t = k as f64 * dt;
        w.push((2.0 * std::f64::consts::PI * f0 * t).sin() + sigma * s.draw());
    }
    let p = w.finish(dt);
    assert_eq!(p.segments, 127);
    let df = p.freq[1];
    let (kmax, _) = p
        .density
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap();
    assert!((p.freq[kmax] - f0).abs() < df / 2.0);
    let power: f64 = p.density[kmax - 3..=kmax + 3].iter().sum::<f64>() * df;
    assert!((power / 0.5 - 1.0).abs() < 0.02, "peak power {power}");
    let floor: Vec<f64> = p
        .freq
        .iter()
        .zip(&p.density)
        .filter(|(f, _)| (**f - f0).abs() > 1.0 && **f > 0.5 && **f < fs / 2.0 - 0.5)
        .map(|(_, d)| *d)
        .collect();
    let mean = floor.iter().sum::<f64>() / floor.len() as f64;
    let expect = 2.0 * sigma * sigma / fs;
    assert!(
        (mean / expect - 1.0).abs() < 0.02,
        "floor {mean:e} vs {expect:e}"
    );
}

// ---------------------------------------------------------------------------------------------
// The fit.

/// Synthetic gyro x: white noise N, bias instability B (the generator's Gauss–Markov bank,
/// band 1 s … 10⁵ s) and rate random walk K, 2^21 samples at 100 Hz (5.8 h), 8 seeds.
///
/// * Coverage: each term's 99 % band from `term_rows` (module `conformance`) should miss
///   about 1 % of the time; at most 2 misses of the 24 checks are allowed (P(≥ 3) = 0.2 % for
///   a true 1 % rate). Seen: 1 (seed 1 K — the record's slowest octaves happened to show
///   little random walk and the fit dropped it).
/// * Unbiasedness: the mean fitted value over the seeds is within 4σ of the specified one,
///   σ taken from the band (half-width/2.576 per record, /√8 for the mean).
/// * A template whose N is 20 % off fails on N for every seed.
#[test]
fn fit_recovers_n_b_k_within_length_bands() {
    let (dt, n, seeds) = (0.01f64, 1usize << 21, 8u64);
    let (nn, b, k) = (1.0e-4, 2.0e-5, 1.0e-6);
    let mut model = imu_emu::errors::template::load("ideal").unwrap();
    model.gyro.noise = [nn; 3];
    model.gyro.bias_instability = [b; 3];
    model.gyro.bias_instability_band = (1.0, 1.0e5);
    model.gyro.random_walk = [k; 3];
    let terms = [Term::WhiteNoise, Term::BiasInstability, Term::RandomWalk];
    let mut misses = Vec::new();
    let mut ratio_sum = [0.0; 3];
    let mut half = [0.0; 3];
    for seed in 1..=seeds {
        let mut white = NormalStream::new(seed, "fit/white");
        let mut flicker = Flicker::new(b, (1.0, 1.0e5), dt, |j| {
            NormalStream::new(seed, &format!("fit/flicker/{j}"))
        });
        let mut rw = RandomWalk::new(k, dt, NormalStream::new(seed, "fit/rw"));
        let mut an = Analyzer::new(1 << 12);
        for i in 0..n {
            let y = nn / dt.sqrt() * white.draw() + flicker.step() + rw.step();
            an.push(i as f64 * dt, &[y, 0.0, 0.0, 0.0, 0.0, 0.0]);
        }
        let res = an.finish(dt);
        let rows = term_rows(&model, &res);
        for (i, term) in terms.iter().enumerate() {
            let r = rows
                .iter()
                .find(|r| r.sensor == "gyro" && r.axis == 0 && r.term == *term)
                .unwrap();
            let (lo, hi) = r.band.unwrap();
            if r.pass != Some(true) {
                misses.push(format!(
                    "seed {seed} {term:?}: {:e} not in [{lo:e}, {hi:e}]",
                    r.fitted
                ));
            }
            ratio_sum[i] += r.fitted / r.specified;
            half[i] = (hi - lo) / 2.0 / r.specified;
        }
        let mut wrong = model.clone();
        wrong.gyro.noise = [1.2 * nn; 3];
        let rows = term_rows(&wrong, &res);
        let r = rows.iter().find(|r| r.term == Term::WhiteNoise).unwrap();
        assert_eq!(r.pass, Some(false), "seed {seed}: wrong N accepted");
    }
    assert!(misses.len() <= 2, "{misses:#?}");
    for i in 0..3 {
        let mean = ratio_sum[i] / seeds as f64;
        let tol = 4.0 * half[i] / 2.576 / (seeds as f64).sqrt();
        assert!(
            (mean - 1.0).abs() < tol,
            "{:?}: mean ratio {mean} tol {tol}",
            terms[i]
        );
    }
    // White noise is read to better than ±0.2 % from 5.8 h at 100 Hz.
    assert!(half[0] < 0.002, "N half-width {}", half[0]);
}

// ---------------------------------------------------------------------------------------------
// The command.

/// The LN-200 (white noise and carried LSB quantization, 400 Hz) for 600 s, static: every
/// specified term (Q and N of six channels) within its 99 % band. Over 20 seeds one of the
/// 240 terms fell outside (docs/analysis.md); this seed is the default one (the command exits
/// 0). A template with the gyro noise 30 % low fails on the three gyro N rows and exits 1.
#[test]
fn analyze_ln200_end_to_end() {
    let dir = TempDir::new().unwrap();
    let bin = dir.path().join("ln200.bin");
    ok(imu_emu([
        "generate",
        "--scene",
        "static",
        "--imu",
        "ln200",
        "--rate",
        "400",
        "--duration",
        "600",
        "--format",
        "bin",
        "-o",
        p(&bin),
    ]));
    let png = dir.path().join("adev.png");
    let csv = dir.path().join("curves.csv");
    let out = ok(imu_emu([
        "analyze",
        p(&bin),
        "--imu",
        "ln200",
        "--plot",
        p(&png),
        "--csv",
        p(&csv),
    ]));
    assert!(out.contains("240000 samples"), "{out}");
    assert!(
        out.contains("`ln200`: 12 of 12 specified terms within their bands"),
        "{out}"
    );
    // A valid PNG: signature, IHDR with the requested size, and real content.
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    assert_eq!(&bytes[12..16], b"IHDR");
    assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().unwrap()), 1600);
    assert_eq!(u32::from_be_bytes(bytes[20..24].try_into().unwrap()), 1200);
    assert!(bytes.len() > 20_000, "{} bytes", bytes.len());
    assert_eq!(&bytes[bytes.len() - 8..bytes.len() - 4], b"IEND");
    let curves = std::fs::read_to_string(&csv).unwrap();
    assert!(curves.starts_with("kind,channel,x,y,lo,hi\n"));
    for kind in [
        "adev,gyro_x,",
        "psd,accel_z,",
        "theory_adev,gyro_y,",
        "theory_psd,accel_x,",
    ] {
        assert!(curves.contains(kind), "{kind}");
    }

    let wrong = dir.path().join("wrong.toml");
    std::fs::write(
        &wrong,
        "base = \"ln200\"\n[gyro]\nnoise = \"0.049 deg/sqrt(h)\"\n",
    )
    .unwrap();
    // A FAIL row makes the command fail (exit 1), as `validate` does, with the report and the
    // plot still written and the count on stderr.
    let svg = dir.path().join("adev.svg");
    let run = imu_emu(["analyze", p(&bin), "--imu", p(&wrong), "--plot", p(&svg)]);
    assert_eq!(run.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("template `ln200`: 3 of 12 specified terms FAIL"),
        "{stderr}"
    );
    let out = String::from_utf8(run.stdout).unwrap();
    let failed: Vec<&str> = out.lines().filter(|l| l.ends_with("FAIL")).collect();
    assert_eq!(failed.len(), 3, "{out}");
    assert!(
        failed
            .iter()
            .all(|l| l.starts_with("gyro") && l.contains(" N "))
    );
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"));
    assert!(text.contains("Allan deviation") && text.contains("<polyline"));
}

/// Somebody else's CSV: columns in another order, gyro in deg/s, accelerometers in g, an
/// extra column, no header. With the mapping and units given, the analysis equals that of
/// our own file to the printed digits.
#[test]
fn analyze_foreign_csv_with_columns_and_units() {
    let dir = TempDir::new().unwrap();
    let ours = dir.path().join("ours.csv");
    ok(imu_emu([
        "generate",
        "--scene",
        "static",
        "--imu",
        "adis16488",
        "--rate",
        "200",
        "--duration",
        "60",
        "-o",
        p(&ours),
    ]));
    let text = std::fs::read_to_string(&ours).unwrap();
    let deg = 180.0 / std::f64::consts::PI;
    let g0 = 9.80665;
    let mut foreign = String::new();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        foreign.push_str(&format!(
            "{},{},{},{},7,{},{},{}\n",
            v[0],
            v[4] / g0,
            v[5] / g0,
            v[6] / g0,
            v[1] * deg,
            v[2] * deg,
            v[3] * deg
        ));
    }
    let theirs = dir.path().join("theirs.csv");
    std::fs::write(&theirs, foreign).unwrap();
    let a = ok(imu_emu(["analyze", p(&ours)]));
    let b = ok(imu_emu([
        "analyze",
        p(&theirs),
        "--columns",
        "t,ax,ay,az,-,gx,gy,gz",
        "--gyro-unit",
        "deg/s",
        "--accel-unit",
        "g",
    ]));
    let body = |s: &str| s.lines().skip(1).map(String::from).collect::<Vec<_>>();
    assert_eq!(body(&a), body(&b));
}

/// Frames of a protocol decode straight into the analysis.
#[test]
fn analyze_protocol_frames() {
    let dir = TempDir::new().unwrap();
    let frames = dir.path().join("kvh.bin");
    ok(imu_emu([
        "generate",
        "--scene",
        "static",
        "--imu",
        "ln200",
        "--rate",
        "1000",
        "--duration",
        "4",
        "--format",
        "kvh1750",
        "-o",
        p(&frames),
    ]));
    let out = ok(imu_emu([
        "analyze",
        p(&frames),
        "--format",
        "kvh1750",
        "--rate",
        "1000",
    ]));
    assert!(
        out.contains("frames: 4000 decoded, 0 check failures"),
        "{out}"
    );
    assert!(out.contains("4000 samples, Δt = 0.001 s"), "{out}");
}

/// Bad input names the file, line and field, and never panics.
#[test]
fn analyze_bad_input_is_named() {
    let dir = TempDir::new().unwrap();
    let f = dir.path().join("bad.csv");
    let path = p(&f).to_string();

    std::fs::write(&f, "t,x,y\n0.01,1,2\n").unwrap();
    let e = err(imu_emu(["analyze", &path]));
    assert!(
        e.contains(&path)
            && e.contains("no gyro or accelerometer column")
            && e.contains("--columns"),
        "{e}"
    );

    std::fs::write(
        &f,
        "t,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n0.01,1,2,3,4,5,6\n\n0.02,abc,2,3,4,5,6\n",
    )
    .unwrap();
    let e = err(imu_emu(["analyze", &path]));
    assert!(
        e.contains(&format!(
            "{path}:4: column 2 (`gyro_x`): `abc` is not a number"
        )),
        "{e}"
    );

    std::fs::write(&f, "1,2,3,4,5,6\n1,2,3,4,5,6\n").unwrap();
    let e = err(imu_emu([
        "analyze",
        &path,
        "--columns",
        "gx,gy,gz,ax,ay,az,t",
    ]));
    assert!(
        e.contains(&format!("{path}:1: 6 fields, the column mapping needs 7")),
        "{e}"
    );

    let rows: String = (0..20).map(|k| format!("{k},1,2,3,4,5,6\n")).collect();
    std::fs::write(&f, rows).unwrap();
    let e = err(imu_emu(["analyze", &path, "--columns=-,gx,gy,gz,ax,ay,az"]));
    assert!(e.contains("--rate"), "{e}");
    let e = err(imu_emu(["analyze", &path, "--gyro-unit", "furlong/s"]));
    assert!(e.contains("--gyro-unit") && e.contains("furlong"), "{e}");

    let b = dir.path().join("cut.bin");
    std::fs::write(&b, vec![0u8; 104 * 3 + 50]).unwrap();
    let e = err(imu_emu(["analyze", p(&b)]));
    assert!(
        e.contains("362 bytes is not a whole number of 104-byte records (3 records and 50 bytes;"),
        "{e}"
    );
    // A corrupt record (a NaN rate) is named, not averaged into every statistic.
    let nan = dir.path().join("nan.bin");
    let mut bytes = Vec::new();
    for k in 0..20u32 {
        for i in 0..13 {
            let v = match i {
                0 => f64::from(k + 1) * 0.01,
                2 if k == 12 => f64::NAN,
                _ => 0.0,
            };
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(&nan, bytes).unwrap();
    let e = err(imu_emu(["analyze", p(&nan)]));
    assert!(
        e.contains(&format!(
            "{}: record 12: gyro_y is NaN, not a finite number",
            p(&nan)
        )),
        "{e}"
    );
    let e = err(imu_emu(["analyze", p(&dir.path().join("missing.csv"))]));
    assert!(e.contains("missing.csv"), "{e}");
    let e = err(imu_emu([
        "analyze", &path, "--plot", "x.jpg", "--rate", "10",
    ]));
    assert!(e.contains(".png or .svg"), "{e}");
}

/// A CSV of one axis is analysed on that axis: the others are named as not in the input and
/// get neither a statistics row nor a term row, and the plot has the gyro's two panels only.
#[test]
fn analyze_reads_a_csv_of_one_axis() {
    let dir = TempDir::new().unwrap();
    let f = dir.path().join("one.csv");
    let mut text = String::from("t,gx\n");
    // A deterministic ±1 deg/s square wave of period 2 samples on a 0.5 deg/s offset.
    for k in 0..4096 {
        let v = 0.5 + if k % 2 == 0 { 1.0 } else { -1.0 };
        text.push_str(&format!("{},{v}\n", k as f64 * 0.01));
    }
    std::fs::write(&f, text).unwrap();
    let png = dir.path().join("one.png");
    let out = ok(imu_emu([
        "analyze",
        p(&f),
        "--gyro-unit",
        "deg/s",
        "--plot",
        p(&png),
    ]));
    assert!(out.contains("accel z  (not in the input)"), "{out}");
    assert!(!out.contains("gyro y   N") && !out.contains("inf"), "{out}");
    // mean 0.5 deg/s printed in the stats row.
    assert!(out.contains("gyro x      5.000000e-1"), "{out}");
    assert!(png.exists());
}

/// A named pipe is read once: the analysis comes from that read, and the transients, which
/// need a second, are not looked for — with a warning, and without waiting for a writer that
/// never comes.
#[test]
fn analyze_reads_a_pipe_once() {
    let dir = TempDir::new().unwrap();
    let fifo = dir.path().join("pipe.csv");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(made.success());
    let mut text = String::from("t,gx\n");
    for k in 0..2048 {
        text.push_str(&format!("{},{}\n", k as f64 * 0.01, (k % 3) as f64));
    }
    let path = fifo.clone();
    let writer = std::thread::spawn(move || std::fs::write(path, text).unwrap());
    let out = imu_emu(["analyze", p(&fifo), "--gyro-unit", "deg/s"]);
    writer.join().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("not a regular file") && stderr.contains("were not looked for"),
        "{stderr}"
    );
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("2048 samples"),
        "{stderr}"
    );
}
