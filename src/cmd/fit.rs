//! `imu-emu fit`: a template fitted to a static recording (any input `analyze` reads), with a
//! report and the closure check against a record simulated from the template.

use std::path::PathBuf;

use anyhow::Result;

use imu_emu::analysis::analyzer::DEFAULT_SEGMENT;
use imu_emu::analysis::recording::file_name;
use imu_emu::fit::recording_fit::{self, Settings};

use super::analyze::write_file;
use super::input::InputArgs;

#[derive(clap::Args)]
pub struct FitArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Write the fitted template here (TOML, loadable by --imu) [default: stdout]
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Name of the fitted template [default: the output file's stem, else "fitted"]
    #[arg(long)]
    pub name: Option<String>,
    /// Write the Markdown report here (with the closure check against a simulated record)
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write the ADEV plot here (.png or .svg): recording, fitted model, simulated record
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the spectral lines found as [[vibration.sine]] entries, and the broad resonances
    /// as [[vibration.random]] entries, of a scene file here
    #[arg(long)]
    pub sines: Option<PathBuf>,
    /// Seed of the closure simulation
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Welch segment length in samples: a power of two from 8 to 1048576 (2^20)
    #[arg(long, default_value_t = DEFAULT_SEGMENT)]
    pub segment: usize,
}

/// `imu-emu fit`.
pub fn fit(a: FitArgs) -> Result<()> {
    super::input::check_plot_path(a.plot.as_deref())?;
    let (rec, _) = super::input::analyze(&a.input.recording(), a.segment, "fit")?;
    let name = a.name.clone().unwrap_or_else(|| {
        a.output
            .as_ref()
            .and_then(|p| p.file_stem())
            .map_or("fitted".into(), |s| s.to_string_lossy().into_owned())
    });
    let settings = Settings {
        name,
        source: a.input.input.display().to_string(),
        template_path: a.output.clone().unwrap_or_else(|| "fitted.toml".into()),
        // The closure check is part of every report (stdout with -o, --report) and the plot.
        closure: a.report.is_some() || a.plot.is_some() || a.output.is_some(),
        seed: a.seed,
        segment: a.segment,
        plot: a
            .plot
            .as_ref()
            .map(|p| (file_name(p), file_name(&a.input.input))),
    };
    let fitted = recording_fit::fit(&rec, &settings)?;
    if let (Some(p), Some((panels, columns))) = (&a.plot, &fitted.plot) {
        let rows = panels.len().div_ceil(*columns) as u32;
        imu_emu::plot::render(p, panels, *columns, (600 * *columns as u32, 500 * rows))?;
        eprintln!("imu-emu fit: plot written to {}", p.display());
    }
    if let Some(p) = &a.report {
        write_file(p, fitted.report.as_bytes())?;
        eprintln!("imu-emu fit: report written to {}", p.display());
    }
    if let Some(p) = &a.sines {
        write_file(p, fitted.sines.as_bytes())?;
        eprintln!("imu-emu fit: spectral lines written to {}", p.display());
    }
    let alone = a.report.is_none() && a.plot.is_none() && a.sines.is_none();
    match &a.output {
        Some(p) => {
            write_file(p, fitted.toml.as_bytes())?;
            eprintln!("imu-emu fit: template written to {}", p.display());
            super::stdout::write(fitted.report.as_bytes(), "the report", false)?;
        }
        None => super::stdout::write(fitted.toml.as_bytes(), "the template", alone)?,
    }
    if fitted.failures > 0 {
        eprintln!(
            "imu-emu fit: closure: {} octaves or PSD bands of the simulated record fall outside the recording's band (see the report)",
            fitted.failures
        );
    }
    Ok(())
}
