//! The reference navigator's run time against closure error, for each algorithm order.
//!
//! `cargo bench --bench navigator` prints the table docs/navigator.md shows: error-free records of
//! `survey` (600 s) and `coning` (60 s) at 400 Hz, generated once, navigated from the true
//! initial state with each setting; ns per update (one core, records already in memory)
//! and the final 3-D position and attitude errors.

use std::time::Instant;

use imu_emu::engine;
use imu_emu::generator::IdealImu;
use imu_emu::motion::Motion;
use imu_emu::nav::{NavState, Navigator, Settings, StateError};
use imu_emu::record::Record;
use imu_emu::scenes::{self, SceneParams};
use imu_emu::source::AnyMotion;

const RATE: f64 = 400.0;

fn main() {
    let cases: Vec<(&str, f64)> = vec![("survey", 600.0), ("coning", 60.0)];
    println!("Records at {RATE} Hz, error-free; navigated from the true initial state.\n");
    println!(
        "| scene | samples | stages | ns/update | position error (m) | attitude error (rad) |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    for (name, seconds) in cases {
        let p = SceneParams::defaults_for(name);
        let m = AnyMotion::Scene(scenes::build(name, &p).unwrap().unwrap());
        let grid = engine::plan(&m, RATE, None, Some(seconds)).unwrap();
        let mut imu = IdealImu::new(m.clone(), RATE, 0.0, grid.count, 3);
        let mut rec = vec![Record::default(); grid.count as usize];
        imu.fill(1, &mut rec);
        let start = NavState::from_pose(&m.pose(0.0));
        for samples in [1, 2, 4, 6, 8] {
            for stages in [2, 3] {
                let settings = Settings { samples, stages };
                let mut nav = Navigator::new(start, RATE, settings).unwrap();
                let t = Instant::now();
                for r in &rec {
                    nav.step(r.dtheta, r.dv);
                }
                let ns = t.elapsed().as_secs_f64() * 1e9 / rec.len() as f64;
                let s = nav.state();
                let e = StateError::of(&s, &m.pose(s.t));
                println!(
                    "| {name} {seconds} s | {samples} | {stages} | {ns:.0} | {:.2e} | {:.2e} |",
                    e.pos_ned.norm(),
                    e.att_ned.norm()
                );
            }
        }
    }
}
