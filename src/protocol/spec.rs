//! The specification language of a frame (`protocols/NAME.toml`): fixed-layout frames of
//! typed fields in order, each a constant or a quantity of the record scaled by its LSB,
//! optionally closed by an integrity check. Parsing and validation only; [`super::plan`]
//! compiles a validated spec.
//!
//! ```toml
//! name = "kvh1750"
//! byte_order = "big"            # default of every field
//! rate_hz = 1000
//! [[field]]
//! name = "header"
//! type = "u32"
//! value = 0xFE81FF55            # a constant
//! [[field]]
//! name = "dtheta_x"
//! type = "f32"
//! source = "dtheta.x"           # a quantity of the record, in SI
//! lsb = 1.0                     # SI units per wire unit (wire = SI / lsb)
//! [[field]]
//! name = "sequence"
//! type = "u8"
//! source = "counter"
//! modulo = 128
//! [check]
//! kind = "crc-32/mpeg-2"
//! type = "u32"
//! from = 0                      # first byte covered; the check covers up to itself
//! ```

use std::path::{Path, PathBuf};

use serde::Deserialize;

/// Byte order of a multi-byte field.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ByteOrder {
    /// Most significant byte first.
    #[default]
    Big,
    /// Least significant byte first.
    Little,
}

/// A field's wire type.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum WireType {
    /// Unsigned 8-bit.
    U8,
    /// Signed 8-bit.
    I8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit.
    I16,
    /// Unsigned 24-bit.
    U24,
    /// Signed 24-bit (two's complement).
    I24,
    /// Unsigned 32-bit.
    U32,
    /// Signed 32-bit.
    I32,
    /// Unsigned 64-bit.
    U64,
    /// Signed 64-bit.
    I64,
    /// IEEE-754 single.
    F32,
    /// IEEE-754 double.
    F64,
}

impl WireType {
    /// Size on the wire.
    pub fn bytes(self) -> usize {
        match self {
            WireType::U8 | WireType::I8 => 1,
            WireType::U16 | WireType::I16 => 2,
            WireType::U24 | WireType::I24 => 3,
            WireType::U32 | WireType::I32 | WireType::F32 => 4,
            WireType::U64 | WireType::I64 | WireType::F64 => 8,
        }
    }
    /// Representable integer range, `None` for floats.
    pub fn int_range(self) -> Option<(i128, i128)> {
        let b = self.bytes() as u32 * 8;
        match self {
            WireType::F32 | WireType::F64 => None,
            WireType::U8 | WireType::U16 | WireType::U24 | WireType::U32 | WireType::U64 => {
                Some((0, (1i128 << b) - 1))
            }
            _ => Some((-(1i128 << (b - 1)), (1i128 << (b - 1)) - 1)),
        }
    }
}

/// A quantity a field can carry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// Interval-mean angular rate, axis 0–2 (rad/s).
    Gyro(usize),
    /// Interval-mean specific force (m/s²).
    Accel(usize),
    /// Angle increment (rad).
    DTheta(usize),
    /// Velocity increment (m/s).
    Dv(usize),
    /// The record's time tag (s).
    Time,
    /// The frame counter (advances by `step` per frame, wraps at `modulo`).
    Counter,
    /// Sensor temperature (°C).
    Temperature,
    /// Magnetic field, axis 0–2 (T), in the IMU's axes: the latest sample of the
    /// simulation's magnetometer (scene file `[magnetometer]`), 0 without one; decoders read
    /// what a real unit sends (KVH Format C, MAVLink HIL_SENSOR).
    Mag(usize),
    /// GPS week number of the record's time tag.
    GpsWeek,
    /// GPS seconds of week (s, fractional).
    GpsSeconds,
    /// Whole GPS seconds of week.
    GpsWholeSeconds,
    /// Microseconds within the GPS second.
    GpsMicros,
    /// GPS milliseconds of week.
    GpsMillis,
    /// A status word: its healthy value with bits set or cleared by the record's saturation
    /// flags, by values beyond a field's range and by injected failures (`[field.status]`).
    Status,
    /// Single-axis channel `i` of an N-channel unit (a skew-redundant one): `gyro[i]`,
    /// `accel[i]`, `dtheta[i]`, `dv[i]`, in SI.
    Channel(Channel, usize),
    /// A vehicle state quantity of a simulator's state message (MAVLink
    /// HIL_STATE_QUATERNION, read by live input): decoded, never encoded (no IMU output
    /// carries it; an encoder treats it as a value that is not a measurement).
    State(StateQty),
    /// An integer carried as is, read by the caller itself (MAVLink's flags and system id);
    /// encoders send 0.
    Raw,
}

/// A vehicle state quantity (`state.qw`, `state.lat`, …).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateQty {
    /// Attitude quaternion body → NED, component w, x, y, z (0–3).
    Q(usize),
    /// Latitude (deg, as trajectory files).
    Lat,
    /// Longitude (deg).
    Lon,
    /// Altitude (m).
    Alt,
    /// Velocity north, east, down (0–2; m/s).
    Vel(usize),
    /// Indicated airspeed (m/s).
    Ias,
    /// True airspeed (m/s).
    Tas,
}

impl StateQty {
    fn from_name(s: &str) -> Option<StateQty> {
        Some(match s {
            "qw" => StateQty::Q(0),
            "qx" => StateQty::Q(1),
            "qy" => StateQty::Q(2),
            "qz" => StateQty::Q(3),
            "lat" => StateQty::Lat,
            "lon" => StateQty::Lon,
            "alt" => StateQty::Alt,
            "vn" => StateQty::Vel(0),
            "ve" => StateQty::Vel(1),
            "vd" => StateQty::Vel(2),
            "ias" => StateQty::Ias,
            "tas" => StateQty::Tas,
            _ => return None,
        })
    }
}

/// What a single-axis channel field carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// Interval-mean angular rate of gyro i (rad/s).
    Gyro,
    /// Interval-mean specific force of accelerometer i (m/s²).
    Accel,
    /// Angle increment of gyro i (rad).
    DTheta,
    /// Velocity increment of accelerometer i (m/s).
    Dv,
}

impl Channel {
    /// Whether the channel is a gyro's (else an accelerometer's).
    pub fn is_gyro(self) -> bool {
        matches!(self, Channel::Gyro | Channel::DTheta)
    }

    /// Whether the channel carries an increment (else an interval mean).
    pub fn is_increment(self) -> bool {
        matches!(self, Channel::DTheta | Channel::Dv)
    }

    fn from_name(s: &str) -> Option<Channel> {
        Some(match s {
            "gyro" => Channel::Gyro,
            "accel" => Channel::Accel,
            "dtheta" => Channel::DTheta,
            "dv" => Channel::Dv,
            _ => return None,
        })
    }
}

/// Most single-axis channels of one kind (gyros, accelerometers) a frame can carry: the bits of
/// a unit's failure mask.
pub const MAX_CHANNELS: usize = 64;

/// `gyro[3]` → (Gyro, 3..4); `dtheta[0..6]` → (DTheta, 0..6): the channels an indexed source
/// names, `None` when it is not one. `Err` for an indexed source that cannot be.
pub fn channel_range(s: &str) -> Option<Result<(Channel, std::ops::Range<usize>), String>> {
    let (kind, rest) = s.split_once('[')?;
    let kind = Channel::from_name(kind)?;
    let bad = || {
        format!(
            "`{s}`: expected `{{gyro|accel|dtheta|dv}}[i]` or `[i..j]` with i < j ≤ {MAX_CHANNELS}"
        )
    };
    let Some(inner) = rest.strip_suffix(']') else {
        return Some(Err(bad()));
    };
    let num = |x: &str| x.trim().parse::<usize>().ok();
    let range = match inner.split_once("..") {
        Some((a, b)) => num(a).zip(num(b)).map(|(a, b)| a..b),
        None => num(inner).map(|i| i..i + 1),
    };
    Some(match range {
        Some(r) if r.start < r.end && r.end <= MAX_CHANNELS => Ok((kind, r)),
        _ => Err(bad()),
    })
}

impl Source {
    /// Parses `gyro.x`, `accel.z`, `dtheta.y`, `dv.x`, `mag.x`, `time`, `counter`,
    /// `temperature`, `gps.week`, `gps.seconds`, `gps.whole_seconds`, `gps.micros`, `gps.millis`,
    /// `status`, single-axis channels `gyro[i]`, `accel[i]`, `dtheta[i]`, `dv[i]`, vehicle
    /// state `state.qw|qx|qy|qz|lat|lon|alt|vn|ve|vd|ias|tas` and `raw`.
    pub fn from_name(s: &str) -> Option<Source> {
        let axis = |a: &str| match a {
            "x" => Some(0),
            "y" => Some(1),
            "z" => Some(2),
            _ => None,
        };
        Some(match s.split_once('.') {
            Some(("gyro", a)) => Source::Gyro(axis(a)?),
            Some(("accel", a)) => Source::Accel(axis(a)?),
            Some(("dtheta", a)) => Source::DTheta(axis(a)?),
            Some(("dv", a)) => Source::Dv(axis(a)?),
            Some(("mag", a)) => Source::Mag(axis(a)?),
            None if s == "time" => Source::Time,
            None if s == "counter" => Source::Counter,
            None if s == "temperature" => Source::Temperature,
            None if s == "status" => Source::Status,
            Some(("gps", "week")) => Source::GpsWeek,
            Some(("gps", "seconds")) => Source::GpsSeconds,
            Some(("gps", "whole_seconds")) => Source::GpsWholeSeconds,
            Some(("gps", "micros")) => Source::GpsMicros,
            Some(("gps", "millis")) => Source::GpsMillis,
            Some(("state", q)) => Source::State(StateQty::from_name(q)?),
            None if s == "raw" => Source::Raw,
            _ => match channel_range(s)? {
                Ok((c, r)) if r.len() == 1 => Source::Channel(c, r.start),
                _ => return None,
            },
        })
    }
}

/// One `[[field]]` as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FieldSpec {
    /// Name (for messages and decoded columns).
    pub name: String,
    /// Wire type.
    #[serde(rename = "type")]
    pub ty: WireType,
    /// Overrides the spec's byte order.
    pub byte_order: Option<ByteOrder>,
    /// A constant value (sync words, fixed status).
    pub value: Option<i64>,
    /// The quantity carried (`gyro.x`, `dtheta.z`, `counter`, …).
    pub source: Option<String>,
    /// SI units per wire unit (default 1).
    pub lsb: Option<f64>,
    /// Multiplier applied before scaling (e.g. −1 for a reversed axis).
    pub sign: Option<f64>,
    /// Counter wrap (the counter runs 0..modulo−1).
    pub modulo: Option<u64>,
    /// Counter increment per frame (default 1).
    pub step: Option<u64>,
    /// The value wraps at the type's range instead of saturating (a free-running timestamp).
    pub wrap: Option<bool>,
    /// A counter of internal ticks at this rate (Hz): it advances by ticks/output-rate per
    /// frame, set from the run's rate (STIM300: 2000).
    pub ticks_per_second: Option<u64>,
    /// The status model of a `source = "status"` field.
    pub status: Option<StatusSpec>,
    /// Whether a value beyond this field's range raises the status overrange bits of its
    /// sensor (default true; false for a channel with its own smaller range, e.g. STIM300
    /// inclinometers).
    pub flags_overrange: Option<bool>,
}

/// `[field.status]`: the value of a status word when all is well, and the bits each condition
/// sets or clears.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StatusSpec {
    /// The word when all is well.
    pub ok: i64,
    /// A gyro channel saturated (error model's range, or beyond this protocol's field range).
    pub gyro_overrange: Option<BitEdit>,
    /// An accelerometer channel saturated.
    pub accel_overrange: Option<BitEdit>,
    /// A built-in-test failure (set by fault injection).
    pub failure: Option<BitEdit>,
    /// Per-channel failure bits of an N-channel unit: bit `failed_channels + i` is set while
    /// channel i (gyros, then accelerometers) has an active failure.
    pub failed_channels: Option<u32>,
    /// Edit of a frame that carries a magnetometer sample no earlier frame carried (MAVLink's
    /// `fields_updated` mag bits); a healthy word either way.
    pub mag_updated: Option<BitEdit>,
}

/// Bits a condition sets and clears in a status word (clear first, then set).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct BitEdit {
    /// Bits set.
    #[serde(default)]
    pub set: u64,
    /// Bits cleared.
    #[serde(default)]
    pub clear: u64,
}

impl BitEdit {
    /// `v` with the edit applied.
    pub fn apply(self, v: i64) -> i64 {
        ((v as u64 & !self.clear) | self.set) as i64
    }
}

/// `[check]` as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CheckSpec {
    /// The check algorithm (see `protocol::check`), as TOML.
    pub kind: toml::Value,
    /// Wire type of the check field (`u8`, `u16`, `u32`).
    #[serde(rename = "type")]
    pub ty: WireType,
    /// Byte order of the check field.
    pub byte_order: Option<ByteOrder>,
    /// First byte covered (default 0).
    pub from: Option<usize>,
    /// Zero bytes appended to the covered data before computing (not transmitted).
    pub pad_to_multiple_of: Option<usize>,
    /// Bytes appended to the covered data (after any padding) before computing, not
    /// transmitted: MAVLink's CRC_EXTRA.
    #[serde(default)]
    pub append: Vec<u8>,
}

/// `[truncate]`: trailing zero bytes of the payload are not sent (MAVLink 2); a length field
/// carries the payload bytes sent (at least 1).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TruncateSpec {
    /// The field carrying the sent payload length (an unsigned integer, not a source).
    pub length_field: String,
    /// The first field of the payload; the payload runs to the check.
    pub payload_from: String,
}

/// One `[[message]]` of a protocol that interleaves several frame layouts.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MessageSpec {
    /// Name (used by `schedule`).
    pub name: String,
    /// Its Δθ and ΔV fields carry the sums over every record since this message was last
    /// sent (e.g. HG4930's 100 Hz inertial message in a 600 Hz stream).
    #[serde(default)]
    pub accumulate: bool,
    /// The fields in wire order.
    pub field: Vec<FieldSpec>,
    /// The integrity check.
    pub check: Option<CheckSpec>,
    /// Trailing-zero truncation.
    pub truncate: Option<TruncateSpec>,
}

/// What picks each frame's message from the `schedule`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ScheduleBy {
    /// Frame k of the stream is message `schedule[k mod len]`.
    #[default]
    Position,
    /// A frame whose counter reads c is message `schedule[c mod len]`, so a decoder tells
    /// messages of identical layout apart by the counter (KVH Format C's multiplexed word).
    Counter,
}

/// A golden test vector: bytes and the values they decode to.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TestVector {
    /// What the vector is and where it comes from.
    pub comment: Option<String>,
    /// The frame, hex (spaces allowed).
    pub hex: String,
    /// Decoded values by source name (`dtheta.x`, `counter`, …), in SI.
    pub values: toml::Table,
    /// Relative tolerance of the value comparison (default 1e-6: single floats).
    pub tolerance: Option<f64>,
    /// Index of the frame in the stream (selects the scheduled message; default: the counter).
    pub frame: Option<u64>,
}

/// A frame specification as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FrameSpec {
    /// Protocol name.
    pub name: String,
    /// One-line description.
    pub description: Option<String>,
    /// Where each fact comes from.
    #[serde(default)]
    pub sources: Vec<String>,
    /// Nominal output rate (Hz).
    pub rate_hz: Option<f64>,
    /// Nominal link speed (bit/s).
    pub baud: Option<u64>,
    /// Default byte order.
    #[serde(default)]
    pub byte_order: ByteOrder,
    /// The fields in wire order (a single-layout protocol).
    #[serde(default)]
    pub field: Vec<FieldSpec>,
    /// The integrity check, appended after the fields.
    pub check: Option<CheckSpec>,
    /// Trailing-zero truncation of a single-layout protocol.
    pub truncate: Option<TruncateSpec>,
    /// Several interleaved layouts (instead of `field`/`check`).
    #[serde(default)]
    pub message: Vec<MessageSpec>,
    /// The repeating order of messages by name, one per record (default: each once, in order).
    pub schedule: Option<Vec<String>>,
    /// What picks a frame's message from the schedule: its position in the stream (default)
    /// or its counter value (messages that look alike, told apart by the counter).
    #[serde(default)]
    pub schedule_by: ScheduleBy,
    /// Synchronous SDLC transport: the frame (fields and check) is the payload of a bit-stuffed
    /// SDLC frame packed into bytes (`framing::SdlcOptions`).
    pub sdlc: Option<crate::protocol::framing::SdlcOptions>,
    /// Asynchronous HDLC transport: the frame is byte-stuffed between `7E` flags.
    pub hdlc: Option<crate::protocol::framing::HdlcOptions>,
    /// Golden vectors.
    #[serde(default)]
    pub test_vector: Vec<TestVector>,
}

/// Most fields in one message: several times the longest real frame's (MAVLink 2's 255-byte
/// payload of one-byte fields would need 265), so that a runaway generated file is refused
/// rather than compiled.
pub const MAX_FIELDS: usize = 512;
/// Most bytes in one frame (fields and check), before any transport: MAVLink 2's longest packet
/// is 280 bytes; the IMU frames here have 13 to 72.
pub const MAX_FRAME_BYTES: usize = 2048;
/// Most messages of one protocol, and most entries in its schedule.
pub const MAX_MESSAGES: usize = 256;
/// Largest specification file read (bytes); the built-ins have 3 to 10 kB.
pub const MAX_SPEC_BYTES: u64 = 1 << 20;
/// Highest `rate_hz` a spec can give (Hz), as for a run's `--rate`.
pub const MAX_RATE_HZ: f64 = 1e7;

/// A specification that cannot be used, naming the file, the field and the problem.
#[derive(Debug, thiserror::Error)]
pub enum SpecError {
    /// Neither a built-in protocol nor a spec file.
    #[error("unknown protocol `{name}`: neither a built-in ({builtin}) nor an existing spec file")]
    Unknown {
        /// The name or path given.
        name: String,
        /// The built-in names, comma-separated.
        builtin: String,
    },
    /// Unreadable file.
    #[error("{path}: cannot read")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// TOML syntax or schema.
    #[error("{path}: {message}")]
    Syntax {
        /// File.
        path: PathBuf,
        /// Message with line and column.
        message: String,
    },
    /// A field that cannot be used.
    #[error("{}{}: field `{field}`: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Field {
        /// File.
        path: PathBuf,
        /// Line of the field's `name` in the file, when known.
        line: Option<usize>,
        /// Field name.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The check cannot be used.
    #[error("{path}: `check`: {message}")]
    Check {
        /// File.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// A number for a message: as written when short, in exponent form when huge or tiny (a
/// 300-digit `1e300` stays `1e300`).
pub fn compact(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e12).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

impl FrameSpec {
    /// Parses spec text; `path` is used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<FrameSpec, SpecError> {
        toml::from_str(text).map_err(|e| SpecError::Syntax {
            path: path.to_path_buf(),
            message: crate::csvio::toml_error_line(text, &e),
        })
    }
}
