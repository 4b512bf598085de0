//! A recording named by a user — a CSV in any column layout and units, our binary records, a
//! protocol's frame stream, or an ADEV table (with further per-sensor tables) — read into an
//! [`Analysis`] (`imu-emu analyze` and `fit`). The format is given or told from the file: an
//! ADEV table by its `tau_` header, binary records by a `.bin` name, else CSV.

use std::error::Error;
use std::path::{Path, PathBuf};

use super::adev_table::{self, TableOptions};
use super::analyzer::Analysis;
use super::passes::{First, Passes, Sink};
use super::reader::{self, CsvOptions, InputFormat, ReadSummary};
use crate::csvio::CsvLines;
use crate::units::{self, Kind};

/// A recording and how to read it; messages name the flags of `imu-emu analyze`.
#[derive(Clone, Debug)]
pub struct Recording {
    /// The file: CSV, our binary records, a protocol frame stream or an ADEV table.
    pub input: PathBuf,
    /// csv, bin or a protocol name; `None`: bin for `*.bin`, else CSV (or an ADEV table).
    pub format: Option<String>,
    /// A protocol spec file describing the frames.
    pub protocol_file: Option<PathBuf>,
    /// Sampling rate (Hz); `None`: from the time column (or the protocol's nominal rate).
    pub rate: Option<f64>,
    /// CSV column roles in order (`t,gx,gy,gz,ax,ay,az`, `-` skips); `None`: from the header.
    pub columns: Option<String>,
    /// Unit of the CSV gyro columns.
    pub gyro_unit: String,
    /// Unit of the CSV accelerometer columns.
    pub accel_unit: String,
    /// ADEV table input: the length of the recording it was computed from.
    pub record_length: Option<String>,
    /// ADEV table input: further tables whose channels are added.
    pub tables: Vec<PathBuf>,
    /// Keep the record's transients in the statistics (else they are left out:
    /// [`super::transients`]).
    pub keep_transients: bool,
}

/// A recording read.
pub struct Read {
    /// Its statistics, Allan deviation and PSD.
    pub analysis: Analysis,
    /// What was read besides the samples.
    pub summary: ReadSummary,
    /// Time steps that are not uniform, in words: the analysis assumed they are.
    pub warning: Option<String>,
}

/// Why a recording cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// `what` (a flag, a file) is at fault, because of `source`.
    #[error("{what}")]
    Context {
        /// What was at fault.
        what: String,
        /// The cause.
        #[source]
        source: Box<dyn Error + Send + Sync>,
    },
    /// The input or a flag is refused, with the reason.
    #[error("{0}")]
    Refused(String),
    /// The file, a table or a protocol could not be read.
    #[error(transparent)]
    Read(Box<dyn Error + Send + Sync>),
}

fn read_error(e: impl Into<Box<dyn Error + Send + Sync>>) -> RecordingError {
    RecordingError::Read(e.into())
}

fn context<E: Into<Box<dyn Error + Send + Sync>>>(
    what: impl FnOnce() -> String,
) -> impl FnOnce(E) -> RecordingError {
    move |e| RecordingError::Context {
        what: what(),
        source: e.into(),
    }
}

impl Recording {
    /// `input` with its format told from the file (`format`: a protocol, csv or bin, when
    /// that is not enough), CSV units SI.
    pub fn new(input: PathBuf, format: Option<String>) -> Recording {
        Recording {
            input,
            format,
            protocol_file: None,
            rate: None,
            columns: None,
            gyro_unit: "rad/s".into(),
            accel_unit: "m/s^2".into(),
            record_length: None,
            tables: Vec::new(),
            keep_transients: false,
        }
    }

    /// The input as an ADEV table, when it is one (a CSV whose header starts with `tau_`).
    fn table(&self) -> Result<Option<Analysis>, RecordingError> {
        let csv =
            matches!(self.format.as_deref(), None | Some("csv")) && self.protocol_file.is_none();
        let is_bin = self.input.extension().is_some_and(|e| e == "bin");
        if !csv || (is_bin && self.format.is_none()) {
            return Ok(None);
        }
        // Only a regular file is sniffed: a pipe read here would be gone for the reader.
        // Only its first line with content is read: a recording may be gigabytes.
        // (A stat, not an open: opening a named pipe waits for its writer.)
        if !std::fs::metadata(&self.input).is_ok_and(|m| m.is_file()) {
            return Ok(None);
        }
        let file = match std::fs::File::open(&self.input) {
            Ok(f) => f,
            // The recording reader reports what is wrong with the file.
            Err(_) => return Ok(None),
        };
        // The recording's own line reader, with its bound on a line: a file without line
        // ends costs what it costs that reader, which then names the line and the limit.
        let mut lines = CsvLines::new(
            std::io::BufReader::with_capacity(1 << 16, file),
            &self.input,
        );
        let first = lines.next_line().ok().flatten().map(str::to_string);
        if !first.as_deref().is_some_and(adev_table::is_table_header) {
            if let Some(t) = self.tables.first() {
                return Err(RecordingError::Refused(format!(
                    "--table {}: only with an ADEV table as input",
                    t.display()
                )));
            }
            return Ok(None);
        }
        let record_length = match &self.record_length {
            Some(t) => {
                let v = units::parse(t, Kind::Time)
                    .map_err(context(|| format!("--record-length `{t}`")))?
                    .0;
                if v <= 0.0 {
                    return Err(RecordingError::Refused(format!(
                        "--record-length `{t}`: expected a positive duration"
                    )));
                }
                Some(v)
            }
            None => None,
        };
        let opts = TableOptions {
            rate: self.rate,
            record_length,
        };
        let mut table = adev_table::read_file(&self.input, opts).map_err(read_error)?;
        for p in &self.tables {
            let other = adev_table::read_file(p, opts).map_err(read_error)?;
            table.merge(other, p).map_err(read_error)?;
        }
        Ok(Some(table.analysis()))
    }

    /// Reads the recording (or ADEV table) through an analyzer with Welch segments of
    /// `segment` samples.
    pub fn read(&self, segment: usize) -> Result<Read, RecordingError> {
        super::analyzer::check_segment(segment).map_err(RecordingError::Refused)?;
        let refuse = |m: String| Err(RecordingError::Refused(m));
        if let Some(r) = self.rate {
            super::analyzer::check_rate(r)
                .map_err(|e| RecordingError::Refused(format!("--{e}")))?;
        }
        if let Some(t) = self.table()? {
            return Ok(Read {
                analysis: t,
                summary: ReadSummary::default(),
                warning: None,
            });
        }
        if self.record_length.is_some() {
            return refuse(
                "--record-length: only with an ADEV table as input (a recording has its own)"
                    .into(),
            );
        }
        let unit = |text: &str, kind: Kind, flag: &str| -> Result<f64, RecordingError> {
            Ok(units::parse(&format!("1 {text}"), kind)
                .map_err(context(|| format!("{flag} `{text}`")))?
                .0)
        };
        let csv = CsvOptions {
            columns: match &self.columns {
                Some(c) => Some(
                    reader::parse_columns(c)
                        .map_err(|e| RecordingError::Refused(format!("--columns: {e}")))?,
                ),
                None => None,
            },
            gyro_scale: unit(&self.gyro_unit, Kind::AngularRate, "--gyro-unit")?,
            accel_scale: unit(&self.accel_unit, Kind::Acceleration, "--accel-unit")?,
        };
        let is_bin = self.input.extension().is_some_and(|e| e == "bin");
        let (format, spec_rate) = match (self.format.as_deref(), &self.protocol_file) {
            (_, Some(p)) => {
                let (spec, plan) =
                    crate::protocol::load(&p.to_string_lossy()).map_err(read_error)?;
                (InputFormat::Frames(plan), spec.rate_hz)
            }
            (Some("csv"), _) => (InputFormat::Csv(csv), None),
            (Some("bin"), _) => (InputFormat::Bin, None),
            (Some(name), _) => {
                let (spec, plan) = crate::protocol::load(name).map_err(context(|| {
                    format!(
                        "--format `{name}`: not csv, bin or a protocol (built-in: {})",
                        crate::protocol::builtin_names().join(", ")
                    )
                }))?;
                (InputFormat::Frames(plan), spec.rate_hz)
            }
            (None, None) if is_bin => (InputFormat::Bin, None),
            (None, None) => (InputFormat::Csv(csv), None),
        };
        let rate = self.rate.or(spec_rate);
        let read = |sink: &mut Sink<'_>| {
            reader::read(&self.input, &format, rate.map(|r| 1.0 / r), sink).map_err(read_error)
        };
        let mut first = First::new(segment);
        let summary = read(&mut |t, v| first.push(t, v))?;
        let name = self.input.display();
        if summary.samples < 8 {
            return refuse(format!(
                "{name}: {} samples; the analysis needs at least 8",
                summary.samples
            ));
        }
        let dt = match (rate, first.analyzer.measured_dt()) {
            (Some(r), _) => 1.0 / r,
            (None, Some(dt)) => dt,
            (None, None) => {
                return refuse(format!(
                    "{name}: no usable time column; give the sampling rate with --rate"
                ));
            }
        };
        // A pipe cannot be read twice, and opening a named one again would wait for a
        // writer that never comes (a stat, not an open).
        let again = if std::fs::metadata(&self.input).is_ok_and(|m| m.is_file()) {
            Ok(|sink: &mut Sink<'_>| read(sink).map(|s| s.samples))
        } else {
            Err(format!(
                "{name}: not a regular file (a pipe cannot be read twice): transients (knocks, spikes) were not looked for"
            ))
        };
        let passes = Passes {
            segment,
            keep: self.keep_transients,
            missing: summary.missing,
            dt_given: rate.is_some(),
        };
        let (analysis, unsearched) = passes.finish(first, dt, &name.to_string(), again)?;
        let dt = analysis.dt;
        let (smin, smax) = analysis.step_range;
        let steps_warning = (smin.is_finite() && (smin < 0.99 * dt || smax > 1.01 * dt)).then(|| {
            format!(
                "time steps range from {smin} s to {smax} s; the analysis assumes uniform sampling at Δt = {dt} s"
            )
        });
        let warning = match (steps_warning, unsearched) {
            (Some(a), Some(b)) => Some(format!("{a}; {b}")),
            (a, b) => a.or(b),
        };
        Ok(Read {
            analysis,
            summary,
            warning,
        })
    }

    /// The file's name, for titles (`input` when it has none).
    pub fn title(&self) -> String {
        file_name(&self.input)
    }
}

/// A path's file name, for titles and tables (`input` when it has none).
pub fn file_name(p: &Path) -> String {
    p.file_name()
        .map_or("input".into(), |n| n.to_string_lossy().into_owned())
}
