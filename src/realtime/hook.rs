//! Per-frame hooks of the pacer: what the time-mark channel and the pulse output need to know
//! of each frame — its index, time of validity, deadline and the instant it was written.

use std::io;

use super::lock::Schedule;

/// When one frame was valid, due and written. Instants are CLOCK_MONOTONIC ns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameTime {
    /// Record index (0-based) in the run.
    pub index: u64,
    /// The stream whose record it is (a rig's unit; 0 for one IMU).
    pub stream: usize,
    /// Time of validity after the run's t₀ on the records' own time axis (simulated ns).
    pub tov_sim_ns: i64,
    /// Wall-clock instant of the time of validity.
    pub tov_ns: i128,
    /// The time of validity as a nominal offset from the start (ns, at the run's speed): what
    /// the pacer's schedule maps to `tov_ns`, so a hook can map it again after a phase lock
    /// slewed the schedule.
    pub tov_nominal_ns: i128,
    /// Wall-clock instant the frame's first byte is due.
    pub due_ns: i128,
    /// Wall-clock instant the pacer began handing the frame's batch to the sinks (equals
    /// `due_ns` until written).
    pub written_ns: i128,
}

/// Something the pacer tells about every frame. Calls come from the pacer's thread, so each
/// must return quickly (no blocking I/O).
pub trait FrameHook: Send {
    /// A block of frames arrived, ahead of their deadlines (`written_ns` not yet known).
    fn ahead(&mut self, _frames: &[FrameTime]) {}
    /// A phase lock slewed the schedule: frames not yet written are due at `sched.at(…)` of
    /// their nominal offsets from now on.
    fn rescheduled(&mut self, _sched: &Schedule) {}
    /// Frame `f` was handed to the sinks at `f.written_ns`.
    fn written(&mut self, f: &FrameTime) -> io::Result<()>;
    /// End of the run: flush what is buffered, stop threads.
    fn finish(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// A hook told of one stream's frames only: the time marks or the pulse of one unit of a rig.
pub struct OfStream {
    stream: usize,
    inner: Box<dyn FrameHook>,
    scratch: Vec<FrameTime>,
}

impl OfStream {
    /// `inner`, told of the frames of `stream` only.
    pub fn new(stream: usize, inner: Box<dyn FrameHook>) -> OfStream {
        OfStream {
            stream,
            inner,
            scratch: Vec::new(),
        }
    }
}

impl FrameHook for OfStream {
    fn ahead(&mut self, frames: &[FrameTime]) {
        self.scratch.clear();
        (self.scratch).extend(frames.iter().filter(|f| f.stream == self.stream));
        self.inner.ahead(&self.scratch);
    }

    fn rescheduled(&mut self, sched: &Schedule) {
        self.inner.rescheduled(sched);
    }

    fn written(&mut self, f: &FrameTime) -> io::Result<()> {
        if f.stream == self.stream {
            self.inner.written(f)?;
        }
        Ok(())
    }

    fn finish(&mut self) -> io::Result<()> {
        self.inner.finish()
    }
}
