//! Several frame streams on one pacer: each source (a rig's units, a GNSS receiver, an
//! odometer) gives, window after window of simulated time, its frames with their emission
//! times; the merger lays them out in one [`FrameBlock`] in emission-time order, one stream
//! per source stream. A frame belongs to one stream: in the others it is empty (zero bytes),
//! and the pacer hands a sink only the non-empty frames of its stream.
//!
//! The interface is deliberately small: a stream is a sequence of (emission time, bytes).

use crate::engine::{EngineError, Producer};

pub use crate::engine::frames::{Part, WindowSource};

use crate::realtime::FrameBlock;

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
    block.records.clear();
    // Only a record stream's frames are timed by the hooks; the others' validity is their
    // emission.
    let marked = parts.iter().any(|p| p.marks_records);
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
        if marked {
            let (k, tov) = p.records.get(i).copied().unwrap_or((u64::MAX, t));
            block.records.push(k);
            block.tov_ns.push(tov);
        }
    }
}

/// Merges `sources` window by window (`window_ns` of simulated time each) and sends a block
/// per non-empty window, like [`produce`] does for one IMU: blocking, on its own
/// thread; buffers come back on `recycled`. Returns why production stopped early, if it did.
pub fn produce_merged(
    mut sources: Vec<Box<dyn WindowSource>>,
    window_ns: i64,
    tx: tokio::sync::mpsc::Sender<FrameBlock>,
    mut recycled: tokio::sync::mpsc::Receiver<FrameBlock>,
) -> Option<EngineError> {
    let n: usize = sources.iter().map(|s| s.streams()).sum();
    let mut parts = vec![Part::default(); n];
    let mut order = Vec::new();
    let (mut until, mut first) = (0i64, 0u64);
    while !sources.iter().all(|s| s.done()) {
        until += window_ns;
        parts.iter_mut().for_each(Part::clear);
        let mut at = 0;
        for s in sources.iter_mut() {
            let k = s.streams();
            if let Err(e) = s.fill(until, &mut parts[at..at + k]) {
                return Some(e);
            }
            at += k;
        }
        if parts.iter().all(|p| p.ends.is_empty()) {
            continue;
        }
        let mut b = recycled.try_recv().unwrap_or_default();
        merge_into(&parts, &mut b, &mut order);
        b.first = first;
        first += b.len() as u64;
        if tx.blocking_send(b).is_err() {
            return None;
        }
    }
    None
}

/// One IMU's frames as a window source: a stream per encoding of its producer (the main
/// protocol, then the extra ones), record k emitted at the end of its interval, k/rate after
/// t₀, or when the IMU's timing model says. Lets aiding streams share the IMU's pacer.
pub struct ProducerWindow {
    producer: Producer,
    block: usize,
    rate_hz: f64,
    /// A block made but not all due yet: per stream its bytes and frame ends, the emission
    /// time of each frame (ns after t₀), and the next frame to give.
    held: Vec<(Vec<u8>, Vec<usize>)>,
    emit: Vec<i64>,
    /// Each held record's index and time of validity (ns after t₀).
    tov: Vec<(u64, i64)>,
    next: usize,
    done: bool,
}

impl ProducerWindow {
    /// `producer`'s records at `rate_hz` in `streams` encodings, made `block` records at a
    /// time.
    pub fn new(producer: Producer, rate_hz: f64, streams: usize, block: usize) -> Self {
        ProducerWindow {
            producer,
            block,
            rate_hz,
            held: vec![Default::default(); streams],
            emit: Vec::new(),
            tov: Vec::new(),
            next: 0,
            done: false,
        }
    }

    /// Makes the next block; false at the end of the run (or on a producer error).
    fn refill(&mut self) -> Result<bool, EngineError> {
        for (bytes, ends) in self.held.iter_mut() {
            bytes.clear();
            ends.clear();
        }
        self.emit.clear();
        self.tov.clear();
        self.next = 0;
        let Some(out) = self.producer.next_block_multi(self.block, &mut self.held) else {
            return self.producer.take_error().map_or(Ok(false), Err);
        };
        let (first, n) = (out.first, out.records.len() as u64);
        match &out.times {
            Some(t) => {
                (self.emit).extend(t.emit.iter().map(|e| (e * 1e9).round() as i64));
                let tov = t.tov.iter().map(|v| (v * 1e9).round() as i64);
                self.tov.extend((first..first + n).zip(tov));
            }
            None => {
                let rate = self.rate_hz;
                (self.emit).extend(
                    (first + 1..=first + n).map(|k| (k as f64 / rate * 1e9).round() as i64),
                );
                self.tov
                    .extend((first..first + n).zip(self.emit.iter().copied()));
            }
        }
        Ok(true)
    }
}

impl WindowSource for ProducerWindow {
    fn streams(&self) -> usize {
        self.held.len()
    }

    fn fill(&mut self, until_ns: i64, parts: &mut [Part]) -> Result<(), EngineError> {
        // The main stream's frames are the records (the extra encodings repeat them).
        parts[0].marks_records = true;
        while !self.done {
            while self.next < self.emit.len() && self.emit[self.next] <= until_ns {
                let i = self.next;
                for ((bytes, ends), p) in self.held.iter().zip(parts.iter_mut()) {
                    let from = if i == 0 { 0 } else { ends[i - 1] };
                    p.push(&bytes[from..ends[i]], self.emit[i]);
                }
                parts[0].records.push(self.tov[i]);
                self.next += 1;
            }
            if self.next < self.emit.len() {
                break;
            }
            self.done = !self.refill()?;
        }
        Ok(())
    }

    fn done(&self) -> bool {
        self.done
    }
}

/// Runs `producer` to the end (or until the receiver hangs up), sending blocks of `block`
/// frames in `streams` encodings (the main one and the producer's extra ones); reuses the
/// buffers the pacer returns on `recycled`. Blocking: call it on its own thread (or
/// `spawn_blocking`). Returns why production stopped early (a non-finite record), if it did:
/// nothing of the bad block was sent, and the caller reports it.
pub fn produce(
    mut producer: Producer,
    block: usize,
    streams: usize,
    tx: tokio::sync::mpsc::Sender<FrameBlock>,
    mut recycled: tokio::sync::mpsc::Receiver<FrameBlock>,
) -> Option<crate::engine::EngineError> {
    loop {
        let mut b = recycled.try_recv().unwrap_or_default();
        b.streams.resize_with(streams, Default::default);
        for (bytes, ends) in b.streams.iter_mut() {
            bytes.clear();
            ends.clear();
        }
        let Some(out) = producer.next_block_multi(block, &mut b.streams) else {
            return producer.take_error();
        };
        b.first = out.first;
        b.emit_ns.clear();
        b.tov_ns.clear();
        b.records.clear();
        if let Some(t) = &out.times {
            b.emit_ns
                .extend(t.emit.iter().map(|e| (e * 1e9).round() as i64));
            b.tov_ns
                .extend(t.tov.iter().map(|e| (e * 1e9).round() as i64));
        }
        if tx.blocking_send(b).is_err() {
            return None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(frames: &[(&[u8], i64)]) -> Part {
        let mut p = Part::default();
        for (f, t) in frames {
            p.push(f, *t);
        }
        p
    }

    /// Two streams at different rates come out in emission order, each frame in its own
    /// stream only, equal times in stream order; a sink of one stream sees its frames alone.
    #[test]
    fn merges_in_emission_order() {
        let a = part(&[(b"a1", 10), (b"a2", 20), (b"a3", 30)]);
        let b = part(&[(b"bb1", 15), (b"bb2", 30)]);
        let mut block = FrameBlock::default();
        merge_into(&[a, b], &mut block, &mut Vec::new());
        assert_eq!(block.emit_ns, [10, 15, 20, 30, 30]);
        assert_eq!(block.len(), 5);
        assert_eq!(block.streams[0].0, b"a1a2a3");
        assert_eq!(block.streams[0].1, [2, 2, 4, 6, 6]);
        assert_eq!(block.streams[1].0, b"bb1bb2");
        assert_eq!(block.streams[1].1, [0, 3, 3, 3, 6]);
        let mut ends = Vec::new();
        assert_eq!(block.frames(1, 0, 5, &mut ends), b"bb1bb2");
        assert_eq!(ends, [3, 6]);
        assert_eq!(block.frames(0, 1, 4, &mut ends), b"a2a3");
        assert_eq!(ends, [2, 4]);
        assert_eq!(block.frames(1, 2, 3, &mut ends), b"");
        assert!(ends.is_empty());
    }

    /// A source with frames every 3 ns, windows of 10 ns: blocks are numbered on, and no
    /// frame is lost or repeated.
    #[test]
    fn windows_cover_every_frame() {
        struct Every3(i64);
        impl WindowSource for Every3 {
            fn streams(&self) -> usize {
                1
            }
            fn fill(&mut self, until: i64, parts: &mut [Part]) -> Result<(), EngineError> {
                while self.0 + 3 <= until.min(40) {
                    self.0 += 3;
                    parts[0].push(&[self.0 as u8], self.0);
                }
                Ok(())
            }
            fn done(&self) -> bool {
                self.0 + 3 > 40
            }
        }
        let (tx, mut rx) = tokio::sync::mpsc::channel(64);
        let (_keep, recycled) = tokio::sync::mpsc::channel(1);
        assert!(produce_merged(vec![Box::new(Every3(0))], 10, tx, recycled).is_none());
        let (mut all, mut next) = (Vec::new(), 0);
        while let Ok(b) = rx.try_recv() {
            assert_eq!(b.first, next);
            next += b.len() as u64;
            all.extend_from_slice(&b.emit_ns);
        }
        assert_eq!(all, (1..=13).map(|k| 3 * k).collect::<Vec<i64>>());
    }
}
