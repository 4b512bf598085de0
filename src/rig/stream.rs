//! A rig as a frame source: every unit's frames, one stream per unit (then the truth streams
//! asked for), window by window of simulated time, for the merger and pacer of `imu-emu run`
//! and for `generate`. A unit sends record k at the end of its interval, t_k = t₀ + k/rate,
//! or when its timing model says (latency, its own clock); units on the same grid share one
//! evaluation of the motion per instant, as do all shared units at a trigger's edges. A unit
//! with a producer of its own (an output filter, timing errors) evaluates the motion itself
//! and holds its frames until they are due, as one IMU's source does
//! (`run::sources::imu::ImuFrames`).

use std::collections::VecDeque;
use std::io::Write;

use super::{Rig, Scratch, Unit};
use crate::engine::frames::{Part, Until, WindowSource};
use crate::engine::trigger::Queue;
use crate::engine::{self, EngineError, Grid, Producer};
use crate::generator::{IdealImu, RotationTerms};
use crate::record::Record;
use crate::source::AnyMotion;

/// The units that share a time grid, and where their motion evaluation has got to.
struct GroupRun {
    units: Vec<usize>,
    grid: Grid,
    ideal: IdealImu<AnyMotion>,
    rot_needed: bool,
    /// The next record to produce (1-based).
    next: u64,
}

/// The shared units of a triggered rig: one evaluation of the motion per trigger interval.
struct EdgeRun {
    units: Vec<usize>,
    /// Integrates over any interval after the run's t₀ (its rate is 1 Hz, so the rotation
    /// terms it gives are integrals, divided here by each interval).
    ideal: IdealImu<AnyMotion>,
    rot_needed: bool,
    /// Intervals (lo, hi] (s after t₀) whose edges came and that are not made yet.
    queue: VecDeque<(f64, f64)>,
    /// Records made, per unit of `units`.
    made: Vec<u64>,
}

/// A producer-backed unit's frames made but not all given yet (the frames, their truth rows
/// and emission times are in the unit's [`Scratch`]).
#[derive(Default)]
struct Held {
    /// The first frame of the block not given yet.
    next: usize,
    /// How far (ns) the unit emits ahead of its nominal grid (a fast clock), from the last
    /// block: records are made that much early.
    ahead_ns: i64,
    done: bool,
    /// The intervals a triggered unit's producer takes its samples over.
    queue: Option<Queue>,
}

/// Every unit of a rig streamed in emission-time order: stream i is unit i's frames.
pub struct RigStream {
    units: Vec<Unit>,
    scratch: Vec<Scratch>,
    groups: Vec<GroupRun>,
    edges: Option<EdgeRun>,
    held: Vec<Held>,
    /// The run's t₀ (s): the earliest unit's; emission times count from it.
    origin: f64,
    nodes: usize,
    reference: Vec<Record>,
    rot: Vec<RotationTerms>,
    /// The rig's motion (the magnetometer samples it).
    motion: AnyMotion,
    /// Per unit: the stream of its error-free readings, when asked for
    /// ([`RigStream::with_truth`]).
    truth: Vec<Option<usize>>,
    /// Each unit's truth rows of the block being made.
    truth_buf: Vec<u8>,
    /// Per unit: the stream of each further protocol it speaks ([`super::Unit::add_protocol`]),
    /// after the truth streams, in unit order.
    extra: Vec<Vec<usize>>,
}

impl Rig {
    /// The rig as a frame source for the pacer (one stream per unit, in unit order).
    pub fn stream(self) -> RigStream {
        let groups = self
            .groups()
            .into_iter()
            .map(|units| {
                let grid = self.units[units[0]].grid;
                let rot_needed = units.iter().any(|&i| self.units[i].needs_rotation_terms());
                GroupRun {
                    ideal: IdealImu::new(
                        self.motion.clone(),
                        grid.rate_hz,
                        grid.t0,
                        grid.count,
                        self.nodes,
                    ),
                    units,
                    grid,
                    rot_needed,
                    next: 1,
                }
            })
            .collect();
        let origin = self.span().0;
        RigStream {
            truth: vec![None; self.units.len()],
            scratch: self.units.iter().map(|_| Scratch::default()).collect(),
            held: self.units.iter().map(|_| Held::default()).collect(),
            units: self.units,
            groups,
            edges: None,
            origin,
            nodes: self.nodes,
            reference: Vec::new(),
            rot: Vec::new(),
            truth_buf: Vec::new(),
            motion: self.motion,
            extra: Vec::new(),
        }
        .with_extra_streams()
    }
}

impl Rig {
    /// The run's t₀ and end (s): from the earliest unit's first instant to the latest unit's
    /// last record.
    pub fn span(&self) -> (f64, f64) {
        let t0 = (self.units.iter().map(|u| u.grid.t0)).fold(f64::INFINITY, f64::min);
        let t1 = (self.units.iter())
            .map(|u| u.grid.t0 + u.grid.count as f64 / u.grid.rate_hz)
            .fold(f64::NEG_INFINITY, f64::max);
        (t0, t1)
    }
}

/// Emission time of record `k` of `grid` after `origin` (ns).
fn emit_ns(grid: &Grid, origin: f64, k: u64) -> i64 {
    ((grid.t0 - origin + k as f64 / grid.rate_hz) * 1e9).round() as i64
}

/// The last record of `grid` emitted at or before `until_ns` (0: none).
fn last_due(grid: &Grid, origin: f64, until_ns: i64) -> u64 {
    let guess = ((until_ns as f64 / 1e9 + origin - grid.t0) * grid.rate_hz).floor();
    let mut k = guess.clamp(0.0, grid.count as f64) as u64;
    // The float guess may be one off either way: settle it on the integer emission times.
    while k < grid.count && emit_ns(grid, origin, k + 1) <= until_ns {
        k += 1;
    }
    while k > 0 && emit_ns(grid, origin, k) > until_ns {
        k -= 1;
    }
    k
}

/// Nominal emission time of record `k` (1-based) of `grid` after `origin` (ns), counted as
/// one IMU's source counts it (`run::sources::imu`): the unit's offset, then k/rate.
fn nominal_ns(grid: &Grid, origin: f64, k: u64) -> i64 {
    ((grid.t0 - origin) * 1e9).round() as i64 + (k as f64 / grid.rate_hz * 1e9).round() as i64
}

impl RigStream {
    /// The units, in stream order.
    pub fn units(&self) -> &[Unit] {
        &self.units
    }

    /// Also streams the error-free readings of each unit `i` with `wanted[i]` (CSV with the
    /// failed-channel mask, as `generate --truth` writes them), after the units' streams, in
    /// unit order.
    pub fn with_truth(mut self, wanted: &[bool]) -> RigStream {
        let mut next = self.units.len();
        for (i, (t, w)) in self.truth.iter_mut().zip(wanted).enumerate() {
            if *w {
                *t = Some(next);
                next += 1;
            }
            if let super::Body::Produced { producer, .. } = &mut self.units[i].body {
                producer.set_keep_truth(*w);
            }
        }
        self.with_extra_streams()
    }

    /// Numbers the further protocols' streams, after the units' and the truth streams.
    fn with_extra_streams(mut self) -> RigStream {
        let mut next = self.units.len() + self.truth.iter().flatten().count();
        self.extra = (self.units.iter())
            .map(|u| (0..u.protocols()).map(|_| post_inc(&mut next)).collect())
            .collect();
        self
    }

    /// The stream of unit `i`'s error-free readings, if it is streamed.
    pub fn truth_stream(&self, i: usize) -> Option<usize> {
        self.truth.get(i).copied().flatten()
    }

    /// Every unit samples at an external trigger's edges instead of on its clock
    /// ([`WindowSource::edge`]: one record per interval (previous edge, this edge], for each
    /// unit until it has made its grid's count of records): the units that share
    /// evaluations then share one per interval; a unit with a producer of its own takes the
    /// intervals in its producer (its timing errors give way to the trigger; an output
    /// filter becomes the uniform average over the interval, as KVH's units under external
    /// sync). The edges count from the run's t₀, which every unit starts at.
    pub fn triggered(mut self) -> RigStream {
        let mut shared = Vec::new();
        for (i, u) in self.units.iter_mut().enumerate() {
            u.triggered = true;
            match &mut u.body {
                super::Body::Produced { producer, .. } => {
                    let q = Queue::default();
                    producer.set_trigger(Box::new(q.clone()));
                    self.held[i].queue = Some(q);
                }
                _ => shared.push(i),
            }
        }
        self.groups.clear();
        if !shared.is_empty() {
            let rot_needed = shared.iter().any(|&i| self.units[i].needs_rotation_terms());
            let ideal = IdealImu::new(self.motion.clone(), 1.0, self.origin, 0, self.nodes);
            self.edges = Some(EdgeRun {
                made: vec![0; shared.len()],
                units: shared,
                ideal,
                rot_needed,
                queue: VecDeque::new(),
            });
        }
        self
    }

    /// What each stream starts with: a CSV unit's header, each truth stream's header.
    pub fn preambles(&self) -> Vec<Vec<u8>> {
        let mut out: Vec<Vec<u8>> = (self.units.iter())
            .map(|u| u.headers().0.into_bytes())
            .collect();
        for (u, t) in self.units.iter().zip(&self.truth) {
            if t.is_some() {
                out.push(u.headers().1.into_bytes());
            }
        }
        out.extend(self.extra.iter().flatten().map(|_| Vec::new()));
        out
    }

    /// The run's t₀ (s): emission times count from it.
    pub fn origin(&self) -> f64 {
        self.origin
    }
}

impl WindowSource for RigStream {
    fn streams(&self) -> usize {
        self.units.len() + self.truth.iter().flatten().count() + self.extra.iter().flatten().count()
    }

    fn next_due_ns(&self) -> Option<i64> {
        let groups = (self.groups.iter())
            .filter(|g| g.next <= g.grid.count)
            .map(|g| emit_ns(&g.grid, self.origin, g.next));
        let own = (self.units.iter().enumerate()).filter_map(|(i, u)| {
            let (h, s) = (&self.held[i], &self.scratch[i]);
            if let Some(&e) = s.emit.get(h.next) {
                return Some(e);
            }
            // A triggered unit is due when its next edge comes.
            if h.done || h.queue.is_some() || !u.has_own_producer() {
                return None;
            }
            let k = u.grid.count - u.remaining()? + 1;
            Some(nominal_ns(&u.grid, self.origin, k) - h.ahead_ns)
        });
        groups.chain(own).min()
    }

    fn set_flags(&mut self, flags: u8) {
        for u in self.units.iter_mut() {
            u.flags = flags;
        }
    }

    fn fill(&mut self, until: Until, parts: &mut [Part]) -> Result<(), EngineError> {
        let origin = self.origin;
        self.produce(
            |g| last_due(g, origin, until.ns).min(engine::released(g, until.t)),
            parts,
        )?;
        self.produce_edges(parts)?;
        for i in 0..self.units.len() {
            if self.units[i].has_own_producer() {
                self.fill_own(i, until, parts)?;
            }
        }
        Ok(())
    }

    fn done(&self) -> bool {
        let own = (self.units.iter().enumerate())
            .filter(|(_, u)| u.has_own_producer())
            .all(|(i, _)| self.held[i].done && self.held[i].next >= self.scratch[i].emit.len());
        let edges = self.edges.as_ref().is_none_or(|e| {
            (e.units.iter().zip(&e.made)).all(|(&i, &m)| m >= self.units[i].grid.count)
        });
        own && edges && self.groups.iter().all(|g| g.next > g.grid.count)
    }

    fn edge(&mut self, lo: f64, hi: f64) {
        if let Some(e) = self.edges.as_mut() {
            e.queue.push_back((lo, hi));
        }
        for h in &self.held {
            if let Some(q) = &h.queue {
                q.push(lo, hi);
            }
        }
    }
}

impl RigStream {
    /// Produces, group by group, every record up to `last(grid)` of the group's grid.
    fn produce(
        &mut self,
        last: impl Fn(&Grid) -> u64,
        parts: &mut [Part],
    ) -> Result<(), EngineError> {
        // Each unit's frames are its records: time marks and pulses of that unit follow them.
        for p in parts.iter_mut().take(self.units.len()) {
            p.marks_records = true;
        }
        for g in self.groups.iter_mut() {
            let last = last(&g.grid);
            let dt = 1.0 / g.grid.rate_hz;
            while g.next <= last {
                let k = g.next;
                let n = ((last - k + 1) as usize).min(engine::BLOCK);
                self.reference.resize(n, Record::default());
                g.ideal.fill(k, &mut self.reference);
                Producer::check_finite(&self.reference, "in the error-free signal")?;
                if g.rot_needed {
                    self.rot.resize(n, RotationTerms::default());
                    g.ideal.rotation_terms(k, &mut self.rot);
                }
                let terms = g.rot_needed.then_some(&self.rot[..]);
                for &i in &g.units {
                    let s = &mut self.scratch[i];
                    self.truth_buf.clear();
                    let mut truth = self.truth[i].map(|_| &mut self.truth_buf as &mut dyn Write);
                    let (motion, reference) = (&self.motion, &self.reference[..]);
                    self.units[i].encode(motion, reference, terms, dt, s, &mut truth)?;
                    let at = |j: usize| emit_ns(&g.grid, self.origin, k + j as u64);
                    let streams = (i, self.truth[i], &self.extra[i][..]);
                    push_frames(s, &self.truth_buf, streams, k - 1, at, parts);
                }
                g.next += n as u64;
            }
        }
        Ok(())
    }

    /// The shared units' record over each queued trigger interval: one evaluation of the
    /// motion over it, each unit's record integrating over the whole interval, emitted at its
    /// closing edge.
    fn produce_edges(&mut self, parts: &mut [Part]) -> Result<(), EngineError> {
        let Some(e) = self.edges.as_mut() else {
            return Ok(());
        };
        while let Some((lo, hi)) = e.queue.pop_front() {
            let units = &self.units;
            if (e.units.iter().zip(&e.made)).all(|(&i, &m)| m >= units[i].grid.count) {
                e.queue.clear();
                break;
            }
            let (bounds, span) = ([lo, hi], hi - lo);
            self.reference.resize(1, Record::default());
            e.ideal.fill_between(&bounds, &mut self.reference);
            Producer::check_finite(&self.reference, "in the error-free signal")?;
            if e.rot_needed {
                self.rot.resize(1, RotationTerms::default());
                e.ideal.rotation_terms_timed(&bounds, &mut self.rot);
                // Integrals (the generator's rate is 1 Hz): the means over the interval.
                self.rot[0].omega_outer *= 1.0 / span;
                self.rot[0].gravitation *= 1.0 / span;
            }
            let terms = e.rot_needed.then(|| &self.rot[..1]);
            let at_ns = (hi * 1e9).round() as i64;
            for (&i, made) in e.units.iter().zip(e.made.iter_mut()) {
                if *made >= self.units[i].grid.count {
                    continue;
                }
                let s = &mut self.scratch[i];
                self.truth_buf.clear();
                let mut truth = self.truth[i].map(|_| &mut self.truth_buf as &mut dyn Write);
                let (motion, reference) = (&self.motion, &self.reference[..1]);
                self.units[i].encode(motion, reference, terms, span, s, &mut truth)?;
                let streams = (i, self.truth[i], &self.extra[i][..]);
                push_frames(s, &self.truth_buf, streams, *made, |_| at_ns, parts);
                *made += 1;
            }
        }
        Ok(())
    }

    /// Gives producer-backed unit `i`'s frames due by `until`, making more blocks as the
    /// window releases them (a triggered unit: one per interval queued).
    fn fill_own(&mut self, i: usize, until: Until, parts: &mut [Part]) -> Result<(), EngineError> {
        let truth = self.truth[i];
        let grid = self.units[i].grid;
        loop {
            let (s, h) = (&mut self.scratch[i], &mut self.held[i]);
            while h.next < s.emit.len() && s.emit[h.next] <= until.ns {
                let j = h.next;
                let from = if j == 0 { 0 } else { s.ends[j - 1] };
                parts[i].push(&s.buf[from..s.ends[j]], s.emit[j]);
                parts[i].records.push(s.marks[j]);
                if let Some(t) = truth {
                    let from = if j == 0 { 0 } else { s.side_ends[j - 1] };
                    parts[t].push(&s.side[from..s.side_ends[j]], s.emit[j]);
                }
                for (&x, (buf, ends)) in self.extra[i].iter().zip(&s.extra) {
                    let from = if j == 0 { 0 } else { ends[j - 1] };
                    parts[x].push(&buf[from..ends[j]], s.emit[j]);
                }
                h.next += 1;
            }
            if h.next < s.emit.len() || h.done {
                return Ok(());
            }
            let remaining = self.units[i].remaining().unwrap_or(0);
            let made = grid.count - remaining;
            let max = match &h.queue {
                Some(q) => q.len(),
                None => {
                    let t = until.t + h.ahead_ns as f64 * 1e-9;
                    (engine::released(&grid, t).min(grid.count)).saturating_sub(made) as usize
                }
            };
            if max == 0 {
                h.done = remaining == 0;
                return Ok(());
            }
            h.next = 0;
            let (motion, origin) = (&self.motion, self.origin);
            let n = self.units[i].produce(
                motion,
                max.min(engine::BLOCK),
                origin,
                truth.is_some(),
                s,
            )?;
            let remaining = self.units[i].remaining().unwrap_or(0);
            if n == 0 {
                // Every sample of the block was skipped (a clocked unit goes on with the next
                // ones released), or a triggered unit's producer ended.
                h.done = remaining == 0;
                if h.done || h.queue.is_some() {
                    return Ok(());
                }
                continue;
            }
            if h.queue.is_none()
                && let Some(&e) = s.emit.last()
            {
                let made = grid.count - remaining;
                h.ahead_ns = (nominal_ns(&grid, origin, made) - e).max(0);
            }
        }
    }
}

/// Appends a unit's block (its frames in `s`, its truth rows in `truth_rows`, one per frame)
/// to its streams (`i`, its truth stream, its further protocols' streams), frame j — record
/// `first + j` (0-based), valid when it is sent — emitted at `at(j)`.
fn push_frames(
    s: &Scratch,
    truth_rows: &[u8],
    (i, truth, extra): (usize, Option<usize>, &[usize]),
    first: u64,
    at: impl Fn(usize) -> i64,
    parts: &mut [Part],
) {
    let mut from = 0;
    for (j, &end) in s.ends.iter().enumerate() {
        parts[i].push(&s.buf[from..end], at(j));
        (parts[i].records).push((first + j as u64, at(j)));
        from = end;
    }
    for (&x, (buf, ends)) in extra.iter().zip(&s.extra) {
        let mut from = 0;
        for (j, &end) in ends.iter().enumerate() {
            parts[x].push(&buf[from..end], at(j));
            from = end;
        }
    }
    if let Some(t) = truth {
        let rows = truth_rows.split_inclusive(|&b| b == b'\n');
        for (j, row) in rows.enumerate() {
            parts[t].push(row, at(j));
        }
    }
}

/// `*n`, then one more.
fn post_inc(n: &mut usize) -> usize {
    *n += 1;
    *n - 1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Record k's emission time is k/rate after t₀, and the last record due at a window's
    /// end is found exactly, also where k/rate is not a whole number of ns.
    #[test]
    fn records_are_due_at_the_end_of_their_interval() {
        let g = Grid {
            t0: 2.0,
            rate_hz: 3.0,
            count: 10,
        };
        assert_eq!(emit_ns(&g, 2.0, 3), 1_000_000_000);
        assert_eq!(emit_ns(&g, 1.5, 1), 833_333_333);
        assert_eq!(last_due(&g, 2.0, 999_999_999), 2);
        assert_eq!(last_due(&g, 2.0, 1_000_000_000), 3);
        assert_eq!(last_due(&g, 2.0, 333_333_333), 1);
        assert_eq!(last_due(&g, 2.0, 333_333_332), 0);
        assert_eq!(last_due(&g, 2.0, 100_000_000_000), 10);
        assert_eq!(last_due(&g, 2.0, -5), 0);
    }
}
