//! One run: a motion source, one or more units, their streams, a clock and sinks, composed
//! into one pipeline.

#[cfg(feature = "realtime")]
pub mod live_realtime;
pub mod lockstep;
#[cfg(feature = "realtime")]
pub mod merge;
pub mod target;
#[cfg(feature = "realtime")]
pub mod trigger;
