//! The timing errors over a run, as the block producer ([`crate::engine::Producer`]) uses them:
//! the sensor's instants of each block, then the skipped samples folded into the next one
//! taken, leaving per kept sample its time of validity, emission time and the number of
//! samples skipped before it (which the frame counter steps over).

use super::timed_merge::{Carry, merge_components, merge_records};
use crate::errors::chain::Components;
use crate::record::Record;
use crate::timing::{SensorTiming, TimedBlock, Times};

/// Per-run state of the timing errors.
#[derive(Clone, Debug)]
pub struct TimedRun {
    sensor: SensorTiming,
    block: TimedBlock,
    rate_hz: f64,
    t0: f64,
    records: Carry<Record>,
    truth: Carry<Record>,
    comps: Carry<Components>,
    gap: u32,
    gaps: Vec<u32>,
    tov: Vec<f64>,
    tov_accel: Vec<f64>,
    emit: Vec<f64>,
    /// How long before its sample instant a record is valid (an output filter's delay, s).
    /// The gyros' and the accelerometers' (they differ when each has its own filter).
    validity_offset: [f64; 2],
}

impl TimedRun {
    /// The run of `sensor` for records at `rate_hz` after `t0`.
    pub fn new(sensor: SensorTiming, rate_hz: f64, t0: f64) -> TimedRun {
        TimedRun {
            sensor,
            block: TimedBlock::default(),
            rate_hz,
            t0,
            records: None,
            truth: None,
            comps: None,
            gap: 0,
            gaps: Vec::new(),
            tov: Vec::new(),
            tov_accel: Vec::new(),
            emit: Vec::new(),
            validity_offset: [0.0; 2],
        }
    }

    /// Records valid `offset` s (gyro, accel) before their sample instants (the delay of the
    /// unit's output filter, [`crate::errors::output_filter::FilterSpec::validity_offset_s`]):
    /// `tov` and `tov_accel` move back by them; the emission times stay, so it adds to the
    /// latency.
    pub fn with_validity_offset(mut self, offset: [f64; 2]) -> TimedRun {
        self.validity_offset = offset;
        self
    }

    /// The sensor's instants of samples `k_first .. k_first + n`.
    pub fn instants(&mut self, k_first: u64, n: usize) -> &TimedBlock {
        self.sensor.fill(k_first, n, &mut self.block);
        &self.block
    }

    /// The instants [`TimedRun::instants`] last filled.
    pub fn block(&self) -> &TimedBlock {
        &self.block
    }

    /// Drops the block's skipped samples from `records`, `truth` (empty when not kept) and
    /// `comps` (the injected errors, if captured), folding them into the next sample taken;
    /// returns the number of records kept, whose times [`TimedRun::times`] then gives.
    pub fn compact(
        &mut self,
        records: &mut [Record],
        truth: &mut [Record],
        comps: Option<&mut Vec<Components>>,
    ) -> usize {
        let b = &self.block;
        let missing = &b.missing[..records.len()];
        let kept = merge_records(records, missing, &mut self.records, self.rate_hz);
        if !truth.is_empty() {
            merge_records(truth, missing, &mut self.truth, self.rate_hz);
        }
        if let Some(c) = comps {
            let n = merge_components(&mut c[..missing.len()], missing, &mut self.comps);
            c.truncate(n);
        }
        self.gaps.clear();
        self.tov.clear();
        self.tov_accel.clear();
        self.emit.clear();
        for (i, &m) in missing.iter().enumerate() {
            if m {
                self.gap += 1;
                continue;
            }
            self.gaps.push(std::mem::take(&mut self.gap));
            self.tov.push(b.tov(i) - self.validity_offset[0]);
            self.tov_accel
                .push(b.tov_accel(i) - self.validity_offset[1]);
            self.emit.push(b.emit[i]);
        }
        kept
    }

    /// The times of the records [`TimedRun::compact`] kept.
    pub fn times(&self) -> Times<'_> {
        Times {
            t0: self.t0,
            tov: &self.tov,
            tov_accel: &self.tov_accel,
            emit: &self.emit,
            gaps: &self.gaps,
        }
    }
}
