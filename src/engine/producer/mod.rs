//! Block-wise production: the ideal records of a motion on a grid, an IMU's error chain (or
//! output filter), timing errors or a trigger, and the encodings, one block at a time.

mod step;

use crate::aiding::mag_samples::{FrameMag, MagHold};
use crate::errors::ErrorChain;
use crate::errors::temperature::TemperatureProfile;
use crate::generator::IdealImu;
use crate::motion::Motion;
use crate::output::{self, Format};
use crate::record::Record;
use crate::source::AnyMotion;

use super::{Encoding, EngineError, Grid};

/// Where a unit's error-free records are taken: turns the records of the motion's reference
/// point (body axes) into those at a unit's place and in its axes (a rig unit's mounting and
/// lever arm, `crate::rig::Placement`), for the truth a [`Producer`] keeps.
pub trait TruthPlace: Send {
    /// Whether [`TruthPlace::place`] needs the motion's rotation terms (a lever arm).
    fn needs_rotation_terms(&self) -> bool;
    /// Places `records` in place. Their rates are means over `dt` (their increments are the
    /// rates times `dt`); `rot`, when needed, holds their rotation terms normalised by `dt`
    /// too.
    fn place(
        &self,
        records: &mut [Record],
        rot: Option<&[crate::generator::RotationTerms]>,
        dt: f64,
    );
}

/// Block-wise production: ideal records → error chain → encoding, with each record's
/// encoded bytes delimited. `run` (offline) and the real-time emulator both drive it, so the
/// same seed gives the same bytes whatever consumes them.
pub struct Producer {
    imu: IdealImu<AnyMotion>,
    chain: Option<ErrorChain>,
    encoding: Encoding,
    extra: Vec<Encoding>,
    /// Next record index (1-based: record k covers (t_{k−1}, t_k]).
    k: u64,
    count: u64,
    grid: Grid,
    block: Vec<Record>,
    truth: Vec<Record>,
    keep_truth: bool,
    /// Turns the truth into the readings at a unit's place and in its axes (a rig unit).
    truth_place: Option<Box<dyn TruthPlace>>,
    rot: Vec<crate::generator::RotationTerms>,
    /// The sensor temperature over the run, carried by frames with a temperature field.
    temperature: Option<TemperatureProfile>,
    /// Why production stopped early (a non-finite value), for [`Producer::take_error`].
    error: Option<EngineError>,
    /// The IMU's timing errors, when it has any.
    timing: Option<Box<crate::engine::timed::TimedRun>>,
    /// A unit with an output filter: replaces the generator and chain above for the records
    /// (the output-rate generator still gives the truth).
    filtered: Option<Box<crate::engine::filtered::FilteredImu>>,
    /// The external trigger, when samples are taken at its edges.
    trigger: Option<Box<dyn crate::engine::trigger::TriggerSource>>,
    /// The last triggered sample's time of validity (= emission) after t₀ (s).
    trigger_tov: [f64; 1],
    /// Flags added to every record from now on ([`Producer::mark`]).
    mark: u8,
    /// The magnetometer whose latest sample frames carry, if any.
    mag: Option<Box<MagHold>>,
    /// The field of each record of the block, for the frames.
    mag_block: Vec<FrameMag>,
}

/// One block of production: the corrupted records and, if asked for, the error-free ones.
pub struct Block<'a> {
    /// Index (0-based) of the block's first record in the run.
    pub first: u64,
    /// Records after the error chain.
    pub records: &'a [Record],
    /// Error-free records (empty unless the producer keeps truth).
    pub truth: &'a [Record],
    /// The error chain, for its per-record components.
    pub chain: Option<&'a ErrorChain>,
    /// The error each stage kind injected into each record (empty unless asked for): the
    /// chain's, or those of the output filter's chain through the filter.
    pub components: &'a [crate::errors::chain::Components],
    /// Times of validity and emission of the records, when the IMU has timing errors.
    pub times: Option<crate::timing::Times<'a>>,
    /// The motion the records sense (for the truth's GNSS visibility).
    pub motion: &'a AnyMotion,
}

impl Producer {
    /// A producer of `grid.count` records; `keep_truth` also returns the error-free records.
    pub fn new(
        motion: AnyMotion,
        grid: Grid,
        nodes: usize,
        encoding: impl Into<Encoding>,
        chain: Option<ErrorChain>,
        keep_truth: bool,
    ) -> Result<Producer, EngineError> {
        if !(1..=crate::quadrature::MAX_NODES).contains(&nodes) {
            return Err(EngineError::Setting {
                key: "quadrature",
                value: nodes.to_string(),
                expected: "1 to 16 Gauss–Legendre nodes",
            });
        }
        Ok(Producer::build(
            motion,
            grid,
            nodes,
            encoding.into(),
            chain,
            keep_truth,
        ))
    }

    fn build(
        motion: AnyMotion,
        grid: Grid,
        nodes: usize,
        encoding: Encoding,
        chain: Option<ErrorChain>,
        keep_truth: bool,
    ) -> Producer {
        Producer {
            imu: IdealImu::new(motion, grid.rate_hz, grid.t0, grid.count, nodes),
            grid,
            chain,
            encoding,
            extra: Vec::new(),
            k: 1,
            count: grid.count,
            block: Vec::new(),
            truth: Vec::new(),
            keep_truth,
            truth_place: None,
            rot: Vec::new(),
            temperature: None,
            error: None,
            timing: None,
            filtered: None,
            trigger: None,
            trigger_tov: [0.0],
            mark: 0,
            mag: None,
            mag_block: Vec::new(),
        }
    }

    /// Also records the error each stage injects into each record ([`Block::components`]):
    /// an ideal unit gets an empty chain to count them in.
    pub fn with_components(mut self) -> Producer {
        match self.filtered.take() {
            Some(f) => self.filtered = Some(Box::new(f.with_components())),
            None => {
                let chain = self.chain.take().unwrap_or_else(ErrorChain::ideal);
                self.chain = Some(chain.with_components());
            }
        }
        self
    }

    /// Whether each block also returns the error-free records ([`Block::truth`]).
    pub fn set_keep_truth(&mut self, keep: bool) {
        self.keep_truth = keep;
    }

    /// The format of the side outputs (truth, injected errors): the records' own, or CSV for
    /// frames.
    pub fn side_format(&self) -> Format {
        self.encoding.side()
    }

    /// The header of the truth CSV (with the timing and GNSS-visibility columns this run's
    /// records have).
    pub fn truth_header(&self) -> String {
        output::csv_header_truth(self.is_timed(), self.imu.motion().defined().is_some())
    }

    /// The run's time grid.
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// True when the records come through an output filter at an internal rate.
    pub fn is_filtered(&self) -> bool {
        self.filtered.is_some()
    }

    /// Produces the records of a unit with an output filter (`None`: none): the motion at the
    /// filter's internal rate through `filtered`, instead of the output-rate generator and the
    /// producer's own chain (give it none). The truth stays the exact increments over the
    /// output intervals.
    pub fn with_filter(
        mut self,
        filtered: Option<crate::engine::filtered::FilteredImu>,
    ) -> Producer {
        self.filtered = filtered.map(Box::new);
        self
    }

    /// A record producer for `model` seeded with `seed`: its plain error chain, or its output
    /// filter's chain at the internal rate when it has one.
    pub fn for_model(
        motion: AnyMotion,
        grid: Grid,
        model: &crate::errors::ImuModel,
        seed: u64,
    ) -> Result<Producer, EngineError> {
        if model.output_filter.is_none() {
            let chain = ErrorChain::new(model, grid.rate_hz, seed);
            return Ok(Producer::records(motion, grid, Some(chain)));
        }
        let chain = crate::errors::filtered::FilteredChain::new(model, grid.rate_hz, seed)
            .map_err(EngineError::Filter)?;
        let nodes = crate::generator::DEFAULT_NODES;
        let f = crate::engine::filtered::FilteredImu::new(motion.clone(), grid, nodes, chain)
            .map_err(EngineError::Filter)?;
        Ok(Producer::records(motion, grid, None).with_filter(Some(f)))
    }

    /// Samples at the sensor clock's instants with the IMU's timing errors (`None`: on the
    /// nominal grid): increments over the true intervals, skipped samples folded into the
    /// next, and each record's time of validity and emission time in [`Block::times`].
    pub fn with_timing(mut self, timing: Option<crate::engine::timed::TimedRun>) -> Producer {
        self.timing = timing.map(Box::new);
        self
    }

    /// Samples once per edge of `source` instead of on the clock (an external sample trigger),
    /// each record integrating over the interval since the previous edge; the run ends when
    /// the source does or after the grid's count. Replaces the IMU's own timing errors.
    pub fn with_trigger(
        mut self,
        source: Box<dyn crate::engine::trigger::TriggerSource>,
    ) -> Producer {
        self.set_trigger(source);
        self
    }

    /// [`Producer::with_trigger`] on a producer held in place (before its first record).
    pub fn set_trigger(&mut self, source: Box<dyn crate::engine::trigger::TriggerSource>) {
        self.trigger = Some(source);
        self.timing = None;
    }

    /// Keeps the error-free records ([`Block::truth`]) at the place and in the axes `place`
    /// gives instead of at the motion's reference point in body axes: each block's truth is
    /// placed over the same intervals it was integrated over (the sensor's true intervals
    /// under timing errors, the trigger's), before skipped samples are folded in.
    pub fn with_truth_place(mut self, place: Box<dyn TruthPlace>) -> Producer {
        self.truth_place = Some(place);
        self
    }

    /// How far the motion reaches after t₀ (s): the last instant a trigger edge may close.
    pub fn span_after_t0(&self) -> f64 {
        self.imu.motion().end() - self.imu.time_of(0)
    }

    /// Whether the records carry times of validity and emission (timing errors, a trigger).
    pub fn is_timed(&self) -> bool {
        self.timing.is_some() || self.trigger.is_some()
    }

    /// Frames with magnetic-field fields carry the latest sample of `hold` at each record's
    /// time (`None`: 0).
    pub fn with_magnetometer(mut self, hold: Option<MagHold>) -> Producer {
        self.mag = hold.map(Box::new);
        self
    }

    /// Frames with a temperature field carry `profile` at each record's time (the profile the
    /// error chain's temperature terms follow) instead of the encoding's constant.
    pub fn with_temperature(mut self, profile: Option<TemperatureProfile>) -> Producer {
        self.temperature = profile;
        self
    }

    /// The error that ended production early: the block methods return `None` both at the
    /// end of the run and when a record came out non-finite; this tells them apart.
    pub fn take_error(&mut self) -> Option<EngineError> {
        self.error.take()
    }

    /// After the last block: `Err` if production stopped early on a non-finite value, so a
    /// consumer of [`Producer::next_records`] never takes a short run for a whole one.
    pub fn finished(&mut self) -> Result<(), EngineError> {
        self.take_error().map_or(Ok(()), Err)
    }

    /// Whether a record of the last block is non-finite (before or after the error chain):
    /// nothing non-finite leaves the producer.
    pub(crate) fn check_finite(records: &[Record], stage: &'static str) -> Result<(), EngineError> {
        // x·0 is 0 for every finite x and NaN for ±inf and NaN, so one branch-free sum over
        // the block settles the common case; only a bad block is searched value by value.
        let any_bad: f64 = records
            .iter()
            .map(|r| r.values().iter().map(|x| x * 0.0).sum::<f64>())
            .sum();
        if any_bad == 0.0 {
            return Ok(());
        }
        for r in records {
            let v = r.values();
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(EngineError::NonFinite {
                    t: r.t,
                    quantity: crate::record::COLUMNS[i],
                    value: v[i],
                    stage,
                });
            }
        }
        Ok(())
    }

    /// A producer of records only (no wire encoding), with the default quadrature: for
    /// consumers that use the records themselves (navigation, analysis).
    pub fn records(motion: AnyMotion, grid: Grid, chain: Option<ErrorChain>) -> Producer {
        let nodes = crate::generator::DEFAULT_NODES;
        Producer::build(motion, grid, nodes, Format::Bin.into(), chain, false)
    }

    /// Generates and corrupts the next block of up to `max` records, without encoding them.
    pub fn next_records(&mut self, max: usize) -> Option<Block<'_>> {
        let (first, n) = self.step(max)?;
        Some(self.view(first, n))
    }

    /// Records still to produce.
    pub fn remaining(&self) -> u64 {
        self.count + 1 - self.k
    }

    /// Bytes that precede the first record (the CSV header of a CSV record stream).
    pub fn preamble(&self) -> String {
        if matches!(self.encoding, Encoding::Records(Format::Csv)) {
            output::csv_header()
        } else {
            String::new()
        }
    }

    /// Sets the flags (e.g. [`crate::record::FLAG_STALE`]) that every record of the following
    /// [`Producer::next_block_multi`] blocks carries, on top of its own.
    pub fn mark(&mut self, flags: u8) {
        self.mark = flags;
    }

    /// Also encodes every record with each of `extra` (further wire formats of the same
    /// records, each with its own counter), for [`Producer::next_block_multi`].
    pub fn with_extra_encodings(mut self, extra: Vec<Encoding>) -> Producer {
        self.extra = extra;
        self
    }

    /// Ends production with `e` (kept for [`Producer::take_error`]).
    fn fail(&mut self, e: EngineError) -> Option<(u64, usize)> {
        self.error = Some(e);
        self.k = self.count + 1;
        None
    }

    fn view(&self, first: u64, n: usize) -> Block<'_> {
        Block {
            first,
            records: &self.block[..n],
            truth: &self.truth[..if self.keep_truth { n } else { 0 }],
            chain: self.chain.as_ref(),
            components: match &self.filtered {
                Some(f) => f.components(),
                None => self.chain.as_ref().map_or(&[], |c| c.components()),
            },
            times: match (&self.timing, &self.trigger) {
                (Some(t), _) => Some(t.times()),
                (None, Some(_)) => Some(crate::timing::Times {
                    t0: self.imu.time_of(0),
                    tov: &self.trigger_tov,
                    tov_accel: &self.trigger_tov,
                    emit: &self.trigger_tov,
                    gaps: &[0],
                }),
                (None, None) => None,
            },
            motion: self.imu.motion(),
        }
    }

    /// Produces up to `max` records, appending their encoding to `out` and the end offset
    /// (in `out`) of each record's bytes to `ends`; `None` once the run is complete.
    pub fn next_block(
        &mut self,
        max: usize,
        out: &mut Vec<u8>,
        ends: &mut Vec<usize>,
    ) -> Option<Block<'_>> {
        let (first, n) = self.step(max)?;
        if !self.fill_mag(n) {
            return None;
        }
        let profile = self.temperature.as_ref();
        let gaps = self.timing.as_ref().map_or(&[][..], |t| t.times().gaps);
        let mag = &self.mag_block[..];
        (self.encoding).encode_with_mag(&self.block[..n], gaps, profile, mag, out, ends);
        Some(self.view(first, n))
    }

    /// Like [`Producer::next_block`] for the main encoding (`outs[0]`) and each extra one
    /// (`outs[1..]`): (bytes, frame ends) appended per encoding.
    pub fn next_block_multi(
        &mut self,
        max: usize,
        outs: &mut [(Vec<u8>, Vec<usize>)],
    ) -> Option<Block<'_>> {
        let (first, n) = self.step(max)?;
        for r in &mut self.block[..n] {
            r.flags |= self.mark;
        }
        if !self.fill_mag(n) {
            return None;
        }
        let encodings = std::iter::once(&mut self.encoding).chain(self.extra.iter_mut());
        let gaps = self.timing.as_ref().map_or(&[][..], |t| t.times().gaps);
        let (profile, mag) = (self.temperature.as_ref(), &self.mag_block[..]);
        for (e, (out, ends)) in encodings.zip(outs.iter_mut()) {
            e.encode_with_mag(&self.block[..n], gaps, profile, mag, out, ends);
        }
        Some(self.view(first, n))
    }
}
