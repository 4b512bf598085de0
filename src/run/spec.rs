//! The description of a run: what it simulates (the signal: motion, units, environment,
//! aiding sensors — a [`SimulationBuilder`]), where the motion comes from when it arrives live,
//! which streams go to which sinks, the sync lines, the clock and the time base. A scene
//! file's tables and the command line's flags both fill one [`RunSpec`]; nothing is checked
//! here — [`RunSpec::build`](super::RunSpec::build) checks the whole description at once.

use std::fmt;
use std::path::PathBuf;

use crate::aiding::GnssFormat;
use crate::aiding::sensors::SensorKind;
use crate::live::InputFormat;
use crate::output::SinkAddr;
use crate::sim::SimulationBuilder;

/// A stream of a run: one sequence of frames (or records, or rows) with emission times.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StreamId {
    /// A unit's readings in its own format, or in `protocol` (a second wire format of the same
    /// records, with its own counters). `unit`: a rig unit's name; `None`: the single IMU.
    Unit {
        /// The rig unit, or `None` for the single IMU.
        unit: Option<String>,
        /// Another protocol than the unit's own (built-in name or spec file).
        protocol: Option<String>,
    },
    /// A unit's error-free readings (the single IMU's in its records' format, a rig unit's as
    /// CSV with the failed-channel mask).
    Truth {
        /// The rig unit, or `None` for the single IMU.
        unit: Option<String>,
    },
    /// The error each stage injected into each of the single IMU's records.
    Errors,
    /// A rig unit's failure schedule (CSV, written once at the start).
    Failures {
        /// The rig unit.
        unit: String,
    },
    /// The GNSS receiver's epochs in a wire format.
    Gnss(GnssFormat),
    /// The truth of each GNSS epoch (CSV).
    GnssTruth,
    /// An aiding sensor's CSV rows.
    Sensor(SensorKind),
}

impl StreamId {
    /// The single IMU's (or, in a rig, the named unit's) readings in its own format.
    pub fn imu() -> StreamId {
        StreamId::Unit {
            unit: None,
            protocol: None,
        }
    }

    /// The readings of the rig unit `name` in its own format.
    pub fn unit(name: &str) -> StreamId {
        StreamId::Unit {
            unit: Some(name.into()),
            protocol: None,
        }
    }
}

impl fmt::Display for StreamId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let unit = |u: &Option<String>| u.clone().unwrap_or_else(|| "imu".into());
        match self {
            StreamId::Unit { unit: u, protocol } => match protocol {
                Some(p) => write!(f, "{} ({p})", unit(u)),
                None => write!(f, "{}", unit(u)),
            },
            StreamId::Truth { unit: u } => write!(f, "{} truth", unit(u)),
            StreamId::Errors => write!(f, "imu injected errors"),
            StreamId::Failures { unit } => write!(f, "{unit} failures"),
            StreamId::Gnss(g) => write!(f, "gnss-{}", GnssFormat::NAMES[*g as usize]),
            StreamId::GnssTruth => write!(f, "gnss truth"),
            StreamId::Sensor(k) => write!(f, "{}", k.name()),
        }
    }
}

/// One stream to one sink.
#[derive(Clone, Debug, PartialEq)]
pub struct Route {
    /// What is sent.
    pub stream: StreamId,
    /// Where to.
    pub sink: SinkAddr,
    /// Where the route was given (`--pty`, `scene.toml: `imu.sink``), for messages.
    pub origin: String,
}

/// Live motion: states of a vehicle simulation arriving while the run goes on.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveSpec {
    /// `udp://HOST:PORT`, `tcp://HOST:PORT`, `-` (stdin), or a FIFO or file.
    pub source: String,
    /// Wire format of the states [default: csv].
    pub format: Option<InputFormat>,
    /// Follow the input in lockstep (no wall clock) instead of in real time.
    pub lockstep: bool,
    /// Real time: how long the frames trail the simulation (s) [default: measured].
    pub output_delay_s: Option<f64>,
    /// Real time: the longest extrapolation past the newest state (s) [default 0.25].
    pub max_extrapolation_s: Option<f64>,
    /// Real time: duration of the smooth correction after a late state (s) [default 0.1].
    pub correction_horizon_s: Option<f64>,
    /// Real time: `stop`, `hold` or `extrapolate` once the input is silent [default stop].
    pub on_timeout: Option<String>,
    /// Seconds without a datagram or TCP data after which the input counts as ended
    /// [default 10].
    pub input_timeout_s: Option<f64>,
    /// Every message received, written here to replay the run.
    pub record: Option<PathBuf>,
}

impl LiveSpec {
    /// Whether the time mode `m` (`realtime` or `lockstep`) is lockstep, else what is expected.
    pub fn read_mode(m: &str) -> Result<bool, &'static str> {
        match m {
            "realtime" => Ok(false),
            "lockstep" => Ok(true),
            _ => Err("expected realtime or lockstep"),
        }
    }

    /// The live wire format named `f`, else what is expected.
    pub fn read_format(f: &str) -> Result<InputFormat, &'static str> {
        InputFormat::from_name(f).ok_or("expected csv, bin or mavlink")
    }

    /// Live states from `source` (see [`LiveSpec::source`]), every other setting default.
    pub fn new(source: impl Into<String>) -> LiveSpec {
        LiveSpec {
            source: source.into(),
            format: None,
            lockstep: false,
            output_delay_s: None,
            max_extrapolation_s: None,
            correction_horizon_s: None,
            on_timeout: None,
            input_timeout_s: None,
            record: None,
        }
    }
}

/// How fast a run goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Speed {
    /// As fast as the machine allows (no wall clock).
    Max,
    /// Paced at this factor of real time (1: real time).
    Factor(f64),
}

impl Speed {
    /// A speed written as a word: `max`, or a factor of real time; else what is expected.
    pub fn read(s: &str) -> Result<Speed, &'static str> {
        match s {
            "max" => Ok(Speed::Max),
            s => s.parse().map(Speed::Factor).map_err(|_| Speed::EXPECTED),
        }
    }

    /// What a speed is, for refusals.
    pub const EXPECTED: &'static str = "expected a factor of real time (1 = real time) or `max`";
}

/// The run's time scale for the frames' GPS-time fields.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeBase {
    /// The simulation's own time, offset by the signal's GPS time of record time 0.
    #[default]
    Sim,
    /// GPS time from the host clock (leap seconds applied); with live input, the input's
    /// time tags are GPS time.
    Gps,
    /// UTC from the host clock (no leap seconds).
    Utc,
}

impl TimeBase {
    /// The time base named `sim`, `gps` or `utc`.
    pub fn from_name(s: &str) -> Option<TimeBase> {
        match s {
            "sim" => Some(TimeBase::Sim),
            "gps" => Some(TimeBase::Gps),
            "utc" => Some(TimeBase::Utc),
            _ => None,
        }
    }

    /// The time base named `s`, else what is expected.
    pub fn read(s: &str) -> Result<TimeBase, &'static str> {
        TimeBase::from_name(s).ok_or("expected sim, gps or utc")
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            TimeBase::Sim => "sim",
            TimeBase::Gps => "gps",
            TimeBase::Utc => "utc",
        }
    }
}

/// A GNSS stream written `FORMAT:SINK`: its format and the sink's text, else why not.
pub fn read_gnss(v: &str) -> Result<(GnssFormat, &str), String> {
    let (name, target) = v.split_once(':').unwrap_or((v, ""));
    let f = GnssFormat::from_name(name).ok_or_else(|| {
        format!(
            "unknown format `{name}` (expected FORMAT:SINK with FORMAT one of {})",
            GnssFormat::NAMES.join(", ")
        )
    })?;
    Ok((f, target))
}

/// The clock of a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ClockSpec {
    /// Replay speed [default: real time, or as fast as possible when every sink is a file].
    pub speed: Option<Speed>,
    /// Wall-clock instant of t₀: RFC 3339, `gps:WEEK:SECONDS` or `next-second`.
    pub start_at: Option<String>,
    /// What the frames' GPS-time fields carry [default: sim].
    pub time_base: Option<TimeBase>,
    /// Frames later than this are skipped and counted rather than sent in a burst (ms)
    /// [default 100].
    pub max_behind_ms: Option<f64>,
    /// Run the pacer `SCHED_FIFO`.
    pub realtime_priority: bool,
}

/// The sync lines and side channels of a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SyncSpec {
    /// Time-mark targets (`udp://HOST:PORT` or a file), each for one unit (`None`: the
    /// single IMU, or every unit of a rig).
    pub time_marks: Vec<(Option<String>, String)>,
    /// A pulse on a modem line: `LINE:MARK[:OFFSET][:WIDTH]`.
    pub pulse: Option<String>,
    /// The serial device whose modem line the pulse drives [default: the pulsed unit's first
    /// serial sink].
    pub pulse_port: Option<String>,
    /// The unit whose records the pulse marks (a rig's; default: the single IMU, or the first
    /// unit).
    pub pulse_unit: Option<String>,
    /// A line given in code that the pulse drives instead of a serial port's modem line (a
    /// GPIO, a test's recorder).
    #[cfg(feature = "realtime")]
    pub pulse_line: Option<PulseLine>,
    /// Phase-lock the output's whole seconds to a PPS source.
    pub pps_in: Option<String>,
    /// External sample trigger: every unit samples once per edge.
    pub trigger: Option<String>,
}

/// A pulse line given in code ([`RunSpec::pulse_on`]), shared with the run's pulse thread.
#[cfg(feature = "realtime")]
#[derive(Clone)]
pub struct PulseLine(pub std::sync::Arc<std::sync::Mutex<dyn crate::realtime::pulse::Line>>);

#[cfg(feature = "realtime")]
impl fmt::Debug for PulseLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("PulseLine")
    }
}

#[cfg(feature = "realtime")]
impl PartialEq for PulseLine {
    /// The same line.
    fn eq(&self, other: &PulseLine) -> bool {
        std::sync::Arc::ptr_eq(&self.0, &other.0)
    }
}

/// Settings of the links the sinks open.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinkSpec {
    /// Serial baud rate [default: the protocol's nominal link speed, else 921600].
    pub baud: Option<u32>,
    /// Serial character framing, `8N1` and the like [default 8N1].
    pub framing: Option<String>,
    /// Frames per UDP datagram [default 1].
    pub udp_batch: Option<usize>,
    /// Replace a pty link another running emulator holds.
    pub take_over: bool,
}

/// Everything a run needs, before it is checked.
#[derive(Clone, Debug, Default)]
pub struct RunSpec {
    /// The signal: motion (unless live), the IMU or the rig's units, environment, aiding
    /// sensors, seed, span.
    pub signal: SimulationBuilder,
    /// Live motion instead of the signal's trajectory.
    pub input: Option<LiveSpec>,
    /// Which stream goes where. A stream without a route is not produced.
    pub routes: Vec<Route>,
    /// Sync lines and side channels.
    pub sync: SyncSpec,
    /// The clock and time base.
    pub clock: ClockSpec,
    /// Link settings of the sinks.
    pub link: LinkSpec,
    /// The settings a scene file's `[run]` table gave, so that a refusal names the file's key
    /// while the value is still the file's (a flag may have replaced it since).
    pub file_keys: Vec<FileKey>,
}

/// A setting a scene file's `[run]` table gave.
#[derive(Clone, Debug, PartialEq)]
pub struct FileKey {
    /// The flag that gives the same setting (`--pulse-port`).
    pub flag: &'static str,
    /// `FILE: `run.KEY``.
    pub origin: String,
    /// The value the file gave, in words ([`RunSpec::setting`]).
    pub value: String,
}

impl RunSpec {
    /// A run of `signal` with no route yet.
    pub fn new(signal: SimulationBuilder) -> RunSpec {
        RunSpec {
            signal,
            ..RunSpec::default()
        }
    }

    /// Sends `stream` to `sink` as well.
    pub fn route(mut self, stream: StreamId, sink: SinkAddr) -> RunSpec {
        let origin = format!("route {stream} → {sink}");
        self.add_route(stream, sink, origin);
        self
    }

    /// Sends `stream` to the sink written `addr` (`pty:PATH`, `serial:DEV`, `udp:HOST:PORT`,
    /// `tcp:HOST:PORT`, `tcp-listen:ADDR:PORT`, `file:PATH`: the scene file's and the command
    /// line's spelling) as well; an address that does not read is refused, named.
    pub fn sink(self, stream: StreamId, addr: &str) -> Result<RunSpec, super::RunError> {
        let sink = SinkAddr::parse(addr)
            .map_err(|why| super::RunError::spec(&format!("sink of {stream}"), why))?;
        Ok(self.route(stream, sink))
    }

    /// Sends `stream` to `sink` as well; `origin` names where the route was given.
    pub fn add_route(&mut self, stream: StreamId, sink: SinkAddr, origin: String) {
        self.routes.push(Route {
            stream,
            sink,
            origin,
        });
    }

    /// Drops the routes of the streams `which` selects (flags replacing a scene file's sinks).
    pub fn replace_routes(&mut self, which: impl Fn(&StreamId) -> bool) {
        self.routes.retain(|r| !which(&r.stream));
    }

    /// Follows live states.
    pub fn live(mut self, input: LiveSpec) -> RunSpec {
        self.input = Some(input);
        self
    }

    /// Replay speed.
    pub fn speed(mut self, speed: Speed) -> RunSpec {
        self.clock.speed = Some(speed);
        self
    }

    /// Frames later than `ms` are skipped and counted rather than sent in a burst.
    pub fn max_behind_ms(mut self, ms: f64) -> RunSpec {
        self.clock.max_behind_ms = Some(ms);
        self
    }

    /// The time base.
    pub fn time_base(mut self, base: TimeBase) -> RunSpec {
        self.clock.time_base = Some(base);
        self
    }

    /// Wall-clock instant of t₀ (see [`ClockSpec::start_at`]).
    pub fn start_at(mut self, at: impl Into<String>) -> RunSpec {
        self.clock.start_at = Some(at.into());
        self
    }

    /// Time marks of `unit` (`None`: the single IMU or every unit) to `target`.
    pub fn time_marks(mut self, unit: Option<&str>, target: impl Into<String>) -> RunSpec {
        (self.sync.time_marks).push((unit.map(str::to_string), target.into()));
        self
    }

    /// External sample trigger from `source`.
    pub fn trigger(mut self, source: impl Into<String>) -> RunSpec {
        self.sync.trigger = Some(source.into());
        self
    }

    /// Phase-lock to the PPS `source`.
    pub fn pps_in(mut self, source: impl Into<String>) -> RunSpec {
        self.sync.pps_in = Some(source.into());
        self
    }

    /// A pulse `LINE:MARK[:OFFSET][:WIDTH]` (see [`SyncSpec::pulse`]) on the records of `unit`
    /// (`None`: the single IMU, or a rig's first unit).
    pub fn pulse(mut self, spec: impl Into<String>, unit: Option<&str>) -> RunSpec {
        self.sync.pulse = Some(spec.into());
        self.sync.pulse_unit = unit.map(str::to_string);
        self
    }

    /// Drives the pulse on `line` (a GPIO, a recorder) instead of a serial port's modem line.
    #[cfg(feature = "realtime")]
    pub fn pulse_on(mut self, line: impl crate::realtime::pulse::Line + 'static) -> RunSpec {
        let line = std::sync::Arc::new(std::sync::Mutex::new(line));
        self.sync.pulse_line = Some(PulseLine(line));
        self
    }
}
