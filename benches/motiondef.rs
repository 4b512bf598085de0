//! Evaluation cost per record of motion definitions against the built-in scenes: error-free
//! records (3-node Gauss–Legendre increments, the default) at 1 kHz, no error chain, best of
//! three passes.
//!
//! `cargo bench --bench motiondef` prints the table docs/motion-definitions.md shows; the rows
//! of gnss-ins-sim's demo files need the public data sets (docs/testing.md), and are left out
//! with a line saying so when they are not found.

use std::path::Path;
use std::time::Instant;

use imu_emu::engine::{self, BLOCK, Producer, SourceSpec};
use imu_emu::motion::Motion;
use imu_emu::scenes::SceneParams;
use imu_emu::source::AnyMotion;

#[path = "../tests/common/public_data.rs"]
mod public_data;

const RATE: f64 = 1000.0;
const SECONDS: f64 = 60.0;

fn ns_per_record(m: &AnyMotion) -> f64 {
    let seconds = SECONDS.min(m.end() - m.start());
    let grid = engine::plan(m, RATE, None, Some(seconds)).expect("plan");
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let start = Instant::now();
        let mut p = Producer::records(m.clone(), grid, None);
        let mut sum = 0.0;
        while let Some(b) = p.next_records(BLOCK) {
            sum += b.records.iter().map(|r| r.gyro[0]).sum::<f64>();
        }
        std::hint::black_box(sum);
        best = best.min(start.elapsed().as_secs_f64() * 1e9 / grid.count as f64);
    }
    best
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    println!(
        "error-free records at {RATE} Hz over {SECONDS} s (or the whole trip if shorter), best of 3\n"
    );
    println!("| source | ns/record |\n| --- | ---: |");
    for name in ["static", "circle", "survey", "coning"] {
        let spec = SourceSpec::Scene(name.into(), SceneParams::defaults_for(name));
        let m = engine::build_motion(&spec, Default::default()).expect("scene");
        println!("| scene {name} | {:.0} |", ns_per_record(&m));
    }
    let demos = public_data::set("gnss-ins-sim", "bench motiondef")
        .map(|d| ["motion_def-long_drive.csv", "motion_def-90deg_turn.csv"].map(|f| d.join(f)));
    let own = ["examples/mission.toml", "examples/waypoints.toml"].map(|f| root.join(f));
    for file in demos.into_iter().flatten().chain(own) {
        let m = AnyMotion::Defined(imu_emu::motiondef::open(&file).expect("a motion definition"));
        let name = file.file_name().unwrap_or_default().to_string_lossy();
        println!("| motion definition {name} | {:.0} |", ns_per_record(&m));
    }
}
