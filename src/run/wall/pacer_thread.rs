//! The pacer on its thread, the feed of frame blocks it is handed, and what a run adds to it:
//! time marks, pulses, a PPS lock, the schedule a lock slews.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use tokio::sync::mpsc::{Receiver as BlockRx, Sender as BlockTx};

use crate::engine::frames::Part;
use crate::output::SinkAddr;
use crate::realtime::clock::monotonic_ns;
use crate::realtime::hook::{FrameHook, OfStream};
use crate::realtime::pacer::{self, Clocking, Extras, Pacing, Routed, Status};
use crate::realtime::{self as rt, FrameBlock};

use crate::run::clock::Wall;
use crate::run::error::RunError;
use crate::run::pipeline::{Outlets, unit_streams};
use crate::run::routing::StreamPlan;
use crate::run::status::{RunStatus, StreamCounts};
use crate::run::sync::{PulseOut, Sync};

/// The pacer on its thread, with its figures and its sinks' streams.
pub(super) struct PacerThread {
    status: Arc<Mutex<Status>>,
    pub(super) handle: JoinHandle<std::io::Result<Status>>,
    /// Per sink handed to the pacer, its stream.
    owners: Vec<usize>,
    /// Files written live, removed if the run fails.
    files: Vec<String>,
}

/// What feeds the pacer: its bounded channel, and the buffers it gives back.
pub(super) struct PacerFeed {
    tx: BlockTx<FrameBlock>,
    recycle: BlockRx<FrameBlock>,
    order: Vec<(i64, u32, u32)>,
    first: u64,
}

impl PacerThread {
    /// Starts the pacer on `out`'s sinks with `clocking` and `extras`; frames go in through
    /// the feed, which is dropped to let the pacer finish.
    pub(super) fn start(
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
        for (i, v) in out.take().into_iter().enumerate() {
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
    pub(super) fn observe(&self, st: &mut RunStatus) {
        if let Ok(s) = self.status.try_lock() {
            fill_status(st, &s, &self.owners);
        }
    }

    /// Waits for the pacer (its feed dropped) to write what it has: its final figures (or why
    /// it failed), each sink's stream, and the files written live.
    pub(super) fn join(self) -> (Result<Status, RunError>, Vec<usize>, Vec<String>) {
        let st = (self.handle.join())
            .map_err(|_| {
                RunError::io(
                    "the pacer",
                    std::io::Error::other("the pacer thread panicked"),
                )
            })
            .and_then(|r| r.map_err(RunError::Output));
        (st, self.owners, self.files)
    }
}

impl PacerFeed {
    /// Merges `parts` (emission times on the pacer's clock) into a block and hands it to the
    /// pacer, waiting for room; false once the pacer has gone.
    pub(super) fn send(&mut self, parts: &[Part]) -> bool {
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
pub(super) fn fill_status(st: &mut RunStatus, p: &Status, owners: &[usize]) {
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
pub(super) fn extras(
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
pub(super) struct ScheduleWatch(Arc<Mutex<Option<crate::realtime::lock::Schedule>>>);

impl ScheduleWatch {
    /// The schedule now (`None`: never slewed).
    pub(super) fn get(&self) -> Option<crate::realtime::lock::Schedule> {
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
struct SharedLine(crate::run::spec::PulseLine);

impl crate::realtime::pulse::Line for SharedLine {
    fn set(&mut self, high: bool) -> std::io::Result<()> {
        (self.0.0.lock())
            .unwrap_or_else(|e| e.into_inner())
            .set(high)
    }
}

/// Frames per wall-clock second over every stream at `speed`.
pub(super) fn frames_per_s(streams: &[StreamPlan], speed: f64) -> f64 {
    (streams.iter().map(|s| s.rate_hz).sum::<f64>() * speed).max(1.0)
}

/// The pacer's timing for `streams` at `wall`, starting at `start_ns`.
pub(super) fn clocking(
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
