//! The signal engine: a motion model, a time grid, an IMU's error chain and an output encoding,
//! run block by block ([`Producer`]): ideal records → error chain → encoded bytes. Every
//! consumer — files, the real-time pacer, the navigator — takes its records from here.
//!
//! `source_spec` (where the trajectory comes from) and `grid` (the span as records) plan a
//! run; `producer` makes it block by block through an `encoding`; `drain` writes a whole run
//! offline; `frames` and its neighbours turn blocks into timed frame streams.

mod drain;
mod encoding;
mod error;
pub mod filtered;
pub mod frames;
mod grid;
mod producer;
mod source_spec;
pub mod timed;
mod timed_merge;
pub mod trigger;

pub use drain::{drain, run};
pub use encoding::Encoding;
pub use error::EngineError;
pub use grid::{DEFAULT_UNBOUNDED_DURATION_S, Grid, TIME_RESOLUTION, plan, released};
pub use producer::{Block, Producer, TruthPlace};
pub use source_spec::{SourceSpec, build_motion};

/// The temperature frames carry when the scene gives no temperature profile (°C).
pub const DEFAULT_FRAME_CELSIUS: f64 = 25.0;

/// Records per block: large enough to amortise the writer, small enough to stay in cache.
pub const BLOCK: usize = 4096;

#[cfg(test)]
mod tests;
