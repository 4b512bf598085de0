//! `imu-emu plot-errors`: the injected error components of a `--truth-errors` file over time.

use std::path::PathBuf;

use anyhow::Result;

#[derive(clap::Args)]
pub struct PlotErrorsArgs {
    /// A `--truth-errors` CSV written by `generate` or `run`.
    pub input: PathBuf,
    /// The plot (.png or .svg).
    #[arg(short, long)]
    pub output: PathBuf,
    /// At most this many points per line, at least half as many (the largest-magnitude sample
    /// of each stretch); up to 100 000.
    #[arg(long, default_value_t = 4000)]
    pub points: usize,
}

/// Reads the file, builds the panels, renders them.
pub fn plot_errors(a: PlotErrorsArgs) -> Result<()> {
    let panels = imu_emu::analysis::error_plot::file_panels(&a.input, a.points)?;
    imu_emu::plot::render(&a.output, &panels, 3, (1800, 1000))?;
    eprintln!("imu-emu: wrote {}", a.output.display());
    Ok(())
}
