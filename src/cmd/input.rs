//! The recording flags `analyze` and `fit` share, and reading a recording with them into an
//! [`Analysis`].

use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use imu_emu::analysis::analyzer::{Analysis, Analyzer};
use imu_emu::analysis::reader::{self, CsvOptions, InputFormat, ReadSummary};
use imu_emu::units::{self, Kind};

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
    /// CSV column roles in order, e.g. t,gx,gy,gz,ax,ay,az (- skips a column) [default: from the header]
    #[arg(long)]
    pub columns: Option<String>,
    /// Unit of the CSV gyro columns (rad/s, deg/s, deg/h, mrad/s)
    #[arg(long, default_value = "rad/s")]
    pub gyro_unit: String,
    /// Unit of the CSV accelerometer columns (m/s^2, g, mg, ug)
    #[arg(long, default_value = "m/s^2")]
    pub accel_unit: String,
}

impl InputArgs {
    /// Reads the recording through an analyzer with Welch segments of `segment` samples;
    /// `command` names the caller in warnings. Returns the analysis and the read summary.
    pub fn analyze(&self, segment: usize, command: &str) -> Result<(Analysis, ReadSummary)> {
        if let Some(r) = self.rate
            && !(r > 0.0 && r.is_finite())
        {
            bail!("--rate: expected a positive number of Hz, got {r}");
        }
        let unit = |text: &str, kind: Kind, flag: &str| -> Result<f64> {
            Ok(units::parse(&format!("1 {text}"), kind)
                .with_context(|| format!("{flag} `{text}`"))?
                .0)
        };
        let csv = CsvOptions {
            columns: match &self.columns {
                Some(c) => {
                    Some(reader::parse_columns(c).map_err(|e| anyhow::anyhow!("--columns: {e}"))?)
                }
                None => None,
            },
            gyro_scale: unit(&self.gyro_unit, Kind::AngularRate, "--gyro-unit")?,
            accel_scale: unit(&self.accel_unit, Kind::Acceleration, "--accel-unit")?,
        };
        let is_bin = self.input.extension().is_some_and(|e| e == "bin");
        let (format, spec_rate) = match (self.format.as_deref(), &self.protocol_file) {
            (_, Some(p)) => {
                let (spec, plan) = imu_emu::protocol::load(&p.to_string_lossy())?;
                (InputFormat::Frames(plan), spec.rate_hz)
            }
            (Some("csv"), _) => (InputFormat::Csv(csv), None),
            (Some("bin"), _) => (InputFormat::Bin, None),
            (Some(name), _) => {
                let (spec, plan) = imu_emu::protocol::load(name).with_context(|| {
                    format!(
                        "--format `{name}`: not csv, bin or a protocol (built-in: {})",
                        imu_emu::protocol::builtin_names().join(", ")
                    )
                })?;
                (InputFormat::Frames(plan), spec.rate_hz)
            }
            (None, None) if is_bin => (InputFormat::Bin, None),
            (None, None) => (InputFormat::Csv(csv), None),
        };
        let rate = self.rate.or(spec_rate);
        let mut an = Analyzer::new(segment);
        let summary = reader::read(&self.input, &format, rate.map(|r| 1.0 / r), |t, v| {
            an.push(t, v)
        })?;
        if summary.samples < 8 {
            bail!(
                "{}: {} samples; the analysis needs at least 8",
                self.input.display(),
                summary.samples
            );
        }
        let dt = match (rate, an.measured_dt()) {
            (Some(r), _) => 1.0 / r,
            (None, Some(dt)) => dt,
            (None, None) => bail!(
                "{}: no usable time column; give the sampling rate with --rate",
                self.input.display()
            ),
        };
        let res = an.finish(dt);
        let (smin, smax) = res.step_range;
        if smin.is_finite() && (smin < 0.99 * dt || smax > 1.01 * dt) {
            eprintln!(
                "imu-emu {command}: warning: time steps range from {smin} s to {smax} s; the analysis assumes uniform sampling at Δt = {dt} s"
            );
        }
        Ok((res, summary))
    }
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
