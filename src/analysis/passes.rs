//! The reads of a static record that leave its transients out ([`super::transients`]) and
//! put back the samples it dropped: the first feeds the analyzer and the step scale, the
//! second flags steps beyond the bar, the third (only when something is left out or was
//! dropped) analyses the record again with the flagged spans skipped. The record is read again
//! through a callback, so a file (the CLI's [`super::recording`]) and rows in memory (the
//! Python package's arrays) go through the same code. Pure: the callbacks do the reading.
//!
//! **Dropped samples.** A logger that loses a sample now and then (a serial link's overrun,
//! a USB hiccup) leaves a time step of a whole number m ≥ 2 of Δt. When every step of the
//! record is Δt or such a multiple (each within [`STEP_TOLERANCE`] of Δt) and the samples
//! missing are at most [`MAX_DROPPED`] of the record, the later reads put m − 1 stand-ins on
//! the time grid ([`Analyzer::push_dropped`], [`Scanner::skip`]), and
//! every statistic leaves them out as it leaves out a transient: each Allan-variance
//! difference and Welch segment that spans one. The record keeps its time grid, so no τ
//! window is shifted by the samples lost. Without a time column a drop cannot be seen.

use super::analyzer::{Analysis, Analyzer, Dropped};
use super::transients::{self, Handling, Scanner, StepScale, Transients};

/// How far a time step may be from Δt (or from a whole number of Δt, a drop), relative to Δt.
pub const STEP_TOLERANCE: f64 = 0.01;

/// The most of a record that may have been dropped for it to be read as uniform with drops:
/// past that its sampling is not uniform (a logger that loses that much loses it for a
/// reason that may bias what is kept).
pub const MAX_DROPPED: f64 = 0.01;

/// How a record is read after its first read: its dropped samples and its transients.
#[derive(Clone, Copy, Debug)]
pub struct Passes {
    /// Welch segment length (samples).
    pub segment: usize,
    /// Keep transients in the statistics (`--keep-transients`), reporting them.
    pub keep: bool,
    /// Channels not in the input (left out of the analysis and of the search).
    pub missing: [bool; 6],
    /// Δt was given (a rate), not measured from the time column: drops are counted in it.
    pub dt_given: bool,
}

/// What the first read gathers: the analysis and each channel's step scale.
pub struct First {
    /// The analyzer fed by the first read.
    pub analyzer: Analyzer,
    steps: StepScale,
}

impl First {
    /// Empty accumulators, Welch segments of `segment` samples.
    pub fn new(segment: usize) -> First {
        First {
            analyzer: Analyzer::new(segment),
            steps: StepScale::default(),
        }
    }

    /// One sample of the first read.
    #[inline]
    pub fn push(&mut self, t: f64, v: &[f64; 6]) {
        self.analyzer.push(t, v);
        self.steps.push(v);
    }
}

/// A sample sink: a read again feeds every sample of the record, in order, to it.
pub type Sink<'a> = dyn FnMut(f64, &[f64; 6]) + 'a;

/// A sink on the time grid: each sample (None: a dropped sample's stand-in) at its time.
type GridSink<'a> = dyn FnMut(f64, Option<&[f64; 6]>) + 'a;

impl Passes {
    /// The record's analysis at interval `dt` from its first read, the samples it dropped put
    /// back, its transients found in a second read and, unless kept, left out in a third.
    /// `again` reads the record again from its start into the sink and returns the samples
    /// read; `Err(why)` in its place when the record cannot be read twice (a pipe). The
    /// second element is a warning when transients were not looked for (`label` names the
    /// record in it).
    pub fn finish<E, F>(
        &self,
        first: First,
        dt: f64,
        label: &str,
        again: Result<F, String>,
    ) -> Result<(Analysis, Option<String>), E>
    where
        F: FnMut(&mut Sink<'_>) -> Result<u64, E>,
    {
        let dropped = self.drops(&first.analyzer, dt);
        let mut analysis = first.analyzer.finish(dt).without(self.missing);
        let mut again = match again {
            Ok(f) => f,
            Err(why) => return Ok((analysis, Some(why))),
        };
        let (dt, samples) = match &dropped {
            Some(d) => (d.dt, analysis.samples + d.samples()),
            None => (dt, analysis.samples),
        };
        // Every later read is on the time grid, the dropped samples' stand-ins in place.
        let mut read = |sink: &mut GridSink<'_>| -> Result<u64, E> {
            let Some(d) = &dropped else {
                return again(&mut |t, v| sink(t, Some(v)));
            };
            let (mut next, mut k, mut t_prev) = (d.at.iter().peekable(), 0u64, f64::NAN);
            let n = again(&mut |t, v| {
                if let Some(&&(at, _, missing)) = next.peek()
                    && at == k
                {
                    for i in 1..=missing {
                        sink(t_prev + i as f64 * d.dt, None);
                    }
                    next.next();
                }
                sink(t, Some(v));
                (t_prev, k) = (t, k + 1);
            })?;
            Ok(n + d.samples())
        };
        let not_again = |got: u64| {
            format!(
                "{label}: a second read gave {got} samples where the first gave {samples} (a pipe cannot be read twice): transients (knocks, spikes) were not looked for"
            )
        };
        let found = match self.scanner(&analysis, &first.steps, dt) {
            None => None,
            Some((mut scan, z)) => {
                let got = read(&mut |_, v| match v {
                    Some(v) => scan.push(v),
                    None => scan.skip(),
                })?;
                if got != samples {
                    return Ok((analysis, Some(not_again(got))));
                }
                self.handle(scan, z, samples, dt)
            }
        };
        let left_out = found
            .as_ref()
            .is_some_and(|t| t.handling == Handling::LeftOut);
        if left_out || dropped.is_some() {
            let gaps = found.as_ref().map_or(Vec::new(), |t| t.gaps.clone());
            let mut an = Analyzer::with_gaps(self.segment, gaps);
            let got = read(&mut |t, v| match v {
                Some(v) => an.push(t, v),
                None => an.push_dropped(t),
            })?;
            if got != samples {
                return Ok((analysis, Some(not_again(got))));
            }
            analysis = an.finish(dt).without(self.missing);
        }
        analysis.transients = found;
        analysis.dropped = dropped;
        Ok((analysis, None))
    }

    /// The samples the first read shows dropped: every long step a whole number m ≥ 2 of Δt
    /// (Δt as given, else the smallest step, then the record's span over its samples with the
    /// missing ones counted), each within [`STEP_TOLERANCE`] of Δt, at most [`MAX_DROPPED`] of
    /// the record missing; None when there are none or the steps are not all of that kind.
    fn drops(&self, an: &Analyzer, dt: f64) -> Option<Dropped> {
        let long = an.long_steps()?;
        if long.is_empty() {
            return None;
        }
        let base = if self.dt_given { dt } else { an.step_min() };
        let ms: Vec<u64> = long
            .iter()
            .map(|&(_, s)| (s / base).round() as u64)
            .collect();
        let missing: u64 = ms.iter().map(|m| m.saturating_sub(1)).sum();
        let n = an.samples();
        let dt = if self.dt_given {
            dt
        } else {
            (an.t_last() - an.t_first()) / (n - 1 + missing) as f64
        };
        let whole = long
            .iter()
            .zip(&ms)
            .all(|(&(_, s), &m)| m >= 2 && (s - m as f64 * dt).abs() <= STEP_TOLERANCE * dt);
        if !whole || missing as f64 > MAX_DROPPED * (n + missing) as f64 {
            return None;
        }
        let mut before = 0;
        let at = long
            .iter()
            .zip(&ms)
            .map(|(&(k, _), &m)| {
                before += m - 1;
                (k, (k + before) as f64 * dt, m - 1)
            })
            .collect();
        Some(Dropped { at, dt })
    }

    /// The second read's scanner and its threshold z: each present channel's bar is z of its
    /// step scale and at least [`transients::MIN_LSBS`] of its lattice's LSB; None when no
    /// channel has a scale (a constant record has no steps to judge).
    fn scanner(&self, a: &Analysis, steps: &StepScale, dt: f64) -> Option<(Scanner, f64)> {
        let present: Vec<usize> = (0..6).filter(|&ch| !self.missing[ch]).collect();
        // The Gaussian point for the record's false-alarm rate over all its steps, never
        // below the bar real units' tails need.
        let z = transients::threshold(steps.samples().saturating_sub(1) * present.len() as u64)
            .max(transients::MIN_Z);
        let mut bar = [f64::INFINITY; 6];
        let mut scale = [0.0; 6];
        for &ch in &present {
            scale[ch] = steps.scale(ch, z);
            let lsb = a.channels[ch].lattice.map_or(0.0, |l| l.lsb);
            if scale[ch] > 0.0 {
                bar[ch] = (z * scale[ch]).max(transients::MIN_LSBS * lsb);
            }
        }
        bar.iter()
            .any(|b| b.is_finite())
            .then(|| (Scanner::new(bar, scale, 2 * self.pad(dt)), z))
    }

    /// [`transients::PAD_S`] in samples.
    fn pad(&self, dt: f64) -> u64 {
        (transients::PAD_S / dt).round() as u64
    }

    /// What is done with the transients the scan found: left out, kept as asked, or kept as
    /// heavy tails past [`transients::MAX_LEFT_OUT`] of the record; None when there are none.
    fn handle(&self, scan: Scanner, z: f64, samples: u64, dt: f64) -> Option<Transients> {
        let list = scan.finish();
        if list.is_empty() {
            return None;
        }
        let pad = self.pad(dt);
        let gaps = transients::gaps(&list, pad, samples);
        let left_out: u64 = gaps.iter().map(|(x, y)| y - x + 1).sum();
        let handling = if self.keep {
            Handling::Kept
        } else if left_out as f64 > transients::MAX_LEFT_OUT * samples as f64 {
            Handling::HeavyTailed
        } else {
            Handling::LeftOut
        };
        Some(Transients {
            list,
            z,
            pad,
            handling,
            gaps: if handling == Handling::LeftOut {
                gaps
            } else {
                Vec::new()
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::NormalStream;

    const DT: f64 = 0.01;

    /// A white record of `n` samples on the grid k·Δt (time tags within ±0.1 % of it).
    fn record(n: usize) -> Vec<(f64, [f64; 6])> {
        let mut g = NormalStream::new(7, "passes");
        (0..n)
            .map(|k| {
                let jitter = 1e-3 * DT * g.draw().clamp(-1.0, 1.0);
                (k as f64 * DT + jitter, std::array::from_fn(|_| g.draw()))
            })
            .collect()
    }

    fn passes(dt_given: bool) -> Passes {
        Passes {
            segment: 1024,
            keep: false,
            missing: [false; 6],
            dt_given,
        }
    }

    /// The analysis of `rows` through the passes, Δt measured or given.
    fn analyse(rows: &[(f64, [f64; 6])], p: Passes) -> (Analysis, Option<String>) {
        let replay = |sink: &mut Sink<'_>| {
            for (t, v) in rows {
                sink(*t, v);
            }
            Ok::<u64, ()>(rows.len() as u64)
        };
        let mut first = First::new(p.segment);
        replay(&mut |t, v| first.push(t, v)).unwrap();
        let dt = if p.dt_given {
            DT
        } else {
            first.analyzer.measured_dt().unwrap()
        };
        p.finish(first, dt, "rows", Ok(replay)).unwrap()
    }

    /// Samples dropped from a record are read as the whole record with those samples left
    /// out: the same Allan deviation and PSD (to rounding: the running sums differ by the
    /// left-out values), the same Δt, and the drops named where they are.
    #[test]
    fn dropped_samples_read_as_the_whole_record_with_them_left_out() {
        let whole = record(1 << 16);
        let gone: Vec<usize> = vec![5000, 20000, 20001, 20002, 41234];
        let kept: Vec<(f64, [f64; 6])> = whole
            .iter()
            .enumerate()
            .filter(|(k, _)| !gone.contains(k))
            .map(|(_, r)| *r)
            .collect();
        for dt_given in [false, true] {
            let (a, warning) = analyse(&kept, passes(dt_given));
            assert_eq!(warning, None);
            let d = a.dropped.as_ref().expect("the drops are found");
            assert_eq!(d.samples(), 5);
            assert_eq!(
                d.at.iter().map(|x| (x.0, x.2)).collect::<Vec<_>>(),
                [(5000, 1), (19999, 3), (41230, 1)]
            );
            // The sample after the three dropped (20003 of the whole record), on the grid: the
            // jitter of the first and last time tags (±10 µs) moves the measured Δt by up to
            // 3e-10 s, and 20003 steps of it by up to 6 µs.
            assert!((d.at[1].1 - 200.03).abs() < 1e-3 * DT, "{}", d.at[1].1);
            // Δt from the span and the samples counted with the missing ones.
            assert!((a.dt - DT).abs() < 1e-7 * DT, "{}", a.dt);
            assert_eq!(a.samples, 1 << 16);
            let mut an =
                Analyzer::with_gaps(1024, gone.iter().map(|&k| (k as u64, k as u64)).collect());
            for (t, v) in &whole {
                an.push(*t, v);
            }
            let b = an.finish(a.dt);
            for ch in 0..6 {
                let (x, y) = (&a.channels[ch], &b.channels[ch]);
                assert_eq!(x.adev.len(), y.adev.len());
                for (p, q) in x.adev.iter().zip(&y.adev) {
                    assert!((p.adev / q.adev - 1.0).abs() < 1e-9, "{ch} τ {}", p.tau);
                    assert_eq!(p.edf, q.edf);
                }
                for (p, q) in x.psd.density.iter().zip(&y.psd.density) {
                    assert!((p / q - 1.0).abs() < 1e-9);
                }
                assert_eq!(x.psd.segments, y.psd.segments);
            }
            // Steps on the grid again: within the time tags' jitter of Δt.
            let (smin, smax) = a.step_range;
            assert!(smin > 0.99 * a.dt && smax < 1.01 * a.dt, "{smin} {smax}");
        }
    }

    /// A record whose long steps are not whole numbers of Δt, or that lost more than 1 %, is
    /// not read as one with drops: its steps stay as they were (and `fit` refuses them).
    #[test]
    fn other_long_steps_are_not_drops() {
        let whole = record(1 << 14);
        // A step of 2.5 Δt: a time tag, not a drop.
        let mut odd = whole.clone();
        for r in odd.iter_mut().skip(3000) {
            r.0 += 1.5 * DT;
        }
        odd.remove(3000);
        let (a, _) = analyse(&odd, passes(false));
        assert!(a.dropped.is_none());
        assert!(a.step_range.1 > 2.4 * DT);
        let every = |n: usize| -> Vec<_> {
            let keep = whole.iter().enumerate().filter(|(k, _)| k % n != n / 2);
            keep.map(|(_, r)| *r).collect()
        };
        // 2 % dropped, one sample in fifty.
        let (a, _) = analyse(&every(50), passes(false));
        assert!(a.dropped.is_none());
        // 0.5 % dropped is read as drops.
        let (a, _) = analyse(&every(200), passes(false));
        assert_eq!(a.dropped.map(|d| d.samples()), Some(82));
    }
}
