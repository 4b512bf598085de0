//! `imu-emu run`: the flags of a run, turned into a [`RunSpec`] (over the scene file's), built,
//! then run by the library with its status and summary printed.

use anyhow::Result;

use imu_emu::run::{LiveOverrides, Overrides, RunSpec};

use super::setup::SimArgs;

/// The protocol `run` speaks by default: LN-200-style frames.
pub const DEFAULT_PROTOCOL: &str = "ln200";
/// The IMU template `run` emulates by default.
pub const DEFAULT_IMU: &str = "ln200";

#[derive(clap::Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub sim: SimArgs,
    #[command(flatten)]
    pub live: LiveArgs,
    /// Pseudo-terminal sink: the slave is published at PATH (a symlink); repeatable. Every
    /// sink takes `,protocol=NAME` (built-in name or spec file) to speak its own protocol.
    /// Without any sink, one pty is opened and its /dev/pts path printed.
    #[arg(long, value_name = "PATH[,protocol=NAME]")]
    pub pty: Vec<String>,
    /// Replace a `--pty` link that another running emulator holds (refused by default).
    #[arg(long)]
    pub take_over: bool,
    /// Serial device sink; repeatable.
    #[arg(long, value_name = "DEV[,protocol=NAME]")]
    pub serial: Vec<String>,
    /// Serial baud rate [default: the protocol's nominal link speed, else 921600].
    #[arg(long)]
    pub baud: Option<u32>,
    /// Serial character framing (data bits, parity N/E/O, stop bits) [default: 8N1].
    #[arg(long)]
    pub framing: Option<String>,
    /// UDP sink HOST:PORT (unicast, broadcast or multicast); repeatable.
    #[arg(long, value_name = "HOST:PORT[,protocol=NAME]")]
    pub udp: Vec<String>,
    /// TCP sink: connects to a consumer listening at HOST:PORT (reconnects when it goes,
    /// frames count as "no reader" meanwhile); repeatable.
    #[arg(long, value_name = "HOST:PORT[,protocol=NAME]")]
    pub tcp: Vec<String>,
    /// TCP sink: listens on ADDR:PORT and sends every frame to every client connected;
    /// repeatable.
    #[arg(long, value_name = "ADDR:PORT[,protocol=NAME]")]
    pub tcp_listen: Vec<String>,
    /// File sink, or - for stdout; repeatable.
    #[arg(long, value_name = "PATH[,protocol=NAME]")]
    pub file: Vec<String>,
    /// A rig unit's sink, NAME=KIND:TARGET with KIND pty, serial, udp, tcp, tcp-listen or file (e.g.
    /// `nav=udp:127.0.0.1:9001`); repeatable; replaces the scene file's `sink` of that unit.
    /// `,protocol=NAME` sends the unit's records in another protocol than its own.
    #[arg(long, value_name = "NAME=SINK[,protocol=NAME]")]
    pub unit_sink: Vec<String>,
    /// A GNSS receiver's stream, FORMAT:SINK with FORMAT nmea, ubx or mavlink and SINK as
    /// `--unit-sink`'s (e.g. `nmea:udp:127.0.0.1:9010`); repeatable (docs/aiding.md).
    #[arg(long = "gnss", value_name = "FORMAT:SINK")]
    pub gnss: Vec<String>,
    /// The odometer's CSV rows, to SINK (as `--unit-sink`'s); repeatable.
    #[arg(long, value_name = "SINK")]
    pub odometer: Vec<String>,
    /// The barometer's CSV rows, to SINK; repeatable.
    #[arg(long, value_name = "SINK")]
    pub baro: Vec<String>,
    /// The magnetometer's CSV rows, to SINK; repeatable.
    #[arg(long, value_name = "SINK")]
    pub magnetometer: Vec<String>,
    /// Frames per UDP datagram [default: 1].
    #[arg(long)]
    pub udp_batch: Option<usize>,
    /// Replay speed: a factor of real time, or `max` for unpaced [default: 1, or max when
    /// every sink is a file].
    #[arg(long)]
    pub speed: Option<String>,
    /// Wall-clock instant of simulation time t₀, to align several emulators: RFC 3339
    /// (2026-11-24T15:00:00Z, or with an offset like +01:00), GPS `gps:WEEK:SECONDS`, or
    /// `next-second` [default: when the first frames are ready; with --time-base gps or utc,
    /// next-second].
    #[arg(long)]
    pub start_at: Option<String>,
    /// What the frames' GPS-time fields carry: `gps` (GPS time of each record from the host
    /// clock, leap seconds applied), `utc` (UTC, no leap seconds) or `sim` (the simulation's
    /// own time, offset by --gps-time) [default: sim]. With --motion: `gps` says the input's
    /// time tags are GPS time (MAVLink: Unix time, converted), and in real time that the host
    /// clock is too, so they map to it directly.
    #[arg(long, value_parser = ["gps", "utc", "sim"])]
    pub time_base: Option<String>,
    /// Time-mark side channel: per frame its index, time of validity, due and emission
    /// instants, to `udp://HOST:PORT` (40-byte datagrams) or a file (CSV if it ends in .csv,
    /// else 40-byte records); a rig's marks name their unit, UNIT=TARGET; see docs/timing.md.
    /// Repeatable.
    #[arg(long, value_name = "[UNIT=]udp://HOST:PORT|FILE")]
    pub time_marks: Vec<String>,
    /// Pulse on a modem line: LINE rts|dtr, MARK tov (every sample's time of validity) or pps
    /// (each whole second), the rising edge OFFSET after it and WIDTH high [default 0, 500us].
    #[arg(long, value_name = "LINE:MARK[:OFFSET][:WIDTH]")]
    pub pulse: Option<String>,
    /// Serial device whose modem line --pulse drives [default: the pulsed unit's first
    /// serial sink].
    #[arg(long, value_name = "DEV")]
    pub pulse_port: Option<String>,
    /// The rig unit whose records --pulse marks [default: the first unit].
    #[arg(long, value_name = "UNIT")]
    pub pulse_unit: Option<String>,
    /// Phase-lock the output's whole seconds to a PPS: `/dev/ppsN`, `dcd:DEV`, `cts:DEV` or
    /// `udp://HOST:PORT` (edge datagrams); see docs/timing.md.
    #[arg(long, value_name = "SOURCE")]
    pub pps_in: Option<String>,
    /// External sample trigger: one sample per edge, integrating over the interval since the
    /// previous edge (the first edge is t₀): `udp://HOST:PORT` (edge datagrams), `dcd:DEV`,
    /// `cts:DEV` or `/dev/ppsN`; see docs/timing.md.
    #[arg(long, value_name = "SOURCE")]
    pub trigger: Option<String>,
    /// Frames later than this are skipped and counted rather than sent in a burst (ms)
    /// [default: 100].
    #[arg(long)]
    pub max_behind_ms: Option<f64>,
    /// Run the pacer SCHED_FIFO (needs CAP_SYS_NICE or an RLIMIT_RTPRIO; falls back with a
    /// warning).
    #[arg(long)]
    pub realtime: bool,
    /// Print the run as built — motion, clock, units, streams and their sinks, sync lines —
    /// and exit without running it.
    #[arg(long)]
    pub describe: bool,
    /// More log output (-v info, -vv debug).
    #[arg(short, long, action = clap::ArgAction::Count)]
    pub verbose: u8,
}

/// The live-input flags of `run`.
#[derive(clap::Args)]
pub struct LiveArgs {
    /// Follow states that arrive live instead of a scene or a trajectory file:
    /// udp://HOST:PORT (unicast or multicast), tcp://HOST:PORT (listens; one connection after
    /// another, so a readiness probe or a reconnect ends nothing), - (stdin), or a FIFO or
    /// file (docs/live-input.md).
    #[arg(long, value_name = "SOURCE", conflicts_with_all = ["scene", "trajectory"])]
    pub motion: Option<String>,
    /// Wire format of the --motion states: csv, bin or mavlink (HIL_STATE_QUATERNION)
    /// [default: csv].
    #[arg(long, value_name = "FORMAT")]
    pub input_format: Option<String>,
    /// How output follows --motion: realtime (simulation time mapped to the host clock,
    /// frames at their instants plus --output-delay) or lockstep (each state releases the
    /// records up to its time, no wall clock) [default: realtime].
    #[arg(long, value_name = "MODE")]
    pub time_mode: Option<String>,
    /// Realtime: how long the frames trail the simulation (s) [default: the measured input
    /// period plus its jitter plus 3 ms, reported at the start].
    #[arg(long, value_name = "SECONDS")]
    pub output_delay: Option<f64>,
    /// Realtime: the longest extrapolation past the newest state with its jerk and angular
    /// acceleration (s); past it the motion holds its acceleration and angular rate
    /// [default: 0.25].
    #[arg(long, value_name = "SECONDS")]
    pub max_extrapolation: Option<f64>,
    /// Realtime: duration of the smooth correction back to the received motion after a late
    /// state (s) [default: 0.1].
    #[arg(long, value_name = "SECONDS")]
    pub correction_horizon: Option<f64>,
    /// Realtime: once the input is silent for --input-timeout (or its stream ended): stop
    /// (end the run; the frames due while waiting out the silence were already sent,
    /// extrapolated up to --max-extrapolation past the newest state, then held; a stream
    /// that ends stops after the frames up to its newest state — a pipe or file: a TCP
    /// sender's close is no end, its listener waits for the next), hold (keep going at
    /// constant acceleration and angular rate, frames marked stale) or extrapolate (keep
    /// going, bounded by --max-extrapolation, then hold) [default: stop].
    #[arg(long, value_name = "POLICY")]
    pub on_timeout: Option<String>,
    /// Write every message received on --motion to FILE, to replay the run bit for bit
    /// (`--motion FILE`).
    #[arg(long, value_name = "FILE")]
    pub record_input: Option<std::path::PathBuf>,
    /// A --motion input counts as ended after this many seconds without a UDP datagram or
    /// TCP data (on any connection: connecting is no data), once the first has arrived
    /// [default: 10].
    #[arg(long, value_name = "SECONDS")]
    pub input_timeout: Option<f64>,
}

/// The run the flags describe, over the scene file's.
pub fn spec(a: &RunArgs) -> Result<RunSpec> {
    let signal = a.sim.builder(DEFAULT_IMU, DEFAULT_PROTOCOL)?;
    let l = &a.live;
    let mut spec = RunSpec::from_signal(signal)?;
    let sinks = [
        ("pty", &a.pty),
        ("serial", &a.serial),
        ("udp", &a.udp),
        ("tcp", &a.tcp),
        ("tcp-listen", &a.tcp_listen),
        ("file", &a.file),
    ];
    let imu_sinks = (sinks.iter())
        .flat_map(|(kind, values)| values.iter().map(|v| (kind.to_string(), v.clone())))
        .collect();
    spec.apply_overrides(&Overrides {
        live: LiveOverrides {
            motion: l.motion.clone(),
            input_format: l.input_format.clone(),
            time_mode: l.time_mode.clone(),
            output_delay: l.output_delay,
            max_extrapolation: l.max_extrapolation,
            correction_horizon: l.correction_horizon,
            on_timeout: l.on_timeout.clone(),
            record_input: l.record_input.clone(),
            input_timeout: l.input_timeout,
        },
        imu_sinks,
        unit_sinks: a.unit_sink.clone(),
        gnss: a.gnss.clone(),
        sensors: [&a.odometer, &a.baro, &a.magnetometer].map(Clone::clone),
        speed: a.speed.clone(),
        start_at: a.start_at.clone(),
        time_base: a.time_base.clone(),
        max_behind_ms: a.max_behind_ms,
        realtime_priority: a.realtime,
        time_marks: a.time_marks.clone(),
        pulse: a.pulse.clone(),
        pulse_port: a.pulse_port.clone(),
        pulse_unit: a.pulse_unit.clone(),
        pps_in: a.pps_in.clone(),
        trigger: a.trigger.clone(),
        baud: a.baud,
        framing: a.framing.clone(),
        udp_batch: a.udp_batch,
        take_over: a.take_over,
    })?;
    Ok(spec)
}

/// Installs the `tracing` subscriber on stderr: warnings only, `-v` info, `-vv` debug
/// (`RUST_LOG` overrides).
pub fn init_logging(verbose: u8) {
    use std::io::IsTerminal;
    let level = ["warn", "info", "debug"][(verbose as usize).min(2)];
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(level));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .try_init();
}

pub fn run(a: RunArgs) -> Result<()> {
    init_logging(a.verbose);
    let run = spec(&a)?.build()?;
    if a.describe {
        let text = run.describe() + "\n";
        return super::stdout::write(text.as_bytes(), "the description", true);
    }
    super::flow::execute(run)
}
