//! `imu-emu run`: the emulator. Frames at wall-clock rate to ptys, serial devices, UDP and
//! files; tokio runs the control plane (signals, status line), the pacer its own thread.

use std::io::IsTerminal;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result, bail};

use imu_emu::engine;
use imu_emu::protocol::Plan;
use imu_emu::realtime::hostclock::GpsClock;
use imu_emu::realtime::pacer::{self, Clocking, Pacing, Routed, Status};
use imu_emu::realtime::serial::{Framing, SerialSink, check_link};
use imu_emu::realtime::signal::{Interrupted, StopSignals};
use imu_emu::realtime::sink::FileSink;
use imu_emu::realtime::udp::{self, UdpSink};
use imu_emu::realtime::{self, FrameBlock, clock, pty::PtySink};

use imu_emu::rig::SinkAddr;
use imu_emu::run::merge::{self, ProducerWindow, WindowSource};

use super::aiding_run;
use super::rigrun::{Stream, WINDOW_NS};
use super::setup::{SimArgs, announce, require_frames};

/// The protocol `run` speaks by default: LN-200-style frames.
pub const DEFAULT_PROTOCOL: &str = "ln200";
/// The IMU template `run` emulates by default.
pub const DEFAULT_IMU: &str = "ln200";
/// Duration of a run on an unbounded scene when none is given: "until Ctrl-C" (a year).
pub const FOREVER_S: f64 = 365.0 * 86_400.0;

#[derive(clap::Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub sim: SimArgs,
    #[command(flatten)]
    pub live: super::live::LiveArgs,
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
    /// Serial character framing (data bits, parity N/E/O, stop bits).
    #[arg(long, default_value = "8N1")]
    pub framing: Framing,
    /// UDP sink HOST:PORT (unicast, broadcast or multicast); repeatable.
    #[arg(long, value_name = "HOST:PORT[,protocol=NAME]")]
    pub udp: Vec<String>,
    /// A rig unit's sink, NAME=KIND:TARGET with KIND pty, serial, udp or file (e.g.
    /// `nav=udp:127.0.0.1:9001`); repeatable; replaces the scene file's `sink` of that unit.
    #[arg(long, value_name = "NAME=SINK")]
    pub unit_sink: Vec<String>,
    /// A GNSS receiver's stream on the same pacer, FORMAT:SINK with FORMAT nmea, ubx or
    /// mavlink and SINK as `--unit-sink`'s (e.g. `nmea:udp:127.0.0.1:9010`); repeatable
    /// (docs/aiding.md).
    #[arg(long = "gnss", value_name = "FORMAT:SINK")]
    pub gnss: Vec<String>,
    /// The odometer's CSV rows on the same pacer, to SINK (as `--unit-sink`'s); repeatable.
    #[arg(long, value_name = "SINK")]
    pub odometer: Vec<String>,
    /// The barometer's CSV rows on the same pacer, to SINK; repeatable.
    #[arg(long, value_name = "SINK")]
    pub baro: Vec<String>,
    /// The magnetometer's CSV rows on the same pacer, to SINK; repeatable.
    #[arg(long, value_name = "SINK")]
    pub magnetometer: Vec<String>,
    /// Frames per UDP datagram.
    #[arg(long, default_value_t = 1)]
    pub udp_batch: usize,
    /// File sink, or - for stdout; repeatable.
    #[arg(long, value_name = "PATH[,protocol=NAME]")]
    pub file: Vec<String>,
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
    /// own time, offset by --gps-time). With --motion: `gps` says the input's time tags are
    /// GPS time (MAVLink: Unix time, converted), and in real time that the host clock is too,
    /// so they map to it directly.
    #[arg(long, default_value = "sim", value_parser = ["gps", "utc", "sim"])]
    pub time_base: String,
    /// Time-mark side channel: per frame its index, time of validity, due and emission
    /// instants, to `udp://HOST:PORT` (40-byte datagrams) or a file (CSV if it ends in .csv,
    /// else 40-byte records); see docs/timing.md. Repeatable.
    #[arg(long, value_name = "udp://HOST:PORT|FILE")]
    pub time_marks: Vec<String>,
    /// Pulse on a modem line: LINE rts|dtr, MARK tov (every sample's time of validity) or pps
    /// (each whole second), the rising edge OFFSET after it and WIDTH high [default 0, 500us].
    #[arg(long, value_name = "LINE:MARK[:OFFSET][:WIDTH]")]
    pub pulse: Option<imu_emu::realtime::pulse::PulseSpec>,
    /// Serial device whose modem line --pulse drives [default: the first --serial].
    #[arg(long, value_name = "DEV")]
    pub pulse_port: Option<String>,
    /// Phase-lock the output's whole seconds to a PPS: `/dev/ppsN`, `dcd:DEV`, `cts:DEV` or
    /// `udp://HOST:PORT` (edge datagrams); see docs/timing.md.
    #[arg(long, value_name = "SOURCE")]
    pub pps_in: Option<String>,
    /// External sample trigger: one sample per edge, integrating over the interval since the
    /// previous edge (the first edge is t₀): `udp://HOST:PORT` (edge datagrams), `dcd:DEV`,
    /// `cts:DEV` or `/dev/ppsN`; see docs/timing.md.
    #[arg(long, value_name = "SOURCE")]
    pub trigger: Option<String>,
    /// Frames later than this are skipped and counted rather than sent in a burst (ms).
    #[arg(long, default_value_t = 100.0)]
    pub max_behind_ms: f64,
    /// Run the pacer SCHED_FIFO (needs CAP_SYS_NICE or an RLIMIT_RTPRIO; falls back with a
    /// warning).
    #[arg(long)]
    pub realtime: bool,
    /// More log output (-v info, -vv debug).
    #[arg(short, long, action = clap::ArgAction::Count)]
    pub verbose: u8,
}

/// Installs the `tracing` subscriber on stderr: warnings only, `-v` info, `-vv` debug
/// (`RUST_LOG` overrides).
pub fn init_logging(verbose: u8) {
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
    if a.udp_batch == 0 {
        bail!("--udp-batch 0: expected at least 1 frame per datagram");
    }
    if !(a.max_behind_ms.is_finite() && a.max_behind_ms >= 0.0) {
        bail!(
            "--max-behind-ms {}: expected a non-negative number",
            a.max_behind_ms
        );
    }
    // A scene file with an `[[imu]]` list: every unit on one pacer.
    if a.sim.source.scene_file.is_some() && a.sim.builder(DEFAULT_IMU, DEFAULT_PROTOCOL)?.is_rig() {
        return super::rigrun::run(a);
    }
    if !a.unit_sink.is_empty() {
        bail!("--unit-sink names a unit of a rig: the scene file lists no `[[imu]]` units");
    }
    let asked = aiding_run::requests(&a)?;
    aiding_run::refuse_with_aiding(&a, &asked)?;
    // A live run in lockstep writes records as well as frames.
    if let Some(source) = &a.live.motion {
        return super::live::run(&a, source);
    }
    if let Some(p) = a.sim.format.as_deref()
        && imu_emu::output::Format::from_name(p).is_some()
    {
        bail!(
            "--format {p}: `run` streams protocol frames; use `generate --format {p}` for records"
        );
    }
    let speed = match a.speed.as_deref() {
        None => None,
        Some("max") => Some(f64::INFINITY),
        Some(s) => match s.parse::<f64>() {
            Ok(x) if x.is_finite() && x > 0.0 => Some(x),
            _ => bail!("--speed {s}: expected a positive factor (1 = real time) or `max`"),
        },
    };
    let leap = imu_emu::timebase::LeapTable::builtin();
    let host = GpsClock::new(leap.clone());
    let mut start_at = a
        .start_at
        .as_deref()
        .map(|s| {
            imu_emu::timebase::parse_start(s, clock::realtime_ns(), &leap)
                .map_err(|e| anyhow::anyhow!("--start-at {e}"))
        })
        .transpose()?;
    let mut sim = (a.sim.builder(DEFAULT_IMU, DEFAULT_PROTOCOL)?)
        .unbounded_duration(FOREVER_S)
        .build()?;
    if a.time_base != "sim" && a.sim.gps_time.is_some() {
        bail!("--gps-time sets the GPS reference of --time-base sim only");
    }
    if let Some(((week, sow), (gw, gs))) = time_base_start(&a, &host, &leap, &mut start_at) {
        sim.set_gps_time(week, sow - sim.grid().t0);
        sim.set_gnss_gps_time(gw, gs - sim.grid().t0);
    }
    announce(&sim);
    let plan = require_frames(&sim, "run")?;
    let grid = sim.grid();
    let aiding = aiding_run::build(asked, &sim);
    let only_files = a.pty.is_empty()
        && a.serial.is_empty()
        && a.udp.is_empty()
        && aiding.iter().flat_map(|s| &s.sinks).all(SinkAddr::is_file);
    let speed = speed.unwrap_or(if only_files && !a.file.is_empty() {
        f64::INFINITY
    } else {
        1.0
    });
    let paced = speed.is_finite();
    let frames_per_s = grid.rate_hz * if paced { speed } else { 1.0 };

    // Before any sink is visible (a pty link, a first datagram): a signal from then on ends
    // the run with its summary and exit status.
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let mut signals = {
        let _rt = rt.enter();
        StopSignals::new()?
    };

    let stop = Arc::new(AtomicBool::new(false));
    let mut aiding_lines = Vec::new();
    let (mut sinks, plans) = open_sinks(&a, plan.clone(), grid.rate_hz, frames_per_s, paced)?;
    let n_streams = plans.len();
    // Aiding streams follow the IMU's: merged, every frame carries its emission time.
    let merged = !aiding.is_empty();
    let mut sources: Vec<Box<dyn WindowSource>> = Vec::new();
    let mut frames_per_s = frames_per_s;
    if merged {
        frames_per_s *= n_streams as f64;
        for (j, s) in aiding.into_iter().enumerate() {
            let stream = Stream {
                name: s.what.name(),
                rate_hz: s.rate_hz,
                plan: None,
            };
            for addr in &s.sinks {
                let sink = super::rigrun::open(&a, &stream, addr, paced, speed)?;
                sinks.push(Routed {
                    stream: n_streams + j,
                    sink,
                });
            }
            frames_per_s += s.rate_hz * if paced { speed } else { 1.0 };
            aiding_lines.push((stream.name, s.what.unit(), s.planned));
            sources.push(s.source);
        }
    }
    let extra: Vec<engine::Encoding> = (plans.into_iter().skip(1))
        .map(|p| sim.frames_encoding(p))
        .collect();

    let extras = sync_extras(&a, paced, speed, grid.rate_hz, &stop)?;
    let mut producer = sim.producer()?.with_extra_encodings(extra);
    let mut first_edge = None;
    if let Some(spec) = &a.trigger {
        let (p, first) = triggered(
            &a,
            spec,
            paced && speed == 1.0,
            producer,
            &stop,
            &rt,
            &mut signals,
        )?;
        producer = p;
        first_edge = Some(first);
    }
    let pacing = if paced {
        let start_ns = match first_edge {
            Some(f) => Some(f),
            None => start_at.map(clock::start_at).transpose().map_err(|e| {
                anyhow::anyhow!("--start-at {}: {e}", a.start_at.clone().unwrap_or_default())
            })?,
        };
        let mut c = Clocking::new(frames_per_s, start_ns, a.realtime)
            .map_err(|e| anyhow::anyhow!(e))?
            .with_speed(speed);
        c.max_behind_ns = (a.max_behind_ms * 1e6) as i128;
        c.on_edges = first_edge.is_some();
        if c.batch > 1 {
            tracing::info!("{frames_per_s} frames/s: {} frames per wake-up", c.batch);
        }
        Pacing::Paced(c)
    } else {
        Pacing::Unpaced
    };
    let block = realtime::block_len(frames_per_s);
    tracing::info!(
        "{} records at {} Hz, {}; blocks of {block} frames, {} in flight",
        grid.count,
        grid.rate_hz,
        if paced {
            format!("{frames_per_s} frames/s of wall clock")
        } else {
            "unpaced".into()
        },
        realtime::CHANNEL_BLOCKS
    );

    let produce: Produce = if merged {
        let imu = ProducerWindow::new(producer, grid.rate_hz, n_streams, block);
        sources.insert(0, Box::new(imu));
        Box::new(move |tx, rx| merge::produce_merged(sources, WINDOW_NS, tx, rx))
    } else {
        Box::new(move |tx, rx| imu_emu::run::merge::produce(producer, block, n_streams, tx, rx))
    };
    let ended = drive(
        &rt,
        &mut signals,
        sinks,
        pacing,
        (stop, extras),
        produce,
        |s| format!("{} | {}", status_line(s), host.brief()),
    )?;
    let (final_status, interrupted, failed) = (ended.status, ended.interrupted, ended.failed);
    eprintln!(
        "imu-emu: {}{}",
        interrupted.map_or(String::new(), |i| format!("{i}: ")),
        merged_summary(&final_status, grid.count, paced, n_streams, &aiding_lines)
    );
    if paced {
        eprintln!("imu-emu: host clock: {}", host.brief());
    }
    // After the summary: the exit status tells a script the run did not complete.
    if let Some(e) = failed {
        return Err(anyhow::Error::new(e).context("stopped: nothing non-finite was sent"));
    }
    interrupted.map_or(Ok(()), |i| Err(i.into()))
}

/// How a paced (or unpaced) run ended.
pub(super) struct Ended {
    /// The pacer's final counts.
    pub status: Status,
    /// The signal that stopped it, if one did.
    pub interrupted: Option<Interrupted>,
    /// Why the producer stopped early, if it did.
    pub failed: Option<imu_emu::engine::EngineError>,
}

/// Runs `produce` (blocks of frames, on a blocking thread) into the pacer (its own thread)
/// writing `sinks` with the `extras` (time marks, pulses, phase lock), shows `line` of the
/// live status once a second on a terminal, and stops on a signal (or when `stop` is set).
pub(super) fn drive(
    rt: &tokio::runtime::Runtime,
    signals: &mut StopSignals,
    sinks: Vec<Routed>,
    pacing: Pacing,
    (stop, extras): (Arc<AtomicBool>, pacer::Extras),
    produce: impl FnOnce(
        tokio::sync::mpsc::Sender<FrameBlock>,
        tokio::sync::mpsc::Receiver<FrameBlock>,
    ) -> Option<imu_emu::engine::EngineError>
    + Send
    + 'static,
    line: impl Fn(&Status) -> String,
) -> Result<Ended> {
    let paced = matches!(pacing, Pacing::Paced(_));
    let status = Arc::new(Mutex::new(Status::default()));
    let (tx, rx) = tokio::sync::mpsc::channel(realtime::CHANNEL_BLOCKS);
    let (recycle_tx, recycle_rx) = tokio::sync::mpsc::channel(realtime::CHANNEL_BLOCKS);
    let (done_tx, done_rx) = tokio::sync::oneshot::channel();
    let producer_task = rt.spawn_blocking(move || produce(tx, recycle_rx));
    let pacer_thread = {
        let (stop, status) = (stop.clone(), status.clone());
        std::thread::Builder::new()
            .name("imu-pacer".into())
            .spawn(move || {
                let r = pacer::run_with(rx, recycle_tx, sinks, pacing, stop, status, extras);
                let _ = done_tx.send(());
                r
            })?
    };
    let live = std::io::stderr().is_terminal();
    let interrupted = rt.block_on(async {
        let mut tick = tokio::time::interval(std::time::Duration::from_secs(1));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        tokio::pin!(done_rx);
        loop {
            tokio::select! {
                _ = &mut done_rx => return None,
                sig = signals.recv() => {
                    stop.store(true, Ordering::Relaxed);
                    return Some(Interrupted(sig));
                }
                _ = tick.tick() => {
                    if live && paced {
                        let s = status.lock().unwrap_or_else(|e| e.into_inner()).clone();
                        eprint!("\r\x1b[2K{}", line(&s));
                    }
                }
            }
        }
    });
    if live && paced {
        eprint!("\r\x1b[2K");
    }
    let status = pacer_thread
        .join()
        .map_err(|_| anyhow::anyhow!("the pacer thread panicked"))??;
    // The producer ends once the pacer has dropped its channel.
    let failed = rt
        .block_on(producer_task)
        .map_err(|e| anyhow::anyhow!("the producer task failed: {e}"))?;
    Ok(Ended {
        status,
        interrupted,
        failed,
    })
}

/// A file sink at `path` (`-`: stdout), buffered; its write errors name the file.
pub(super) fn file_sink(path: &str, paced: bool) -> Result<Box<dyn realtime::sink::Sink>> {
    let (label, w): (String, Box<dyn std::io::Write + Send>) = if path == "-" {
        ("stdout".into(), Box::new(std::io::stdout()))
    } else {
        let f = std::fs::File::create(path).with_context(|| format!("creating {path}"))?;
        let label = format!("file {path}");
        (label.clone(), Box::new(Labeled { label, inner: f }))
    };
    Ok(Box::new(FileSink::new(
        label,
        Box::new(std::io::BufWriter::with_capacity(1 << 16, w)),
        paced,
    )))
}

/// Opens every sink of `a` (a pty when none is given), each on stream 0 (the main protocol,
/// `plan`) or on a stream of its own protocol; returns them and the plans of the streams.
pub fn open_sinks(
    a: &RunArgs,
    plan: Plan,
    rate_hz: f64,
    frames_per_s: f64,
    paced: bool,
) -> Result<(Vec<Routed>, Vec<Plan>)> {
    let grid_rate = rate_hz;
    // Sinks, each on stream 0 (the main protocol) or on a stream of its own protocol.
    let mut streams = Streams::new(plan, grid_rate);
    let mut sinks: Vec<Routed> = Vec::new();
    let mut ptys: Vec<Option<&str>> = a.pty.iter().map(|p| Some(p.as_str())).collect();
    if ptys.is_empty() && a.serial.is_empty() && a.udp.is_empty() && a.file.is_empty() {
        ptys.push(None);
    }
    for value in ptys {
        let (link, proto) = value.map_or((None, None), |v| {
            let (l, p) = split_sink(v);
            (Some(Path::new(l)), p)
        });
        let (stream, p) = streams.route(proto)?;
        let s = PtySink::open(link, a.take_over).with_context(|| {
            format!(
                "opening a pty{}",
                link.map_or(String::new(), |l| format!(" at {}", l.display()))
            )
        })?;
        eprintln!(
            "imu-emu: {} frames at {} Hz on {}{}",
            p.name,
            grid_rate,
            s.path().display(),
            if s.path() != s.slave() {
                format!(" -> {}", s.slave().display())
            } else {
                String::new()
            }
        );
        sinks.push(Routed {
            stream,
            sink: Box::new(s),
        });
    }
    for value in &a.serial {
        let (dev, proto) = split_sink(value);
        let (stream, p) = streams.route(proto)?;
        let baud = a.baud.or(p.baud.map(|b| b as u32)).unwrap_or(921_600);
        check_link(p.len(), frames_per_s, baud, a.framing)
            .map_err(|e| anyhow::anyhow!("--serial {dev}: {e}"))?;
        let sink = Box::new(SerialSink::open(dev, baud, a.framing)?);
        sinks.push(Routed { stream, sink });
    }
    for value in &a.udp {
        let (dest, proto) = split_sink(value);
        let (stream, p) = streams.route(proto)?;
        let sink = UdpSink::open(dest, a.udp_batch).with_context(|| format!("--udp {dest}"))?;
        sink.check_datagram(udp::max_wire_len(&p))
            .map_err(|e| anyhow::anyhow!("--udp {dest}: {e}"))?;
        sinks.push(Routed {
            stream,
            sink: Box::new(sink),
        });
    }
    for value in &a.file {
        let (path, proto) = split_sink(value);
        let (stream, _) = streams.route(proto)?;
        let sink = file_sink(path, paced)?;
        sinks.push(Routed { stream, sink });
    }
    Ok((sinks, streams.plans))
}

/// Splits a sink flag's value into its target and the protocol of `,protocol=NAME`.
fn split_sink(v: &str) -> (&str, Option<&str>) {
    match v.rsplit_once(",protocol=") {
        Some((target, p)) => (target, Some(p)),
        None => (v, None),
    }
}

/// The wire formats of a run: the main protocol (stream 0) and one stream per other protocol
/// a sink asks for.
struct Streams {
    names: Vec<Option<String>>,
    plans: Vec<Plan>,
    /// The run's rate, which counters that count internal ticks step by.
    rate_hz: f64,
}

impl Streams {
    fn new(main: Plan, rate_hz: f64) -> Streams {
        Streams {
            names: vec![None],
            plans: vec![main],
            rate_hz,
        }
    }

    /// The stream of `protocol` (`None`: the main one), compiling it on first use.
    fn route(&mut self, protocol: Option<&str>) -> Result<(usize, Plan)> {
        let i = match self.names.iter().position(|n| n.as_deref() == protocol) {
            Some(i) => i,
            None => {
                let name = protocol.expect("the main stream is always there");
                let (_, mut plan) = imu_emu::protocol::load(name)
                    .with_context(|| format!("sink protocol `{name}`"))?;
                plan.set_rate(self.rate_hz)
                    .map_err(|e| anyhow::anyhow!("sink protocol `{name}`: {e}"))?;
                self.names.push(Some(name.to_string()));
                self.plans.push(plan);
                self.plans.len() - 1
            }
        };
        Ok((i, self.plans[i].clone()))
    }
}

/// The one-line live status.
fn status_line(s: &Status) -> String {
    let elapsed = s
        .start_ns
        .map_or(0.0, |t| (clock::monotonic_ns() - t) as f64 / 1e9);
    let mut line = format!(
        "{elapsed:.1} s, {} frames, late {}",
        s.frames,
        s.lateness.summary()
    );
    if let Some(e) = &s.edge_latency {
        line += &format!(", edge to frame {}", e.summary());
    }
    if s.skipped > 0 {
        line += &format!(", {} skipped", s.skipped);
    }
    if let Some(l) = &s.lock {
        line += &format!(", {}", lock_text(l));
    }
    for (label, st) in &s.sinks {
        line += &format!(" | {label}: {} dropped", st.dropped + st.no_reader);
    }
    line
}

/// The phase lock's state in words.
fn lock_text(l: &imu_emu::realtime::lock::LockState) -> String {
    format!(
        "PPS lock: {} edges, phase error {:.3} ms, frequency offset {:+.3} ppm",
        l.edges,
        l.phase_error_ns / 1e6,
        l.freq_offset_ppm
    )
}

/// The time marks, pulse output and PPS lock the flags ask for.
fn sync_extras(
    a: &RunArgs,
    paced: bool,
    speed: f64,
    rate_hz: f64,
    stop: &Arc<AtomicBool>,
) -> Result<pacer::Extras> {
    use imu_emu::realtime::{lock::PhaseLock, pps, pulse, timemark::TimeMarks};
    let mut extras = pacer::Extras::default();
    let asked = !a.time_marks.is_empty() || a.pulse.is_some() || a.pps_in.is_some();
    if asked && !paced {
        bail!("--time-marks, --pulse and --pps-in need a paced run: give --speed 1");
    }
    for t in &a.time_marks {
        extras.hooks.push(Box::new(TimeMarks::open(t)?));
    }
    if let Some(spec) = a.pulse {
        spec.check(1e9 / (rate_hz * speed))
            .map_err(|e| anyhow::anyhow!("--pulse: {e}"))?;
        let dev = (a.pulse_port.as_deref())
            .or(a.serial.first().map(|s| split_sink(s).0))
            .ok_or_else(|| {
                anyhow::anyhow!("--pulse: give --pulse-port DEV or a --serial device")
            })?;
        let line = pulse::ModemLine::open(dev, spec.pin).context("--pulse")?;
        extras
            .hooks
            .push(Box::new(pulse::Pulse::new(spec, Box::new(line))?));
    } else if a.pulse_port.is_some() {
        bail!("--pulse-port without --pulse");
    }
    if let Some(src) = &a.pps_in {
        if speed != 1.0 {
            bail!("--pps-in locks real seconds: give --speed 1");
        }
        let edges = pps::spawn(pps::open(src)?, stop.clone())?;
        extras.lock = Some((edges, PhaseLock::new(1_000_000_000)));
    }
    Ok(extras)
}

/// On `--time-base gps|utc` (`None` on `sim`): the GPS week and seconds of the run's start
/// instant — `start_at` (UTC ns), set to the next whole second unless `--start-at` gave one —
/// in the time base, printed with the host clock's source and error.
pub(super) fn time_base_start(
    a: &RunArgs,
    host: &GpsClock,
    leap: &imu_emu::timebase::LeapTable,
    start_at: &mut Option<i128>,
) -> Option<((u32, f64), (u32, f64))> {
    if a.time_base == "sim" {
        return None;
    }
    // Record time t₀ falls on the start instant: a whole second unless given.
    let utc0 = *start_at.get_or_insert((clock::realtime_ns() / 1_000_000_000 + 1) * 1_000_000_000);
    let base = if a.time_base == "gps" {
        host.utc_to_gps_ns(utc0)
    } else {
        utc0 - imu_emu::timebase::GPS_EPOCH_UNIX_S as i128 * 1_000_000_000
    };
    let (week, sow) = imu_emu::timebase::week_sow(base);
    // GNSS streams carry true GPS time whatever the frames' scale.
    let gps = imu_emu::timebase::week_sow(host.utc_to_gps_ns(utc0));
    eprintln!(
        "imu-emu: time base {}: t₀ at week {week}, {sow} s; {}",
        a.time_base,
        host.describe(utc0)
    );
    if a.time_base == "gps" && utc0 / 1_000_000_000 > leap.valid_until as i128 {
        eprintln!(
            "imu-emu: warning: the leap-second table is only known valid until Unix time {}; update src/timebase/leap-seconds.txt (docs/timing.md)",
            leap.valid_until
        );
    }
    Some(((week, sow), gps))
}

/// The producer sampling at the edges of `--trigger`, once the first edge (t₀, returned) came.
fn triggered(
    a: &RunArgs,
    spec: &str,
    real_time: bool,
    producer: engine::Producer,
    stop: &Arc<AtomicBool>,
    rt: &tokio::runtime::Runtime,
    signals: &mut StopSignals,
) -> Result<(engine::Producer, i128)> {
    use imu_emu::realtime::pps;
    use imu_emu::run::trigger::ChannelTrigger;
    if !real_time {
        bail!("--trigger samples at real edges: give --speed 1");
    }
    if producer.is_filtered() {
        // A filtered unit samples on its own internal clock and decimates; one sample per
        // external edge would need the filter run over each irregular interval.
        bail!(
            "--trigger: the IMU template has an [output_filter]; a triggered unit with an output filter is not supported"
        );
    }
    if a.pps_in.is_some() || a.start_at.is_some() {
        bail!("--trigger sets t₀ at its first edge: drop --pps-in and --start-at");
    }
    let edges = pps::spawn(pps::open_for("--trigger", spec)?, stop.clone())?;
    eprintln!("imu-emu: waiting for the first trigger edge on {spec}");
    let wait = rt.spawn_blocking(move || {
        let first = edges.recv().ok();
        (edges, first)
    });
    let (edges, first) = rt.block_on(async {
        tokio::select! {
            r = wait => r.map_err(|e| anyhow::anyhow!("waiting for a trigger edge: {e}")),
            sig = signals.recv() => {
                stop.store(true, Ordering::Relaxed);
                Err(Interrupted(sig).into())
            }
        }
    })?;
    let first =
        first.ok_or_else(|| anyhow::anyhow!("--trigger {spec}: the edge source stopped"))?;
    let span = producer.span_after_t0();
    let source = ChannelTrigger::new(edges, first, span, stop.clone());
    Ok((producer.with_trigger(Box::new(source)), first))
}

/// The end-of-run summary.
pub(super) fn summary(s: &Status, planned: u64, paced: bool) -> String {
    let mut out = format!("{} of {planned} frames", s.frames);
    if paced {
        out += &format!(", write lateness {}", s.lateness.summary());
        out += &format!(", {} skipped (too late)", s.skipped);
    }
    if let Some(e) = &s.edge_latency {
        out += &format!(", trigger edge to frame {}", e.summary());
    }
    if let Some(l) = &s.lock {
        out += &format!(", {}", lock_text(l));
    }
    if let Some(f) = s.fifo {
        out += if f {
            ", SCHED_FIFO"
        } else {
            ", SCHED_FIFO refused"
        };
    }
    for (label, st) in &s.sinks {
        out += &format!(
            "\n  {label}: {} sent, {} dropped (slow consumer), {} dropped (no reader), {} bytes",
            st.sent, st.dropped, st.no_reader, st.bytes
        );
    }
    out
}

/// The producer side of [`drive`]: frames into the pacer's channel.
type Produce = Box<
    dyn FnOnce(
            tokio::sync::mpsc::Sender<FrameBlock>,
            tokio::sync::mpsc::Receiver<FrameBlock>,
        ) -> Option<imu_emu::engine::EngineError>
        + Send,
>;

/// [`summary`] of a run whose IMU frames (`imu_streams` protocols) shared the pacer with
/// aiding streams (name, what its frames are, how many were planned): the IMU's records and
/// skips counted on its main stream, then each aiding stream's.
fn merged_summary(
    s: &Status,
    planned: u64,
    paced: bool,
    imu_streams: usize,
    aiding: &[(String, &str, u64)],
) -> String {
    if aiding.is_empty() {
        return summary(s, planned, paced);
    }
    let main = s.streams.first().copied().unwrap_or_default();
    let imu = Status {
        frames: main.frames,
        skipped: main.skipped,
        ..s.clone()
    };
    let mut out = summary(&imu, planned, paced);
    for (i, (name, unit, n)) in aiding.iter().enumerate() {
        let c = s.streams.get(imu_streams + i).copied().unwrap_or_default();
        out += &format!(
            "\n  stream {name}: {} of {n} {unit}, {} skipped (too late)",
            c.frames, c.skipped
        );
    }
    out
}

/// A writer whose errors name what it writes to (the sink's label), keeping their kind.
struct Labeled<W> {
    label: String,
    inner: W,
}

/// An I/O error of a labelled writer: the label, then the cause as its `source()`.
#[derive(Debug, thiserror::Error)]
#[error("writing {label}")]
struct LabeledError {
    label: String,
    source: std::io::Error,
}

impl<W: std::io::Write> Labeled<W> {
    fn wrap(&self, e: std::io::Error) -> std::io::Error {
        let kind = e.kind();
        let label = self.label.clone();
        std::io::Error::new(kind, LabeledError { label, source: e })
    }
}

impl<W: std::io::Write> std::io::Write for Labeled<W> {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.inner.write(b).map_err(|e| self.wrap(e))
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush().map_err(|e| self.wrap(e))
    }
}
