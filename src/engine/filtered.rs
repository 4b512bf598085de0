//! A unit with an output filter, as a run produces it: the motion's exact increments over the
//! unit's internal intervals (the same generator as every run, at the internal rate), the
//! error chain at that rate, the filter and the decimation to the output rate
//! ([`crate::errors::filtered::FilteredChain`]). [`crate::engine::Producer`] drives it in place
//! of the output-rate generator and chain.

use crate::engine::Grid;
use crate::errors::filtered::FilteredChain;
use crate::generator::{IdealImu, RotationTerms};
use crate::record::Record;
use crate::source::AnyMotion;
use crate::timing::ReadRatio;

/// The internal-rate generator and the filtered chain of one run.
pub struct FilteredImu {
    imu: IdealImu<AnyMotion>,
    chain: FilteredChain,
    read: ReadRatio,
    grid: Grid,
    internal: Vec<Record>,
    rot: Vec<RotationTerms>,
    out: Vec<Record>,
}

impl FilteredImu {
    /// The run of `chain` over the output grid `grid`, the motion integrated with `nodes`
    /// Gauss–Legendre nodes per internal interval. Refuses an internal rate the output rate
    /// cannot read ([`crate::errors::output_filter::FilterSpec::check`]).
    pub fn new(
        motion: AnyMotion,
        grid: Grid,
        nodes: usize,
        chain: FilteredChain,
    ) -> Result<FilteredImu, String> {
        let read = chain.spec().check(grid.rate_hz)?;
        let rate = chain.spec().internal_rate_hz;
        Ok(FilteredImu {
            imu: IdealImu::new(motion, rate, grid.t0, read.index(grid.count), nodes),
            chain,
            read,
            grid,
            internal: Vec::new(),
            rot: Vec::new(),
            out: Vec::new(),
        })
    }

    /// The filtered chain (its spec and latency).
    pub fn chain(&self) -> &FilteredChain {
        &self.chain
    }

    /// Also records the error each stage kind injected into each output record
    /// ([`FilteredImu::components`]); before the first fill.
    pub fn with_components(mut self) -> FilteredImu {
        self.chain = self.chain.with_components();
        self
    }

    /// The injected errors of the records of the last fill (empty unless asked for).
    pub fn components(&self) -> &[crate::errors::chain::Components] {
        self.chain.components()
    }

    /// The injected errors of the last fill, to fold skipped samples into (`None` unless
    /// asked for).
    pub fn components_mut(&mut self) -> Option<&mut Vec<crate::errors::chain::Components>> {
        self.chain.components_mut()
    }

    /// Whether the internal-rate chain needs the motion's rotation terms (a lever arm).
    pub fn needs_rotation_terms(&self) -> bool {
        self.chain.needs_rotation_terms()
    }

    /// Corrupts `records`, each the exact interval mean over an externally triggered interval
    /// of `dt` s, as the unit's filter does under external sync: a uniform average over the
    /// interval (see [`FilteredChain::apply_over`]); `rotation`: their rotation terms.
    pub fn apply_over(
        &mut self,
        records: &mut [Record],
        rotation: Option<&[RotationTerms]>,
        dt: f64,
    ) {
        self.chain.apply_over(records, rotation, dt);
    }

    /// Fills `out` with output records k_first, k_first + 1, … (k ≥ 1): record k is the
    /// filtered internal record it reads ([`ReadRatio`]: the one ending its output interval,
    /// or under a polled read the newest complete one); its time tag is t₀ + k/rate (from the
    /// integer k, as every run's).
    pub fn fill(&mut self, k_first: u64, out: &mut [Record]) {
        self.fill_with(k_first, None, out);
    }

    /// [`FilteredImu::fill`] under sampling-clock timing errors: the internal records
    /// integrate over the sensor's true internal intervals, `internal` (gyro and accelerometer
    /// bounds, [`crate::timing::TimedBlock::internal`], one more than the internal records
    /// the outputs read, n_{k_last} − n_{k_first − 1}).
    pub fn fill_timed(&mut self, k_first: u64, internal: (&[f64], &[f64]), out: &mut [Record]) {
        self.fill_with(k_first, Some(internal), out);
    }

    fn fill_with(&mut self, k_first: u64, timed: Option<(&[f64], &[f64])>, out: &mut [Record]) {
        let j_first = self.read.index(k_first - 1) + 1;
        let n_in = (self.read.index(k_first - 1 + out.len() as u64) + 1 - j_first) as usize;
        self.internal.resize(n_in, Record::default());
        match timed {
            Some(bounds) => self.imu.fill_timed(j_first, bounds, &mut self.internal),
            None => self.imu.fill(j_first, &mut self.internal),
        }
        let rotation = if self.chain.needs_rotation_terms() {
            self.rot.resize(n_in, RotationTerms::default());
            // The accelerometers' lever-arm terms over their own true intervals.
            match timed {
                Some((_, accel)) => self.imu.rotation_terms_timed(accel, &mut self.rot),
                None => self.imu.rotation_terms(j_first, &mut self.rot),
            }
            Some(&self.rot[..])
        } else {
            None
        };
        self.out.clear();
        self.chain
            .apply_with(&self.internal, rotation, &mut self.out);
        debug_assert_eq!(self.out.len(), out.len());
        for (i, (o, r)) in out.iter_mut().zip(&self.out).enumerate() {
            *o = Record {
                t: self.grid.t0 + (k_first + i as u64) as f64 / self.grid.rate_hz,
                ..*r
            };
        }
    }
}
