//! A rig as a real-time frame source: every unit's frames, one stream per unit, window by
//! window of simulated time, for the merger and pacer of `imu-emu run`
//! (`realtime::merge`). A unit sends record k at the end of its interval,
//! t_k = t₀ + k/rate; units on the same grid share one evaluation of the motion per instant,
//! as in [`Rig::write`].

use std::io::Write;

use super::{Rig, Scratch, Unit};
use crate::engine::frames::{Part, Until, WindowSource};
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

/// Every unit of a rig streamed in emission-time order: stream i is unit i's frames.
pub struct RigStream {
    units: Vec<Unit>,
    scratch: Vec<Scratch>,
    groups: Vec<GroupRun>,
    /// The run's t₀ (s): the earliest unit's; emission times count from it.
    origin: f64,
    reference: Vec<Record>,
    rot: Vec<RotationTerms>,
    /// The rig's motion (the magnetometer samples it).
    motion: AnyMotion,
    /// Per unit: the stream of its error-free readings, when asked for
    /// ([`RigStream::with_truth`]).
    truth: Vec<Option<usize>>,
    /// Each unit's truth rows of the block being made.
    truth_buf: Vec<u8>,
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
            units: self.units,
            groups,
            origin,
            reference: Vec::new(),
            rot: Vec::new(),
            truth_buf: Vec::new(),
            motion: self.motion,
        }
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
        for (t, w) in self.truth.iter_mut().zip(wanted) {
            if *w {
                *t = Some(next);
                next += 1;
            }
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
        out
    }

    /// The run's t₀ (s): emission times count from it.
    pub fn origin(&self) -> f64 {
        self.origin
    }
}

impl WindowSource for RigStream {
    fn streams(&self) -> usize {
        self.units.len() + self.truth.iter().flatten().count()
    }

    fn next_due_ns(&self) -> Option<i64> {
        (self.groups.iter())
            .filter(|g| g.next <= g.grid.count)
            .map(|g| emit_ns(&g.grid, self.origin, g.next))
            .min()
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
        )
    }

    fn done(&self) -> bool {
        self.groups.iter().all(|g| g.next > g.grid.count)
    }
}

impl RigStream {
    /// Appends to `parts` (one per unit) every record whose interval ends at or before `t`
    /// (s) that was not given before: what a state at `t` releases in a lockstep run.
    pub fn release_upto(&mut self, t: f64, parts: &mut [Part]) -> Result<(), EngineError> {
        self.produce(|g| engine::released(g, t).min(g.count), parts)
    }

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
                    self.units[i].encode(&self.motion, &self.reference, terms, s, &mut truth)?;
                    let at = |j: usize| emit_ns(&g.grid, self.origin, k + j as u64);
                    let mut from = 0;
                    for (j, &end) in s.ends.iter().enumerate() {
                        parts[i].push(&s.buf[from..end], at(j));
                        // Record k (1-based) is valid at the end of its interval, when it is sent.
                        (parts[i].records).push((k + j as u64 - 1, at(j)));
                        from = end;
                    }
                    if let Some(t) = self.truth[i] {
                        let rows = self.truth_buf.split_inclusive(|&b| b == b'\n');
                        for (j, row) in rows.enumerate() {
                            parts[t].push(row, at(j));
                        }
                    }
                }
                g.next += n as u64;
            }
        }
        Ok(())
    }
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
