//! `imu-emu run --motion SOURCE --time-mode realtime`: frames at the host-clock instants of
//! the states' simulation time plus an output delay, to every sink of `run`. Parses flags,
//! wires the input, emitter and pacer threads, prints the status and the summary; the run is
//! `imu_emu::run::live_realtime`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::{Context, Result, bail};

use imu_emu::live::InputFormat;
use imu_emu::live::transport::{Endpoint, Receiver};
use imu_emu::motion::chain::ChainSettings;
use imu_emu::motion::sampled::Degree;
use imu_emu::output::AtomicFile;
use imu_emu::realtime::hostclock::GpsClock;
use imu_emu::realtime::pacer::{self, Clocking, Pacing, Routed, Status};
use imu_emu::realtime::signal::{Interrupted, StopSignals};
use imu_emu::realtime::{self, clock};
use imu_emu::rig::{SinkAddr, Unit};
use imu_emu::run::live_realtime::{
    FrameOut, GpsBase, LiveStatus, OnTimeout, Realtime, RealtimeSettings, RealtimeSummary,
    RigRealtimeSummary,
};
use imu_emu::run::lockstep::LiveError;
use imu_emu::sim::SimulationBuilder;
use imu_emu::timebase::LeapTable;

use super::rigrun::Stream;
use super::run::{DEFAULT_IMU, DEFAULT_PROTOCOL, FOREVER_S, RunArgs, open_sinks, summary};
use super::setup::require_frames;

/// The real-time settings the flags give (and the GPS time base read now, when asked).
fn settings(a: &RunArgs) -> Result<RealtimeSettings> {
    let l = &a.live;
    let on_timeout = OnTimeout::from_name(&l.on_timeout).with_context(|| {
        format!(
            "--on-timeout {}: expected stop, hold or extrapolate",
            l.on_timeout
        )
    })?;
    let seconds = |name: &str, v: f64, min: f64| {
        if v.is_finite() && v >= min {
            Ok(v)
        } else {
            Err(anyhow::anyhow!(
                "{name} {v}: expected a number of seconds of at least {min}"
            ))
        }
    };
    let delay = l
        .output_delay
        .map(|d| seconds("--output-delay", d, 0.0))
        .transpose()?;
    let chain = ChainSettings {
        horizon: seconds("--correction-horizon", l.correction_horizon, 1e-3)?,
        max_extrapolation: seconds("--max-extrapolation", l.max_extrapolation, 0.0)?,
    };
    if a.speed.is_some() || a.start_at.is_some() {
        bail!(
            "--speed and --start-at apply to scene runs; a --motion run follows the input's clock"
        );
    }
    let gps = match a.time_base.as_str() {
        "sim" => None,
        "gps" => {
            let host = GpsClock::new(LeapTable::builtin());
            let (gps_ns, mono_ns) = (host.now_gps_ns(), clock::monotonic_ns());
            eprintln!(
                "imu-emu: time base gps: the input's time tags are GPS time, mapped to {}",
                host.describe(clock::realtime_ns())
            );
            Some(GpsBase::at(gps_ns, mono_ns))
        }
        other => bail!(
            "--time-base {other}: a --motion run takes sim (the clock map is estimated from the arrivals) or gps (the tags and the host clock are both GPS time)"
        ),
    };
    Ok(RealtimeSettings {
        delay,
        chain,
        on_timeout,
        gps,
    })
}

/// What a real-time run gave: the emitter's result, the pacer's final status, and the signal
/// that interrupted it.
struct Ran<R> {
    result: Result<R, LiveError>,
    status: Status,
    interrupted: Option<Interrupted>,
}

/// The input record a run writes, shared with the input thread.
type Record = Arc<Mutex<Option<AtomicFile>>>;

/// Opens `sinks` and the input, then runs `emit` (the emitter) and the pacer (`frames_per_s`
/// frames per second in all), printing the live status once a second, until the emitter
/// returns or a signal stops it. The input record is kept whatever happened.
fn follow<R: Send + 'static, S: Send + 'static>(
    a: &RunArgs,
    (endpoint, format, what): (&Endpoint, InputFormat, &str),
    sinks: impl FnOnce() -> Result<(Vec<Routed>, S)>,
    frames_per_s: f64,
    emit: impl FnOnce(
        S,
        Receiver,
        Record,
        FrameOut,
        Arc<AtomicBool>,
        Arc<Mutex<LiveStatus>>,
    ) -> Result<R, LiveError>
    + Send
    + 'static,
) -> Result<Ran<R>> {
    let l = &a.live;
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let mut signals = {
        let _rt = rt.enter();
        StopSignals::new()?
    };
    let (sinks, given) = sinks()?;
    let idle = Some(Duration::from_secs_f64(l.input_timeout));
    let rx = Receiver::open(endpoint, format, idle)
        .with_context(|| format!("--motion {}: opening", l.motion.as_deref().unwrap_or("")))?;
    eprintln!(
        "imu-emu: following {} ({}) in real time{what}",
        rx.name(),
        l.input_format
    );
    let record = Arc::new(Mutex::new(match &l.record_input {
        Some(p) => {
            Some(AtomicFile::create(p).with_context(|| format!("creating {}", p.display()))?)
        }
        None => None,
    }));

    let anchor_ns = clock::monotonic_ns();
    let mut c =
        Clocking::new(frames_per_s, Some(anchor_ns), a.realtime).map_err(|e| anyhow::anyhow!(e))?;
    c.max_behind_ns = (a.max_behind_ms * 1e6) as i128;
    let stop = Arc::new(AtomicBool::new(false));
    let pacer_status = Arc::new(Mutex::new(Status::default()));
    let live_status = Arc::new(Mutex::new(LiveStatus::default()));
    let (tx, brx) = tokio::sync::mpsc::channel(realtime::CHANNEL_BLOCKS);
    let (recycle_tx, recycle_rx) = tokio::sync::mpsc::channel(realtime::CHANNEL_BLOCKS);
    let (done_tx, done_rx) = tokio::sync::oneshot::channel();
    let pacer_thread = {
        let (stop, status) = (stop.clone(), pacer_status.clone());
        std::thread::Builder::new()
            .name("imu-pacer".into())
            .spawn(move || pacer::run(brx, recycle_tx, sinks, Pacing::Paced(c), stop, status))?
    };
    let emitter = {
        let (stop, status, record) = (stop.clone(), live_status.clone(), record.clone());
        let out = FrameOut {
            tx,
            recycle: recycle_rx,
            anchor_ns,
        };
        std::thread::Builder::new()
            .name("imu-live-emitter".into())
            .spawn(move || {
                let r = emit(given, rx, record, out, stop, status);
                let _ = done_tx.send(());
                r
            })?
    };
    let interrupted = rt.block_on(async {
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        tick.tick().await;
        tokio::pin!(done_rx);
        loop {
            tokio::select! {
                _ = &mut done_rx => return None,
                sig = signals.recv() => {
                    stop.store(true, Ordering::Relaxed);
                    return Some(Interrupted(sig));
                }
                _ = tick.tick() => {
                    let s = live_status.lock().unwrap_or_else(|e| e.into_inner()).clone();
                    if s.tail.is_some() {
                        eprintln!("imu-emu: {}", s.line());
                    }
                }
            }
        }
    });
    let result = emitter
        .join()
        .map_err(|_| anyhow::anyhow!("the emitter thread panicked"))?;
    let final_status = pacer_thread
        .join()
        .map_err(|_| anyhow::anyhow!("the pacer thread panicked"))??;
    // The input record is kept whatever happened: it is how a failed run is reproduced.
    let taken = record.lock().unwrap_or_else(|e| e.into_inner()).take();
    if let (Some(r), Some(p)) = (taken, &l.record_input) {
        r.commit()
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(Ran {
        result,
        status: final_status,
        interrupted,
    })
}

/// Runs `run --motion` in real time.
pub fn run(a: &RunArgs, endpoint: &Endpoint, format: InputFormat) -> Result<()> {
    let settings = settings(a)?;
    let builder = quintic(a.sim.builder(DEFAULT_IMU, DEFAULT_PROTOCOL)?)?;
    // The wire format and rate, from the settings alone (the motion comes later).
    let stand_in = (builder.clone().scene("static").start(0.0).duration(1000.0)).build()?;
    let plan = require_frames(&stand_in, "run --motion (realtime)")?;
    let rate = stand_in.grid().rate_hz;
    let live = Realtime::new(builder, format, settings)?;

    let Ran {
        result,
        status: final_status,
        interrupted,
    } = follow(
        a,
        (endpoint, format, &format!(" at {rate} Hz")),
        || open_sinks(a, plan, rate, rate, true),
        rate,
        move |plans, rx, record, out, stop, status| {
            let extra = plans.into_iter().skip(1).collect();
            live.run(rx, record, extra, out, stop, status)
        },
    )?;
    let s: RealtimeSummary = match result {
        Ok(s) => s,
        Err(e) => {
            remove_files(
                a.file
                    .iter()
                    .map(|v| v.rsplit_once(",protocol=").map_or(v.as_str(), |x| x.0)),
            );
            return Err(e.into());
        }
    };
    eprintln!(
        "imu-emu: {}{} frames at {} Hz from t = {} s ({}); {}; input: {}",
        interrupted.map_or(String::new(), |i| format!("{i}: ")),
        s.status.frames,
        s.grid.rate_hz,
        s.grid.t0,
        s.ended,
        s.status.line(),
        s.status.stats.summary()
    );
    for p in &s.status.stats.problems {
        eprintln!("  {p}");
    }
    eprintln!("imu-emu: {}", summary(&final_status, s.status.frames, true));
    interrupted.map_or(Ok(()), |i| Err(i.into()))
}

/// The unbounded run of `builder`, which real time needs on the quintic motion model.
fn quintic(builder: SimulationBuilder) -> Result<SimulationBuilder> {
    if builder.model_settings()?.degree != Degree::Quintic {
        bail!("--time-mode realtime needs the quintic motion model (--interp quintic)");
    }
    Ok(builder.unbounded_duration(FOREVER_S))
}

/// No partial output file behind a failed run (`-`: stdout, nothing to remove).
fn remove_files<'a>(paths: impl Iterator<Item = &'a str>) {
    for path in paths.filter(|p| *p != "-") {
        let _ = std::fs::remove_file(path);
    }
}

/// Runs `run RIG.toml --motion` in real time: every unit of the rig on one pacer, each to
/// its sinks `addrs[i]`, at the host instants of its records' simulation time plus the delay.
pub fn run_rig(
    a: &RunArgs,
    endpoint: &Endpoint,
    format: InputFormat,
    units: &[Unit],
    addrs: &[Vec<SinkAddr>],
) -> Result<()> {
    if a.time_base != "sim" {
        bail!(
            "--time-base {}: a rig following --motion takes --time-base sim (the GPS time base is not built yet for a rig)",
            a.time_base
        );
    }
    let settings = settings(a)?;
    let live = Realtime::rig(quintic(a.sim.builder("ideal", "csv")?)?, format, settings)?;
    let streams: Vec<Stream> = (units.iter())
        .map(|u| Stream {
            name: u.name().to_string(),
            rate_hz: u.grid().rate_hz,
            plan: u.plan(),
        })
        .collect();
    let frames_per_s = streams.iter().map(|s| s.rate_hz).sum();
    let open_all = || {
        let mut sinks = Vec::new();
        for (i, (u, list)) in streams.iter().zip(addrs).enumerate() {
            for addr in list {
                let sink = super::rigrun::open(a, u, addr, true, 1.0)?;
                sinks.push(Routed { stream: i, sink });
            }
        }
        Ok((sinks, ()))
    };
    let Ran {
        result,
        status,
        interrupted,
    } = follow(
        a,
        (endpoint, format, &format!(" with {} units", units.len())),
        open_all,
        frames_per_s,
        move |(), rx, record, out, stop, status| live.run_rig(rx, record, out, stop, status),
    )?;
    let s: RigRealtimeSummary = match result {
        Ok(s) => s,
        Err(e) => {
            remove_files(addrs.iter().flatten().filter_map(|x| match x {
                SinkAddr::File(p) => Some(p.as_str()),
                _ => None,
            }));
            return Err(e.into());
        }
    };
    eprintln!(
        "imu-emu: {}{} records of {} units ({}); {}; input: {}",
        interrupted.map_or(String::new(), |i| format!("{i}: ")),
        s.status.frames,
        units.len(),
        s.ended,
        s.status.line(),
        s.status.stats.summary()
    );
    for (i, (u, (g, n))) in units.iter().zip(&s.units).enumerate() {
        let paced = status.streams.get(i).copied().unwrap_or_default();
        eprintln!(
            "  unit {}: {n} records at {} Hz from t = {} s to {} s, {} written, {} skipped (too late)",
            u.name(),
            g.rate_hz,
            g.t0,
            g.t0 + *n as f64 / g.rate_hz,
            paced.frames,
            paced.skipped
        );
    }
    for p in &s.status.stats.problems {
        eprintln!("  {p}");
    }
    eprintln!("imu-emu: {}", summary(&status, s.status.frames, true));
    interrupted.map_or(Ok(()), |i| Err(i.into()))
}
