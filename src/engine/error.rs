//! What the engine refuses, each error naming what to fix.

use std::path::PathBuf;

use crate::motion::sampled::ModelError;
use crate::scenes::{SceneParamError, UnknownScene};
use crate::trajectory::TrajectoryError;

use super::TIME_RESOLUTION;

/// Everything the engine can refuse, each naming what to fix.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// Bad trajectory file.
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    /// Unknown scene.
    #[error(transparent)]
    UnknownScene(#[from] UnknownScene),
    /// Bad scene parameter.
    #[error(transparent)]
    SceneParam(#[from] SceneParamError),
    /// The model cannot be built from the file (the cause is the error's `source()`).
    #[error("{path}: cannot model the trajectory")]
    Model {
        /// File.
        path: PathBuf,
        /// Cause.
        source: ModelError,
    },
    /// The requested time span is not inside the trajectory.
    #[error(
        "requested IMU span [{}, {}] s is outside the trajectory [{}, {}] s",
        crate::csvio::num(*.from), crate::csvio::num(*.to),
        crate::csvio::num(*.start), crate::csvio::num(*.end)
    )]
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
    /// Time tags too coarse for the record interval (see [`TIME_RESOLUTION`]).
    #[error(
        "times up to {} s are held to {} s, more than 1/{} of the record interval {} s: \
         successive time tags t₀ + k/rate would not be Δt apart (give an earlier --start, \
         e.g. the time since the run began, or a lower --rate)",
        crate::csvio::num(*t), crate::csvio::num(*ulp), 1.0 / TIME_RESOLUTION, crate::csvio::num(*dt)
    )]
    TimeResolution {
        /// Largest |time| of the run (s).
        t: f64,
        /// Spacing of f64 values there (s).
        ulp: f64,
        /// Record interval (s).
        dt: f64,
    },
    /// A record, its error-free counterpart or a side output came out non-finite: stopped
    /// rather than written.
    #[error("record at t = {t} s: {quantity} is {value} {stage}")]
    NonFinite {
        /// Record time (s).
        t: f64,
        /// Column of the record contract (`gyro_x`, `dv_z`, …).
        quantity: &'static str,
        /// The value (NaN or ±inf).
        value: f64,
        /// Where it appeared: in the error-free signal or after the error chain.
        stage: &'static str,
    },
    /// The template's output filter cannot run at this output rate, or is asked for something
    /// it does not provide.
    #[error("output filter: {0}")]
    Filter(String),
    /// The caller asked to stop (an interrupted run).
    #[error("stopped before the end of the run")]
    Stopped,
    /// An external trigger edge that cannot close a sample interval.
    #[error("{0}")]
    Trigger(String),
    /// An aiding sensor cannot give a sample (outside its field table, not finite).
    #[error(transparent)]
    Sensor(#[from] crate::aiding::SampleError),
    /// A magnetometer sample for the frames cannot be taken (outside its field table).
    #[error(transparent)]
    Magnetometer(#[from] crate::aiding::mag_samples::MagError),
    /// The caller gave a number of outputs other than the run writes.
    #[error("{given} outputs given for a run that writes {need}")]
    Outputs {
        /// Outputs given.
        given: usize,
        /// Outputs the run writes.
        need: usize,
    },
    /// Writing failed (the cause is the error's `source()`, not repeated here).
    #[error("writing output")]
    Io(#[from] std::io::Error),
}
