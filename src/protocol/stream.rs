//! Decoding a byte stream of frames: finds frame boundaries (constants, or the flags of an
//! SDLC/HDLC transport), resynchronises after garbage, and counts what a receiver would flag —
//! check failures, counter gaps, repeated frames and counters, status failures, skipped bytes.

use super::frame::{DecodeError, Decoded};
use super::framing::{ByteUnstuffer, FrameError, SdlcDecoder};
use super::plan::{Plan, Transport};
use super::spec::Source;

/// What a stream contained besides good frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Frames that decoded (duplicates included).
    pub frames: u64,
    /// Frames whose boundary was found but whose check (or transport FCS) did not match.
    pub check_failures: u64,
    /// Breaks in the counter sequence between good frames, allowing for the frames lost to
    /// check failures in between (one per break, however many frames are missing).
    pub counter_gaps: u64,
    /// Frames byte-identical to the previous good frame (with a counter: the same counter too).
    pub duplicates: u64,
    /// Frames repeating the previous frame's counter with different contents.
    pub stale_counters: u64,
    /// Good frames (duplicates not counted again) whose status word is not the healthy value.
    pub status_flagged: u64,
    /// Bytes skipped while looking for a frame (plain transport).
    pub skipped_bytes: u64,
    /// SDLC/HDLC frames rejected for framing (aborted, misaligned, wrong length or constants).
    pub framing_errors: u64,
    /// A frame begun but cut short by the end of the input ([`StreamDecoder::finish`]).
    pub truncated: u64,
}

/// The stream's frame interval from the time tags of its frames: the smallest positive
/// difference between consecutive ones (a lost frame only lengthens one difference, a repeated
/// frame or a wrapped timestamp gives none that counts).
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameInterval {
    last: Option<f64>,
    dt: Option<f64>,
}

impl FrameInterval {
    /// Takes a frame's time tag; returns the interval known so far (s).
    pub fn observe(&mut self, d: &Decoded) -> Option<f64> {
        if let Some(t) = d.time() {
            if let Some(l) = self.last {
                let step = t - l;
                if step > 0.0 && self.dt.is_none_or(|dt| step < dt) {
                    self.dt = Some(step);
                }
            }
            self.last = Some(t);
        }
        self.dt
    }
}

/// What the decoder remembers of the previous good frame.
#[derive(Clone, Debug, Default)]
struct Tally {
    last_counter: Option<u64>,
    last_frame: Vec<u8>,
    /// Check failures since the last good frame: frames that took a counter value.
    lost: u64,
    /// The previous window was a good frame: the next frame boundary is known even without
    /// sync constants.
    locked: bool,
    /// The previous window was a check failure right after a good frame: the next window is
    /// at a frame boundary too.
    aligned: bool,
    /// Bytes the plain deframer has consumed: at 0 the stream starts at a frame boundary (a
    /// file of frames does).
    consumed: u64,
    stats: StreamStats,
}

#[derive(Clone, Debug)]
enum Deframer {
    Plain(Vec<u8>),
    Sdlc(Box<SdlcDecoder>),
    Hdlc(Box<ByteUnstuffer>),
}

/// Incremental decoder over a byte stream.
#[derive(Clone, Debug)]
pub struct StreamDecoder {
    plan: Plan,
    deframer: Deframer,
    tally: Tally,
}

impl StreamDecoder {
    /// A decoder for frames of `plan`.
    pub fn new(plan: Plan) -> StreamDecoder {
        let deframer = match &plan.transport {
            Transport::Plain => Deframer::Plain(Vec::new()),
            Transport::Sdlc(o) => Deframer::Sdlc(Box::new(SdlcDecoder::new(o))),
            Transport::Hdlc(o) => Deframer::Hdlc(Box::new(ByteUnstuffer::new(o))),
        };
        StreamDecoder {
            plan,
            deframer,
            tally: Tally::default(),
        }
    }

    /// The plan.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// Counts so far.
    pub fn stats(&self) -> StreamStats {
        self.tally.stats
    }

    /// The input has ended: counts a frame begun and not finished as truncated, and any other
    /// bytes left over as skipped. Frames still waiting for the run that confirms them
    /// ([`Plan::frames_to_lock`]) are dropped: [`StreamDecoder::finish_frames`] hands them on.
    pub fn finish(&mut self) {
        self.finish_frames(|_| {});
    }

    /// [`StreamDecoder::finish`], calling `frame` for the frames the end of the input confirms:
    /// a run shorter than [`Plan::frames_to_lock`] that ends exactly where the input does.
    pub fn finish_frames(&mut self, mut frame: impl FnMut(&Decoded)) {
        if let Deframer::Plain(buf) = &mut self.deframer {
            plain(&self.plan, &mut self.tally, buf, true, &mut frame);
        }
        let stats = &mut self.tally.stats;
        match &mut self.deframer {
            Deframer::Plain(buf) => {
                // A frame start: constants that match, or right after a good frame when the
                // frames have none.
                let start = (0..buf.len()).find(|&p| {
                    self.plan.starts_frame(&buf[p..])
                        || (p == 0 && self.tally.locked && !self.plan.has_sync())
                });
                stats.skipped_bytes += start.unwrap_or(buf.len()) as u64;
                stats.truncated += u64::from(start.is_some());
                buf.clear();
            }
            Deframer::Sdlc(dec) => {
                stats.truncated += u64::from(dec.pending_bits() >= 8);
                dec.reset();
            }
            Deframer::Hdlc(dec) => {
                stats.truncated += u64::from(dec.pending() > 0);
                dec.reset();
            }
        }
    }

    /// Feeds bytes; calls `frame` for every good frame, in order (duplicates included).
    pub fn feed(&mut self, bytes: &[u8], mut frame: impl FnMut(&Decoded)) {
        let plan = &self.plan;
        let tally = &mut self.tally;
        match &mut self.deframer {
            Deframer::Plain(buf) => {
                buf.extend_from_slice(bytes);
                plain(plan, tally, buf, false, &mut frame);
            }
            Deframer::Sdlc(dec) => dec.feed(bytes, |r| tally.deframed(plan, r, &mut frame)),
            Deframer::Hdlc(dec) => dec.feed(bytes, |r| tally.deframed(plan, r, &mut frame)),
        }
    }
}

/// Decodes the frames of `buf` (`eof`: nothing more will come) and drains what it used.
fn plain(
    plan: &Plan,
    tally: &mut Tally,
    buf: &mut Vec<u8>,
    eof: bool,
    frame: &mut impl FnMut(&Decoded),
) {
    let need = plan.frames_to_lock();
    let mut p = 0;
    while buf.len() - p >= plan.shortest() {
        let window = &buf[p..];
        // Garbage: the places where no frame starts go at once, as the byte-by-byte hunt
        // below would take them (1 GiB of zeros took two minutes that way).
        let none = plan.no_frame_before(window);
        if none > 0 {
            tally.stats.skipped_bytes += none as u64;
            tally.locked = false;
            tally.aligned = false;
            p += none;
            continue;
        }
        match plan.decode(window) {
            Ok(d) => {
                // Where no boundary is known, a frame is believed once the run of frames it
                // starts is long enough that noise would hardly pass them all.
                let known = tally.locked || tally.aligned || tally.consumed + p as u64 == 0;
                if !known && need > 1 {
                    match run(plan, window, need, eof) {
                        Run::Whole => {}
                        Run::Pending => break,
                        Run::Broken => {
                            tally.stats.skipped_bytes += 1;
                            p += 1;
                            continue;
                        }
                    }
                }
                tally.good(plan, &window[..d.len], &d);
                frame(&d);
                p += d.len;
            }
            // A frame start whose end has not arrived yet.
            Err(DecodeError::Short { .. }) => break,
            // A frame boundary with a damaged body: skip the frame, as a receiver would.
            // Without sync constants the boundary is only known right after a good frame;
            // otherwise hunt byte by byte for a frame whose check holds.
            Err(DecodeError::Check { len, .. }) if plan.has_sync() || tally.locked => {
                tally.check_failure();
                tally.aligned = tally.locked;
                tally.locked = false;
                p += len;
            }
            Err(_) => {
                tally.stats.skipped_bytes += 1;
                tally.locked = false;
                tally.aligned = false;
                p += 1;
            }
        }
    }
    buf.drain(..p);
    tally.consumed += p as u64;
}

/// Whether a frame that decodes at the start of `window` begins a run of `need` frames.
enum Run {
    /// It does.
    Whole,
    /// The bytes so far agree; more are needed to tell.
    Pending,
    /// A window in the run is no frame.
    Broken,
}

/// The run of frames from the start of `window`; at the end of the input (`eof`), a shorter
/// run that ends exactly where the input does counts as whole.
fn run(plan: &Plan, window: &[u8], need: usize, eof: bool) -> Run {
    let mut at = 0;
    for _ in 0..need {
        if eof && at > 0 && at == window.len() {
            return Run::Whole;
        }
        match plan.decode(&window[at..]) {
            Ok(d) => at += d.len,
            Err(DecodeError::Short { .. }) if !eof => return Run::Pending,
            Err(_) => return Run::Broken,
        }
    }
    Run::Whole
}

impl Tally {
    fn check_failure(&mut self) {
        self.stats.check_failures += 1;
        self.lost += 1;
    }

    /// A payload (or rejection) from an SDLC/HDLC deframer.
    fn deframed(
        &mut self,
        plan: &Plan,
        r: Result<&[u8], FrameError>,
        frame: &mut impl FnMut(&Decoded),
    ) {
        match r {
            Ok(payload) => match plan.decode(payload) {
                Ok(d) if d.len == payload.len() => {
                    self.good(plan, payload, &d);
                    frame(&d);
                }
                Err(DecodeError::Check { len, .. }) if len == payload.len() => self.check_failure(),
                _ => self.stats.framing_errors += 1,
            },
            Err(FrameError::FcsMismatch { .. }) => self.check_failure(),
            _ => self.stats.framing_errors += 1,
        }
    }

    /// A frame that decoded: duplicates, stale counters, gaps and status.
    fn good(&mut self, plan: &Plan, bytes: &[u8], d: &Decoded) {
        self.stats.frames += 1;
        self.locked = true;
        self.aligned = false;
        let counter = d.get(Source::Counter).map(|c| c as u64);
        let same_bytes = self.last_frame == bytes;
        let repeated = match (counter, self.last_counter) {
            (Some(c), Some(l)) => c == l,
            (None, _) => !self.last_frame.is_empty(),
            _ => false,
        };
        if repeated && same_bytes && self.lost == 0 {
            self.stats.duplicates += 1;
            return;
        }
        if repeated && counter.is_some() && self.lost == 0 {
            self.stats.stale_counters += 1;
        } else if let (Some((modulo, step)), Some(c), Some(l)) =
            (plan.counter(), counter, self.last_counter)
            && (l + (1 + self.lost) * step) % modulo != c
        {
            self.stats.counter_gaps += 1;
        }
        if d.flagged {
            self.stats.status_flagged += 1;
        }
        self.last_counter = counter;
        self.last_frame.clear();
        self.last_frame.extend_from_slice(bytes);
        self.lost = 0;
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
                    bad[10] ^= 1; // corrupted: a check failure, not a gap
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
        // The corrupted frame took its counter value: only the dropped one is a gap.
        assert_eq!(
            d.stats(),
            StreamStats {
                frames: 8,
                check_failures: 1,
                counter_gaps: 1,
                skipped_bytes: 6,
                ..StreamStats::default()
            }
        );
    }

    /// Random bytes with a fixed seed.
    fn noise(n: usize) -> Vec<u8> {
        use rand::{RngExt, SeedableRng};
        let mut r = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(23);
        (0..n).map(|_| r.random::<u8>()).collect()
    }

    fn ln200_frames(n: usize) -> Vec<Vec<u8>> {
        let (_, plan) = load("ln200").unwrap();
        let mut st = EncoderState::default();
        (0..n)
            .map(|i| {
                let mut b = Vec::new();
                let r = Record {
                    t: i as f64,
                    ..Record::default()
                };
                plan.encode(&r, 25.0, &mut st, &mut b);
                b
            })
            .collect()
    }

    /// Decodes `bytes` fed in 4096-byte reads, then ends the input; the frames and counts.
    fn ln200_decode(bytes: &[u8]) -> (usize, StreamStats) {
        let (_, plan) = load("ln200").unwrap();
        assert_eq!(plan.frames_to_lock(), 2);
        let mut d = StreamDecoder::new(plan);
        let mut n = 0;
        for c in bytes.chunks(4096) {
            d.feed(c, |_| n += 1);
        }
        d.finish_frames(|_| n += 1);
        (n, d.stats())
    }

    /// LN-200 frames have no sync word and a 16-bit sum: one position in 65 536 of random
    /// bytes passes it, so these 4 MB of noise held 74 "frames" (issue 23 item 6: 313 from 20 MB,
    /// exit 0). Hunting, the decoder now believes a frame only when the next one holds too
    /// ([`Plan::frames_to_lock`]): noise gives none. Real frames still come out whole: from the
    /// start of a stream, after garbage when two follow, and a single one after garbage when
    /// the input ends with it.
    #[test]
    fn unsynchronised_frames_need_a_run_in_noise() {
        let (n, s) = ln200_decode(&noise(4 << 20));
        assert_eq!((n, s.frames), (0, 0), "{s:?}");
        let f = ln200_frames(3);
        assert_eq!(ln200_decode(&f[0]).0, 1);
        let mut g = noise(97);
        g.extend_from_slice(&f[0]);
        g.extend_from_slice(&f[1]);
        assert_eq!(ln200_decode(&g).0, 2);
        let mut g = noise(97);
        g.extend_from_slice(&f[2]);
        let (n, s) = ln200_decode(&g);
        assert_eq!((n, s.skipped_bytes), (1, 97));
        // In a stream of frames, a corrupted one is a check failure and the next is taken.
        let mut bad = f[1].clone();
        bad[0] ^= 1;
        let stream = [f[0].clone(), bad, f[2].clone()].concat();
        let (n, s) = ln200_decode(&stream);
        assert_eq!((n, s.check_failures, s.skipped_bytes), (2, 1, 0), "{s:?}");
    }

    /// Skipping the places where no frame starts finds what trying every byte finds: for
    /// every built-in protocol with constant fields, frames among zeros, random bytes, runs of
    /// a frame's first bytes and cut frames, fed in reads of random sizes, give the same
    /// frames and the same counts (skipped bytes, check failures, gaps) both ways.
    #[test]
    fn skipping_garbage_finds_what_a_byte_by_byte_hunt_finds() {
        use rand::{RngExt, SeedableRng};
        let mut r = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(38);
        let mut tried = 0;
        for name in crate::protocol::builtin_names() {
            let (_, plan) = load(name).unwrap();
            if !matches!(plan.transport, Transport::Plain) || plan.no_frame_before(&[0; 4096]) == 0
            {
                continue;
            }
            tried += 1;
            let mut st = EncoderState::default();
            let mut stream = Vec::new();
            for k in 0..60 {
                let mut f = Vec::new();
                let rec = Record {
                    t: k as f64 * 0.01,
                    ..Record::default()
                };
                plan.encode(&rec, 20.0, &mut st, &mut f);
                match k % 6 {
                    0 => stream.extend(std::iter::repeat_n(0, r.random_range(0..300))),
                    1 => stream.extend((0..r.random_range(0..300)).map(|_| r.random::<u8>())),
                    2 => (0..30).for_each(|_| stream.extend_from_slice(&f[..3])),
                    3 => stream.extend_from_slice(&f[..r.random_range(0..f.len())]),
                    _ => {}
                }
                stream.extend_from_slice(&f);
            }
            let mut fast = StreamDecoder::new(plan.clone());
            let mut slow = StreamDecoder::new(plan.clone().without_anchors());
            let (mut got, mut want) = (Vec::new(), Vec::new());
            let mut at = 0;
            while at < stream.len() {
                let end = (at + r.random_range(1..500)).min(stream.len());
                fast.feed(&stream[at..end], |d| got.push(d.clone()));
                slow.feed(&stream[at..end], |d| want.push(d.clone()));
                at = end;
            }
            fast.finish_frames(|d| got.push(d.clone()));
            slow.finish_frames(|d| want.push(d.clone()));
            assert!(
                fast.stats().skipped_bytes > 3000,
                "{name}: {:?}",
                fast.stats()
            );
            assert_eq!(fast.stats(), slow.stats(), "{name}");
            assert!(
                got == want,
                "{name}: {} frames, {} byte by byte",
                got.len(),
                want.len()
            );
        }
        assert!(tried >= 10, "{tried} protocols tried");
    }
}
