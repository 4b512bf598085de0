//! Decoding a byte stream of frames: finds frame boundaries, resynchronises after garbage,
//! and counts what a receiver would flag — check failures, counter gaps, skipped bytes.

use super::plan::{DecodeError, Decoded, Plan};
use super::spec::Source;

/// What a stream contained besides good frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Frames that decoded.
    pub frames: u64,
    /// Frames whose constants matched but whose check did not.
    pub check_failures: u64,
    /// Breaks in the counter sequence between consecutive good frames.
    pub counter_gaps: u64,
    /// Bytes skipped while looking for a frame.
    pub skipped_bytes: u64,
}

/// Incremental decoder over a byte stream.
#[derive(Clone, Debug)]
pub struct StreamDecoder {
    plan: Plan,
    buf: Vec<u8>,
    last_counter: Option<u64>,
    /// Counts so far.
    pub stats: StreamStats,
}

impl StreamDecoder {
    /// A decoder for frames of `plan`.
    pub fn new(plan: Plan) -> StreamDecoder {
        StreamDecoder {
            plan,
            buf: Vec::new(),
            last_counter: None,
            stats: StreamStats::default(),
        }
    }

    /// The plan.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// Feeds bytes; calls `frame` for every good frame, in order.
    pub fn feed(&mut self, bytes: &[u8], mut frame: impl FnMut(&Decoded)) {
        self.buf.extend_from_slice(bytes);
        let len = self.plan.len();
        let mut p = 0;
        while self.buf.len() - p >= len {
            let window = &self.buf[p..];
            match self.plan.decode(window) {
                Ok(d) => {
                    self.count_counter(&d);
                    self.stats.frames += 1;
                    frame(&d);
                    p += len;
                }
                Err(DecodeError::Check { .. }) if self.plan.constants_match(window) => {
                    // A frame boundary with a damaged body: skip the frame, as a receiver would.
                    self.stats.check_failures += 1;
                    p += len;
                }
                Err(_) => {
                    self.stats.skipped_bytes += 1;
                    p += 1;
                }
            }
        }
        self.buf.drain(..p);
    }

    fn count_counter(&mut self, d: &Decoded) {
        let (Some((modulo, step)), Some(c)) = (self.plan.counter(), d.get(Source::Counter)) else {
            return;
        };
        let c = c as u64;
        if let Some(last) = self.last_counter
            && (last + step) % modulo != c
        {
            self.stats.counter_gaps += 1;
        }
        self.last_counter = Some(c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{EncoderState, load};
    use crate::record::Record;

    /// Garbage before, between and inside frames; a dropped frame; a corrupted one: the counts
    /// are exactly what was injected, and every intact frame comes out.
    #[test]
    fn resync_and_counts() {
        let (_, plan) = load("kvh1750").unwrap();
        let mut st = EncoderState::default();
        let frames: Vec<Vec<u8>> = (0..10)
            .map(|i| {
                let mut b = Vec::new();
                plan.encode(
                    &Record {
                        t: i as f64,
                        ..Record::default()
                    },
                    20.0,
                    &mut st,
                    &mut b,
                );
                b
            })
            .collect();
        let mut stream = vec![1u8, 2, 3];
        for (i, f) in frames.iter().enumerate() {
            match i {
                4 => continue, // dropped: a counter gap
                6 => {
                    let mut bad = f.clone();
                    bad[10] ^= 1; // corrupted: a check failure (and then a gap)
                    stream.extend_from_slice(&bad);
                }
                _ => stream.extend_from_slice(f),
            }
            if i == 2 {
                stream.extend_from_slice(&[0xFE, 0x81, 0x00]); // garbage that starts like a header
            }
        }
        let mut d = StreamDecoder::new(plan);
        let mut n = 0;
        for chunk in stream.chunks(7) {
            d.feed(chunk, |_| n += 1);
        }
        assert_eq!(n, 8);
        assert_eq!(
            d.stats,
            StreamStats {
                frames: 8,
                check_failures: 1,
                counter_gaps: 2,
                skipped_bytes: 6
            }
        );
    }
}
