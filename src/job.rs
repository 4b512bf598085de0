//! An offline generation job: a motion model, a time grid and an output encoding, run block by
//! block into any writer. The binary adds flags, files and the progress bar around it.

use std::io::Write;
use std::path::PathBuf;

use crate::errors::ErrorChain;
use crate::generator::IdealImu;
use crate::motion::Motion;
use crate::motion::sampled::{ModelError, ModelSettings, SampledMotion};
use crate::output::{self, Format};
use crate::record::Record;
use crate::scenes::{self, SceneParamError, SceneParams, UnknownScene};
use crate::source::AnyMotion;
use crate::trajectory::{self, TrajectoryError};

/// Duration of a run on an unbounded scene when none is given (s).
pub const DEFAULT_UNBOUNDED_DURATION_S: f64 = 60.0;

/// Records per block: large enough to amortise the writer, small enough to stay in cache.
pub const BLOCK: usize = 4096;

/// Where the trajectory comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum SourceSpec {
    /// A built-in scene with its parameters.
    Scene(String, SceneParams),
    /// A trajectory CSV.
    File(PathBuf),
}

/// Everything a job can refuse, each naming what to fix.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// Bad trajectory file.
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    /// Unknown scene.
    #[error(transparent)]
    UnknownScene(#[from] UnknownScene),
    /// Bad scene parameter.
    #[error(transparent)]
    SceneParam(#[from] SceneParamError),
    /// The model cannot be built from the file.
    #[error("{path}: {source}")]
    Model {
        /// File.
        path: PathBuf,
        /// Cause.
        source: ModelError,
    },
    /// The requested time span is not inside the trajectory.
    #[error("requested IMU span [{from}, {to}] s is outside the trajectory [{start}, {end}] s")]
    Span {
        /// Requested start.
        from: f64,
        /// Requested end.
        to: f64,
        /// Trajectory start.
        start: f64,
        /// Trajectory end.
        end: f64,
    },
    /// A setting outside its range.
    #[error("`{key}` = {value}: {expected}")]
    Setting {
        /// Setting name.
        key: &'static str,
        /// Value given.
        value: String,
        /// What is expected.
        expected: &'static str,
    },
    /// Writing failed.
    #[error("writing output: {0}")]
    Io(#[from] std::io::Error),
}

/// Builds the motion model of a source.
pub fn build_motion(source: &SourceSpec, model: ModelSettings) -> Result<AnyMotion, JobError> {
    match source {
        SourceSpec::Scene(name, params) => Ok(AnyMotion::Scene(scenes::build(name, params)??)),
        SourceSpec::File(path) => {
            let samples = trajectory::read(path)?;
            if samples.len() < model.min_samples() {
                return Err(TrajectoryError::TooFewSamples {
                    path: path.clone(),
                    got: samples.len(),
                    need: model.min_samples(),
                }
                .into());
            }
            let m = SampledMotion::new(&samples, model).map_err(|source| JobError::Model {
                path: path.clone(),
                source,
            })?;
            Ok(AnyMotion::Sampled(m))
        }
    }
}

/// The time grid of a run: t₀ and the number of records.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// t₀ (s); record k is at t₀ + k/rate.
    pub t0: f64,
    /// IMU rate (Hz).
    pub rate_hz: f64,
    /// Number of records.
    pub count: u64,
}

/// Checks a requested span against the motion and returns the grid.
pub fn plan(
    motion: &impl Motion,
    rate_hz: f64,
    start: Option<f64>,
    duration: Option<f64>,
) -> Result<Grid, JobError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= 1.0e7) {
        return Err(JobError::Setting {
            key: "rate",
            value: rate_hz.to_string(),
            expected: "a rate in (0, 1e7] Hz",
        });
    }
    let (m0, m1) = (motion.start(), motion.end());
    let t0 = start.unwrap_or(m0);
    if !t0.is_finite() {
        return Err(JobError::Setting {
            key: "start",
            value: t0.to_string(),
            expected: "a finite time",
        });
    }
    let duration = match duration {
        Some(d) if d.is_finite() && d > 0.0 => d,
        Some(d) => {
            return Err(JobError::Setting {
                key: "duration",
                value: d.to_string(),
                expected: "a positive duration in seconds",
            });
        }
        None if m1.is_finite() => m1 - t0,
        None => DEFAULT_UNBOUNDED_DURATION_S,
    };
    // Rounding slack: a span that ends within 1e-9 s of the last sample is still inside.
    let count = (duration * rate_hz + 1e-9).floor();
    let t_last = t0 + count / rate_hz;
    let slack = 1e-9 * m1.abs().max(1.0);
    if t0 < m0 - slack || t_last > m1 + slack || count < 1.0 {
        return Err(JobError::Span {
            from: t0,
            to: t0 + duration,
            start: m0,
            end: m1,
        });
    }
    Ok(Grid {
        t0,
        rate_hz,
        count: count as u64,
    })
}

/// What the main output carries.
#[derive(Clone, Debug)]
pub enum Encoding {
    /// The record contract: CSV or binary.
    Records(Format),
    /// A protocol's frames, one per record; side files (truth, injected errors) use `side`.
    Frames {
        /// The compiled frame.
        plan: Box<crate::protocol::Plan>,
        /// Counter and GPS time reference.
        state: crate::protocol::EncoderState,
        /// The sensor temperature carried by frames that have one (°C).
        temperature: f64,
        /// Format of the side files.
        side: Format,
    },
}

impl From<Format> for Encoding {
    fn from(f: Format) -> Encoding {
        Encoding::Records(f)
    }
}

impl Encoding {
    /// Format of the side files (truth, injected errors).
    fn side(&self) -> Format {
        match self {
            Encoding::Records(f) => *f,
            Encoding::Frames { side, .. } => *side,
        }
    }

    /// Appends the main output's bytes for `records`.
    fn encode(&mut self, records: &[Record], buf: &mut Vec<u8>) {
        match self {
            Encoding::Records(f) => output::encode(*f, records, buf),
            Encoding::Frames {
                plan,
                state,
                temperature,
                ..
            } => {
                for r in records {
                    plan.encode(r, *temperature, state, buf);
                }
            }
        }
    }
}

/// Runs the job into `out`, calling `progress(records_done)` after each block.
///
/// With an error `chain`, records are corrupted after generation; `truth`, if given, receives
/// the error-free records in the same format and on the same time grid, and `injected` the
/// error each stage added to each record (`output::components_header`).
#[allow(clippy::too_many_arguments)] // the run's inputs, each distinct; a struct would only rename them
pub fn run(
    motion: AnyMotion,
    grid: Grid,
    nodes: usize,
    encoding: impl Into<Encoding>,
    mut chain: Option<ErrorChain>,
    out: &mut impl Write,
    mut truth: Option<&mut dyn Write>,
    mut injected: Option<&mut dyn Write>,
    mut progress: impl FnMut(u64),
) -> Result<(), JobError> {
    if !(1..=crate::quadrature::MAX_NODES).contains(&nodes) {
        return Err(JobError::Setting {
            key: "quadrature",
            value: nodes.to_string(),
            expected: "1 to 16 Gauss–Legendre nodes",
        });
    }
    let mut imu = IdealImu::new(motion, grid.rate_hz, grid.t0, grid.count, nodes);
    let mut block = vec![Record::default(); BLOCK];
    let needs_rot = chain.as_ref().is_some_and(|c| c.needs_rotation_terms());
    let mut rot =
        vec![crate::generator::RotationTerms::default(); if needs_rot { BLOCK } else { 0 }];
    let mut buf = Vec::with_capacity(BLOCK * 104);
    let mut encoding = encoding.into();
    let format = encoding.side();
    if matches!(encoding, Encoding::Records(Format::Csv)) {
        out.write_all(output::csv_header().as_bytes())?;
    }
    if format == Format::Csv {
        if let Some(t) = truth.as_mut() {
            t.write_all(output::csv_header().as_bytes())?;
        }
        if let Some(t) = injected.as_mut() {
            t.write_all(output::components_header().as_bytes())?;
        }
    }
    if injected.is_some() {
        chain = Some(
            chain
                .take()
                .unwrap_or_else(ErrorChain::ideal)
                .with_components(),
        );
    }
    let mut k = 1u64;
    while k <= grid.count {
        let n = ((grid.count - k + 1) as usize).min(BLOCK);
        imu.fill(k, &mut block[..n]);
        if let Some(t) = truth.as_mut() {
            buf.clear();
            output::encode(format, &block[..n], &mut buf);
            t.write_all(&buf)?;
        }
        if let Some(c) = chain.as_mut() {
            if c.needs_rotation_terms() {
                imu.rotation_terms(k, &mut rot[..n]);
                c.apply_with(&mut block[..n], Some(&rot[..n]));
            } else {
                c.apply(&mut block[..n]);
            }
        }
        if let (Some(w), Some(c)) = (injected.as_mut(), chain.as_ref()) {
            buf.clear();
            output::encode_components(format, &block[..n], c.components(), &mut buf);
            w.write_all(&buf)?;
        }
        buf.clear();
        encoding.encode(&block[..n], &mut buf);
        out.write_all(&buf)?;
        k += n as u64;
        progress(k - 1);
    }
    out.flush()?;
    if let Some(t) = truth.as_mut() {
        t.flush()?;
    }
    if let Some(t) = injected.as_mut() {
        t.flush()?;
    }
    Ok(())
}
