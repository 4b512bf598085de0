//! `imu-emu run --motion SOURCE`: follow a vehicle simulation's states as they arrive
//! (docs/live-input.md), with one IMU or a rig's units (docs/rig.md). Parses and prints; the
//! run is `imu_emu::run::lockstep`, or `imu_emu::run::live_realtime` through [`super::live_rt`].

use std::io::{IsTerminal, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};

use imu_emu::live::transport::{Endpoint, Receiver};
use imu_emu::live::{InputFormat, TimeBase};
use imu_emu::output::AtomicFile;
use imu_emu::rig::{SinkAddr, Unit};
use imu_emu::run::lockstep::{LiveSummary, Lockstep};
use imu_emu::run::target::Target;

use super::run::{DEFAULT_IMU, DEFAULT_PROTOCOL, FOREVER_S, RunArgs};

/// The live-input flags of `run`.
#[derive(clap::Args)]
pub struct LiveArgs {
    /// Follow states that arrive live instead of a scene or a trajectory file:
    /// udp://HOST:PORT (unicast or multicast), tcp://HOST:PORT (listens, takes the first
    /// connection), - (stdin), or a FIFO or file (docs/live-input.md).
    #[arg(long, value_name = "SOURCE")]
    pub motion: Option<String>,
    /// Wire format of the --motion states: csv, bin or mavlink (HIL_STATE_QUATERNION).
    #[arg(long, default_value = "csv", value_name = "FORMAT")]
    pub input_format: String,
    /// How output follows --motion: realtime (simulation time mapped to the host clock,
    /// frames at their instants plus --output-delay, to every sink) or lockstep (each state
    /// releases the records up to its time, no wall clock, one --file).
    #[arg(long, default_value = "realtime", value_name = "MODE")]
    pub time_mode: String,
    /// Realtime: how long the frames trail the simulation (s) [default: the measured input
    /// period plus its jitter plus 3 ms, reported at the start].
    #[arg(long, value_name = "SECONDS")]
    pub output_delay: Option<f64>,
    /// Realtime: the longest extrapolation past the newest state with its jerk and angular
    /// acceleration (s); past it the motion holds its acceleration and angular rate.
    #[arg(long, default_value_t = 0.25, value_name = "SECONDS")]
    pub max_extrapolation: f64,
    /// Realtime: duration of the smooth correction back to the received motion after a late
    /// state (s).
    #[arg(long, default_value_t = 0.1, value_name = "SECONDS")]
    pub correction_horizon: f64,
    /// Realtime: once the input is silent for --input-timeout (or its stream ended):
    /// stop (emit up to the newest state, then end), hold (constant acceleration and
    /// angular rate) or extrapolate (keep going).
    #[arg(long, default_value = "stop", value_name = "POLICY")]
    pub on_timeout: String,
    /// Write every message received on --motion to FILE, to replay the run bit for bit
    /// (`--motion FILE`).
    #[arg(long, value_name = "FILE")]
    pub record_input: Option<std::path::PathBuf>,
    /// End a --motion run after this many seconds without a UDP datagram or TCP data, once
    /// the first has arrived.
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    pub input_timeout: f64,
}

/// The input flags of a `--motion` run, checked: the wire format and where to listen.
fn input(a: &RunArgs, source: &str) -> Result<(InputFormat, Endpoint)> {
    let l = &a.live;
    let format = InputFormat::from_name(&l.input_format).with_context(|| {
        format!(
            "--input-format {}: expected csv, bin or mavlink",
            l.input_format
        )
    })?;
    if l.time_mode != "lockstep" && l.time_mode != "realtime" {
        bail!("--time-mode {}: expected realtime or lockstep", l.time_mode);
    }
    if !(l.input_timeout.is_finite() && l.input_timeout > 0.0) {
        bail!(
            "--input-timeout {}: expected a positive number of seconds",
            l.input_timeout
        );
    }
    if a.sim.source.scene.is_some() || a.sim.source.trajectory.is_some() {
        bail!("--motion replaces --scene and --trajectory: give one source");
    }
    let endpoint = Endpoint::parse(source).map_err(|e| anyhow::anyhow!("--motion {e}"))?;
    Ok((format, endpoint))
}

/// The time base of a lockstep run's input tags: `sim` (the tags as sent) or `gps` (GPS time
/// tags; MAVLink's Unix `time_usec` converted to GPS time), counted from the first GPS week.
fn lockstep_base(a: &RunArgs) -> Result<TimeBase> {
    Ok(match a.time_base.as_str() {
        "sim" => TimeBase::Sim,
        "gps" => TimeBase::Gps,
        other => bail!(
            "--time-base {other}: a --motion run takes sim (the tags as sent) or gps (GPS time tags; MAVLink's Unix time_usec converted to GPS time)"
        ),
    })
}

/// Runs `run --motion`.
pub fn run(a: &RunArgs, source: &str) -> Result<()> {
    let (format, endpoint) = input(a, source)?;
    if a.live.time_mode == "realtime" {
        return super::live_rt::run(a, &endpoint, format);
    }
    let base = lockstep_base(a)?;
    if !(a.pty.is_empty() && a.serial.is_empty() && a.udp.is_empty()) || a.file.len() != 1 {
        bail!(
            "--motion in lockstep writes to one --file (a path, a FIFO or - for stdout); the paced sinks (--pty, --serial, --udp) take --time-mode realtime"
        );
    }
    let builder = (a.sim.builder(DEFAULT_IMU, DEFAULT_PROTOCOL)?).unbounded_duration(FOREVER_S);
    let run = Lockstep::with_time_base(builder, format, base)?;
    let s = follow(a, &endpoint, run, std::slice::from_ref(&a.file[0]))?;
    eprintln!(
        "imu-emu: {} records at {} Hz from t = {} s to {} s; input: {}",
        s.records,
        s.grid.rate_hz,
        s.grid.t0,
        s.grid.t0 + s.records as f64 / s.grid.rate_hz,
        s.stats.summary()
    );
    for p in &s.stats.problems {
        eprintln!("  {p}");
    }
    Ok(())
}

/// Runs `run RIG.toml --motion`: every unit of the rig follows the input, in real time
/// ([`super::live_rt::run_rig`]) or in lockstep, each to its one file sink.
pub fn run_rig(a: &RunArgs, source: &str, units: &[Unit], sinks: &[Vec<SinkAddr>]) -> Result<()> {
    let (format, endpoint) = input(a, source)?;
    super::aiding_run::refuse_with_aiding(a, &super::aiding_run::requests(a)?)?;
    if a.live.time_mode == "realtime" {
        return super::live_rt::run_rig(a, &endpoint, format, units, sinks);
    }
    if a.time_base != "sim" {
        bail!(
            "--time-base {}: a rig following --motion takes its input's tags as simulation seconds (sim); GPS-tagged input is followed by one IMU",
            a.time_base
        );
    }
    if a.speed.is_some() || a.start_at.is_some() {
        bail!("--speed and --start-at apply to scene runs; a --motion run follows the input");
    }
    let mut paths = Vec::new();
    for (u, list) in units.iter().zip(sinks) {
        match list.as_slice() {
            [SinkAddr::File(p)] => paths.push(p.clone()),
            _ => bail!(
                "unit `{}`: a rig following --motion in lockstep writes each unit to one file (`--unit-sink {}=file:PATH`, or - for stdout); the paced sinks (pty, serial, udp) take --time-mode realtime",
                u.name(),
                u.name()
            ),
        }
    }
    if paths.iter().filter(|p| *p == "-").count() > 1 {
        bail!("at most one unit can write to stdout (file:-)");
    }
    let builder = (a.sim.builder("ideal", "csv")?).unbounded_duration(FOREVER_S);
    let run = Lockstep::rig(builder, format)?;
    let s = follow(a, &endpoint, run, &paths)?;
    eprintln!(
        "imu-emu: {} records of {} units; input: {}",
        s.records,
        units.len(),
        s.stats.summary()
    );
    for (u, (g, n)) in units.iter().zip(&s.outputs) {
        eprintln!(
            "  unit {}: {n} records at {} Hz from t = {} s to {} s",
            u.name(),
            g.rate_hz,
            g.t0,
            g.t0 + *n as f64 / g.rate_hz
        );
    }
    for p in &s.stats.problems {
        eprintln!("  {p}");
    }
    Ok(())
}

/// One output of a lockstep run: a file written whole or not at all, or stdout.
enum Out {
    File(AtomicFile),
    Stdout(std::io::StdoutLock<'static>),
}

impl Out {
    fn writer(&mut self) -> &mut dyn Write {
        match self {
            Out::File(f) => f,
            Out::Stdout(s) => s,
        }
    }
}

/// Follows `endpoint` in lockstep, output i to `paths[i]` (`-`: stdout), recording the input
/// when asked; every file is kept only if the run succeeds, the input record always.
fn follow<T: Target>(
    a: &RunArgs,
    endpoint: &Endpoint,
    run: Lockstep<T>,
    paths: &[String],
) -> Result<LiveSummary> {
    let l = &a.live;
    let idle = Some(Duration::from_secs_f64(l.input_timeout));
    let format = InputFormat::from_name(&l.input_format).expect("checked");
    let mut rx = Receiver::open(endpoint, format, idle)
        .with_context(|| format!("--motion {}: opening", l.motion.as_deref().unwrap_or("")))?;
    eprintln!("imu-emu: following {} ({})", rx.name(), l.input_format);
    let mut outs = Vec::new();
    for path in paths {
        outs.push(if path == "-" {
            Out::Stdout(std::io::stdout().lock())
        } else {
            Out::File(
                AtomicFile::create(Path::new(path)).with_context(|| format!("creating {path}"))?,
            )
        });
    }
    let mut record = match &l.record_input {
        Some(p) => {
            Some(AtomicFile::create(p).with_context(|| format!("creating {}", p.display()))?)
        }
        None => None,
    };
    let live = std::io::stderr().is_terminal();
    let mut last = Instant::now();
    let mut writers: Vec<&mut dyn Write> = outs.iter_mut().map(Out::writer).collect();
    let result = run.run_to(
        &mut rx,
        &mut writers,
        record.as_mut().map(|r| r as &mut dyn Write),
        |s| {
            if live && last.elapsed() >= Duration::from_secs(1) {
                last = Instant::now();
                eprint!("\r\x1b[2K{} records; {}", s.records(), s.stats().summary());
            }
        },
    );
    drop(writers);
    if live {
        eprint!("\r\x1b[2K");
    }
    // The input record is kept whatever happened: it is how a failed run is reproduced.
    if let (Some(r), Some(p)) = (record, &l.record_input) {
        r.commit()
            .with_context(|| format!("writing {}", p.display()))?;
    }
    let s = result?;
    for (o, path) in outs.into_iter().zip(paths) {
        if let Out::File(f) = o {
            f.commit().with_context(|| format!("writing {path}"))?;
        }
    }
    Ok(s)
}
