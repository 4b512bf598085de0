//! `imu-emu run --motion SOURCE --time-mode realtime`: frames at the host-clock instants of
//! the states' simulation time plus an output delay, to every sink of `run`. Parses flags,
//! wires the input, emitter and pacer threads, prints the status and the summary; the run is
//! `imu_emu::live::realtime`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::{Context, Result, bail};

use imu_emu::live::InputFormat;
use imu_emu::live::realtime::{
    FrameOut, GpsBase, LiveStatus, OnTimeout, Realtime, RealtimeSettings, RealtimeSummary,
};
use imu_emu::live::transport::{Endpoint, Receiver};
use imu_emu::motion::chain::ChainSettings;
use imu_emu::motion::sampled::Degree;
use imu_emu::output::AtomicFile;
use imu_emu::realtime::hostclock::GpsClock;
use imu_emu::realtime::pacer::{self, Clocking, Pacing, Status};
use imu_emu::realtime::signal::{Interrupted, StopSignals};
use imu_emu::realtime::{self, clock};
use imu_emu::timebase::LeapTable;

use super::run::{DEFAULT_IMU, DEFAULT_PROTOCOL, FOREVER_S, RunArgs, open_sinks, summary};
use super::setup::require_frames;

/// Runs `run --motion` in real time.
pub fn run(a: &RunArgs, endpoint: &Endpoint, format: InputFormat) -> Result<()> {
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
    let builder = (a.sim.builder(DEFAULT_IMU, DEFAULT_PROTOCOL)?).unbounded_duration(FOREVER_S);
    if builder.model_settings()?.degree != Degree::Quintic {
        bail!("--time-mode realtime needs the quintic motion model (--interp quintic)");
    }
    // The wire format and rate, from the settings alone (the motion comes later).
    let stand_in = (builder.clone().scene("static").start(0.0).duration(1000.0)).build()?;
    let plan = require_frames(&stand_in, "run --motion (realtime)")?;
    let rate = stand_in.grid().rate_hz;
    let settings = RealtimeSettings {
        delay,
        chain,
        on_timeout,
        gps,
    };
    let live = Realtime::new(builder, format, settings)?;

    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let mut signals = {
        let _rt = rt.enter();
        StopSignals::new()?
    };
    let (sinks, plans) = open_sinks(a, plan, rate, rate, true)?;
    let idle = Some(Duration::from_secs_f64(l.input_timeout));
    let rx = Receiver::open(endpoint, format, idle)
        .with_context(|| format!("--motion {}: opening", l.motion.as_deref().unwrap_or("")))?;
    eprintln!(
        "imu-emu: following {} ({}) in real time at {rate} Hz",
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
    let mut c = Clocking::new(rate, Some(anchor_ns), a.realtime).map_err(|e| anyhow::anyhow!(e))?;
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
        let extra = plans.into_iter().skip(1).collect();
        let out = FrameOut {
            tx,
            recycle: recycle_rx,
            anchor_ns,
        };
        std::thread::Builder::new()
            .name("imu-live-emitter".into())
            .spawn(move || {
                let r = live.run(rx, record, extra, out, stop, status);
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
    let s: RealtimeSummary = match result {
        Ok(s) => s,
        Err(e) => {
            // No partial output file behind a failed run.
            for v in &a.file {
                let path = v.rsplit_once(",protocol=").map_or(v.as_str(), |x| x.0);
                if path != "-" {
                    let _ = std::fs::remove_file(path);
                }
            }
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
