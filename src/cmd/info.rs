//! The listing commands (`scenes`, `templates`) and `trajectory`.

use std::path::{Path, PathBuf};

use anyhow::Result;

use imu_emu::motion::Motion;

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

/// `imu-emu templates`: the built-in IMU templates' headline figures. Written, not printed:
/// a full disk or a closed pipe is an error, never a panic.
pub fn list_templates() -> Result<()> {
    let table = imu_emu::errors::headline::table()?;
    super::stdout::write(table.as_bytes(), "the templates", true)
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
        super::stdout::write(text.as_bytes(), "the trajectory", a.plot.is_none())?;
    } else {
        imu_emu::output::write_whole(&a.output, text.as_bytes())?;
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
