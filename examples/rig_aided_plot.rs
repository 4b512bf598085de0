//! The land-vehicle rig of `examples/rig_aided.toml` (two IMUs of different grades, GNSS and
//! a wheel odometer on one motion) run from code as `imu-emu generate` runs it, and the error
//! of each stream over time drawn (the picture in docs/rig.md and docs/aiding.md):
//!
//!     cargo run --release --example rig_aided_plot -- docs/rig-aided.png
//!
//! Each IMU's error is its output minus its error-free readings at its own place (the
//! `--truth` files), averaged over 1 s so the bias shows through the white noise; the GNSS
//! error is the reported antenna position minus the truth (none in the 30–40 s outage); the
//! odometer's is its speed minus the true distance rolled in the interval over its length.

use std::ops::ControlFlow;

use imu_emu::plot::{Panel, Series};
use imu_emu::rig::UnitOutputs;
use imu_emu::sim::Simulation;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// A time and the six channels' errors (gyro x, y, z in rad/s, accel x, y, z in m/s²).
type Errors = Vec<(f64, [f64; 6])>;

const RAD_S_TO_DEG_H: f64 = 180.0 / std::f64::consts::PI * 3600.0;
const M_S2_TO_MG: f64 = 1000.0 / 9.80665;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "rig-aided.png".into());
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/rig_aided.toml");
    let rig = Simulation::from_scene_file(scene)?.build_rig()?;
    let (mut gnss, mut odo) = (Vec::new(), Vec::new());
    let aid = rig.aiding();
    aid.write_gnss(&mut [], Some(&mut gnss))?;
    aid.write_odometer(&mut odo)?;
    let names: Vec<String> = rig.units().iter().map(|u| u.name().to_string()).collect();
    let n = names.len();
    let (mut mains, mut truths, mut fails) = (
        vec![Vec::new(); n],
        vec![Vec::new(); n],
        vec![Vec::new(); n],
    );
    let mut outs: Vec<UnitOutputs<'_>> = (mains.iter_mut().zip(&mut truths).zip(&mut fails))
        .map(|((m, t), f)| UnitOutputs {
            main: m,
            truth: Some(t),
            failures: Some(f),
        })
        .collect();
    rig.write(&mut outs, |_| ControlFlow::Continue(()))?;
    drop(outs);
    let mut gyro = Vec::new();
    let mut accel = Vec::new();
    for (i, name) in names.iter().enumerate() {
        let err = unit_errors(&mains[i], &truths[i])?;
        for (axis, c) in ["x", "y", "z"].iter().enumerate() {
            gyro.push(series(
                format!("{name} gyro {c}"),
                3 * i + axis,
                &err,
                |e| e[axis] * RAD_S_TO_DEG_H,
            ));
            accel.push(series(
                format!("{name} accel {c}"),
                3 * i + axis,
                &err,
                |e| e[3 + axis] * M_S2_TO_MG,
            ));
        }
    }
    let panels = [
        panel("IMU gyro error (output − truth, 1 s means)", "deg/h", gyro),
        panel(
            "IMU accelerometer error (output − truth, 1 s means)",
            "mg",
            accel,
        ),
        panel(
            "GNSS antenna position error (outage 30–40 s)",
            "m",
            gnss_errors(&gnss)?,
        ),
        panel(
            "Odometer speed error (1 s means; scale factor 0.5 %)",
            "m/s",
            odometer_errors(&odo)?,
        ),
    ];
    imu_emu::plot::render(std::path::Path::new(&out), &panels, 2, (1400, 900))?;
    eprintln!("wrote {out}");
    Ok(())
}

fn panel(title: &str, unit: &str, series: Vec<Series>) -> Panel {
    Panel {
        title: title.into(),
        x_label: "time (s)".into(),
        y_label: unit.into(),
        series,
        ..Default::default()
    }
}

fn series(
    label: String,
    color: usize,
    pts: &[(f64, [f64; 6])],
    f: impl Fn(&[f64; 6]) -> f64,
) -> Series {
    Series {
        label,
        color,
        x: pts.iter().map(|p| p.0).collect(),
        y: pts.iter().map(|p| f(&p.1)).collect(),
        ..Default::default()
    }
}

fn rows(csv: &[u8]) -> Res<Vec<Vec<String>>> {
    let text = std::str::from_utf8(csv)?;
    Ok((text.lines().skip(1))
        .map(|l| l.split(',').map(String::from).collect())
        .collect())
}

/// Output − truth of gyro x, y, z (rad/s) and accel x, y, z (m/s²), averaged over 1 s.
fn unit_errors(main: &[u8], truth: &[u8]) -> Res<Errors> {
    let (m, t) = (rows(main)?, rows(truth)?);
    let mut out = Vec::new();
    let (mut sum, mut count, mut second) = ([0.0; 6], 0.0, 1.0);
    for (a, b) in m.iter().zip(&t) {
        let time: f64 = a[0].parse()?;
        for (k, s) in sum.iter_mut().enumerate() {
            *s += a[1 + k].parse::<f64>()? - b[1 + k].parse::<f64>()?;
        }
        count += 1.0;
        if time >= second - 1e-9 {
            out.push((second - 0.5, sum.map(|s| s / count)));
            (sum, count, second) = ([0.0; 6], 0.0, second + 1.0);
        }
    }
    Ok(out)
}

/// Horizontal and vertical position error of each epoch with a fix (m); an outage breaks
/// the curves.
fn gnss_errors(truth: &[u8]) -> Res<Vec<Series>> {
    let mut out: Vec<Series> = Vec::new();
    let mut in_fix = false;
    for r in rows(truth)? {
        if r[3] == "none" {
            in_fix = false;
            continue;
        }
        if !in_fix {
            let first = out.is_empty();
            for (i, name) in ["horizontal", "vertical (down)"].iter().enumerate() {
                out.push(Series {
                    label: if first {
                        name.to_string()
                    } else {
                        String::new()
                    },
                    color: i,
                    ..Default::default()
                });
            }
            in_fix = true;
        }
        let t: f64 = r[1].parse()?;
        let (n, e, d): (f64, f64, f64) = (r[17].parse()?, r[18].parse()?, r[19].parse()?);
        let k = out.len() - 2;
        out[k].x.push(t);
        out[k].y.push(n.hypot(e));
        out[k + 1].x.push(t);
        out[k + 1].y.push(d);
    }
    Ok(out)
}

/// Reported speed minus the true distance over the interval's length (m/s), averaged over
/// 1 s: a single sample's error is mostly the ±1 tick quantization, whose 1 s mean is
/// bounded by one tick per second, so the scale factor shows.
fn odometer_errors(csv: &[u8]) -> Res<Vec<Series>> {
    let mut s = Series {
        label: "speed error".into(),
        color: 2,
        ..Default::default()
    };
    let (mut prev, mut sum, mut count, mut second) = (0.0, 0.0, 0.0, 1.0);
    for r in rows(csv)? {
        let t: f64 = r[0].parse()?;
        let (speed, dist): (f64, f64) = (r[3].parse()?, r[4].parse()?);
        sum += speed - dist / (t - prev);
        count += 1.0;
        prev = t;
        if t >= second - 1e-9 {
            s.x.push(second - 0.5);
            s.y.push(sum / count);
            (sum, count, second) = (0.0, 0.0, second + 1.0);
        }
    }
    Ok(vec![s])
}
