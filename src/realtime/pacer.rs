//! The pacer: one dedicated OS thread that writes frame k (1-based) at the absolute deadline
//! start + k·Δt/speed — record k covers (t_{k−1}, t_k], and a real IMU sends it at the end of
//! its interval — sleeping with `clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)` and 1 ns
//! timer slack (tokio's timer has millisecond granularity, as the `tokio::time::sleep` docs
//! say: too coarse for frames 1 ms apart). Deadlines are integer
//! nanoseconds computed from k, so nothing accumulates: frame N's deadline error does not
//! grow with N.
//!
//! Above [`BATCH_ABOVE_HZ`] frames per second the pacer wakes about once a millisecond and
//! writes the frames due since the last wake-up in one go, at the deadline of the last of
//! them (each frame is late by at most the batch span, never early).
//!
//! Catch-up after a stall (the VM is descheduled for milliseconds): frames whose deadline is
//! less than `max_behind` ago go out at once, back to back, as a device FIFO would send them;
//! older ones are skipped and counted, and the time base is kept (a rig aligned on
//! `--start-at` stays aligned).

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use tokio::sync::mpsc::{Receiver, Sender};

use super::FrameBlock;
use super::clock::{monotonic_ns, sleep_until};
use super::hook::{FrameHook, FrameTime};
use super::lock::{LockState, PhaseLock, Schedule};
use super::sink::{Sink, SinkStats};
use super::stats::Lateness;
use crate::output::failure::absorb;

/// Frame rates (frames per wall-clock second) above which frames are batched per wake-up.
pub const BATCH_ABOVE_HZ: f64 = 2000.0;

/// Default limit of burst catch-up (ns).
pub const DEFAULT_MAX_BEHIND_NS: i128 = 100_000_000;

/// How frames are timed.
#[derive(Clone, Debug)]
pub enum Pacing {
    /// As fast as the sinks take them (offline, `--speed max`).
    Unpaced,
    /// At wall-clock deadlines.
    Paced(Clocking),
}

/// Wall-clock timing of a paced run.
#[derive(Clone, Debug)]
pub struct Clocking {
    /// CLOCK_MONOTONIC instant (ns) of t₀; `None`: when the first block is ready.
    pub start_ns: Option<i128>,
    /// Frames per wall-clock second (IMU rate × speed), in µHz so deadlines are integers.
    pub frames_per_s_uhz: u128,
    /// Frames per wake-up (1, or more above [`BATCH_ABOVE_HZ`]).
    pub batch: u64,
    /// Frames later than this are skipped, not sent (ns).
    pub max_behind_ns: i128,
    /// Ask for `SCHED_FIFO`.
    pub realtime: bool,
    /// Wall-clock seconds per simulated second (1/speed), for frames that carry their own
    /// emission times ([`FrameBlock::emit_ns`]).
    pub wall_per_sim: f64,
    /// Frames follow external trigger edges (`run --trigger`): a frame cannot exist before
    /// its edge came and was integrated, so its write lateness counts from when its block
    /// reached the pacer, if that is after the edge; the edge-to-write time is kept apart
    /// ([`Status::edge_latency`]).
    pub on_edges: bool,
}

impl Clocking {
    /// Timing for `frames_per_s` frames per second: batched above [`BATCH_ABOVE_HZ`] to one
    /// wake-up per millisecond or so.
    pub fn new(
        frames_per_s: f64,
        start_ns: Option<i128>,
        realtime: bool,
    ) -> Result<Clocking, String> {
        if !(1e-6..=1e8).contains(&frames_per_s) {
            return Err(format!("{frames_per_s} frames/s: expected 1e-6 to 1e8"));
        }
        let batch = if frames_per_s > BATCH_ABOVE_HZ {
            (frames_per_s / 1000.0).ceil() as u64
        } else {
            1
        };
        Ok(Clocking {
            start_ns,
            frames_per_s_uhz: (frames_per_s * 1e6).round() as u128,
            batch,
            max_behind_ns: DEFAULT_MAX_BEHIND_NS,
            realtime,
            wall_per_sim: 1.0,
            on_edges: false,
        })
    }

    /// Frames written on external trigger edges ([`Clocking::on_edges`]).
    pub fn with_edges(mut self) -> Clocking {
        self.on_edges = true;
        self
    }

    /// Emission times scaled by `speed` (simulated seconds per wall-clock second).
    pub fn with_speed(mut self, speed: f64) -> Clocking {
        self.wall_per_sim = 1.0 / speed;
        self
    }

    /// Deadline of frame `i` of `block` after `start` (ns): its own emission time when the
    /// block carries them, else the nominal one.
    fn deadline_in(&self, start: i128, block: &FrameBlock, i: usize) -> i128 {
        match block.emit_ns.get(i) {
            Some(e) => start + self.wall(*e),
            None => self.deadline(start, block.first + i as u64 + 1),
        }
    }

    /// Wall-clock ns of `sim_ns` simulated ns at the run's speed.
    fn wall(&self, sim_ns: i64) -> i128 {
        (sim_ns as f64 * self.wall_per_sim).round() as i128
    }

    /// When frame `i` of `block` is valid, on the records' time axis (simulated ns after t₀)
    /// and as a nominal wall-clock offset after the start.
    fn tov_in(&self, block: &FrameBlock, i: usize) -> (i64, i128) {
        if let (Some(t), Some(w)) = (block.tov_ns.get(i), block.tov_wall_ns.get(i)) {
            return (*t, *w as i128);
        }
        match block.tov_ns.get(i) {
            Some(t) => (*t, self.wall(*t)),
            None => {
                let n = self.deadline(0, block.first + i as u64 + 1);
                ((n as f64 / self.wall_per_sim).round() as i64, n)
            }
        }
    }

    /// Index (exclusive) of the last frame of the batch that frame `i` of `block` starts.
    fn batch_end(&self, start: i128, block: &FrameBlock, i: usize) -> usize {
        let n = block.len();
        if block.emit_ns.is_empty() {
            let k = block.first + i as u64 + 1;
            let group_end = ((k - 1) / self.batch + 1) * self.batch;
            return (group_end - block.first).min(n as u64) as usize;
        }
        // Frames due within the batch's span of the first one go with it.
        let span = self.deadline(0, self.batch - 1);
        let limit = self.deadline_in(start, block, i) + span;
        let mut end = i + 1;
        while end < n && self.deadline_in(start, block, end) <= limit {
            end += 1;
        }
        end
    }

    /// Deadline of frame `k` (1-based) after `start` (ns).
    pub fn deadline(&self, start: i128, k: u64) -> i128 {
        start + (k as u128 * 1_000_000_000_000_000 / self.frames_per_s_uhz) as i128
    }
}

/// Live counts, published by the pacer a few times a second for the status line.
#[derive(Clone, Debug, Default)]
pub struct Status {
    /// CLOCK_MONOTONIC instant of t₀ (ns), once known.
    pub start_ns: Option<i128>,
    /// Frames handed to the sinks.
    pub frames: u64,
    /// Frames skipped by catch-up (too late to send).
    pub skipped: u64,
    /// Write lateness of every frame handed to the sinks.
    pub lateness: Lateness,
    /// On trigger edges ([`Clocking::on_edges`]): each frame's time from its edge to its
    /// hand-over to the sinks (integration, the channel and the write together).
    pub edge_latency: Option<Lateness>,
    /// Per sink: label and counts.
    pub sinks: Vec<(String, SinkStats)>,
    /// Whether `SCHED_FIFO` was granted (`None`: not asked).
    pub fifo: Option<bool>,
    /// Per stream of the blocks: frames handed to its sinks and frames skipped (a merged
    /// run's per-source counts; empty frames of other streams are not counted).
    pub streams: Vec<StreamCounts>,
    /// The phase lock to external edges, when there is one.
    pub lock: Option<LockState>,
    /// At the end: the sinks retired after a failure while the run went on for its live
    /// links, each with its reason and the frames it lost.
    pub failures: Vec<String>,
}

/// One stream's frames, as the pacer handled them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamCounts {
    /// Frames handed to the sinks.
    pub frames: u64,
    /// Frames skipped by catch-up.
    pub skipped: u64,
}

/// Adds frames `i..j` of `block` to the per-stream counts (`skipped` or handed over).
fn count_streams(
    counts: &mut Vec<StreamCounts>,
    block: &FrameBlock,
    i: usize,
    j: usize,
    skipped: bool,
) {
    counts.resize(
        block.streams.len().max(counts.len()),
        StreamCounts::default(),
    );
    for (s, c) in counts.iter_mut().enumerate().take(block.streams.len()) {
        let n = block.count(s, i, j);
        if skipped {
            c.skipped += n;
        } else {
            c.frames += n;
        }
    }
}

/// A sink and the stream (index into [`FrameBlock::streams`]) it takes.
pub struct Routed {
    /// Stream index: 0 is the main protocol.
    pub stream: usize,
    /// The sink.
    pub sink: Box<dyn Sink>,
}

impl Routed {
    /// A sink of the main stream.
    pub fn main(sink: Box<dyn Sink>) -> Routed {
        Routed { stream: 0, sink }
    }
}

/// What a run may add to the frames: hooks told of every frame, and edges to phase-lock to.
#[derive(Default)]
pub struct Extras {
    /// Told of every frame (time marks, pulses).
    pub hooks: Vec<Box<dyn FrameHook>>,
    /// Edges (CLOCK_MONOTONIC ns) the schedule's whole seconds lock to, and the loop.
    pub lock: Option<(std::sync::mpsc::Receiver<i128>, PhaseLock)>,
}

/// Runs the pacer on the calling thread until the producer's channel closes or `stop` is set;
/// returns the final counts (also left in `status`).
pub fn run(
    rx: Receiver<FrameBlock>,
    recycle: Sender<FrameBlock>,
    sinks: Vec<Routed>,
    pacing: Pacing,
    stop: Arc<AtomicBool>,
    status: Arc<Mutex<Status>>,
) -> io::Result<Status> {
    run_with(rx, recycle, sinks, pacing, stop, status, Extras::default())
}

/// [`run`] with hooks and a phase lock.
pub fn run_with(
    mut rx: Receiver<FrameBlock>,
    recycle: Sender<FrameBlock>,
    mut sinks: Vec<Routed>,
    pacing: Pacing,
    stop: Arc<AtomicBool>,
    status: Arc<Mutex<Status>>,
    mut extras: Extras,
) -> io::Result<Status> {
    let mut st = Status {
        sinks: sink_stats(&sinks),
        ..Status::default()
    };
    let clocking = match &pacing {
        Pacing::Unpaced => None,
        Pacing::Paced(c) => Some(c.clone()),
    };
    if let Some(c) = &clocking {
        // Timer slack 1 ns: without it the kernel may defer each wake-up by 50 µs.
        if let Err(e) = nix::sys::prctl::set_timerslack(1) {
            tracing::warn!("timer slack not set: {e}");
        }
        if c.realtime {
            st.fifo = Some(set_fifo());
        }
    }
    let mut start: Option<i128> = clocking.as_ref().and_then(|c| c.start_ns);
    let mut pending: Vec<i128> = Vec::new();
    let mut last_publish = 0i128;
    let mut warned_skip = false;
    let mut ends = Vec::new();
    let mut times: Vec<FrameTime> = Vec::new();
    // Per frame of the block: its place in `times`, `usize::MAX` for a frame that is no
    // record (an aiding stream's), which the hooks are not told of.
    let mut slots: Vec<usize> = Vec::new();
    let mut sched: Option<Schedule> = None;
    let mut pending_edge: Vec<i128> = Vec::new();
    'blocks: while let Some(block) = rx.blocking_recv() {
        let arrived = monotonic_ns();
        let n = block.len();
        let Some(c) = &clocking else {
            write_all(&mut sinks, &block, 0, n, &mut ends)?;
            count_streams(&mut st.streams, &block, 0, n, false);
            st.frames += n as u64;
            let _ = recycle.try_send(block);
            if stop.load(Ordering::Relaxed) {
                break;
            }
            continue;
        };
        let t0 = *start.get_or_insert_with(monotonic_ns);
        st.start_ns = Some(t0);
        let sched = sched.get_or_insert_with(|| Schedule::new(t0));
        // Deadlines through the schedule, which a phase lock may slew.
        let due = |s: &Schedule, j: usize| s.at(c.deadline_in(0, &block, j));
        // When the pacer could first write frame j: its deadline, or for a frame on a trigger
        // edge (due at the edge itself) the block's arrival if later.
        let ready = |s: &Schedule, j: usize| {
            let d = due(s, j);
            if c.on_edges { d.max(arrived) } else { d }
        };
        if !extras.hooks.is_empty() {
            times.clear();
            slots.clear();
            for j in 0..n {
                let index = match block.records.get(j) {
                    Some(&u64::MAX) => {
                        slots.push(usize::MAX);
                        continue;
                    }
                    Some(&k) => k,
                    None => block.first + j as u64,
                };
                slots.push(times.len());
                let (tov_sim_ns, tov) = c.tov_in(&block, j);
                let due_ns = due(sched, j);
                times.push(FrameTime {
                    index,
                    stream: block.stream_of.get(j).map_or(0, |&s| s as usize),
                    tov_sim_ns,
                    tov_ns: sched.at(tov),
                    tov_nominal_ns: tov,
                    due_ns,
                    written_ns: due_ns,
                });
            }
            for h in extras.hooks.iter_mut() {
                h.ahead(&times);
            }
        }
        let mut i = 0;
        while i < n {
            // The wake-up of i's batch: the deadline of the batch's last frame in this block.
            let last = c.batch_end(0, &block, i); // exclusive index
            loop {
                if stop.load(Ordering::Relaxed) {
                    break 'blocks;
                }
                let now = monotonic_ns();
                if let Some((edges, pll)) = &mut extras.lock {
                    let mut slewed = false;
                    while let Ok(edge) = edges.try_recv() {
                        pll.edge(sched, edge, now);
                        st.lock = Some(pll.state);
                        slewed = true;
                    }
                    if slewed {
                        // The frames not yet written (and their pulses) follow the new rate.
                        let unwritten = (slots.get(i..).unwrap_or_default().iter())
                            .find(|&&s| s != usize::MAX)
                            .map_or(times.len(), |&s| s);
                        for f in times.iter_mut().skip(unwritten) {
                            f.tov_ns = sched.at(f.tov_nominal_ns);
                        }
                        for h in extras.hooks.iter_mut() {
                            h.rescheduled(sched);
                        }
                    }
                }
                let wake = due(sched, last - 1);
                if now >= wake {
                    break;
                }
                // Sleep in slices of at most 100 ms so a stop request (or an edge) is seen
                // promptly.
                sleep_until(wake.min(now + 100_000_000));
            }
            let now = monotonic_ns();
            // Skip what is too late to be worth sending; send at once what is due.
            let mut from = i;
            while from < n && ready(sched, from) + c.max_behind_ns < now {
                from += 1;
            }
            if from > i {
                count_streams(&mut st.streams, &block, i, from, true);
                st.skipped += (from - i) as u64;
                if !warned_skip {
                    tracing::warn!(
                        "{} frames more than {} ms late skipped (the machine stalled); counted in the summary",
                        from - i,
                        c.max_behind_ns / 1_000_000
                    );
                    warned_skip = true;
                }
            }
            let mut to = last.max(from);
            while to < n && due(sched, to) <= now {
                to += 1;
            }
            if to > from {
                // The hand-over instant is read before the write: a reader may have the frame
                // before the write call returns (or before a preempted pacer reads the clock
                // again), so only the instant before can bound its arrival from below.
                let handed = monotonic_ns();
                write_all(&mut sinks, &block, from, to, &mut ends)?;
                count_streams(&mut st.streams, &block, from, to, false);
                let done = monotonic_ns();
                for j in from..to {
                    let due_ns = due(sched, j);
                    pending.push(done - ready(sched, j));
                    if c.on_edges {
                        pending_edge.push(done - due_ns);
                    }
                    if let Some(f) = slots.get(j).and_then(|&s| times.get_mut(s)) {
                        f.due_ns = due_ns;
                        f.written_ns = handed;
                        for h in extras.hooks.iter_mut() {
                            h.written(f)?;
                        }
                    }
                }
                st.frames += (to - from) as u64;
            }
            i = to;
            if done_publish(&mut last_publish) {
                publish(&status, &mut st, [&mut pending, &mut pending_edge], &sinks);
            }
        }
        let _ = recycle.try_send(block);
    }
    for k in 0..sinks.len() {
        if let Err(e) = sinks[k].sink.finish() {
            retire(&mut sinks, k, e)?;
        }
    }
    for h in extras.hooks.iter_mut() {
        h.finish()?;
    }
    let mut guard = status.lock().unwrap_or_else(|e| e.into_inner());
    add_pending(&mut guard, [&mut pending, &mut pending_edge]);
    guard.start_ns = st.start_ns;
    guard.frames = st.frames;
    guard.skipped = st.skipped;
    guard.fifo = st.fifo;
    guard.streams = st.streams.clone();
    guard.lock = st.lock;
    guard.sinks = sink_stats(&sinks);
    guard.failures = sinks.iter().filter_map(|s| s.sink.failure()).collect();
    Ok(guard.clone())
}

/// Hands frames `i..j` of the block to every sink, each in its stream. A merged block
/// (several streams with their own emission times, `merge`) goes frame by frame, so that
/// sinks of different streams get the frames of a burst in emission order too.
fn write_all(
    sinks: &mut [Routed],
    block: &FrameBlock,
    i: usize,
    j: usize,
    ends: &mut Vec<usize>,
) -> io::Result<()> {
    if block.streams.len() > 1 && !block.emit_ns.is_empty() && j > i + 1 {
        for k in i..j {
            write_all(sinks, block, k, k + 1, ends)?;
        }
        return Ok(());
    }
    for k in 0..sinks.len() {
        let s = &mut sinks[k];
        let bytes = block.frames(s.stream, i, j, ends);
        // None of the frames is this sink's (a merged block's other streams).
        if ends.is_empty() {
            continue;
        }
        if let Err(e) = s.sink.write(bytes, ends) {
            retire(sinks, k, e)?;
        }
    }
    Ok(())
}

/// After sink `k` failed with `e`: retired with a warning while a live link of the run still
/// works (the run goes on for it), else `e`, which ends the run ([`absorb`]).
fn retire(sinks: &mut [Routed], k: usize, e: io::Error) -> io::Result<()> {
    let mut all: Vec<&mut (dyn Sink + 'static)> =
        sinks.iter_mut().map(|r| r.sink.as_mut()).collect();
    let warning = absorb(&mut all, k, e)?;
    tracing::warn!("{warning}");
    Ok(())
}

/// Label and counts of each sink.
fn sink_stats(sinks: &[Routed]) -> Vec<(String, SinkStats)> {
    sinks
        .iter()
        .map(|s| (s.sink.label().to_string(), s.sink.stats()))
        .collect()
}

/// True at most every 100 ms.
fn done_publish(last: &mut i128) -> bool {
    let now = monotonic_ns();
    if now - *last >= 100_000_000 {
        *last = now;
        true
    } else {
        false
    }
}

/// Moves the lateness and edge latency samples (ns) gathered since the last time into `g`.
fn add_pending(g: &mut Status, [pending, edge]: [&mut Vec<i128>; 2]) {
    for l in pending.drain(..) {
        g.lateness.add(l);
    }
    if !edge.is_empty() {
        let h = g.edge_latency.get_or_insert_with(Lateness::default);
        for l in edge.drain(..) {
            h.add(l);
        }
    }
}

/// Moves the counts to the shared status without ever waiting for the lock.
fn publish(
    status: &Mutex<Status>,
    st: &mut Status,
    pending: [&mut Vec<i128>; 2],
    sinks: &[Routed],
) {
    if let Ok(mut g) = status.try_lock() {
        add_pending(&mut g, pending);
        g.start_ns = st.start_ns;
        g.frames = st.frames;
        g.skipped = st.skipped;
        g.fifo = st.fifo;
        g.streams.clone_from(&st.streams);
        g.lock = st.lock;
        g.sinks = sink_stats(sinks);
    }
}

/// Asks for `SCHED_FIFO` priority 50 for this thread; false (with a warning) when refused.
fn set_fifo() -> bool {
    let param = libc::sched_param { sched_priority: 50 };
    // Neither std nor nix wraps sched_setscheduler.
    // SAFETY: plain syscall on the calling thread with a valid parameter block.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        tracing::info!("pacer runs SCHED_FIFO priority 50");
        true
    } else {
        let e = io::Error::last_os_error();
        eprintln!(
            "imu-emu: warning: --realtime: SCHED_FIFO refused ({e}); running at normal priority. Grant CAP_SYS_NICE (e.g. `setcap cap_sys_nice+ep imu-emu`) or raise the real-time priority limit (`ulimit -r 50`)."
        );
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integer deadlines: 3 frames/s (Δt not a whole number of ns) has no drift after 10⁹
    /// frames; batches above 2 kHz.
    #[test]
    fn deadlines_do_not_drift() {
        let c = Clocking::new(3.0, None, false).unwrap();
        assert_eq!(c.deadline(0, 3), 1_000_000_000);
        assert_eq!(c.deadline(0, 3_000_000_000), 1_000_000_000 * 1_000_000_000);
        assert_eq!(c.deadline(10, 1), 10 + 333_333_333);
        assert_eq!(c.batch, 1);
        assert_eq!(Clocking::new(10_000.0, None, false).unwrap().batch, 10);
        assert!(Clocking::new(f64::NAN, None, false).is_err());
    }

    /// Frames with their own emission times are due at start + emission/speed; batches
    /// above 2 kHz gather the frames due within the batch's span of its first frame.
    #[test]
    fn emission_times_set_the_deadlines() {
        let block = FrameBlock {
            first: 0,
            streams: vec![(vec![0; 4], vec![1, 2, 3, 4])],
            emit_ns: vec![1_400_000, 2_350_000, 3_450_000, 4_400_000],
            tov_ns: Vec::new(),
            records: Vec::new(),
            stream_of: Vec::new(),
            tov_wall_ns: Vec::new(),
        };
        let c = Clocking::new(1000.0, None, false).unwrap().with_speed(2.0);
        assert_eq!(c.deadline_in(100, &block, 1), 100 + 1_175_000);
        assert_eq!(c.batch_end(0, &block, 0), 1);
        let nominal = FrameBlock {
            emit_ns: Vec::new(),
            ..block
        };
        assert_eq!(c.deadline_in(0, &nominal, 1), c.deadline(0, 2));
        // 4 kHz: batches of 4 frames, 0.75 ms past the first one's deadline.
        let fast = Clocking::new(4000.0, None, false).unwrap();
        let block = FrameBlock {
            emit_ns: vec![250_000, 600_000, 1_000_000, 1_100_000],
            ..nominal
        };
        assert_eq!(fast.batch, 4);
        assert_eq!(fast.batch_end(0, &block, 0), 3);
        assert_eq!(fast.batch_end(0, &block, 3), 4);
    }
}
