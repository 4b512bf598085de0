//! The GNSS stream's errors over time: a receiver with the default errors (white plus
//! 300 s Gauss–Markov position errors, white velocity errors) and a 60 s outage on 600 s of
//! the circle scene, with the antenna 1 m above and 0.5 m ahead of the IMU. Draws
//! docs/aiding-gnss-errors.png: `cargo run --release --example gnss_errors -- FILE.png`.

use imu_emu::aiding::GnssConfig;
use imu_emu::plot::{Panel, Series, render};
use imu_emu::sim::Simulation;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "aiding-gnss-errors.png".into());
    let cfg = GnssConfig {
        rate_hz: 5.0,
        lever_arm_m: [0.5, 0.0, -1.0],
        outages_s: vec![[300.0, 360.0]],
        ..GnssConfig::default()
    };
    let sim = Simulation::builder()
        .scene("circle")
        .duration(600.0)
        .rate(100.0)
        .gnss(cfg)
        .seed(7)
        .build()?;
    let (t0, t1) = sim.span();
    let mut rx = sim.gnss_receiver();
    let (mut t, mut dp, mut dv) = (
        Vec::new(),
        [vec![], vec![], vec![]],
        [vec![], vec![], vec![]],
    );
    while let Some(e) = rx.next_epoch(sim.motion(), t0, t1) {
        if !e.fix.is_valid() {
            continue;
        }
        t.push(e.t);
        for i in 0..3 {
            dp[i].push(e.pos_err_n[i]);
            dv[i].push(e.vel_err_n[i]);
        }
    }
    let panel = |title: &str, unit: &str, ys: [Vec<f64>; 3]| Panel {
        title: title.into(),
        x_label: "time of validity (s); no fix 300–360 s".into(),
        y_label: unit.into(),
        series: ys
            .into_iter()
            .zip(["north", "east", "down"])
            .enumerate()
            .map(|(i, (y, label))| Series {
                label: label.into(),
                x: t.clone(),
                y,
                color: i,
                ..Series::default()
            })
            .collect(),
        ..Panel::default()
    };
    render(
        std::path::Path::new(&out),
        &[
            panel("GNSS position error (reported − true antenna)", "m", dp),
            panel("GNSS velocity error", "m/s", dv),
        ],
        1,
        (1000, 700),
    )?;
    println!("{out}: {} epochs with a fix", t.len());
    Ok(())
}
