//! `imu-emu plot-errors`: the injected error components of a `--truth-errors` file over time.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};

#[derive(clap::Args)]
pub struct PlotErrorsArgs {
    /// A `--truth-errors` CSV written by `generate` or `run`.
    pub input: PathBuf,
    /// The plot (.png or .svg).
    #[arg(short, long)]
    pub output: PathBuf,
    /// At most this many points per line (the largest-magnitude sample of each stretch).
    #[arg(long, default_value_t = 4000)]
    pub points: usize,
}

/// Reads the file, builds the panels, renders them.
pub fn plot_errors(a: PlotErrorsArgs) -> Result<()> {
    let text = std::fs::read_to_string(&a.input)
        .with_context(|| format!("{}: cannot read", a.input.display()))?;
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines
        .next()
        .with_context(|| format!("{}: empty file", a.input.display()))?
        .split(',')
        .map(str::trim)
        .collect();
    let mut rows = Vec::new();
    for (i, line) in lines.enumerate() {
        let row = line
            .split(',')
            .map(|v| v.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect::<Option<Vec<f64>>>();
        match row {
            Some(r) if r.len() == header.len() => rows.push(r),
            _ => bail!(
                "{}: line {}: expected {} finite numbers",
                a.input.display(),
                i + 2,
                header.len()
            ),
        }
    }
    if rows.is_empty() {
        bail!("{}: no data rows", a.input.display());
    }
    let panels = imu_emu::analysis::error_plot::error_panels(&header, &rows, a.points)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.input.display()))?;
    imu_emu::plot::render(&a.output, &panels, 3, (1800, 1000))?;
    eprintln!("imu-emu: wrote {}", a.output.display());
    Ok(())
}
