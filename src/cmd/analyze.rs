//! `imu-emu analyze`: statistics, Allan deviation with fitted IEEE terms, and PSD of a
//! recording (ours or anyone's), optionally against a template, with plots.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use imu_emu::analysis::analyzer::DEFAULT_SEGMENT;
use imu_emu::analysis::recording::{Recording, file_name};
use imu_emu::fit::analysis_report::{Subject, report_on};

use super::input::{self, InputArgs};

#[derive(clap::Args)]
pub struct AnalyzeArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// IMU template to compare with (name or file): theory curves and measured/specified per term
    #[arg(long)]
    pub imu: Option<String>,
    /// Write the plots here (.png or .svg)
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the ADEV / PSD curves here as CSV
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Welch segment length in samples: a power of two from 8 to 1048576 (2^20)
    #[arg(long, default_value_t = DEFAULT_SEGMENT)]
    pub segment: usize,
    /// A second recording or ADEV table to compare with: overlaid on the plot, terms compared (repeatable)
    #[arg(long)]
    pub reference: Vec<PathBuf>,
    /// Format of the reference (csv, bin or a protocol name) [default: bin for *.bin, else csv]
    #[arg(long, requires = "reference")]
    pub reference_format: Option<String>,
    /// Write the per-term comparison with the reference here as CSV
    #[arg(long, requires = "reference")]
    pub compare_csv: Option<PathBuf>,
}

/// `imu-emu analyze`.
pub fn analyze(a: AnalyzeArgs) -> Result<()> {
    super::input::check_plot_path(a.plot.as_deref())?;
    let model = a
        .imu
        .as_deref()
        .map(imu_emu::errors::template::load)
        .transpose()?;
    let (res, summary) = input::analyze(&a.input.recording(), a.segment, "analyze")?;
    let references = a
        .reference
        .iter()
        .map(|p| {
            let r = Recording::new(p.clone(), a.reference_format.clone());
            let (res, _) = input::analyze(&r, a.segment, "analyze")
                .with_context(|| format!("--reference {}", p.display()))?;
            Ok((res, file_name(p)))
        })
        .collect::<Result<Vec<_>>>()?;
    let subject = Subject {
        analysis: &res,
        summary: &summary,
        name: a.input.input.display().to_string(),
        title: file_name(&a.input.input),
        model: model.as_ref(),
        references: &references,
    };
    let r = report_on(&subject, a.plot.is_some());
    if let (Some(p), Some(csv)) = (&a.compare_csv, &r.compare_csv) {
        write_file(p, csv.as_bytes())?;
    }
    if let Some(p) = &a.plot {
        let (panels, columns, size) = &r.plot;
        imu_emu::plot::render(p, panels, *columns, *size)?;
        eprintln!("imu-emu analyze: plot written to {}", p.display());
    }
    if let Some(p) = &a.csv {
        write_file(p, r.curves_csv.as_bytes())?;
    }
    // The report goes to stdout in one write at the end, after the files are whole.
    let alone = a.plot.is_none() && a.csv.is_none() && a.compare_csv.is_none();
    super::stdout::write(r.text.as_bytes(), "the report", alone)?;
    if let Some(v) = r.verdict {
        anyhow::bail!(v);
    }
    Ok(())
}

/// Writes `bytes` to `p` whole or not at all.
pub fn write_file(p: &Path, bytes: &[u8]) -> Result<()> {
    Ok(imu_emu::output::write_whole(p, bytes)?)
}
