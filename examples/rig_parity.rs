//! The rig of `examples/rig.toml` run from code, and the parity residual of its
//! skew-redundant unit's six gyros drawn over time (the picture in docs/rig.md):
//!
//!     cargo run --release --example rig_parity -- docs/rig-parity.png
//!
//! With H the 6×3 matrix of sense axes, P = I − H(HᵀH)⁻¹Hᵀ removes the motion from the six
//! readings m; pᵢ/Pᵢᵢ, component i of P m scaled by Pᵢᵢ, estimates what a failure added to
//! gyro i. The picture shows the bias step on gyro 2 (5–8 s) and the stuck gyro (4 s from
//! its random start), against the noise of the healthy gyros.

use std::ops::ControlFlow;

use imu_emu::math::Vec3;
use imu_emu::plot::{Panel, Series};
use imu_emu::rig::UnitOutputs;
use imu_emu::sim::Simulation;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "rig-parity.png".into());
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/rig.toml");
    let rig = Simulation::from_scene_file(scene)?.build_rig()?;
    let skew = rig
        .units()
        .iter()
        .position(|u| u.skew().is_some())
        .ok_or("no skew unit")?;
    let axes: Vec<Vec3> = rig.units()[skew]
        .skew()
        .unwrap()
        .gyros
        .iter()
        .map(|g| g.axis)
        .collect();
    let failures = rig.units()[skew].failures().to_vec();
    let mut bufs: Vec<Vec<u8>> = vec![Vec::new(); rig.units().len()];
    let mut outs: Vec<UnitOutputs<'_>> = bufs
        .iter_mut()
        .map(|b| UnitOutputs {
            main: b,
            truth: None,
            failures: None,
        })
        .collect();
    rig.write(&mut outs, |_| ControlFlow::Continue(()))?;
    let text = String::from_utf8(bufs.swap_remove(skew))?;
    let p = projector(&axes);
    let n = axes.len();
    let mut series: Vec<Series> = (0..n)
        .map(|i| Series {
            label: format!("gyro {i}"),
            color: i,
            ..Default::default()
        })
        .collect();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(str::parse).collect::<Result<_, _>>()?;
        for (i, s) in series.iter_mut().enumerate() {
            let r: f64 = (0..n).map(|j| p[i][j] * v[1 + j]).sum();
            s.x.push(v[0]);
            s.y.push(r / p[i][i] * 180.0 / std::f64::consts::PI * 3600.0);
        }
    }
    for f in &failures {
        eprintln!(
            "{} on channel {} from {} s to {} s",
            f.kind.name(),
            f.channel,
            f.start_s,
            f.end_s
        );
    }
    let panel = Panel {
        title: "Skew-redundant unit: parity residual per gyro (failures: bias step on gyro 2 at 5–8 s, a stuck gyro for 4 s)".into(),
        x_label: "time (s)".into(),
        y_label: "p_i / P_ii (deg/h)".into(),
        series,
        ..Default::default()
    };
    imu_emu::plot::render(std::path::Path::new(&out), &[panel], 1, (1200, 500))?;
    eprintln!("wrote {out}");
    Ok(())
}

/// P = I − H (HᵀH)⁻¹ Hᵀ for the sense axes `h` (rows of H).
fn projector(h: &[Vec3]) -> Vec<Vec<f64>> {
    let mut m = [[0.0; 3]; 3];
    for u in h {
        for (r, row) in m.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                *x += u[r] * u[c];
            }
        }
    }
    let inv = imu_emu::math::Mat3::from_fn(|r, c| m[r][c])
        .try_inverse()
        .expect("the axes span space");
    (0..h.len())
        .map(|i| {
            (0..h.len())
                .map(|j| (i == j) as u8 as f64 - h[i].dot(&(inv * h[j])))
                .collect()
        })
        .collect()
}
