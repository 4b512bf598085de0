//! Wire formats of real IMUs, described as data (`protocols/NAME.toml`): a specification is
//! validated and compiled once into a flat plan that encodes records into frames and decodes
//! frames back. Pure: no I/O but [`load`], which reads spec files.

mod anchor;
pub mod check;
mod compile;
pub mod faults;
pub mod frame;
pub mod framing;
mod layout;
pub mod load;
pub mod plan;
pub mod spec;
pub mod stream;
mod wire;

pub use faults::{FaultInjector, FaultKind, FaultSpec, FaultTally};
pub use frame::{Channels, DecodeError, Decoded, EncoderState, GPS_WEEK_S};
pub use load::{BUILTIN, builtin_names, load, load_file};
pub use plan::{Plan, Transport};
pub use spec::{FrameSpec, SpecError};
pub use stream::{FrameInterval, StreamDecoder, StreamStats};
