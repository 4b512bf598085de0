//! Evaluation cost per record of motion definitions against the built-in scenes: error-free
//! records (3-node Gauss–Legendre increments, the default) at 1 kHz, no error chain, best of
//! three passes.
//!
//! `cargo bench --bench motiondef` prints the table docs/motion-definitions.md shows.

use std::path::Path;
use std::time::Instant;

use imu_emu::engine::{self, BLOCK, Producer, SourceSpec};
use imu_emu::motion::Motion;
use imu_emu::scenes::SceneParams;
use imu_emu::source::AnyMotion;

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
    for file in [
        "tests/data/gnss-ins-sim/motion_def-long_drive.csv",
        "tests/data/gnss-ins-sim/motion_def-90deg_turn.csv",
        "examples/mission.toml",
        "examples/waypoints.toml",
    ] {
        let m = AnyMotion::Defined(imu_emu::motiondef::open(&root.join(file)).expect(file));
        println!("| motion definition {file} | {:.0} |", ns_per_record(&m));
    }
}
