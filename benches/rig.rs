//! A rig of N units against N separate runs: `cargo bench --bench rig`.
//!
//! N LN-200-template IMUs at 400 Hz on the 600 s survey, each at its own lever arm, binary
//! records into a writer that discards them. The rig evaluates the motion once per instant
//! for all N (`Rig::groups`); N runs of `Simulation` evaluate it N times. Best of 5 runs
//! (this 2-core VM is noisy).

use std::io;
use std::ops::ControlFlow;
use std::time::Instant;

use imu_emu::rig::UnitOutputs;
use imu_emu::rig::UnitSpec;
use imu_emu::sim::Simulation;

const DURATION_S: f64 = 120.0;

fn arm(i: usize) -> [f64; 3] {
    [0.5 * i as f64, -0.2, 0.1]
}

fn rig(n: usize) -> f64 {
    let mut b = Simulation::builder().scene("survey").duration(DURATION_S);
    for i in 0..n {
        let mut u = UnitSpec::imu(&format!("u{i}"), "ln200");
        u.rate_hz = Some(400.0);
        u.format = Some("bin".into());
        u.lever_arm_m = arm(i);
        b = b.unit(u);
    }
    let rig = b.build_rig().expect("valid rig");
    let mut sinks: Vec<io::Sink> = (0..n).map(|_| io::sink()).collect();
    let mut outs: Vec<UnitOutputs<'_>> = sinks
        .iter_mut()
        .map(|s| UnitOutputs {
            main: s,
            truth: None,
            failures: None,
        })
        .collect();
    let t = Instant::now();
    rig.write(&mut outs, |_| ControlFlow::Continue(()))
        .expect("runs");
    t.elapsed().as_secs_f64()
}

fn separate(n: usize) -> f64 {
    let sims: Vec<_> = (0..n)
        .map(|i| {
            Simulation::builder()
                .scene("survey")
                .duration(DURATION_S)
                .imu("ln200")
                .rate(400.0)
                .format("bin")
                .lever_arm_m(arm(i))
                .build()
                .expect("valid simulation")
        })
        .collect();
    let t = Instant::now();
    for s in sims {
        s.write(&mut io::sink()).expect("runs");
    }
    t.elapsed().as_secs_f64()
}

fn best(f: impl Fn() -> f64) -> f64 {
    (0..5).map(|_| f()).fold(f64::INFINITY, f64::min)
}

fn main() {
    println!("| units | rig (s) | separate runs (s) | rig / separate |");
    println!("|---|---|---|---|");
    for n in [1, 2, 4, 8] {
        let (r, s) = (best(|| rig(n)), best(|| separate(n)));
        println!("| {n} | {r:.3} | {s:.3} | {:.2} |", r / s);
    }
}
