//! Finding a protocol's specification: a built-in one by name, or a spec file. The only part
//! of the protocol module that reads files; parsing and compiling take text.

use std::path::Path;

use super::plan::Plan;
use super::spec::{FrameSpec, SpecError};

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
    ("skew6", include_str!("../../protocols/skew6.toml")),
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

/// Parses and compiles spec text; `path` names it in messages.
pub fn compile_text(text: &str, path: &Path) -> Result<(FrameSpec, Plan), SpecError> {
    let spec = FrameSpec::parse(text, path)?;
    let plan = Plan::compile(&spec, path).map_err(|e| with_line(e, text))?;
    Ok((spec, plan))
}

/// A field error with the line of the field's `name = "…"` in `text` (the first such line:
/// a name is unique within a message).
fn with_line(e: SpecError, text: &str) -> SpecError {
    match e {
        SpecError::Field {
            path,
            line: None,
            field,
            message,
        } => {
            let line_of = |name: &str| {
                text.lines().position(|l| {
                    let v = l.trim_start().strip_prefix("name").map(str::trim_start);
                    let v = v.and_then(|r| r.strip_prefix('='));
                    v.is_some_and(|r| {
                        r.split('#').next().unwrap_or("").trim() == format!("\"{name}\"")
                    })
                })
            };
            // A field written as a channel range is reported as `NAME_i`.
            let line = line_of(&field)
                .or_else(|| field.rsplit_once('_').and_then(|(base, _)| line_of(base)));
            SpecError::Field {
                path,
                line: line.map(|i| i + 1),
                field,
                message,
            }
        }
        e => e,
    }
}

/// Loads and compiles a built-in protocol by name, or a spec file by path. A name that is
/// neither a built-in nor an existing file is an unknown protocol (the message lists the
/// built-ins).
pub fn load(name_or_path: &str) -> Result<(FrameSpec, Plan), SpecError> {
    match BUILTIN.iter().find(|b| b.0 == name_or_path) {
        Some((n, text)) => compile_text(text, Path::new(&format!("protocols/{n}.toml"))),
        None if Path::new(name_or_path).is_file() => load_file(Path::new(name_or_path)),
        None => Err(SpecError::Unknown {
            name: name_or_path.to_string(),
            builtin: builtin_names().join(", "),
        }),
    }
}

/// Reads and compiles a spec file.
pub fn load_file(path: &Path) -> Result<(FrameSpec, Plan), SpecError> {
    compile_text(&read_spec(path)?, path)
}

/// The text of a spec file, refusing one larger than any real protocol's specification
/// ([`super::spec::MAX_SPEC_BYTES`]) before reading it whole.
fn read_spec(path: &Path) -> Result<String, SpecError> {
    let io = |source| SpecError::Io {
        path: path.to_path_buf(),
        source,
    };
    let len = std::fs::metadata(path).map_err(io)?.len();
    if len > super::spec::MAX_SPEC_BYTES {
        return Err(SpecError::Syntax {
            path: path.to_path_buf(),
            message: format!(
                "{len} bytes: a specification has at most {} bytes",
                super::spec::MAX_SPEC_BYTES
            ),
        });
    }
    std::fs::read_to_string(path).map_err(io)
}
