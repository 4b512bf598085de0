//! The recording flags `analyze` and `fit` share, and reading a recording with them into an
//! [`Analysis`].

use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use imu_emu::analysis::adev_table::{self, TableOptions};
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
    /// ADEV table input: length of the recording it was computed from, e.g. "6 h" [default: the table's `# record_length`, else the shortest its longest τ allows]
    #[arg(long)]
    pub record_length: Option<String>,
    /// ADEV table input: a further table (per-sensor file) whose channels are added
    #[arg(long = "table")]
    pub tables: Vec<PathBuf>,
}

impl InputArgs {
    /// Input flags for another file read with auto-detected format (`format`: a protocol,
    /// csv or bin, when detection is not enough).
    pub fn other(input: PathBuf, format: Option<String>) -> InputArgs {
        InputArgs {
            input,
            format,
            protocol_file: None,
            rate: None,
            columns: None,
            gyro_unit: "rad/s".into(),
            accel_unit: "m/s^2".into(),
            record_length: None,
            tables: Vec::new(),
        }
    }

    /// The input as an ADEV table, when it is one (a CSV whose header starts with `tau_`).
    fn table(&self) -> Result<Option<Analysis>> {
        let csv =
            matches!(self.format.as_deref(), None | Some("csv")) && self.protocol_file.is_none();
        let is_bin = self.input.extension().is_some_and(|e| e == "bin");
        if !csv || (is_bin && self.format.is_none()) {
            return Ok(None);
        }
        let read = |p: &PathBuf| {
            std::fs::read_to_string(p).with_context(|| format!("{}: cannot read", p.display()))
        };
        let text = match std::fs::read(&self.input) {
            Ok(b) => String::from_utf8_lossy(&b).into_owned(),
            // The recording reader reports what is wrong with the file.
            Err(_) => return Ok(None),
        };
        let first = text
            .lines()
            .map(str::trim)
            .find(|l| !l.is_empty() && !l.starts_with('#'));
        if !first.is_some_and(adev_table::is_table_header) {
            if let Some(t) = self.tables.first() {
                bail!("--table {}: only with an ADEV table as input", t.display());
            }
            return Ok(None);
        }
        let record_length = match &self.record_length {
            Some(t) => {
                let v = units::parse(t, Kind::Time)
                    .with_context(|| format!("--record-length `{t}`"))?
                    .0;
                if v <= 0.0 {
                    bail!("--record-length `{t}`: expected a positive duration");
                }
                Some(v)
            }
            None => None,
        };
        let opts = TableOptions {
            rate: self.rate,
            record_length,
        };
        let mut table = adev_table::parse(&text, &self.input, opts)?;
        for p in &self.tables {
            table.merge(adev_table::parse(&read(p)?, p, opts)?, p)?;
        }
        Ok(Some(table.analysis()))
    }

    /// Reads the recording (or ADEV table) through an analyzer with Welch segments of `segment` samples;
    /// `command` names the caller in warnings. Returns the analysis and the read summary.
    pub fn analyze(&self, segment: usize, command: &str) -> Result<(Analysis, ReadSummary)> {
        if let Some(r) = self.rate
            && !(r > 0.0 && r.is_finite())
        {
            bail!("--rate: expected a positive number of Hz, got {r}");
        }
        if let Some(t) = self.table()? {
            return Ok((t, ReadSummary::default()));
        }
        if self.record_length.is_some() {
            bail!("--record-length: only with an ADEV table as input (a recording has its own)");
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
