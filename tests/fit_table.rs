//! ADEV tables as input: `fit` on a published Allan deviation table, and `analyze
//! --reference` comparing a recording with another recording or a table.

mod common;

use std::ffi::OsStr;
use std::fmt::Write as _;
use std::path::Path;

use common::cli::{err, imu_emu, ok};
use imu_emu::analysis::adev_table::{self, TableOptions};
use imu_emu::errors::template;
use imu_emu::fit::closure;
use imu_emu::fit::compare::fit_all;
use imu_emu::fit::gmwm::{COMPONENTS, Component, Model};
use tempfile::TempDir;

/// A table of a model's exact Allan deviation (every component, band and T on the fit's
/// grids, so that the exact answer is the only one of zero χ²), printed at 17 digits: `fit`
/// gives back every coefficient to the precision the exact-curve fit of `gmwm` reaches
/// (1e-6 relative on σ², set by the least-squares solve of six nearly collinear columns), on
/// the gyro and, at other magnitudes, the accel triad given as per-sensor `g`/`a` columns.
#[test]
fn exact_table_gives_back_the_model() {
    let dt = 0.01;
    let gyro = Model {
        c: [1e-11, 1e-8, 1e-8, 4.4e-12, 0.0, 1e-8],
        band: (10.0, 1000.0),
        gm_tau: 10f64.powf(0.5),
        dt,
        output: Default::default(),
    };
    let accel = Model {
        c: gyro.c.map(|c| c * 4.0),
        ..gyro.clone()
    };
    let mut text = String::from("# record_length = 83886.08 s\ntau_s,g_rad_s,a_m_s2\n");
    for j in 0..22 {
        let m = 1usize << j;
        let _ = writeln!(
            text,
            "{:.17e},{:.17e},{:.17e}",
            m as f64 * dt,
            gyro.avar(m).sqrt(),
            accel.avar(m).sqrt()
        );
    }
    let table = adev_table::parse(&text, Path::new("exact.csv"), TableOptions::default()).unwrap();
    assert_eq!(table.samples, 1 << 23);
    let fits = fit_all(&table.analysis());
    for (ch, f) in fits.iter().enumerate() {
        let f = f.as_ref().unwrap();
        let truth = if ch < 3 { &gyro } else { &accel };
        assert!((f.model.band.0 / 10.0 - 1.0).abs() < 1e-12, "{ch}");
        assert!((f.model.band.1 / 1000.0 - 1.0).abs() < 1e-12, "{ch}");
        assert!((f.model.gm_tau / truth.gm_tau - 1.0).abs() < 1e-12, "{ch}");
        for k in COMPONENTS {
            let (got, want) = (f.model.c[k as usize], truth.c[k as usize]);
            if want == 0.0 {
                assert!(f.estimate(k).is_none(), "{ch} {k:?}");
                continue;
            }
            assert!(
                (got / want - 1.0).abs() < 1e-6,
                "{ch} {k:?}: {got:e} vs {want:e}"
            );
        }
    }
}

const NOISY: &str = r#"
name = "noisy"
rate_hz = 20
[gyro]
noise = "0.15 deg/sqrt(h)"
random_walk = "300 deg/h/sqrt(h)"
[accel]
noise = "0.07 m/s/sqrt(h)"
random_walk = "60 ug/sqrt(s)"
"#;

/// A record's octave Allan deviation as a table of its six channels, its length stated.
fn octave_table(rec: &imu_emu::analysis::analyzer::Analysis, samples: u64, dt: f64) -> String {
    let mut text = format!("# record_length = {} s\ntau_s", samples as f64 * dt);
    for n in [
        "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2",
    ] {
        text += &format!(",{n}");
    }
    text.push('\n');
    for (j, p) in rec.channels[0].adev.iter().enumerate() {
        let _ = write!(text, "{:.12e}", p.tau);
        for c in &rec.channels {
            let _ = write!(text, ",{:.12e}", c.adev[j].adev);
        }
        text.push('\n');
    }
    text
}

/// A recording's own ADEV written as a table (with its record length stated) is fitted as
/// the recording is: the same figures and intervals (to the 12 printed digits), and the true
/// N inside them — the table route adds nothing to or takes nothing from the
/// statistics. Without the stated length the shortest record that gives the table's longest
/// τ is assumed: here (the table runs to T/2) the true one, so the same intervals. (The unit
/// tests of `adev_table` check that a shorter assumed record widens the bands.)
#[test]
fn noisy_table_fits_as_its_recording() {
    let dt = 0.05;
    let model = template::parse(NOISY, Path::new("noisy.toml")).unwrap();
    let rec = closure::simulate(model.clone(), dt, 1 << 17, 5, 1 << 12).unwrap();
    let text = octave_table(&rec, 1 << 17, dt);
    let direct = fit_all(&rec);
    let stated = adev_table::parse(&text, Path::new("rec.csv"), TableOptions::default()).unwrap();
    // Without the length line: the table runs to τ = T/2, so the shortest record that gives
    // it is the true one and the intervals are the same.
    let unstated_text: String = text.lines().skip(1).map(|l| format!("{l}\n")).collect();
    let unstated = adev_table::parse(
        &unstated_text,
        Path::new("rec.csv"),
        TableOptions::default(),
    )
    .unwrap();
    assert!(!unstated.length_stated);
    assert_eq!(unstated.samples, 1 << 17);
    let via_table = fit_all(&stated.analysis());
    let wide = fit_all(&unstated.analysis());
    let mut missed = Vec::new();
    for ch in 0..6 {
        let triad = if ch < 3 { &model.gyro } else { &model.accel };
        for (k, want) in [
            (Component::WhiteNoise, triad.noise[0]),
            (Component::RandomWalk, triad.random_walk[0]),
        ] {
            let a = direct[ch].as_ref().unwrap().estimate(k);
            let b = via_table[ch].as_ref().unwrap().estimate(k);
            assert_eq!(a.is_some(), b.is_some(), "{ch} {k:?}");
            let (Some(a), Some(b)) = (a, b) else {
                assert_eq!(k, Component::RandomWalk, "{ch}: N not kept");
                continue;
            };
            for (x, y) in [(a.value, b.value), (a.lo, b.lo), (a.hi, b.hi)] {
                assert!((x / y - 1.0).abs() < 1e-9, "{ch} {k:?}: {a:?} vs {b:?}");
            }
            if k == Component::WhiteNoise && !(b.lo <= want && want <= b.hi) {
                missed.push(format!("{ch} {k:?}: true {want:e}, {b:?}"));
            }
            let w = wide[ch].as_ref().unwrap().estimate(k).unwrap();
            assert!((w.hi / b.hi - 1.0).abs() < 1e-9, "{ch} {k:?}");
        }
    }
    // The white noise of all six channels inside its 99 % interval (a miss in six has
    // probability 6 %; this fixed seed has none). K is compared only between the two
    // routes: on this record the fit of the recording itself leaves K out on accel z and
    // reads gyro y's 28 % low against a ±13 % interval (a Gauss–Markov component takes part
    // of the rise; docs/fit.md, "Not done yet").
    assert!(missed.is_empty(), "{}", missed.join("\n"));
}

/// `fit` on per-sensor table files writes a template of both sensors; a bad table is named
/// by file, line and column and leaves no template behind.
#[test]
fn fit_command_on_tables() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let mut gyro = String::from("tau_s,g_deg_h\n");
    let mut accel = String::from("tau_s,a_ug\n");
    for j in 0..16 {
        let tau = 0.01 * (1u64 << j) as f64;
        // N = 0.1 deg/sqrt(h): σ = 6/sqrt(τ) deg/h; VRW 50 ug·sqrt(s).
        let _ = writeln!(gyro, "{tau},{}", 6.0 / tau.sqrt());
        let _ = writeln!(accel, "{tau},{}", 50.0 / tau.sqrt());
    }
    std::fs::write(d.join("g.csv"), gyro).unwrap();
    std::fs::write(d.join("a.csv"), accel).unwrap();
    let unit = d.join("unit.toml");
    ok(imu_emu([
        OsStr::new("fit"),
        d.join("g.csv").as_os_str(),
        OsStr::new("--table"),
        d.join("a.csv").as_os_str(),
        OsStr::new("--record-length"),
        OsStr::new("6 h"),
        OsStr::new("-o"),
        unit.as_os_str(),
    ]));
    let m = template::load(unit.to_str().unwrap()).unwrap();
    let n = m.gyro.noise[0] / (0.1f64.to_radians() / 60.0);
    assert!((n - 1.0).abs() < 1e-6, "{n}");
    // 50 µg·√s = 0.029420 m/s/√h, written with the template's four digits as 0.02942: half a
    // unit of the last digit is 1.7e-4 of it.
    let v = m.accel.noise[2] / (50e-6 * imu_emu::units::G0);
    assert!((v - 1.0).abs() < 1.7e-4, "{v}");

    std::fs::write(d.join("bad.csv"), "tau_s,gx_deg_h\n0.01,3\n0.02,-1\n").unwrap();
    let bad = d.join("bad.csv");
    let out = d.join("out.toml");
    let e = err(imu_emu([
        OsStr::new("fit"),
        bad.as_os_str(),
        OsStr::new("-o"),
        out.as_os_str(),
    ]));
    let want = format!(
        "{}:3: column 2 (`gx_deg_h`): expected a positive finite number",
        bad.display()
    );
    assert!(e.contains(&want), "{e}");
    assert!(!out.exists());
    let e = err(imu_emu([
        OsStr::new("fit"),
        d.join("g.csv").as_os_str(),
        OsStr::new("--record-length"),
        OsStr::new("1 s"),
    ]));
    assert!(e.contains("record length 1 s is shorter"), "{e}");
}

fn generate(d: &Path, imu: &str, seed: &str, out: &str) {
    ok(imu_emu([
        "generate",
        "--scene",
        "static",
        "--imu",
        imu,
        "--rate",
        "100",
        "--duration",
        "300",
        "--seed",
        seed,
        "-o",
        d.join(out).to_str().unwrap(),
    ]));
}

/// The verdict column of the comparison CSV for gyro x's white noise.
fn gyro_x_noise_verdict(csv: &str) -> String {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.len(), 11, "{csv}");
    let row: Vec<&str> = lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .find(|r| r[1] == "gyro x" && r[2] == "N")
        .unwrap_or_else(|| panic!("{csv}"));
    for v in &row[4..10] {
        v.parse::<f64>().unwrap();
    }
    row[10].to_string()
}

/// `analyze --reference`: two records of one template agree on the white noise, the
/// datasheet against the typical profile (ARW 0.07 vs 0.0395 deg/√h, intervals of ±2 % at
/// 30 000 samples) differ; a table as reference; the overlay PNG; bad references named.
#[test]
fn analyze_reference_compares_and_overlays() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    generate(d, "ln200", "1", "a.csv");
    generate(d, "ln200", "2", "b.csv");
    generate(d, "ln200:typical", "3", "c.csv");
    let path = |n: &str| d.join(n).to_str().unwrap().to_string();
    let out = ok(imu_emu([
        "analyze",
        &path("a.csv"),
        "--reference",
        &path("b.csv"),
        "--compare-csv",
        &path("ab.csv"),
        "--plot",
        &path("ab.png"),
    ]));
    assert!(out.contains("Per-term comparison with b.csv"), "{out}");
    let csv = std::fs::read_to_string(d.join("ab.csv")).unwrap();
    assert_eq!(gyro_x_noise_verdict(&csv), "agree");
    let png = std::fs::read(d.join("ab.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    ok(imu_emu([
        "analyze",
        &path("a.csv"),
        "--reference",
        &path("c.csv"),
        "--compare-csv",
        &path("ac.csv"),
    ]));
    let csv = std::fs::read_to_string(d.join("ac.csv")).unwrap();
    assert_eq!(gyro_x_noise_verdict(&csv), "DIFFER");

    let table = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/data/ln200-real-adev.csv");
    let out = ok(imu_emu([
        "analyze",
        &path("a.csv"),
        "--reference",
        table,
        "--plot",
        &path("t.svg"),
    ]));
    assert!(
        out.contains("Per-term comparison with ln200-real-adev.csv"),
        "{out}"
    );
    assert!(std::fs::metadata(d.join("t.svg")).unwrap().len() > 1000);

    let e = err(imu_emu([
        "analyze",
        &path("a.csv"),
        "--reference",
        &path("none.csv"),
    ]));
    assert!(e.contains("--reference") && e.contains("none.csv"), "{e}");
    std::fs::write(d.join("bad.csv"), "tau_s,gx_deg_h\n0.01,3\n0.01,2\n").unwrap();
    let e = err(imu_emu([
        "analyze",
        &path("a.csv"),
        "--reference",
        &path("bad.csv"),
    ]));
    assert!(e.contains("bad.csv:3: column 1 (`tau_s`)"), "{e}");
}

const BUMPED: &str = r#"
name = "bumped"
rate_hz = 100
[gyro]
noise = "0.15 deg/sqrt(h)"
random_walk = "30 deg/h/sqrt(h)"
[accel]
noise = "0.07 m/s/sqrt(h)"
random_walk = "60 ug/sqrt(s)"
"#;

/// The octave Allan deviation of a record whose gyro z carries a broad resonance (a random
/// vibration 15–25 Hz, log-log tent peaking at 20 Hz at 10× the white floor), written as a
/// table: `fit` reads a resonance on gyro z from the Allan deviation alone, centred inside the
/// true band, and on no other channel, writes it with `--sines`, and the record simulated from
/// the template and the resonance closes at every octave on every channel. The same record
/// without the vibration gets no resonance (a false bump on any of six channels would be a
/// χ²₃ excess at 99 % that also peaks 10 % over the floor). Gyro z's white noise is read
/// inside its 99 % interval: without the resonance it comes out 15 % high (0.172 deg/√h
/// against ±0.5 %).
#[test]
fn a_resonance_in_a_table_is_read_and_closes() {
    use imu_emu::errors::model::Sensor;
    use imu_emu::errors::vibration::{Random, VibrationSpec};
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let dt = 0.01;
    let samples = 1u64 << 18;
    let model = template::parse(BUMPED, Path::new("bumped.toml")).unwrap();
    let floor = 2.0 * (0.15f64.to_radians() / 60.0).powi(2);
    for (bump, seed) in [(true, 21), (false, 22)] {
        let vibration = VibrationSpec {
            sines: Vec::new(),
            randoms: if bump {
                vec![Random {
                    sensor: Sensor::Gyro,
                    axis: 2,
                    psd: vec![
                        (15.0, 0.1 * floor),
                        (20.0, 10.0 * floor),
                        (25.0, 0.1 * floor),
                    ],
                }]
            } else {
                Vec::new()
            },
        };
        let rec =
            closure::simulate_with(model.clone(), vibration, dt, samples, seed, 1 << 12).unwrap();
        let text = octave_table(&rec, samples, dt);
        let table = d.join(format!("t{seed}.csv"));
        std::fs::write(&table, text).unwrap();
        let (unit, report, sines) = (
            d.join(format!("u{seed}.toml")),
            d.join(format!("r{seed}.md")),
            d.join(format!("s{seed}.toml")),
        );
        ok(imu_emu([
            OsStr::new("fit"),
            table.as_os_str(),
            OsStr::new("-o"),
            unit.as_os_str(),
            OsStr::new("--report"),
            report.as_os_str(),
            OsStr::new("--sines"),
            sines.as_os_str(),
        ]));
        let md = std::fs::read_to_string(&report).unwrap();
        let found: Vec<&str> = md
            .lines()
            .filter(|l| l.contains(": broad resonance "))
            .collect();
        if bump {
            assert_eq!(found.len(), 1, "{md}");
            assert!(found[0].starts_with("- gyro z: "), "{md}");
            let centre: f64 = found[0]
                .split("(centre ")
                .nth(1)
                .and_then(|s| s.split(' ').next())
                .unwrap()
                .parse()
                .unwrap();
            assert!((15.0..=25.0).contains(&centre), "{centre}\n{md}");
            // The white noise under the bump is read as it is: the truth inside gyro z's 99 %
            // interval.
            let row = md
                .lines()
                .find(|l| l.starts_with("| gyro z | white noise |"))
                .unwrap();
            let iv: Vec<f64> = row.split('|').nth(4).unwrap().trim()[1..]
                .trim_end_matches(']')
                .split(", ")
                .map(|x| x.parse().unwrap())
                .collect();
            assert!(iv[0] <= 0.15 && 0.15 <= iv[1], "{row}");
            let scene = std::fs::read_to_string(&sines).unwrap();
            assert!(
                scene.contains("[[vibration.random]]\nsensor = \"gyro\"\naxis = \"z\""),
                "{scene}"
            );
        } else {
            assert!(found.is_empty(), "{md}");
            assert!(md.contains("None that gains χ²₃(99 %) in the Allan deviation"));
        }
        for line in md.lines().filter(|l| l.contains(": Allan deviation ")) {
            let words: Vec<&str> = line.split_whitespace().collect();
            // "- gyro x: Allan deviation K of N octaves inside; ..."
            assert_eq!(words[5], words[7], "{seed}: {line}\n{md}");
        }
    }
}
