//! The reads of a static record that leave its transients out ([`super::transients`]): the
//! first feeds the analyzer and the step scale, the second flags steps beyond the bar, the
//! third (only when something is left out) analyses the record again with the flagged spans
//! skipped. The record is read again through a callback, so a file (the CLI's
//! [`super::recording`]) and rows in memory (the Python package's arrays) go through the same
//! code. Pure: the callbacks do the reading.

use super::analyzer::{Analysis, Analyzer};
use super::transients::{self, Handling, Scanner, StepScale, Transients};

/// How a record's transients are handled.
#[derive(Clone, Copy, Debug)]
pub struct Passes {
    /// Welch segment length (samples).
    pub segment: usize,
    /// Keep transients in the statistics (`--keep-transients`), reporting them.
    pub keep: bool,
    /// Channels not in the input (left out of the analysis and of the search).
    pub missing: [bool; 6],
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

impl Passes {
    /// The record's analysis at interval `dt` from its first read, its transients found in a
    /// second read and, unless kept, left out in a third. `again` reads the record again from
    /// its start into the sink and returns the samples read; `Err(why)` in its place when the
    /// record cannot be read twice (a pipe). The second element is a warning when transients
    /// were not looked for (`label` names the record in it).
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
        let mut analysis = first.analyzer.finish(dt).without(self.missing);
        let mut again = match again {
            Ok(f) => f,
            Err(why) => return Ok((analysis, Some(why))),
        };
        let Some((mut scan, z)) = self.scanner(&analysis, &first.steps) else {
            return Ok((analysis, None));
        };
        let read = again(&mut |_, v| scan.push(v))?;
        if read != analysis.samples {
            let why = format!(
                "{label}: a second read gave {read} samples where the first gave {} (a pipe cannot be read twice): transients (knocks, spikes) were not looked for",
                analysis.samples
            );
            return Ok((analysis, Some(why)));
        }
        let found = self.handle(scan, z, &analysis);
        if let Some(t) = &found
            && t.handling == Handling::LeftOut
        {
            let mut an = Analyzer::with_gaps(self.segment, t.gaps.clone());
            again(&mut |t, v| an.push(t, v))?;
            analysis = an.finish(dt).without(self.missing);
        }
        analysis.transients = found;
        Ok((analysis, None))
    }

    /// The second read's scanner and its threshold z: each present channel's bar is z of its
    /// step scale and at least [`transients::MIN_LSBS`] of its lattice's LSB; None when no
    /// channel has a scale (a constant record has no steps to judge).
    fn scanner(&self, a: &Analysis, steps: &StepScale) -> Option<(Scanner, f64)> {
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
            .then(|| (Scanner::new(bar, scale, 2 * self.pad(a.dt)), z))
    }

    /// [`transients::PAD_S`] in samples.
    fn pad(&self, dt: f64) -> u64 {
        (transients::PAD_S / dt).round() as u64
    }

    /// What is done with the transients the scan found: left out, kept as asked, or kept as
    /// heavy tails past [`transients::MAX_LEFT_OUT`] of the record; None when there are none.
    fn handle(&self, scan: Scanner, z: f64, a: &Analysis) -> Option<Transients> {
        let list = scan.finish();
        if list.is_empty() {
            return None;
        }
        let pad = self.pad(a.dt);
        let gaps = transients::gaps(&list, pad, a.samples);
        let left_out: u64 = gaps.iter().map(|(x, y)| y - x + 1).sum();
        let handling = if self.keep {
            Handling::Kept
        } else if left_out as f64 > transients::MAX_LEFT_OUT * a.samples as f64 {
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
