//! Records per second of offline generation on one core: `cargo bench --bench throughput`.
//!
//! Runs the same code path as `imu-emu generate` (`job::run`: generator → encoder → writer)
//! into a writer that discards the bytes, so the figure is the simulator's, not the disk's.
//! Best of 5 runs; every run produces identical bytes.

use std::io;
use std::time::Instant;

use imu_emu::generator::DEFAULT_NODES;
use imu_emu::job::{self, SourceSpec};
use imu_emu::motion::sampled::ModelSettings;
use imu_emu::output::Format;
use imu_emu::scenes::SceneParams;
use imu_emu::validation::sample_csv;

fn measure(
    source: &SourceSpec,
    rate: f64,
    duration: Option<f64>,
    nodes: usize,
    format: Format,
) -> (u64, f64) {
    let mut best = f64::INFINITY;
    let mut count = 0;
    for _ in 0..5 {
        let motion = job::build_motion(source, ModelSettings::default()).expect("valid source");
        let grid = job::plan(&motion, rate, None, duration).expect("valid span");
        count = grid.count;
        let t = Instant::now();
        job::run(
            motion,
            grid,
            nodes,
            format,
            None,
            &mut io::sink(),
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
    let motion = job::build_motion(&scene("survey"), ModelSettings::default()).expect("survey");
    std::fs::write(&csv, sample_csv(&motion, 100.0, 600.0)).expect("write csv");

    println!(
        "| source | rate Hz | GL nodes | format | records | records/s (one core) | ns/record |"
    );
    println!("|---|---:|---:|---|---:|---:|---:|");
    let cases: Vec<(&str, SourceSpec, Option<f64>, usize, Format)> = vec![
        (
            "static",
            scene("static"),
            Some(600.0),
            DEFAULT_NODES,
            Format::Bin,
        ),
        ("survey", scene("survey"), None, DEFAULT_NODES, Format::Bin),
        ("survey", scene("survey"), None, 2, Format::Bin),
        ("survey", scene("survey"), None, DEFAULT_NODES, Format::Csv),
        (
            "coning",
            scene("coning"),
            Some(600.0),
            DEFAULT_NODES,
            Format::Bin,
        ),
        (
            "survey CSV file @100 Hz",
            SourceSpec::File(csv.clone()),
            Some(599.0),
            DEFAULT_NODES,
            Format::Bin,
        ),
    ];
    for (name, src, dur, nodes, fmt) in cases {
        let (n, rps) = measure(&src, 1000.0, dur, nodes, fmt);
        println!(
            "| {name} | 1000 | {nodes} | {fmt:?} | {n} | {rps:.3e} | {:.0} |",
            1e9 / rps
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
