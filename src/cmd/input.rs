//! The recording flags `analyze` and `fit` share (a library [`Recording`]).

use std::path::PathBuf;

use anyhow::{Result, bail};

use imu_emu::analysis::analyzer::Analysis;
use imu_emu::analysis::reader::ReadSummary;
use imu_emu::analysis::recording::Recording;

#[derive(clap::Args)]
pub struct InputArgs {
    /// Input file: CSV, our binary records, or a protocol frame stream.
    pub input: PathBuf,
    /// Input format: csv, bin, or a protocol name (kvh1750, imar-ixcom, novatel-rawimusx, stim300) [default: bin for *.bin, else csv]
    #[arg(long)]
    pub format: Option<String>,
    /// A protocol spec file describing the frames.
    #[arg(long, conflicts_with = "format")]
    pub protocol_file: Option<PathBuf>,
    /// Sampling rate (Hz); needed when the data have no time column [default: from the time column]
    #[arg(long)]
    pub rate: Option<f64>,
    /// CSV column roles in order, e.g. t,gx,gy,gz,ax,ay,az (- skips a column; axes without a column are left out) [default: from the header]
    #[arg(long)]
    pub columns: Option<String>,
    /// Unit of the CSV gyro columns (rad/s, deg/s, deg/h, mrad/s)
    #[arg(long, default_value = "rad/s")]
    pub gyro_unit: String,
    /// Unit of the CSV accelerometer columns (m/s^2, g, mg, ug)
    #[arg(long, default_value = "m/s^2")]
    pub accel_unit: String,
    /// ADEV table input: length of the recording it was computed from, e.g. "6 h" [default: the table's `# record_length`, else the shortest its longest τ allows]
    #[arg(long)]
    pub record_length: Option<String>,
    /// ADEV table input: a further table (per-sensor file) whose channels are added
    #[arg(long = "table")]
    pub tables: Vec<PathBuf>,
    /// Keep the record's transients (knocks, spikes) in the statistics [default: left out, with 1 s on each side, and reported]
    #[arg(long)]
    pub keep_transients: bool,
}

impl InputArgs {
    /// The recording these flags name.
    pub fn recording(&self) -> Recording {
        Recording {
            input: self.input.clone(),
            format: self.format.clone(),
            protocol_file: self.protocol_file.clone(),
            rate: self.rate,
            columns: self.columns.clone(),
            gyro_unit: self.gyro_unit.clone(),
            accel_unit: self.accel_unit.clone(),
            record_length: self.record_length.clone(),
            tables: self.tables.clone(),
            keep_transients: self.keep_transients,
        }
    }
}

/// Reads `r` with Welch segments of `segment` samples; a warning names `command`.
pub fn analyze(r: &Recording, segment: usize, command: &str) -> Result<(Analysis, ReadSummary)> {
    imu_emu::analysis::analyzer::check_segment(segment).map_err(|e| anyhow::anyhow!("--{e}"))?;
    let read = r.read(segment)?;
    if let Some(w) = read.warning {
        eprintln!("imu-emu {command}: warning: {w}");
    }
    if let Some(d) = &read.analysis.dropped {
        eprintln!(
            "imu-emu {command}: warning: {}",
            imu_emu::analysis::report::dropped_summary(d)
        );
    }
    if let Some(t) = &read.analysis.transients {
        eprintln!(
            "imu-emu {command}: warning: {}",
            imu_emu::analysis::report::transients_summary(t, read.analysis.dt)
        );
    }
    Ok((read.analysis, read.summary))
}

/// Refuses a `--plot` path that does not end in `.png` or `.svg`, before any work is done.
pub fn check_plot_path(plot: Option<&std::path::Path>) -> Result<()> {
    if let Some(p) = plot
        && !p
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("png") || e.eq_ignore_ascii_case("svg"))
    {
        bail!("--plot {}: plot file must end in .png or .svg", p.display());
    }
    Ok(())
}
