//! The wall-clock drivers, on the pacer ([`crate::realtime::pacer`]) that writes each frame at
//! its deadline to every sink of its stream, with the time marks, pulses and PPS lock the run
//! asks for:
//!
//! * **paced** — a known motion runs ahead of the clock on a producer thread, window after
//!   window of simulated time merged in emission order; the pacer writes frame k at
//!   start + emission/speed;
//! * **just in time** — a live motion (real time) or a trigger line: each frame is made just
//!   before it is due (its deadline minus [`LEAD_S`]) from what has arrived by then — states
//!   through the clock map and the output delay, edges through the trigger — so one loop
//!   serves one IMU and a rig's units alike.

//!
//! This file dispatches and holds the paced driver; `just_in_time` the other two, and
//! `pacer_thread` the pacer's thread and feed they all hand frames to.

mod just_in_time;
mod pacer_thread;

use std::sync::atomic::Ordering;

use crate::engine::frames::Until;
use crate::realtime::clock;
use crate::realtime::hostclock::GpsClock;
use crate::timebase::LeapTable;

use super::build::Run;
use super::clock::{Clock, Wall};
use super::error::RunError;
use super::pipeline::{Built, Control, Outlets, unit_streams};
use super::routing::StreamPlan;
use super::spec::TimeBase;
use super::status::{RunReport, RunStatus, StreamCounts};
use just_in_time::{realtime, triggered};
use pacer_thread::{PacerThread, clocking, extras, fill_status, frames_per_s};

/// A just-in-time run makes each frame this long before its deadline (s): making a frame
/// takes microseconds; the rest absorbs the driver's own wake-up lateness.
pub const LEAD_S: f64 = 0.001;

/// Simulated time a paced producer merges at a time (ns): short enough that the first frames
/// are ready at once and the look-ahead stays small, long enough that channel traffic is
/// negligible.
pub const WINDOW_NS: i64 = 100_000_000;

/// Runs a paced or real-time run.
pub(super) fn run(run: Run, ctl: &Control) -> Result<RunReport, RunError> {
    match run.clock.clone() {
        Clock::Realtime(w) => realtime(run, w, ctl),
        Clock::Paced(w) if run.sync.trigger.is_some() => triggered(run, w, ctl),
        Clock::Paced(w) => paced(run, w, ctl),
        Clock::Free | Clock::Lockstep => unreachable!("not a wall-clock run"),
    }
}

/// The GPS time of a run's t₀ starting at UTC instant `utc0` on `base` (frames), and the true
/// GPS time (GNSS streams); told to `ctl`.
fn time_base_ref(base: TimeBase, utc0: i128, ctl: &Control) -> super::pipeline::GpsRef {
    let leap = LeapTable::builtin();
    let host = GpsClock::new(leap.clone());
    let r = super::pipeline::gps_ref(base, utc0, |u| host.utc_to_gps_ns(u))?;
    let (week, sow) = r.0;
    ctl.note(&format!(
        "time base {}: t₀ at week {week}, {sow} s; {}",
        base.name(),
        host.describe(utc0)
    ));
    if base == TimeBase::Gps && utc0 / 1_000_000_000 > leap.valid_until as i128 {
        ctl.note(&format!(
            "warning: the leap-second table is only known valid until Unix time {}; update src/timebase/leap-seconds.txt (docs/timing.md)",
            leap.valid_until
        ));
    }
    Some(r)
}

/// A paced run of a known motion: a producer thread runs ahead of the clock.
fn paced(run: Run, wall: Wall, ctl: &Control) -> Result<RunReport, RunError> {
    let Run {
        signal,
        layout,
        links,
        sync,
        time_base,
        ..
    } = run;
    let leap = LeapTable::builtin();
    let mut start_utc = (wall.start_at.as_deref())
        .map(|s| crate::timebase::parse_start(s, clock::realtime_ns(), &leap))
        .transpose()
        .map_err(|e| RunError::spec("--start-at", e))?;
    if time_base != TimeBase::Sim {
        // Record time t₀ falls on the start instant: a whole second unless given.
        start_utc.get_or_insert((clock::realtime_ns() / 1_000_000_000 + 1) * 1_000_000_000);
    }
    let gps = start_utc.and_then(|u| time_base_ref(time_base, u, ctl));
    let mut built = layout.build(signal, gps, false)?;
    let mut out = Outlets::open(&layout.streams, &links, wall.speed, true, ctl)?;
    out.preamble(&built.preambles)?;
    let stop = ctl.flag();
    let extras = extras(&sync, &layout.streams, wall.speed, &stop)?;
    let start_ns = start_utc
        .map(clock::start_at)
        .transpose()
        .map_err(|e| RunError::spec("--start-at", e))?;
    if start_ns.is_some() || !sync.time_marks.is_empty() {
        ctl.note(&clock::describe_offset());
    }
    let c = clocking(&layout.streams, &wall, start_ns)?;
    tracing::info!(
        "{} streams, {} frames per wall-clock second at {}× real time, {} per wake-up",
        layout.streams.len(),
        frames_per_s(&layout.streams, wall.speed),
        wall.speed,
        c.batch
    );
    let (pacer, mut feed) = PacerThread::start(out, &layout.streams, c, extras, stop.clone())?;
    let origin = built.origin;
    let producer = {
        let stop = stop.clone();
        let mut sources = std::mem::replace(
            &mut built.sources,
            super::pipeline::Sources::new(Vec::new()),
        );
        std::thread::Builder::new()
            .name("imu-producer".into())
            .spawn(move || {
                let mut until = 0i64;
                while !sources.done() {
                    if stop.load(Ordering::Relaxed) {
                        return Ok(());
                    }
                    until += WINDOW_NS;
                    sources.fill(Until::ns(origin, until))?;
                    if !feed.send(&sources.parts) {
                        return Ok(());
                    }
                }
                Ok::<(), crate::engine::EngineError>(())
            })
            .map_err(|e| RunError::io("starting the producer", e))?
    };
    let mut status = RunStatus {
        started: true,
        ..RunStatus::default()
    };
    while !pacer.handle.is_finished() {
        pacer.observe(&mut status);
        ctl.publish(|s| *s = status.clone());
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let produced = producer.join().map_err(|_| {
        RunError::io(
            "the producer",
            std::io::Error::other("the producer thread panicked"),
        )
    })?;
    let ended = match produced {
        Err(e) => Err(RunError::from(e)),
        Ok(()) if ctl.stopped() => Ok("stopped"),
        Ok(()) => Ok("complete"),
    };
    end(pacer, ended, layout.streams, built, None, ctl)
}

/// Waits for the pacer, then reports; a failed run's live files are removed.
fn end(
    pacer: PacerThread,
    ended: Result<&'static str, RunError>,
    streams: Vec<StreamPlan>,
    built: Built,
    input: Option<crate::live::stats::InputStats>,
    ctl: &Control,
) -> Result<RunReport, RunError> {
    let (joined, owners, files) = pacer.join();
    if ended.is_err() || joined.is_err() {
        for f in &files {
            crate::output::remove_partial(std::path::Path::new(f));
        }
    }
    let st = match joined {
        Ok(st) => st,
        Err(e) => {
            ended?;
            return Err(e);
        }
    };
    let ended = ended?;
    let mut status = ctl.status();
    fill_status(&mut status, &st, &owners);
    status
        .streams
        .resize(streams.len(), StreamCounts::default());
    ctl.set(status.clone());
    let mut units = built.units;
    for (u, i) in units.iter_mut().zip(unit_streams(&streams)) {
        u.records = status.streams.get(i).map_or(0, |c| c.frames + c.skipped);
    }
    Ok(RunReport {
        ended,
        stopped: ended == "stopped",
        streams,
        status,
        units,
        faults: built.faults,
        input,
        failures: st.failures,
    })
}
