//! The listing commands (`scenes`, `templates`) and `trajectory`.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use imu_emu::motion::Motion;
use imu_emu::output::AtomicFile;

#[derive(clap::Args)]
pub struct TrajectoryArgs {
    #[command(flatten)]
    pub source: super::setup::SourceArgs,
    /// Sample rate (Hz).
    #[arg(long, default_value_t = 100.0)]
    pub rate: f64,
    /// Start time (s) [default: the scene file's `output.start_s`, else the trajectory's start].
    #[arg(long, allow_negative_numbers = true)]
    pub start: Option<f64>,
    /// Duration (s) [default: the scene file's `output.duration_s`, else the scene's; 60 s
    /// for unbounded scenes].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Output file, or - for stdout.
    #[arg(short, long, default_value = "-")]
    pub output: PathBuf,
    /// Also plot the mission (ground track, height, attitude, velocity) to this .png or .svg.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// `imu-emu templates`: the built-in IMU templates and their headline figures, each typical
/// profile on its own row under its template. Written, not printed: a full disk or a closed
/// pipe is an error, never a panic.
pub fn list_templates() -> Result<()> {
    use imu_emu::errors::template;
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{:<17} {:<11} {:>12} {:>10} {:>13} {:>12} {:>10} {:>13}  description",
        "name", "grade", "gyro BI", "gyro TO", "ARW", "accel BI", "accel TO", "VRW"
    )?;
    writeln!(
        out,
        "{:<17} {:<11} {:>12} {:>10} {:>13} {:>12} {:>10} {:>13}",
        "", "", "deg/h", "deg/h", "deg/sqrt(h)", "ug", "ug", "m/s/sqrt(h)"
    )?;
    let typical = template::typical_names();
    for name in template::builtin_names() {
        template_row(&mut out, &template::load(name)?)?;
        if typical.contains(&name) {
            let m = template::load(&format!("{name}:{}", template::TYPICAL))?;
            template_row(&mut out, &m)?;
        }
    }
    writeln!(
        out,
        "\nBI: bias instability; TO: turn-on bias, the 1σ of the constant bias drawn at each \
         start (largest axis), which often dominates a low-cost unit's navigation error.\n\
         `--imu NAME` uses the datasheet figures (the default); `--imu NAME:typical` the \
         figures read from a public recording of a real unit (docs/fidelity.md)."
    )?;
    out.flush()?;
    Ok(())
}

fn template_row(out: &mut impl Write, m: &imu_emu::errors::ImuModel) -> std::io::Result<()> {
    use std::f64::consts::PI;
    let deg_h = 180.0 / PI * 3600.0;
    let ug = 1e6 / imu_emu::units::G0;
    let largest = |v: [f64; 3]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    writeln!(
        out,
        "{:<17} {:<11} {:>12.3} {:>10.1} {:>13.4} {:>12.1} {:>10.0} {:>13.4}  {}",
        m.name,
        m.grade,
        m.gyro.bias_instability[0] * deg_h,
        largest(m.gyro.bias_turn_on) * deg_h,
        m.gyro.noise[0] * 180.0 / PI * 60.0,
        m.accel.bias_instability[0] * ug,
        largest(m.accel.bias_turn_on) * ug,
        m.accel.noise[0] * 60.0,
        m.description
    )
}

pub fn export_trajectory(a: TrajectoryArgs) -> Result<()> {
    let (motion, grid) = a.source.choice().reference(a.rate, a.start, a.duration)?;
    let motion = &motion;
    let text = imu_emu::trajectory::sample_motion(
        motion,
        grid.t0,
        grid.rate_hz,
        grid.count,
        Some(&format!("imu-emu trajectory of {}", a.source.name())),
    );
    if a.output == Path::new("-") {
        std::io::stdout().write_all(text.as_bytes())?;
    } else {
        let mut f = AtomicFile::create(&a.output)
            .with_context(|| format!("creating {}", a.output.display()))?;
        f.write_all(text.as_bytes())?;
        f.commit()?;
    }
    if let Some(p) = &a.plot {
        // At most ~4000 points per curve whatever the rate: enough for a page-wide plot.
        let n = grid.count + 1;
        let stride = n.div_ceil(4000).max(1);
        let poses: Vec<_> = (0..n)
            .step_by(stride as usize)
            .map(|k| motion.pose(grid.t0 + k as f64 / grid.rate_hz))
            .collect();
        imu_emu::plot::render(p, &imu_emu::plot::mission_panels(&poses), 2, (1600, 1200))?;
    }
    Ok(())
}
