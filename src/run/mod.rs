//! One run, any combination: a motion source (a scene, a trajectory file, a motion
//! definition, or live states in real time or lockstep), one or more units, their streams
//! and the aiding sensors', a clock (offline, paced at wall-clock rate, real time behind a
//! live input, lockstep) and where each stream goes — described by a [`RunSpec`], checked as
//! a whole by [`RunSpec::build`] and run by [`Run::execute`].

pub mod build;
pub mod clock;
mod describe;
pub mod error;
mod exec;
#[cfg(feature = "realtime")]
mod input;
pub mod lockstep;
pub mod offline;
pub mod overrides;
mod pipeline;
pub mod routing;
pub mod scene;
pub mod sinks;
pub mod sources;
pub mod spec;
pub mod status;
pub mod sync;
#[cfg(feature = "realtime")]
mod wall;

pub use build::Run;
pub use clock::Clock;
pub use error::RunError;
pub use offline::{Offline, OfflineFiles};
pub use overrides::{LiveOverrides, Overrides};
pub use pipeline::Control;
pub use spec::{LiveSpec, Route, RunSpec, Speed, StreamId, TimeBase};
pub use status::{RunReport, RunStatus};

/// Duration of a run on an unbounded motion (a live input, the static scene) when none is
/// given: "until stopped" (a year).
pub const FOREVER_S: f64 = 365.0 * 86_400.0;
