//! One IMU's records as a frame source: a stream per wire format of its records (the main
//! encoding, then each further protocol a sink asks for), then, if asked, its error-free
//! records and the error each stage injected. Record k goes out at the end of its interval,
//! k/rate after t₀, or when the IMU's timing model says; a triggered unit samples once per
//! edge it is handed.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use crate::engine::frames::{Part, Until, WindowSource};
use crate::engine::trigger::TriggerSource;
use crate::engine::{EngineError, Grid, Producer, released};
use crate::output::{self, Format};

/// Records per refill at most: large enough to amortise the block machinery, small enough to
/// stay in cache.
const BLOCK: usize = crate::engine::BLOCK;

/// Which side streams an IMU source carries after its encodings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sides {
    /// The error-free records (the records' format; CSV for frames).
    pub truth: bool,
    /// The error each stage injected.
    pub errors: bool,
}

/// Trigger intervals handed to a triggered producer, shared with the source that queues them.
#[derive(Clone, Default)]
struct EdgeQueue(Arc<Mutex<VecDeque<(f64, f64)>>>);

impl TriggerSource for EdgeQueue {
    fn next_interval(&mut self) -> Option<Result<(f64, f64), String>> {
        let mut q = self.0.lock().unwrap_or_else(|e| e.into_inner());
        q.pop_front().map(Ok)
    }
}

/// One IMU's frames.
pub struct ImuFrames {
    producer: Producer,
    grid: Grid,
    /// The unit's t₀ after the run's (ns): emission times count from the run's t₀.
    offset_ns: i64,
    encodings: usize,
    sides: Sides,
    side: Format,
    /// Per stream: frames made but not all due yet, and the end of each in the bytes.
    held: Vec<(Vec<u8>, Vec<usize>)>,
    emit: Vec<i64>,
    /// Each held record's index and time of validity (ns after the run's t₀).
    tov: Vec<(u64, i64)>,
    next: usize,
    done: bool,
    /// How far (ns) the sensor emits ahead of its nominal grid (a fast clock), from the last
    /// block: records are made that much early.
    ahead_ns: i64,
    edges: Option<EdgeQueue>,
}

impl ImuFrames {
    /// The frames of `producer` in `encodings` wire formats (its main one and its extra
    /// ones), with the `sides` streams after them; emission times in ns after `origin` (the
    /// run's t₀, s). `triggered`: the unit samples once per [`WindowSource::edge`].
    pub fn new(
        mut producer: Producer,
        encodings: usize,
        sides: Sides,
        origin: f64,
        triggered: bool,
    ) -> ImuFrames {
        if sides.errors {
            producer = producer.with_components();
        }
        producer.set_keep_truth(sides.truth);
        let edges = triggered.then(EdgeQueue::default);
        if let Some(q) = &edges {
            producer = producer.with_trigger(Box::new(q.clone()));
        }
        let grid = producer.grid();
        let n = encodings + usize::from(sides.truth) + usize::from(sides.errors);
        ImuFrames {
            side: producer.side_format(),
            producer,
            grid,
            offset_ns: ((grid.t0 - origin) * 1e9).round() as i64,
            encodings,
            sides,
            held: vec![Default::default(); n],
            emit: Vec::new(),
            tov: Vec::new(),
            next: 0,
            done: false,
            ahead_ns: 0,
            edges,
        }
    }

    /// The preamble of each stream: the CSV header of CSV records, of the truth and of the
    /// injected errors; nothing for frames.
    pub fn preambles(&self) -> Vec<Vec<u8>> {
        let mut out = vec![self.producer.preamble().into_bytes()];
        out.resize(self.encodings, Vec::new());
        let csv = self.side == Format::Csv;
        if self.sides.truth {
            let h = if csv {
                self.producer.truth_header()
            } else {
                String::new()
            };
            out.push(h.into_bytes());
        }
        if self.sides.errors {
            let h = if csv {
                output::components_header()
            } else {
                String::new()
            };
            out.push(h.into_bytes());
        }
        out
    }

    /// Nominal emission time of record k (1-based) after the run's t₀ (ns).
    fn nominal_ns(&self, k: u64) -> i64 {
        self.offset_ns + round_ns(k as f64 / self.grid.rate_hz * 1e9)
    }

    /// Makes the records the window up to `until` releases (at most a block); false when
    /// none is due or the run is complete.
    fn refill(&mut self, until: Until) -> Result<bool, EngineError> {
        let max = match &self.edges {
            Some(q) => q.0.lock().unwrap_or_else(|e| e.into_inner()).len(),
            None => {
                let made = self.grid.count - self.producer.remaining();
                let t = until.t + self.ahead_ns as f64 * 1e-9;
                (released(&self.grid, t).min(self.grid.count) - made) as usize
            }
        };
        if max == 0 {
            self.done = self.producer.remaining() == 0;
            return Ok(false);
        }
        for (bytes, ends) in self.held.iter_mut() {
            bytes.clear();
            ends.clear();
        }
        self.emit.clear();
        self.tov.clear();
        self.next = 0;
        let (encodings, sides, side) = (self.encodings, self.sides, self.side);
        let (enc, rest) = self.held.split_at_mut(encodings);
        let Some(b) = self.producer.next_block_multi(max.min(BLOCK), enc) else {
            return match self.producer.take_error() {
                Some(e) => Err(e),
                None => {
                    // A triggered unit waits for its next edge; another one is complete.
                    self.done = self.edges.is_none() || self.producer.remaining() == 0;
                    Ok(false)
                }
            };
        };
        let (first, n) = (b.first, b.records.len() as u64);
        match &b.times {
            Some(t) => {
                let ns = |s: f64| ((s * 1e9).round() as i64) + self.offset_ns;
                self.emit.extend(t.emit.iter().map(|&e| ns(e)));
                let tov = t.tov.iter().map(|&v| ns(v));
                self.tov.extend((first..first + n).zip(tov));
            }
            None => {
                let rate = self.grid.rate_hz;
                let off = self.offset_ns;
                let nominal = |k: u64| off + round_ns(k as f64 / rate * 1e9);
                self.emit.extend((first + 1..=first + n).map(nominal));
                self.tov
                    .extend((first..first + n).zip(self.emit.iter().copied()));
            }
        }
        let mut rest = rest.iter_mut();
        if sides.truth {
            let (bytes, ends) = rest.next().expect("the truth stream");
            let gnss = b.motion.defined().map(|m| move |t| m.gnss_visible(t));
            let gnss = gnss.as_ref().map(|g| g as &dyn Fn(f64) -> bool);
            output::encode_truth(side, b.truth, b.times.as_ref(), gnss, bytes);
            record_ends(side, bytes, n as usize, ends);
        }
        if sides.errors {
            let (bytes, ends) = rest.next().expect("the errors stream");
            output::encode_components(side, b.records, b.components, bytes);
            record_ends(side, bytes, n as usize, ends);
        }
        if let (Some(&e), Some(_)) = (self.emit.last(), &b.times) {
            self.ahead_ns = (self.nominal_ns(first + n) - e).max(0);
        }
        Ok(true)
    }
}

/// `ns` (≥ 0) rounded to the nearest integer, halves away from zero: `f64::round` to the bit,
/// without its libm call (x86-64's baseline has no rounding instruction), which cost ~24
/// instructions per record offline (docs/performance.md).
fn round_ns(ns: f64) -> i64 {
    let whole = ns as i64;
    // Exact: the fraction of a double below 2⁵² is representable.
    whole + i64::from(ns - whole as f64 >= 0.5)
}

/// The end of each of `n` records in `bytes`: after each line of CSV, every `len/n` bytes of
/// fixed-size binary records.
fn record_ends(format: Format, bytes: &[u8], n: usize, ends: &mut Vec<usize>) {
    match format {
        Format::Csv => ends.extend(
            (bytes.iter().enumerate())
                .filter(|b| *b.1 == b'\n')
                .map(|(i, _)| i + 1),
        ),
        Format::Bin => {
            let len = bytes.len().checked_div(n).unwrap_or(0);
            ends.extend((1..=n).map(|i| i * len));
        }
    }
    debug_assert_eq!(ends.len(), n);
}

impl WindowSource for ImuFrames {
    fn streams(&self) -> usize {
        self.held.len()
    }

    fn fill(&mut self, until: Until, parts: &mut [Part]) -> Result<(), EngineError> {
        let until_ns = until.ns;
        // The main stream's frames are the records (the others repeat or describe them).
        parts[0].marks_records = true;
        loop {
            let all_due = self.next == 0
                && self.emit.last().is_some_and(|&e| e <= until_ns)
                && parts.iter().all(|p| p.ends.is_empty());
            if all_due {
                // The whole block is due: hand its buffers over instead of copying frames
                // (its times too: the emission times to the first stream, copies to the
                // others; the held ones are then empty, every frame given).
                for ((bytes, ends), p) in self.held.iter_mut().zip(parts.iter_mut()).skip(1) {
                    std::mem::swap(bytes, &mut p.bytes);
                    std::mem::swap(ends, &mut p.ends);
                    p.emit_ns.clone_from(&self.emit);
                }
                let (bytes, ends) = &mut self.held[0];
                std::mem::swap(bytes, &mut parts[0].bytes);
                std::mem::swap(ends, &mut parts[0].ends);
                std::mem::swap(&mut self.emit, &mut parts[0].emit_ns);
                std::mem::swap(&mut self.tov, &mut parts[0].records);
                self.emit.clear();
                self.tov.clear();
                self.next = 0;
            }
            while self.next < self.emit.len() && self.emit[self.next] <= until_ns {
                let i = self.next;
                for ((bytes, ends), p) in self.held.iter().zip(parts.iter_mut()) {
                    let from = if i == 0 { 0 } else { ends[i - 1] };
                    p.push(&bytes[from..ends[i]], self.emit[i]);
                }
                parts[0].records.push(self.tov[i]);
                self.next += 1;
            }
            if self.next < self.emit.len() || self.done || !self.refill(until)? {
                break;
            }
        }
        Ok(())
    }

    fn done(&self) -> bool {
        self.done && self.next >= self.emit.len()
    }

    fn next_due_ns(&self) -> Option<i64> {
        if let Some(&e) = self.emit.get(self.next) {
            return Some(e);
        }
        if self.done || self.edges.is_some() {
            // A triggered unit is due when its next edge comes.
            return None;
        }
        let k = self.grid.count - self.producer.remaining() + 1;
        Some(self.nominal_ns(k) - self.ahead_ns)
    }

    fn set_flags(&mut self, flags: u8) {
        self.producer.mark(flags);
    }

    fn edge(&mut self, lo: f64, hi: f64) {
        if let Some(q) = &self.edges {
            q.0.lock()
                .unwrap_or_else(|e| e.into_inner())
                .push_back((lo, hi));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `round_ns` is `f64::round` on every non-negative value an emission time takes: halves,
    /// the values beside them, and integer-nanosecond ones up to days.
    #[test]
    fn round_ns_is_round() {
        let mut xs = vec![0.0, 0.5, 1.5, 2.5, 0.49999999999999994, 1e15 + 0.5];
        for k in 1..100_000u64 {
            xs.push(k as f64 / 1000.0 * 1e9);
            xs.push(k as f64 / 333.0 * 1e9);
            xs.push(k as f64 * 0.5);
            xs.push(f64::from_bits((k as f64 * 0.5).to_bits() - 1));
        }
        for x in xs {
            assert_eq!(round_ns(x), x.round() as i64, "{x}");
        }
    }
}
