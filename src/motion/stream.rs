//! The sliding window of a sampled motion model: knots computed on demand from samples read
//! in order from a [`SampleSource`], so that memory is bounded whatever the trajectory's length.
//!
//! A first pass over the samples (an [`IndexBuilder`] fed by the reader) checks them, counts
//! them and stores a checkpoint every [`CHECKPOINT_EVERY`] samples: where the sample starts in
//! the source and the previous sample's attitude (the quaternion hemisphere is chained from
//! sample to sample). The window then moves forward as the generator advances; it keeps the
//! last [`HISTORY`] knots for callers that step back a little (a block's rotation terms start
//! one interval before the block's end), and serves a request before that by rewinding the
//! source to the nearest checkpoint and recomputing forward. Each knot depends only on its
//! stencil's samples and the chained hemisphere, so the knots — and the output — are
//! bit-identical to a model holding every knot.

use std::collections::VecDeque;
use std::ops::Range;
use std::sync::Arc;

use super::fd::stencil;
use super::knot::{
    Conv, GAP_FACTOR, Isolated, Knot, ModelError, ModelSettings, Sample, convert, make_knot,
};
use super::limits::{check_sample, check_step};
use crate::math::Quat;

/// Samples between checkpoints (at least twice the largest stencil, see [`Window::restart`]).
pub const CHECKPOINT_EVERY: usize = 1024;

/// Knots kept behind the furthest one asked for (200 bytes each).
pub const HISTORY: usize = 8192;

/// A position in a sample source to resume reading from: (byte offset, lines before it) for a
/// file, (sample index, 0) for samples in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mark(pub u64, pub u64);

/// Samples read in order, that can be re-read from a [`Mark`].
pub trait SampleSource: Send {
    /// The next sample; `None` at the end.
    fn next_sample(&mut self) -> Result<Option<Sample>, String>;
    /// Continues reading at `mark` (taken by the first pass before a sample).
    fn rewind(&mut self, mark: Mark) -> Result<(), String>;
    /// An independent source over the same samples (for a copy of the model).
    fn fork(&self) -> Box<dyn SampleSource>;
}

/// Samples held in memory.
pub struct MemorySamples {
    /// The samples.
    pub samples: Arc<Vec<Sample>>,
    /// Index of the next one.
    pub next: usize,
}

impl SampleSource for MemorySamples {
    fn next_sample(&mut self) -> Result<Option<Sample>, String> {
        let s = self.samples.get(self.next).copied();
        self.next += 1;
        Ok(s)
    }
    fn rewind(&mut self, mark: Mark) -> Result<(), String> {
        self.next = mark.0 as usize;
        Ok(())
    }
    fn fork(&self) -> Box<dyn SampleSource> {
        Box::new(MemorySamples {
            samples: self.samples.clone(),
            next: 0,
        })
    }
}

#[derive(Clone, Copy, Debug)]
struct Checkpoint {
    sample: usize,
    mark: Mark,
    t: f64,
    prev_q: Option<Quat>,
}

/// What the first pass learnt about the samples: their number, time span, gaps and
/// checkpoints.
#[derive(Clone, Debug)]
pub struct Index {
    len: usize,
    stencil: usize,
    first: f64,
    last: f64,
    /// The first sample after each gap, in order: the stencils of a knot never reach across
    /// one (see [`IndexBuilder`]).
    gaps: Vec<usize>,
    checkpoints: Vec<Checkpoint>,
}

impl Index {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.len
    }
    /// True without samples (never for a built model).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Time of the first sample.
    pub fn first_time(&self) -> f64 {
        self.first
    }
    /// Time of the last sample.
    pub fn last_time(&self) -> f64 {
        self.last
    }

    /// The samples between the gaps around sample `i`.
    fn segment(&self, i: usize) -> Range<usize> {
        let g = self.gaps.partition_point(|&s| s <= i);
        let lo = if g == 0 { 0 } else { self.gaps[g - 1] };
        lo..self.gaps.get(g).copied().unwrap_or(self.len)
    }

    /// The stencil of knot `i`: the nearest samples on its side of any gap.
    fn stencil_of(&self, i: usize) -> Range<usize> {
        let seg = self.segment(i);
        let st = stencil(i - seg.start, self.stencil, seg.len());
        st.start + seg.start..st.end + seg.start
    }

    /// The first knot whose stencil starts at or after sample `s` (within a stencil of `s`:
    /// stencil starts never decrease with the knot, and the knot `s + n/2` or its segment's
    /// end has one at `s` or past it).
    fn first_knot_from(&self, s: usize) -> usize {
        (s..self.len)
            .find(|&i| self.stencil_of(i).start >= s)
            .unwrap_or(self.len)
    }
}

/// The first pass: checks each sample against the previous one and the limits, finds the
/// gaps, and builds the [`Index`].
///
/// A gap is a step longer than [`GAP_FACTOR`] times every step within a stencil before it
/// (since the last gap), or every step within a stencil after it. A knot's finite differences
/// never reach across a gap: the samples on each side are modelled as if the series ended
/// there, and the gap is one Hermite piece between the two sides' end knots. A stencil that
/// did reach across would extrapolate (a lone sample after a dense run takes its derivatives
/// from samples a hundred steps of theirs away: 1e4 m/s² off across a 10 s gap). So the
/// samples between two gaps, or between a gap and an end, must fill a stencil; fewer are
/// refused as [`ModelError::Isolated`].
pub struct IndexBuilder {
    settings: ModelSettings,
    prev: Option<(Sample, Quat)>,
    /// The latest samples' times and marks (a stencil before the oldest undecided step, and
    /// the steps after it), from sample `recent_base` on.
    recent: VecDeque<(f64, Mark)>,
    recent_base: usize,
    /// The first sample of the current segment, and the first step not yet judged a gap.
    segment_start: usize,
    undecided: usize,
    index: Index,
}

impl IndexBuilder {
    /// A pass for a model with `settings`.
    pub fn new(settings: ModelSettings) -> IndexBuilder {
        IndexBuilder {
            settings,
            prev: None,
            recent: VecDeque::new(),
            recent_base: 0,
            segment_start: 0,
            undecided: 0,
            index: Index {
                len: 0,
                stencil: settings.stencil,
                first: f64::NAN,
                last: f64::NAN,
                gaps: Vec::new(),
                checkpoints: Vec::new(),
            },
        }
    }

    /// Where sample `i` starts in its source, while the builder still holds it (the samples of
    /// an [`ModelError::Isolated`] it returned are held).
    pub fn mark(&self, i: usize) -> Option<Mark> {
        let k = i.checked_sub(self.recent_base)?;
        self.recent.get(k).map(|r| r.1)
    }

    /// Time of a held sample.
    fn time(&self, i: usize) -> f64 {
        self.recent[i - self.recent_base].0
    }

    /// Judges the steps that have a stencil's steps after them (all of them at the end):
    /// starts a segment at each gap, refusing the one it ends if too short.
    fn judge_steps(&mut self, at_end: bool) -> Result<(), ModelError> {
        let n = self.settings.stencil.max(2);
        let len = self.index.len;
        // Step k is from sample k to k + 1.
        while self.undecided + 1 < len && (at_end || self.undecided + n < len) {
            let k = self.undecided;
            let step = |i: usize| self.time(i + 1) - self.time(i);
            let longest = |r: Range<usize>| r.map(step).reduce(f64::max);
            let before = longest(self.segment_start.max(k.saturating_sub(n - 1))..k);
            let after = longest(k + 1..(k + n).min(len - 1));
            let s = step(k);
            if [before, after]
                .into_iter()
                .flatten()
                .any(|l| s > GAP_FACTOR * l)
            {
                self.end_segment(k)?;
                self.segment_start = k + 1;
                self.index.gaps.push(k + 1);
            }
            self.undecided += 1;
        }
        // What judging the next step needs: a stencil's steps before it, and the start of a
        // segment that may still turn out too short (it then lies within a stencil).
        let keep = self.undecided.saturating_sub(n);
        while self.recent_base < keep {
            self.recent.pop_front();
            self.recent_base += 1;
        }
        Ok(())
    }

    /// Ends the current segment at sample `last`: refused when a stencil does not fit in it.
    fn end_segment(&self, last: usize) -> Result<(), ModelError> {
        let (first, need) = (self.segment_start, self.settings.min_samples());
        if last + 1 - first >= need {
            return Ok(());
        }
        let step = |i: usize| self.time(i + 1) - self.time(i);
        Err(ModelError::Isolated(Isolated {
            first,
            last,
            t_first: self.time(first),
            t_last: self.time(last),
            before: (first > 0).then(|| step(first - 1)),
            after: (last + 1 < self.index.len).then(|| step(last)),
            need,
        }))
    }

    /// Adds the next sample; `mark` is where the source can resume reading it.
    pub fn push(&mut self, s: &Sample, mark: Mark) -> Result<(), ModelError> {
        let index = self.index.len;
        let limit = |v: super::limits::Violation| ModelError::Limit {
            index,
            column: v.column,
            message: v.message,
        };
        if let Some((p, _)) = &self.prev
            && s.t.partial_cmp(&p.t) != Some(std::cmp::Ordering::Greater)
        {
            return Err(ModelError::NonIncreasingTime { index });
        }
        // The sample's own limits first: they keep the step's differences finite.
        check_sample(s).map_err(limit)?;
        if let Some((p, _)) = &self.prev {
            check_step(p, s).map_err(limit)?;
        }
        let prev_q = self.prev.map(|p| p.1);
        if index.is_multiple_of(CHECKPOINT_EVERY) {
            self.index.checkpoints.push(Checkpoint {
                sample: index,
                mark,
                t: s.t,
                prev_q,
            });
        }
        let q = convert(s, prev_q).q;
        self.prev = Some((*s, q));
        if index == 0 {
            self.index.first = s.t;
        }
        self.index.last = s.t;
        self.index.len += 1;
        self.recent.push_back((s.t, mark));
        self.judge_steps(false)
    }

    /// Samples pushed so far.
    pub fn len(&self) -> usize {
        self.index.len
    }

    /// True before the first sample.
    pub fn is_empty(&self) -> bool {
        self.index.len == 0
    }

    /// The index, if there are enough samples for the model and each side of every gap fills
    /// a stencil.
    pub fn finish(mut self) -> Result<Index, ModelError> {
        let need = self.settings.min_samples();
        if self.index.len < need {
            return Err(ModelError::TooFewSamples {
                got: self.index.len,
                need,
            });
        }
        self.finish_gaps()?;
        Ok(self.index)
    }

    /// Judges the last steps and the last segment; after it [`IndexBuilder::mark`] still names
    /// the samples of an [`ModelError::Isolated`] it returns.
    pub fn finish_gaps(&mut self) -> Result<(), ModelError> {
        self.judge_steps(true)?;
        self.end_segment(self.index.len - 1)
    }
}

/// The knots in use and the samples they are computed from.
pub(super) struct Window {
    source: Box<dyn SampleSource>,
    index: Arc<Index>,
    /// Global index of the next sample the source delivers, and its predecessor's attitude.
    next_sample: usize,
    prev_q: Option<Quat>,
    conv: Vec<Conv>,
    conv_base: usize,
    knots: Vec<Knot>,
    knot_base: usize,
    failed: Option<String>,
}

impl Window {
    /// An empty window at the start of `source`.
    pub(super) fn new(source: Box<dyn SampleSource>, index: Arc<Index>) -> Window {
        let mut w = Window {
            source,
            index,
            next_sample: 0,
            prev_q: None,
            conv: Vec::new(),
            conv_base: 0,
            knots: Vec::new(),
            knot_base: 0,
            failed: None,
        };
        w.restart_at(0);
        w
    }

    /// An independent window over the same samples.
    pub(super) fn fork(&self) -> Window {
        Window::new(self.source.fork(), self.index.clone())
    }

    /// Why the source could not be re-read, if it could not.
    pub(super) fn failure(&self) -> Option<String> {
        self.failed.clone()
    }

    /// Knot `i` (0 ≤ i < len).
    pub(super) fn knot(&mut self, i: usize) -> &Knot {
        self.ensure(i, i);
        &self.knots[i - self.knot_base]
    }

    /// Knots `piece` and `piece + 1`.
    #[inline]
    pub(super) fn pair(&mut self, piece: usize) -> (&Knot, &Knot) {
        self.ensure(piece, piece + 1);
        let k = piece - self.knot_base;
        (&self.knots[k], &self.knots[k + 1])
    }

    /// Index of the piece containing `t` (as for a model holding every knot: the last knot at
    /// or before `t`, clamped to a piece). `hint` is a previous answer.
    pub(super) fn piece_at(&mut self, t: f64, hint: usize) -> usize {
        let last = self.index.len - 2;
        let h = hint.min(last);
        let end = self.knot_base + self.knots.len();
        if h >= self.knot_base && h + 1 < end {
            let ks = &self.knots[h - self.knot_base..];
            if ks[0].t <= t && (h == last || t < ks[1].t) {
                return h;
            }
            if h < last && ks[1].t <= t && (h + 1 == last || ks.get(2).is_some_and(|k| t < k.t)) {
                return h + 1;
            }
        }
        // The window must start at or before t (or at knot 0) and reach past it (or the end).
        if self.knots.first().is_none_or(|k| k.t > t || t.is_nan()) && self.knot_base > 0 {
            let c = self.index.checkpoints.partition_point(|c| c.t <= t);
            // One checkpoint earlier: its first computable knot precedes the one sought.
            let c = c.saturating_sub(2);
            self.restart_at(c);
        }
        while self.knots.last().is_none_or(|k| k.t <= t)
            && self.knot_base + self.knots.len() < self.index.len
        {
            self.push_knot();
        }
        // A forward caller's answer is near its hint: search from there, not the whole window
        // (a binary search over megabytes of knots misses the cache at every step).
        let from = match h.checked_sub(self.knot_base) {
            Some(l) if self.knots.get(l).is_some_and(|k| k.t <= t) => l,
            _ => 0,
        };
        let idx = from + self.knots[from..].partition_point(|k| k.t <= t);
        let i = (self.knot_base + idx).saturating_sub(1).min(last);
        self.trim(i);
        i
    }

    /// Makes knots `lo..=hi` available.
    #[inline]
    fn ensure(&mut self, lo: usize, hi: usize) {
        if lo >= self.knot_base && hi < self.knot_base + self.knots.len() {
            return;
        }
        if lo < self.knot_base {
            let st = self.index.stencil_of(lo).start;
            let c = self.index.checkpoints.partition_point(|c| c.sample <= st);
            self.restart_at(c.saturating_sub(1));
        }
        while self.knot_base + self.knots.len() <= hi {
            self.push_knot();
        }
        self.trim(hi);
    }

    /// Drops knots more than [`HISTORY`] behind `i`, and the samples no knot still needs.
    fn trim(&mut self, i: usize) {
        let keep_from = i.saturating_sub(HISTORY);
        if keep_from > self.knot_base + HISTORY {
            let n = keep_from - self.knot_base;
            self.knots.drain(..n);
            self.knot_base = keep_from;
        }
    }

    /// Restarts at checkpoint `c`: the window empties and the source resumes at its sample.
    fn restart_at(&mut self, c: usize) {
        let cp = self.index.checkpoints[c];
        self.conv.clear();
        self.knots.clear();
        self.conv_base = cp.sample;
        self.next_sample = cp.sample;
        self.prev_q = cp.prev_q;
        // Checkpoints used are at or before the stencil start of the knot sought, so the
        // first knot computable from the checkpoint's samples comes at or before it.
        self.knot_base = self.index.first_knot_from(cp.sample);
        if let Err(e) = self.source.rewind(cp.mark) {
            self.failed.get_or_insert(e);
        }
    }

    /// Computes the next knot, reading the samples its stencil needs.
    fn push_knot(&mut self) {
        let i = self.knot_base + self.knots.len();
        let st = self.index.stencil_of(i);
        while self.conv_base + self.conv.len() < st.end {
            self.read_sample();
        }
        if self.failed.is_some() {
            self.knots.push(Knot::NAN);
            return;
        }
        // Samples before the stencil are never needed again by later knots.
        let dead = st.start - self.conv_base;
        if dead > 64 {
            self.conv.drain(..dead);
            self.conv_base = st.start;
        }
        let (conv, base) = (&self.conv, self.conv_base);
        self.knots.push(make_knot(i, st, |k| &conv[k - base]));
    }

    fn read_sample(&mut self) {
        let c = match self.source.next_sample() {
            Ok(Some(s)) if self.failed.is_none() => convert(&s, self.prev_q),
            Ok(Some(_)) => Conv::NAN,
            Ok(None) => {
                let e = format!("ended after {} samples", self.next_sample);
                self.failed.get_or_insert(e);
                Conv::NAN
            }
            Err(e) => {
                self.failed.get_or_insert(e);
                Conv::NAN
            }
        };
        self.prev_q = Some(c.q);
        self.conv.push(c);
        self.next_sample += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Vec3, quat_from_euler};
    use crate::motion::Motion;
    use crate::motion::sampled::SampledMotion;

    /// A turning, climbing vehicle sampled unevenly: heading through ±180° many times (so
    /// the quaternion hemisphere flips), over more than two histories of knots.
    fn samples(n: usize) -> Vec<Sample> {
        (0..n)
            .map(|i| {
                let t = i as f64 * 0.01 + 0.003 * ((i * 7919) % 13) as f64 / 13.0;
                Sample {
                    t,
                    lat: 0.7 + 1e-6 * t,
                    lon: 0.1,
                    h: 100.0 + t,
                    v_n: Vec3::new(50.0 * (0.3 * t).cos(), 50.0 * (0.3 * t).sin(), -1.0),
                    q_b_n: quat_from_euler(0.1 * (2.0 * t).sin(), 0.05, 0.3 * t),
                }
            })
            .collect()
    }

    /// Knots recomputed after a rewind to a checkpoint equal those computed going forward, to
    /// the bit: a window stepped back in every way (a little, past the history, to the start,
    /// by index and by time) answers exactly as a copy that only ever moves forward. A wrong
    /// checkpoint hemisphere, knot base or stale sample would change some value.
    #[test]
    fn rewinds_are_bit_identical_to_forward_evaluation() {
        let n = 2 * HISTORY + 5 * CHECKPOINT_EVERY + 37;
        let s = samples(n);
        let forward = SampledMotion::new(&s, ModelSettings::default()).unwrap();
        let jumpy = forward.clone();
        let times: Vec<f64> = (0..n - 1).step_by(97).map(|i| s[i].t + 0.004).collect();
        let mut expected = Vec::new();
        let mut hint = 0;
        for &t in &times {
            hint = forward.piece_at(t, hint);
            expected.push((hint, forward.sense(hint, t), forward.piece_end(hint)));
        }
        // Largest jumps first and both directions: end, start, middle, then strides back.
        let mut order: Vec<usize> = vec![times.len() - 1, 0, times.len() / 2];
        order.extend((0..times.len()).rev().step_by(3));
        order.extend((0..times.len()).step_by(5));
        for &k in &order {
            let t = times[k];
            let p = jumpy.piece_at(t, 0);
            assert_eq!(p, expected[k].0, "piece at t = {t}");
            // Brute force: the last sample at or before t.
            assert_eq!(p, s.iter().rposition(|x| x.t <= t).unwrap().min(n - 2));
            assert_eq!(jumpy.sense(p, t), expected[k].1, "sense at t = {t}");
            assert_eq!(jumpy.piece_end(p), expected[k].2);
        }
        assert_eq!(jumpy.pose(times[3]), forward.pose(times[3]));
        assert!(jumpy.failure().is_none());
    }

    /// A window never holds more than about two histories of knots, however far it moves.
    #[test]
    fn window_is_bounded() {
        let n = 4 * HISTORY;
        let s = samples(n);
        let m = SampledMotion::new(&s, ModelSettings::default()).unwrap();
        let mut hint = 0;
        for x in &s[..n - 1] {
            hint = m.piece_at(x.t, hint);
            let _ = m.sense(hint, x.t);
        }
        let w = m.window.lock().unwrap();
        assert!(w.knots.len() <= 2 * HISTORY + 1, "{} knots", w.knots.len());
        assert!(w.conv.len() <= 64 + 2 * 15, "{} samples", w.conv.len());
    }

    /// A model whose source ends early (the file shrank) evaluates to NaN and says why.
    #[test]
    fn lost_source_gives_nan_and_a_reason() {
        let s = samples(3000);
        let mut b = IndexBuilder::new(ModelSettings::default());
        for (i, x) in s.iter().enumerate() {
            b.push(x, Mark(i as u64, 0)).unwrap();
        }
        let short = MemorySamples {
            samples: Arc::new(s[..2000].to_vec()),
            next: 0,
        };
        let m = SampledMotion::from_source(
            Box::new(short),
            b.finish().unwrap(),
            ModelSettings::default(),
        );
        let p = m.piece_at(s[100].t, 0);
        assert!(m.sense(p, s[100].t).f_b.x.is_finite());
        let p = m.piece_at(s[2500].t, p);
        assert!(m.sense(p, s[2500].t).f_b.x.is_nan());
        assert_eq!(m.failure().unwrap(), "ended after 2000 samples");
    }

    /// A level turn at 50 m/s and 0.1 rad/s, heading along the track, sampled at `times`.
    fn turn(times: impl Iterator<Item = f64>) -> Vec<Sample> {
        let (w, v, r) = (0.1, 50.0, 6.4e6);
        times
            .map(|t: f64| Sample {
                t,
                lat: 0.7 + v / w * (w * t).sin() / r,
                lon: 0.1 + v / w * (1.0 - (w * t).cos()) / (r * 0.7f64.cos()),
                h: 100.0,
                v_n: Vec3::new(v * (w * t).cos(), v * (w * t).sin(), 0.0),
                q_b_n: quat_from_euler(0.0, 0.0, w * t),
            })
            .collect()
    }

    /// 100 Hz samples of [`turn`] over `[a, b]`.
    fn dense(a: f64, b: f64) -> Vec<Sample> {
        let n = ((b - a) * 100.0).round() as usize;
        turn((0..=n).map(|i| a + i as f64 * 0.01))
    }

    /// Samples alone beyond a gap (after a dense run, before one, between two gaps) are
    /// refused naming them and both sides; the same samples with the gap filled are a model.
    #[test]
    fn samples_alone_beyond_a_gap_are_refused() {
        let settings = ModelSettings::default();
        let refused = |s: &[Sample]| match SampledMotion::new(s, settings) {
            Err(ModelError::Isolated(i)) => i,
            other => panic!("{other:?}"),
        };
        let mut end = dense(0.0, 5.0);
        end.extend(turn([15.0].into_iter()));
        let e = refused(&end);
        assert_eq!((e.first, e.last, e.after, e.need), (501, 501, None, 9));
        assert!((e.before.unwrap() - 10.0).abs() < 1e-9, "{e:?}");
        let mut start = turn([-10.0].into_iter());
        start.extend(dense(0.0, 5.0));
        let e = refused(&start);
        assert_eq!((e.first, e.last, e.before), (0, 0, None));
        assert!(
            e.to_string()
                .contains("between the start and a gap of 10 s"),
            "{e}"
        );
        let mut middle = dense(0.0, 5.0);
        middle.extend(turn([10.0, 10.01, 10.02].into_iter()));
        middle.extend(dense(15.0, 20.0));
        let e = refused(&middle);
        assert_eq!((e.first, e.last), (501, 503));
        assert!(e.before.is_some() && e.after.is_some(), "{e:?}");
        // Eight samples past the gap are one short of a stencil; nine are enough.
        let mut eight = dense(0.0, 5.0);
        eight.extend(dense(15.0, 15.07));
        assert_eq!((refused(&eight).first, refused(&eight).last), (501, 508));
        let mut nine = dense(0.0, 5.0);
        nine.extend(dense(15.0, 15.08));
        SampledMotion::new(&nine, settings).unwrap();
        // A step a hundred times the others is no gap: states lost in a row.
        let mut lossy = dense(0.0, 5.0);
        lossy.extend(turn([6.0].into_iter()));
        SampledMotion::new(&lossy, settings).unwrap();
    }

    /// The samples on each side of a gap are modelled as if the series ended there (to the bit:
    /// no knot's stencil reaches across), and the gap is one quintic Hermite piece whose
    /// velocity error is within the interpolation bound max|v⁽⁶⁾|·(H/2)⁶/6! (three conditions
    /// at each end: the error is v⁽⁶⁾(ξ)/6!·(t−a)³(t−b)³, largest mid-gap).
    #[test]
    fn a_gap_is_one_hermite_piece_between_sides_modelled_alone() {
        let settings = ModelSettings::default();
        let (a, b) = (dense(0.0, 5.0), dense(15.0, 20.0));
        let both: Vec<Sample> = a.iter().chain(&b).copied().collect();
        let gapped = SampledMotion::new(&both, settings).unwrap();
        let left = SampledMotion::new(&a, settings).unwrap();
        let right = SampledMotion::new(&b, settings).unwrap();
        for (side, t) in [
            (&left, 4.995),
            (&left, 4.9),
            (&right, 15.005),
            (&right, 15.1),
        ] {
            let (p, q) = (gapped.piece_at(t, 0), side.piece_at(t, 0));
            assert_eq!(gapped.sense(p, t), side.sense(q, t), "t = {t}");
        }
        // Against the same motion without the gap (its own error ~1e-12 m/s).
        let truth = SampledMotion::new(&dense(0.0, 20.0), settings).unwrap();
        let (w, v, gap) = (0.1f64, 50.0, 10.0f64);
        let bound = v * w.powi(6) * (gap / 2.0).powi(6) / 720.0;
        let mut worst = 0.0f64;
        for k in 1..100 {
            let t = 5.0 + 0.1 * k as f64;
            worst = worst.max((gapped.pose(t).v_n - truth.pose(t).v_n).norm());
        }
        assert!(worst <= bound, "{worst} > {bound}");
        // The error is the interpolation's own, near its bound (v⁽⁶⁾ of the turn hardly varies
        // over the gap): 1.069e-3 against 1.085e-3 m/s.
        assert!(worst > 0.5 * bound, "{worst}");
    }

    /// The first pass refuses what the limits refuse, naming the sample.
    #[test]
    fn index_builder_checks_order_and_limits() {
        let s = samples(20);
        let mut b = IndexBuilder::new(ModelSettings::default());
        b.push(&s[1], Mark(0, 0)).unwrap();
        assert_eq!(
            b.push(&s[0], Mark(1, 0)),
            Err(ModelError::NonIncreasingTime { index: 1 })
        );
        let mut high = s[2];
        high.h = 1e160;
        let e = b.push(&high, Mark(1, 0)).unwrap_err();
        assert!(
            matches!(
                e,
                ModelError::Limit {
                    index: 1,
                    column: "h",
                    ..
                }
            ),
            "{e:?}"
        );
        assert_eq!(
            b.finish().unwrap_err(),
            ModelError::TooFewSamples { got: 1, need: 9 }
        );
    }
}
