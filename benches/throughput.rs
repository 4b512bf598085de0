//! Records per second of offline generation on one core: `cargo bench --bench throughput`.
//!
//! Runs the same code path as `imu-emu generate` (`engine::run`: generator → error chain →
//! encoder → writer) into a writer that discards the bytes, so the figure is the simulator's,
//! not the disk's. Best of 9 runs (this 2-core VM is noisy: run-to-run spread is ±20 %); every run produces
//! identical bytes.

use std::io;
use std::path::Path;
use std::time::Instant;

use imu_emu::engine::{self, SourceSpec};
use imu_emu::errors::{ErrorChain, ImuModel, template};
use imu_emu::generator::DEFAULT_NODES;
use imu_emu::motion::sampled::ModelSettings;
use imu_emu::output::Format;
use imu_emu::scenes::SceneParams;
use imu_emu::validation::sample_csv;

/// One case: source, duration, nodes, format, error model.
type Case<'a> = (
    &'a str,
    SourceSpec,
    Option<f64>,
    usize,
    Format,
    Option<&'a ImuModel>,
);

fn measure(case: &Case, rate: f64) -> (u64, f64) {
    let (_, source, duration, nodes, format, imu) = case;
    let mut best = f64::INFINITY;
    let mut count = 0;
    for _ in 0..9 {
        let motion = engine::build_motion(source, ModelSettings::default()).expect("valid source");
        let grid = engine::plan(&motion, rate, None, *duration).expect("valid span");
        count = grid.count;
        let chain = imu
            .map(|m| ErrorChain::new(m, rate, 1))
            .filter(|c| !c.is_empty());
        let t = Instant::now();
        engine::run(
            motion,
            grid,
            *nodes,
            *format,
            chain,
            &mut io::sink(),
            None,
            None,
            |_| {},
        )
        .expect("runs");
        best = best.min(t.elapsed().as_secs_f64());
    }
    (count, count as f64 / best)
}

fn main() {
    let scene = |n: &str| SourceSpec::Scene(n.into(), SceneParams::defaults_for(n));
    // A trajectory file: the survey sampled at 100 Hz, written to a temporary CSV.
    let dir = std::env::temp_dir().join(format!("imu-emu-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let csv = dir.join("survey100.csv");
    let motion = engine::build_motion(&scene("survey"), ModelSettings::default()).expect("survey");
    std::fs::write(&csv, sample_csv(&motion, 100.0, 600.0)).expect("write csv");
    let noise_only = template::parse(
        "name = \"noise-only\"\n[gyro]\nnoise = \"0.07 deg/sqrt(h)\"\n[accel]\nnoise = \"0.03 m/s/sqrt(h)\"\n",
        Path::new("noise.toml"),
    )
    .expect("valid");
    let full = template::parse(FULL, Path::new("full.toml")).expect("valid");
    let ln200 = template::load("ln200").expect("built in");

    println!(
        "| source | IMU | rate Hz | GL nodes | format | records | records/s (one core) | ns/record |"
    );
    println!("|---|---|---:|---:|---|---:|---:|---:|");
    let (bin, n3) = (Format::Bin, DEFAULT_NODES);
    let cases: Vec<Case> = vec![
        ("static", scene("static"), Some(600.0), n3, bin, None),
        ("survey", scene("survey"), None, n3, bin, None),
        ("survey", scene("survey"), None, 2, bin, None),
        ("survey", scene("survey"), None, n3, Format::Csv, None),
        ("coning", scene("coning"), Some(600.0), n3, bin, None),
        (
            "survey CSV file @100 Hz",
            SourceSpec::File(csv.clone()),
            Some(599.0),
            n3,
            bin,
            None,
        ),
        (
            "static",
            scene("static"),
            Some(600.0),
            n3,
            bin,
            Some(&noise_only),
        ),
        ("survey", scene("survey"), None, n3, bin, Some(&noise_only)),
        ("survey", scene("survey"), None, n3, bin, Some(&ln200)),
        ("survey", scene("survey"), None, n3, bin, Some(&full)),
    ];
    for case in &cases {
        let (n, rps) = measure(case, 1000.0);
        let imu = case.5.map_or("ideal", |m| m.name.as_str());
        println!(
            "| {} | {imu} | 1000 | {} | {:?} | {n} | {rps:.3e} | {:.0} |",
            case.0,
            case.3,
            case.4,
            1e9 / rps
        );
    }
    // Setting up a survey of 100 000 lines (it was quadratic in the lines, and took minutes).
    let params = SceneParams {
        lines: 100_000,
        ..SceneParams::defaults_for("survey")
    };
    let t = Instant::now();
    let big = engine::build_motion(
        &SourceSpec::Scene("survey".into(), params),
        ModelSettings::default(),
    )
    .expect("survey");
    std::hint::black_box(&big);
    println!(
        "\nsurvey of 100 000 lines set up in {:.3} s",
        t.elapsed().as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A template with every term set (LN-200-like magnitudes).
const FULL: &str = r#"
name = "full"
[gyro]
bias_turn_on = "1 deg/h"
bias_instability = "0.35 deg/h"
bias_gm = { sigma = "0.1 deg/h", tau = "100 s" }
random_walk = "0.01 deg/h/sqrt(h)"
noise = "0.07 deg/sqrt(h)"
scale_factor_turn_on = "100 ppm"
misalignment_turn_on = "0.1 mrad"
g_sensitivity = "1 deg/h/g"
quantization = "1.9073486328125e-6 rad"
range = "1000 deg/s"
[accel]
bias_turn_on = "0.3 mg"
bias_instability = "50 ug"
random_walk = "1 ug/sqrt(s)"
noise = "0.03 m/s/sqrt(h)"
scale_factor_turn_on = "300 ppm"
scale_factor_quadratic = "10 ug/g^2"
misalignment_turn_on = "0.1 mrad"
quantization = "6.103515625e-5 m/s"
range = "40 g"
"#;
