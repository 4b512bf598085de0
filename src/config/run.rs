//! The scene file's `[run]` table: how a run goes (clock, time base, sync lines), where its
//! streams go (the single IMU's `sink` is `[imu] sink`, a rig unit's its `[[imu]] sink`), and
//! a live motion input (`[run.input]`). Every key is optional; `imu-emu run`'s flags
//! override them. Read as written; `crate::run::RunSpec` checks the values.

use serde::Deserialize;

use super::rig::OneOrMany;

/// `[run]`.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RunSection {
    /// Replay speed: a factor of real time, or `"max"`.
    pub speed: Option<SpeedValue>,
    /// Wall-clock instant of t₀: RFC 3339, `gps:WEEK:SECONDS` or `next-second`.
    pub start_at: Option<String>,
    /// `sim`, `gps` or `utc`.
    pub time_base: Option<String>,
    /// Frames later than this are skipped and counted (ms).
    pub max_behind_ms: Option<f64>,
    /// Run the pacer `SCHED_FIFO`.
    pub realtime_priority: Option<bool>,
    /// The single IMU's error-free records: a sink.
    pub truth: Option<String>,
    /// The error each stage injected into the single IMU's records: a sink.
    pub truth_errors: Option<String>,
    /// GNSS streams, `FORMAT:SINK` each.
    pub gnss: Option<OneOrMany>,
    /// The GNSS epochs' truth rows: a sink.
    pub gnss_truth: Option<String>,
    /// The odometer's rows: sinks.
    pub odometer: Option<OneOrMany>,
    /// The barometer's rows: sinks.
    pub baro: Option<OneOrMany>,
    /// The magnetometer's rows: sinks.
    pub magnetometer: Option<OneOrMany>,
    /// Time-mark targets, `[UNIT=]TARGET` each.
    pub time_marks: Option<OneOrMany>,
    /// A pulse on a modem line, `LINE:MARK[:OFFSET][:WIDTH]`.
    pub pulse: Option<String>,
    /// The serial device of the pulse's modem line.
    pub pulse_port: Option<String>,
    /// The rig unit the pulse marks.
    pub pulse_unit: Option<String>,
    /// A PPS source the output's whole seconds lock to.
    pub pps_in: Option<String>,
    /// A trigger source every unit samples on.
    pub trigger: Option<String>,
    /// Serial baud rate.
    pub baud: Option<u32>,
    /// Serial character framing (`8N1`…).
    pub framing: Option<String>,
    /// Frames per UDP datagram.
    pub udp_batch: Option<usize>,
    /// Replace a pty link another emulator holds.
    pub take_over: Option<bool>,
    /// A live motion input instead of `[trajectory]`.
    pub input: Option<InputSection>,
}

/// A speed: a number, or `"max"`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum SpeedValue {
    /// A factor of real time.
    Factor(f64),
    /// `"max"` (anything else is refused when checked).
    Word(String),
}

/// `[run.input]`: live motion.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct InputSection {
    /// `udp://HOST:PORT`, `tcp://HOST:PORT`, `-` or a path.
    pub source: String,
    /// `csv`, `bin` or `mavlink`.
    pub format: Option<String>,
    /// `realtime` or `lockstep`.
    pub mode: Option<String>,
    /// Real time: the output delay (s).
    pub output_delay_s: Option<f64>,
    /// Real time: the longest extrapolation past the newest state (s).
    pub max_extrapolation_s: Option<f64>,
    /// Real time: the correction horizon after a late state (s).
    pub correction_horizon_s: Option<f64>,
    /// Real time: `stop`, `hold` or `extrapolate` once the input is silent.
    pub on_timeout: Option<String>,
    /// Silence after which the input counts as ended (s).
    pub timeout_s: Option<f64>,
    /// Every message received, written here.
    pub record: Option<std::path::PathBuf>,
}

impl OneOrMany {
    /// The values, each with its key (`key` or `key[i]`).
    pub fn keyed(&self, key: &str) -> Vec<(String, String)> {
        match self {
            OneOrMany::One(s) => vec![(key.to_string(), s.clone())],
            OneOrMany::Many(v) => (v.iter().enumerate())
                .map(|(i, s)| (format!("{key}[{i}]"), s.clone()))
                .collect(),
        }
    }
}
