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

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use tokio::sync::mpsc::{Receiver as BlockRx, Sender as BlockTx};

use crate::engine::frames::{Part, Until};
use crate::engine::trigger::Trigger;
use crate::live::transport::Receiver;
use crate::motion::causal::CausalMotion;
use crate::motion::chain::Tail;
use crate::output::AtomicFile;
use crate::output::SinkAddr;
use crate::realtime::clock::{self, monotonic_ns, sleep_until};
use crate::realtime::hook::{FrameHook, OfStream};
use crate::realtime::hostclock::GpsClock;
use crate::realtime::pacer::{self, Clocking, Extras, Pacing, Routed, Status};
use crate::realtime::{self as rt, FrameBlock};
use crate::record::FLAG_STALE;
use crate::timebase::LeapTable;

use super::build::{OnTimeout, Run, Signal};
use super::clock::{Clock, Wall};
use super::error::RunError;
use super::input::{self, GPS_TAG_TOLERANCE_S, GpsBase, MARGIN_S};
use super::pipeline::{Built, Control, Outlets, unit_streams};
use super::routing::StreamPlan;
use super::spec::TimeBase;
use super::status::{LiveStatus, RunReport, RunStatus, StreamCounts};
use super::sync::{PulseOut, Sync};

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

/// The pacer on its thread, with its figures and its sinks' streams.
struct PacerThread {
    status: Arc<Mutex<Status>>,
    handle: JoinHandle<std::io::Result<Status>>,
    /// Per sink handed to the pacer, its stream.
    owners: Vec<usize>,
    /// Files written live, removed if the run fails.
    files: Vec<String>,
}

/// What feeds the pacer: its bounded channel, and the buffers it gives back.
struct PacerFeed {
    tx: BlockTx<FrameBlock>,
    recycle: BlockRx<FrameBlock>,
    order: Vec<(i64, u32, u32)>,
    first: u64,
}

impl PacerThread {
    /// Starts the pacer on `out`'s sinks with `clocking` and `extras`; frames go in through
    /// the feed, which is dropped to let the pacer finish.
    fn start(
        out: Outlets,
        streams: &[StreamPlan],
        clocking: Clocking,
        extras: Extras,
        stop: Arc<AtomicBool>,
    ) -> Result<(PacerThread, PacerFeed), RunError> {
        let files = (streams.iter())
            .flat_map(|s| &s.sinks)
            .filter_map(|(a, _)| match a {
                SinkAddr::File(p) if p != "-" => Some(p.clone()),
                _ => None,
            })
            .collect();
        let mut sinks = Vec::new();
        for (i, v) in out.sinks.into_iter().enumerate() {
            sinks.extend(v.into_iter().map(|sink| Routed { stream: i, sink }));
        }
        let owners = sinks.iter().map(|r| r.stream).collect();
        let status = Arc::new(Mutex::new(Status::default()));
        let (tx, brx) = tokio::sync::mpsc::channel(rt::CHANNEL_BLOCKS);
        let (recycle_tx, recycle) = tokio::sync::mpsc::channel(rt::CHANNEL_BLOCKS);
        let handle = {
            let status = status.clone();
            let pacing = Pacing::Paced(clocking);
            std::thread::Builder::new()
                .name("imu-pacer".into())
                .spawn(move || {
                    pacer::run_with(brx, recycle_tx, sinks, pacing, stop, status, extras)
                })
                .map_err(|e| RunError::io("starting the pacer", e))?
        };
        let feed = PacerFeed {
            tx,
            recycle,
            order: Vec::new(),
            first: 0,
        };
        Ok((
            PacerThread {
                status,
                handle,
                owners,
                files,
            },
            feed,
        ))
    }

    /// The pacer's figures now, into `st`.
    fn observe(&self, st: &mut RunStatus) {
        if let Ok(s) = self.status.try_lock() {
            fill_status(st, &s, &self.owners);
        }
    }

    /// Waits for the pacer (its feed dropped) to write what it has; its final figures.
    fn join(self) -> Result<(Status, Vec<usize>, Vec<String>), RunError> {
        let st = (self.handle.join())
            .map_err(|_| {
                RunError::io(
                    "the pacer",
                    std::io::Error::other("the pacer thread panicked"),
                )
            })?
            .map_err(|e| RunError::io("writing the frames", e))?;
        Ok((st, self.owners, self.files))
    }
}

impl PacerFeed {
    /// Merges `parts` (emission times on the pacer's clock) into a block and hands it to the
    /// pacer, waiting for room; false once the pacer has gone.
    fn send(&mut self, parts: &[Part]) -> bool {
        if parts.iter().all(|p| p.ends.is_empty()) {
            return true;
        }
        let mut b = self.recycle.try_recv().unwrap_or_default();
        merge_into(parts, &mut b, &mut self.order);
        b.first = self.first;
        self.first += b.len() as u64;
        self.tx.blocking_send(b).is_ok()
    }
}

/// Copies the pacer's figures into a run's status.
fn fill_status(st: &mut RunStatus, p: &Status, owners: &[usize]) {
    st.elapsed_s = p
        .start_ns
        .map_or(0.0, |t| (monotonic_ns() - t) as f64 / 1e9);
    st.streams.resize(
        p.streams.len().max(st.streams.len()),
        StreamCounts::default(),
    );
    for (c, s) in st.streams.iter_mut().zip(&p.streams) {
        *c = StreamCounts {
            frames: s.frames,
            skipped: s.skipped,
        };
    }
    st.sinks = (owners.iter().zip(&p.sinks))
        .map(|(&o, (label, k))| (o, label.clone(), *k))
        .collect();
    st.lateness = Some(p.lateness.summary());
    st.edge_latency = p.edge_latency.as_ref().map(|e| e.summary());
    st.lock = p.lock.map(|l| {
        format!(
            "PPS lock: {} edges, phase error {:.3} ms, frequency offset {:+.3} ppm",
            l.edges,
            l.phase_error_ns / 1e6,
            l.freq_offset_ppm
        )
    });
    st.fifo = p.fifo;
}

/// Lays `parts` out in `block` in emission-time order (ties: the lower stream first): every
/// stream gets an end per frame, empty where the frame is another stream's. `order` is
/// scratch. `block.first` is left to the caller.
pub fn merge_into(parts: &[Part], block: &mut FrameBlock, order: &mut Vec<(i64, u32, u32)>) {
    order.clear();
    for (s, p) in parts.iter().enumerate() {
        order.extend((p.emit_ns.iter().enumerate()).map(|(i, e)| (*e, s as u32, i as u32)));
    }
    // Each part is already in order: a stable sort by time keeps equal times by stream.
    order.sort_by_key(|o| (o.0, o.1));
    block.streams.resize_with(parts.len(), Default::default);
    block.emit_ns.clear();
    block.tov_ns.clear();
    block.tov_wall_ns.clear();
    block.records.clear();
    block.stream_of.clear();
    // Only a record stream's frames are timed by the hooks; the others' validity is their
    // emission.
    let marked = parts.iter().any(|p| p.marks_records);
    let walls = parts.iter().any(|p| !p.tov_wall_ns.is_empty());
    for (bytes, ends) in block.streams.iter_mut() {
        bytes.clear();
        ends.clear();
    }
    for &(t, s, i) in order.iter() {
        let p = &parts[s as usize];
        let i = i as usize;
        let from = if i == 0 { 0 } else { p.ends[i - 1] };
        for (j, (bytes, ends)) in block.streams.iter_mut().enumerate() {
            if j == s as usize {
                bytes.extend_from_slice(&p.bytes[from..p.ends[i]]);
            }
            ends.push(bytes.len());
        }
        block.emit_ns.push(t);
        block.stream_of.push(s);
        if marked {
            let (k, tov) = p.records.get(i).copied().unwrap_or((u64::MAX, t));
            block.records.push(k);
            block.tov_ns.push(tov);
            if walls {
                block
                    .tov_wall_ns
                    .push(p.tov_wall_ns.get(i).copied().unwrap_or(t));
            }
        }
    }
}

/// The time marks, pulse and PPS lock `sync` asks for; `streams` says which stream holds each
/// unit's records.
fn extras(
    sync: &Sync,
    streams: &[StreamPlan],
    speed: f64,
    stop: &Arc<AtomicBool>,
) -> Result<Extras, RunError> {
    use crate::realtime::{lock::PhaseLock, pps, pulse, timemark::TimeMarks};
    let mut extras = Extras::default();
    let stream_of: Vec<usize> = unit_streams(streams).collect();
    for (unit, target) in &sync.time_marks {
        let marks = TimeMarks::open(target)
            .map_err(|e| RunError::io(format!("--time-marks {target}"), e))?;
        extras
            .hooks
            .push(Box::new(OfStream::new(stream_of[*unit], Box::new(marks))));
    }
    if let Some((spec, out, unit)) = &sync.pulse {
        let spec: pulse::PulseSpec = spec.parse().map_err(|e| RunError::spec("--pulse", e))?;
        let s = stream_of[*unit];
        spec.check(1e9 / (streams[s].rate_hz * speed))
            .map_err(|e| RunError::spec("--pulse", e))?;
        let line: Box<dyn pulse::Line> = match out {
            PulseOut::Port(port) => Box::new(
                pulse::ModemLine::open(port, spec.pin)
                    .map_err(|e| RunError::io(format!("--pulse {port}"), e))?,
            ),
            PulseOut::Line(l) => Box::new(SharedLine(l.clone())),
        };
        let p = pulse::Pulse::new(spec, line).map_err(|e| RunError::io("--pulse", e))?;
        extras
            .hooks
            .push(Box::new(OfStream::new(s, Box::new(p))) as Box<dyn FrameHook>);
    }
    if let Some(src) = &sync.pps_in {
        let open = pps::open(src).map_err(|e| RunError::io(format!("--pps-in {src}"), e))?;
        let edges = pps::spawn(open, stop.clone()).map_err(|e| RunError::io("--pps-in", e))?;
        extras.lock = Some((edges, PhaseLock::new(1_000_000_000)));
    }
    Ok(extras)
}

/// The pacer's latest schedule, once a phase lock has slewed it: a just-in-time driver makes
/// each frame before its slewed deadline.
#[derive(Clone, Default)]
struct ScheduleWatch(Arc<Mutex<Option<crate::realtime::lock::Schedule>>>);

impl ScheduleWatch {
    /// The schedule now (`None`: never slewed).
    fn get(&self) -> Option<crate::realtime::lock::Schedule> {
        *self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl FrameHook for ScheduleWatch {
    fn rescheduled(&mut self, sched: &crate::realtime::lock::Schedule) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = Some(*sched);
    }

    fn written(&mut self, _: &crate::realtime::hook::FrameTime) -> std::io::Result<()> {
        Ok(())
    }
}

/// A pulse line given in code, driven from the pulse thread.
struct SharedLine(super::spec::PulseLine);

impl crate::realtime::pulse::Line for SharedLine {
    fn set(&mut self, high: bool) -> std::io::Result<()> {
        (self.0.0.lock())
            .unwrap_or_else(|e| e.into_inner())
            .set(high)
    }
}

/// Frames per wall-clock second over every stream at `speed`.
fn frames_per_s(streams: &[StreamPlan], speed: f64) -> f64 {
    (streams.iter().map(|s| s.rate_hz).sum::<f64>() * speed).max(1.0)
}

/// The pacer's timing for `streams` at `wall`, starting at `start_ns`.
fn clocking(
    streams: &[StreamPlan],
    wall: &Wall,
    start_ns: Option<i128>,
) -> Result<Clocking, RunError> {
    let mut c = Clocking::new(frames_per_s(streams, wall.speed), start_ns, wall.fifo)
        .map_err(|e| RunError::spec("--speed", e))?
        .with_speed(wall.speed);
    c.max_behind_ns = wall.max_behind_ns;
    Ok(c)
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
    let joined = pacer.join();
    let failed = ended.is_err() || joined.is_err();
    let (st, owners, files) = match joined {
        Ok(x) => x,
        Err(e) => {
            ended?;
            return Err(e);
        }
    };
    if failed {
        for f in &files {
            let _ = std::fs::remove_file(f);
        }
    }
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
    })
}

/// Sleeps until `wake` (CLOCK_MONOTONIC ns) or a stop request, in slices of at most 100 ms.
fn sleep_to(wake: i128, stop: &AtomicBool) {
    while monotonic_ns() < wake && !stop.load(Ordering::Relaxed) {
        sleep_until(wake.min(monotonic_ns() + 100_000_000));
    }
}

/// Waits until `wake` for a trigger edge (CLOCK_MONOTONIC ns); `None` at `wake`, on a stop,
/// or when the edge source has gone (then `gone` is set).
fn wait_edge(
    edges: &std::sync::mpsc::Receiver<i128>,
    wake: i128,
    stop: &AtomicBool,
    gone: &mut bool,
) -> Option<i128> {
    use std::sync::mpsc::RecvTimeoutError;
    loop {
        if stop.load(Ordering::Relaxed) {
            return None;
        }
        let left = (wake - monotonic_ns()).clamp(0, 100_000_000);
        match edges.recv_timeout(std::time::Duration::from_nanos(left as u64)) {
            Ok(e) => return Some(e),
            Err(RecvTimeoutError::Disconnected) => {
                *gone = true;
                sleep_to(wake, stop);
                return None;
            }
            Err(RecvTimeoutError::Timeout) if monotonic_ns() >= wake => return None,
            Err(RecvTimeoutError::Timeout) => {}
        }
    }
}

/// Puts the window's emission times (ns after t₀ on the simulation's axis) on the pacer's
/// clock: `wall(ns)` is the frame's deadline in ns after the pacer's start. A record's time
/// of validity keeps its simulation value (time marks report it) and gets its wall instant.
fn to_wall(parts: &mut [Part], wall: impl Fn(i64) -> i64) {
    for p in parts.iter_mut() {
        for e in p.emit_ns.iter_mut() {
            *e = wall(*e);
        }
        p.tov_wall_ns.clear();
        if p.marks_records {
            let w: Vec<i64> = p.records.iter().map(|r| wall(r.1)).collect();
            p.tov_wall_ns = w;
        }
    }
}

/// A paced run of a known motion whose units sample at a trigger line's edges: t₀ is the
/// first edge, each later edge closes a sample interval, and every frame is made just in time.
fn triggered(run: Run, wall: Wall, ctl: &Control) -> Result<RunReport, RunError> {
    use crate::realtime::pps;
    let Run {
        signal,
        layout,
        links,
        sync,
        time_base,
        ..
    } = run;
    let spec = sync.trigger.clone().expect("a trigger");
    let stop = ctl.flag();
    let mut out = Outlets::open(&layout.streams, &links, 1.0, true, ctl)?;
    let open = pps::open_for("--trigger", &spec)
        .map_err(|e| RunError::io(format!("--trigger {spec}"), e))?;
    let edges = pps::spawn(open, stop.clone()).map_err(|e| RunError::io("--trigger", e))?;
    ctl.note(&format!("waiting for the first trigger edge on {spec}"));
    let mut gone = false;
    let first = loop {
        if let Some(e) = wait_edge(&edges, monotonic_ns() + 100_000_000, &stop, &mut gone) {
            break e;
        }
        if gone {
            return Err(RunError::spec(
                "--trigger",
                format!("{spec}: the edge source stopped"),
            ));
        }
        if stop.load(Ordering::Relaxed) {
            out.close(false)?;
            return Err(RunError::spec(
                "--trigger",
                "stopped before the first edge".into(),
            ));
        }
    };
    let utc0 = first + clock::utc_minus_monotonic();
    let gps = time_base_ref(time_base, utc0, ctl);
    let mut built = layout.build(signal, gps, true)?;
    out.preamble(&built.preambles)?;
    let extras = extras(&sync, &layout.streams, 1.0, &stop)?;
    let c = clocking(&layout.streams, &wall, Some(first))?.with_edges();
    let (pacer, mut feed) = PacerThread::start(out, &layout.streams, c, extras, stop.clone())?;
    let origin = built.origin;
    let span = f64::INFINITY;
    let mut trigger = Trigger::new(span);
    let _ = trigger.edge(first);
    let lead = (LEAD_S * 1e9) as i128;
    let mut status = RunStatus {
        started: true,
        ..RunStatus::default()
    };
    let ended = loop {
        if stop.load(Ordering::Relaxed) {
            break Ok("stopped");
        }
        if built.sources.done() {
            break Ok("complete");
        }
        let wake = built
            .sources
            .next_due()
            .map_or(monotonic_ns() + 100_000_000, |d| first + d as i128 - lead);
        if let Some(e) = wait_edge(&edges, wake, &stop, &mut gone) {
            match trigger.edge(e) {
                Ok(Some((lo, hi))) => built.sources.edge(lo, hi),
                Ok(None) => {}
                Err(m) => break Err(RunError::Engine(crate::engine::EngineError::Trigger(m))),
            }
            while let Ok(e) = edges.try_recv() {
                if let Ok(Some((lo, hi))) = trigger.edge(e) {
                    built.sources.edge(lo, hi);
                }
            }
        } else if gone {
            break Ok("trigger ended");
        }
        let now = monotonic_ns();
        let until = Until::ns(origin, (now + lead - first) as i64);
        if let Err(e) = built.sources.fill(until) {
            break Err(e.into());
        }
        to_wall(&mut built.sources.parts, |ns| ns);
        if !feed.send(&built.sources.parts) {
            break Ok("the output closed");
        }
        pacer.observe(&mut status);
        ctl.publish(|s| *s = status.clone());
    };
    drop(feed);
    end(pacer, ended, layout.streams, built, None, ctl)
}

/// A real-time run behind a live input: the input thread feeds the model and the clock map;
/// frames go out at the host instants of their simulation time plus the output delay.
fn realtime(run: Run, wall: Wall, ctl: &Control) -> Result<RunReport, RunError> {
    let Run {
        signal,
        layout,
        links,
        sync,
        time_base,
        ..
    } = run;
    let Signal::Live {
        builder,
        rig,
        input: live,
    } = signal
    else {
        unreachable!("real time follows a live input")
    };
    let stop = ctl.flag();
    let mut out = Outlets::open(&layout.streams, &links, 1.0, true, ctl)?;
    let settings = builder.model_settings()?;
    let model = CausalMotion::new(settings);
    model.enable_chain(live.chain);
    let need = settings.stencil.max(3);
    let gps = (time_base == TimeBase::Gps).then(|| {
        let host = GpsClock::new(LeapTable::builtin());
        let (gps_ns, mono_ns) = (host.now_gps_ns(), monotonic_ns());
        ctl.note(&format!(
            "time base gps: the input's time tags are GPS time, mapped to {}",
            host.describe(clock::realtime_ns())
        ));
        GpsBase::at(gps_ns, mono_ns)
    });
    let rx = match Receiver::open_until(
        &live.endpoint,
        live.format,
        Some(std::time::Duration::from_secs_f64(live.idle_s)),
        Some(stop.clone()),
    ) {
        Ok(rx) => rx,
        Err(e) => {
            // Stopped (or failed) before a sender connected: no output file is left behind.
            out.close(false)?;
            return Err(RunError::io(
                format!("--motion {}: opening", live.source),
                e,
            ));
        }
    };
    let name = rx.name().to_string();
    ctl.note(&format!("following {name} in real time"));
    let record = Arc::new(Mutex::new(match &live.record {
        Some(p) => Some(
            AtomicFile::create(p)
                .map_err(|e| RunError::io(format!("creating {}", p.display()), e))?,
        ),
        None => None,
    }));
    let shared = input::start(rx, live.format, gps, &model, record.clone(), &stop)?;
    let keep_record = |record: &Arc<Mutex<Option<AtomicFile>>>| -> Result<(), RunError> {
        let taken = record.lock().unwrap_or_else(|e| e.into_inner()).take();
        if let (Some(r), Some(p)) = (taken, &live.record) {
            r.commit()
                .map_err(|e| RunError::io(format!("writing {}", p.display()), e))?;
        }
        Ok(())
    };
    let started = input::first_knot(&shared, &model, &stop, &name, need);
    let started = match started {
        Ok(Some(())) => Ok(()),
        Ok(None) => Err(None),
        Err(e) => Err(Some(e)),
    };
    if let Err(e) = started {
        out.close(false)?;
        keep_record(&record)?;
        return match e {
            Some(e) => Err(e),
            None => Err(RunError::TooFewStates {
                input: name,
                states: input::lock(&shared).stats.states,
                need,
            }),
        };
    }
    let mut st = LiveStatus::default();
    let (map, _) = input::observe(&mut st, &shared);
    let delay = live.delay.unwrap_or_else(|| map.default_delay(MARGIN_S));
    st.delay = delay;
    if let Some(g) = gps {
        let newest = model.newest();
        let off = (map.host_ns(newest) - monotonic_ns()) as f64 / 1e9;
        if off.abs() > GPS_TAG_TOLERANCE_S {
            out.close(false)?;
            keep_record(&record)?;
            return Err(RunError::TimeBase(format!(
                "{name}: the state at {newest} s of GPS week {} maps {off:+.3e} s from now on the host's GPS clock: with the GPS time base the input's time tags must be GPS time (binary: a GPS week; CSV: gps_week,gps_sow)",
                g.week
            )));
        }
    }
    let week = gps.map(|g| g.week).or(input::lock(&shared).week);
    let triggered = sync.trigger.is_some();
    let mut built = match layout.build_live(&builder, rig, &model, week, triggered) {
        Ok(b) => b,
        Err(e) => {
            out.close(false)?;
            keep_record(&record)?;
            return Err(e);
        }
    };
    out.preamble(&built.preambles)?;
    let mut extras = extras(&sync, &layout.streams, 1.0, &stop)?;
    // The pacer's whole seconds are what a PPS lock pulls onto its edges: on the GPS time
    // base they are the host's whole GPS seconds (the week began on one), so the lock
    // disciplines the map from the input's GPS tags to the host clock.
    let now = monotonic_ns();
    let anchor = match gps {
        Some(g) => now - (now - g.host_at_week_ns).rem_euclid(1_000_000_000),
        None => now,
    };
    // With a lock the pacer slews its deadlines: frames are made before the slewed ones.
    let slewed = ScheduleWatch::default();
    if sync.pps_in.is_some() {
        extras.hooks.push(Box::new(slewed.clone()));
    }
    let mut c = clocking(&layout.streams, &wall, Some(anchor))?;
    if triggered {
        c = c.with_edges();
    }
    let (pacer, mut feed) = PacerThread::start(out, &layout.streams, c, extras, stop.clone())?;
    let edges = match &sync.trigger {
        Some(spec) => {
            use crate::realtime::pps;
            let open = pps::open_for("--trigger", spec)
                .map_err(|e| RunError::io(format!("--trigger {spec}"), e))?;
            Some(pps::spawn(open, stop.clone()).map_err(|e| RunError::io("--trigger", e))?)
        }
        None => None,
    };
    let origin = built.origin;
    let delay_ns = (delay * 1e9).round() as i128;
    let lead = (LEAD_S * 1e9) as i128;
    let mut emitted = origin;
    let mut held = false;
    let mut prev_edge: Option<f64> = None;
    let mut gone = false;
    let mut status = RunStatus {
        started: true,
        ..RunStatus::default()
    };
    let ended = loop {
        if stop.load(Ordering::Relaxed) {
            break Ok("stopped");
        }
        if built.sources.done() {
            break Ok("duration reached");
        }
        let (map, _) = input::observe(&mut st, &shared);
        let host = |t: f64| map.host_ns(t) + delay_ns;
        let sched = slewed.get();
        // The pacer's deadline of the host instant `h`, and the host instant due at `w`.
        let due = |h: i128| sched.map_or(h, |s| s.at(h - anchor));
        let undue = |w: i128| sched.map_or(w, |s| anchor + s.nominal(w));
        let wake = (built.sources.next_due()).map_or(monotonic_ns() + 10_000_000, |d| {
            due(host(origin + d as f64 * 1e-9)) - lead
        });
        match &edges {
            Some(rx) => {
                let mut take = |e: i128, sources: &mut super::pipeline::Sources| {
                    // The edge asks for the sample the output delay puts at its instant.
                    let t = map.sim_at(e - delay_ns);
                    if let Some(p) = prev_edge.replace(t)
                        && t > p
                        && p >= origin
                    {
                        sources.edge(p - origin, t - origin);
                    }
                };
                if let Some(e) = wait_edge(rx, wake, &stop, &mut gone) {
                    take(e, &mut built.sources);
                    while let Ok(e) = rx.try_recv() {
                        take(e, &mut built.sources);
                    }
                }
            }
            None => sleep_to(wake, &stop),
        }
        let now = monotonic_ns();
        let (map, input_ended) = input::observe(&mut st, &shared);
        st.stale = input_ended;
        let newest = model.newest();
        let mut horizon = map.sim_at(undue(now + lead) - delay_ns);
        if input_ended {
            match live.on_timeout {
                OnTimeout::Stop => {
                    let next = built.sources.next_due().map(|d| origin + d as f64 * 1e-9);
                    if next.is_none_or(|t| t > newest) {
                        break Ok("input ended");
                    }
                    horizon = horizon.min(newest);
                }
                OnTimeout::Hold if !held => {
                    model.hold_from(emitted);
                    held = true;
                }
                _ => {}
            }
        }
        if horizon <= emitted {
            continue;
        }
        let tail = model.prepare(emitted, horizon);
        // Frames that no longer follow the input say so where their protocol can.
        let stale = input_ended || tail == Tail::Holding;
        built.sources.set_flags(if stale { FLAG_STALE } else { 0 });
        if let Err(e) = built.sources.fill(Until::time(origin, horizon)) {
            break Err(e.into());
        }
        emitted = horizon;
        // The units' records, and those of them past the newest state (made from the
        // extrapolated or held motion).
        let newest_ns = ((newest - origin) * 1e9).round() as i64;
        for p in built.sources.parts.iter().filter(|p| p.marks_records) {
            st.frames += p.records.len() as u64;
            st.extrapolated += p.records.iter().filter(|r| r.1 > newest_ns).count() as u64;
        }
        st.tail = Some(tail);
        st.corrections = model.corrections();
        to_wall(&mut built.sources.parts, |ns| {
            (host(origin + ns as f64 * 1e-9) - anchor) as i64
        });
        if !feed.send(&built.sources.parts) {
            break Ok("the output closed");
        }
        pacer.observe(&mut status);
        status.live = Some(st.clone());
        ctl.publish(|s| *s = status.clone());
    };
    st.corrections = model.corrections();
    let (_, _) = input::observe(&mut st, &shared);
    let read = input::take_error(&shared, &name);
    keep_record(&record)?;
    let ended = match (ended, read) {
        (Err(e), _) => Err(e),
        (Ok(_), Err(e)) => Err(e),
        (Ok(x), Ok(())) => Ok(x),
    };
    let stats = st.stats.clone();
    drop(feed);
    let mut report = end(pacer, ended, layout.streams, built, Some(stats), ctl)?;
    report.status.live = Some(st);
    ctl.set(report.status.clone());
    Ok(report)
}
