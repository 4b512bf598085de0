//! Frames with emission times: the interface between whatever produces frames (a rig's
//! units, a GNSS receiver, an odometer) and the real-time merger and pacer
//! (`realtime::merge`). A stream is a sequence of (emission time, bytes); a source gives its
//! streams' frames a window of simulated time at a time. No I/O here.

use crate::job::JobError;

/// The frames one stream emits in a window: bytes back to back, the end of each frame in
/// `bytes`, and its emission time (simulated ns after the run's t₀).
#[derive(Debug, Default, Clone)]
pub struct Part {
    /// The frames' bytes back to back.
    pub bytes: Vec<u8>,
    /// End offset of each frame in `bytes`.
    pub ends: Vec<usize>,
    /// Emission time of each frame (simulated ns after t₀), non-decreasing.
    pub emit_ns: Vec<i64>,
}

impl Part {
    /// Empties the part, keeping its buffers.
    pub fn clear(&mut self) {
        self.bytes.clear();
        self.ends.clear();
        self.emit_ns.clear();
    }

    /// Appends one frame emitted at `emit_ns`.
    pub fn push(&mut self, frame: &[u8], emit_ns: i64) {
        self.bytes.extend_from_slice(frame);
        self.ends.push(self.bytes.len());
        self.emit_ns.push(emit_ns);
    }
}

/// A source of frames for the merger: one or more streams, filled a window at a time.
pub trait WindowSource: Send {
    /// How many streams this source has (each its own entry in [`FrameBlock::streams`]).
    fn streams(&self) -> usize;
    /// Appends to `parts` (one per stream, cleared by the caller) the frames emitted at or
    /// before `until_ns` that were not given before.
    fn fill(&mut self, until_ns: i64, parts: &mut [Part]) -> Result<(), JobError>;
    /// True once every frame has been given.
    fn done(&self) -> bool;
}
