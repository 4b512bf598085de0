//! Real-time emulation: encoded frames written at their wall-clock deadlines to any number of
//! sinks (pseudo-terminal, serial device, UDP, TCP, file). No physics here: the frames come from
//! the run ([`crate::run`]), the same code that writes `generate`'s output.
//!
//! Shape: a producer (its own thread) runs ahead of the clock and sends blocks of encoded
//! frames through a bounded channel, so memory is the same for any run length; the pacer (a
//! dedicated OS thread sleeping to absolute deadlines) writes each frame at
//! start + k·Δt/speed to every sink. A sink that cannot take a frame drops and counts it: the
//! clock never waits for a consumer.

pub mod clock;
pub mod hook;
pub mod hostclock;
pub mod lock;
pub mod pacer;
pub mod pps;
pub mod pty;
pub mod pulse;
pub mod serial;
pub mod signal;
pub mod sink;
pub mod stats;
pub mod tcp;
pub mod timemark;
pub mod udp;

/// A block of encoded frames travelling from the producer to the pacer: the same records in
/// one or more wire formats (streams), for sinks that speak different protocols.
#[derive(Debug, Default)]
pub struct FrameBlock {
    /// Index (0-based) of the block's first frame in the run.
    pub first: u64,
    /// Per stream: the frames' bytes back to back, and the end offset of each frame.
    pub streams: Vec<(Vec<u8>, Vec<usize>)>,
    /// Emission time of each frame after the run's t₀ in simulated ns, when the IMU has
    /// timing errors (latency, its own clock); empty: frame k at k·Δt, the end of its interval.
    pub emit_ns: Vec<i64>,
    /// Time of validity of each frame after t₀ in simulated ns, when the IMU has timing
    /// errors; empty: frame k's time of validity is the end of its interval, k·Δt.
    pub tov_ns: Vec<i64>,
    /// In a merged block with an IMU's records among other streams' frames: each frame's
    /// record index (0-based), `u64::MAX` for a frame that is no record (an aiding stream's),
    /// of which the pacer's hooks (time marks, pulses) are not told; empty: frame i is record
    /// `first + i`.
    pub records: Vec<u64>,
    /// In a merged block: the stream each frame belongs to (hooks may follow one unit's
    /// records only); empty: every frame is stream 0's.
    pub stream_of: Vec<u32>,
    /// The wall-clock time of validity of each frame, ns after the pacer's start, when it is
    /// not `tov_ns` at the run's speed (a run that follows a live input's clock); empty:
    /// derived from `tov_ns`.
    pub tov_wall_ns: Vec<i64>,
}

impl FrameBlock {
    /// Number of frames (the same in every stream).
    pub fn len(&self) -> usize {
        self.streams.first().map_or(0, |s| s.1.len())
    }

    /// True when the block holds no frame.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Frames `i..j` of stream `s`: their bytes, and their ends relative to those bytes.
    /// Empty frames (another stream's, in a merged block: [`merge`]) are left out.
    pub fn frames(&self, s: usize, i: usize, j: usize, ends: &mut Vec<usize>) -> &[u8] {
        let (bytes, all) = &self.streams[s];
        let start = if i == 0 { 0 } else { all[i - 1] };
        let end = if j == 0 { 0 } else { all[j - 1] };
        ends.clear();
        let mut prev = start;
        for &e in &all[i..j] {
            if e > prev {
                ends.push(e - start);
            }
            prev = e;
        }
        &bytes[start..end]
    }

    /// Number of non-empty frames of stream `s` among frames `i..j`.
    pub fn count(&self, s: usize, i: usize, j: usize) -> u64 {
        let all = &self.streams[s].1;
        let mut prev = if i == 0 { 0 } else { all[i - 1] };
        let mut n = 0;
        for &e in &all[i..j] {
            n += u64::from(e > prev);
            prev = e;
        }
        n
    }
}

/// Frames per block for a run at `rate_hz` (frames per wall-clock second): about 100 ms of
/// frames, so the pacer's look-ahead (channel depth × block) stays short and the first frame is
/// ready quickly, but never fewer than 16 (channel traffic stays negligible).
pub fn block_len(rate_hz: f64) -> usize {
    ((rate_hz * 0.1) as usize).clamp(16, crate::engine::BLOCK)
}

/// Blocks in flight between producer and pacer: bounded memory, enough look-ahead to ride out
/// a scheduling hiccup of the producer.
pub const CHANNEL_BLOCKS: usize = 8;
