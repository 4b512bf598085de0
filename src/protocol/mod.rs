//! Wire formats of real IMUs, described as data (`protocols/NAME.toml`): a specification is
//! validated and compiled once into a flat plan that encodes records into frames and decodes
//! frames back (DESIGN §5). Pure: no I/O.

pub mod check;
pub mod faults;
pub mod framing;
pub mod layout;
pub mod plan;
pub mod spec;
pub mod stream;

pub use faults::{FaultInjector, FaultKind, FaultSpec, FaultTally};
pub use plan::{DecodeError, Decoded, EncoderState, Plan, Transport};
pub use spec::{FrameSpec, SpecError};
pub use stream::{StreamDecoder, StreamStats};

use std::path::Path;

/// The built-in specifications, embedded at compile time (a test checks every file in
/// `protocols/` is listed).
pub const BUILTIN: &[(&str, &str)] = &[
    (
        "hg1700-sdlc",
        include_str!("../../protocols/hg1700-sdlc.toml"),
    ),
    ("hg4930", include_str!("../../protocols/hg4930.toml")),
    (
        "imar-ixcom",
        include_str!("../../protocols/imar-ixcom.toml"),
    ),
    ("kvh1750", include_str!("../../protocols/kvh1750.toml")),
    ("kvh1750-b", include_str!("../../protocols/kvh1750-b.toml")),
    ("kvh1750-c", include_str!("../../protocols/kvh1750-c.toml")),
    ("ln200", include_str!("../../protocols/ln200.toml")),
    (
        "ln200-sdlc",
        include_str!("../../protocols/ln200-sdlc.toml"),
    ),
    (
        "mavlink-highres-imu",
        include_str!("../../protocols/mavlink-highres-imu.toml"),
    ),
    (
        "mavlink-hil-sensor",
        include_str!("../../protocols/mavlink-hil-sensor.toml"),
    ),
    (
        "novatel-rawimusx",
        include_str!("../../protocols/novatel-rawimusx.toml"),
    ),
    ("stim300", include_str!("../../protocols/stim300.toml")),
    (
        "stim300-90",
        include_str!("../../protocols/stim300-90.toml"),
    ),
    (
        "stim300-91",
        include_str!("../../protocols/stim300-91.toml"),
    ),
    (
        "stim300-a7",
        include_str!("../../protocols/stim300-a7.toml"),
    ),
];

/// Names of the built-in protocols.
pub fn builtin_names() -> Vec<&'static str> {
    BUILTIN.iter().map(|b| b.0).collect()
}

/// Loads and compiles a built-in protocol by name or a spec file by path.
pub fn load(name_or_path: &str) -> Result<(FrameSpec, Plan), SpecError> {
    let (text, path) = match BUILTIN.iter().find(|b| b.0 == name_or_path) {
        Some((n, t)) => (t.to_string(), format!("protocols/{n}.toml")),
        None => {
            let p = Path::new(name_or_path);
            let text = std::fs::read_to_string(p).map_err(|source| SpecError::Io {
                path: p.to_path_buf(),
                source,
            })?;
            (text, name_or_path.to_string())
        }
    };
    let path = Path::new(&path);
    let spec = FrameSpec::parse(&text, path)?;
    let plan = Plan::compile(&spec, path)?;
    Ok((spec, plan))
}
