//! The signal engine: a motion model, a time grid, an IMU's error chain and an output encoding,
//! run block by block ([`Producer`]): ideal records → error chain → encoded bytes. Every
//! consumer — files, the real-time pacer, the navigator — takes its records from here.

pub mod filtered;
pub mod frames;
pub mod timed;
mod timed_merge;
pub mod trigger;

use std::io::Write;
use std::ops::ControlFlow;
use std::path::PathBuf;

use crate::aiding::mag_samples::{FrameMag, MagHold};
use crate::errors::ErrorChain;
use crate::errors::temperature::TemperatureProfile;
use crate::generator::IdealImu;
use crate::motion::Motion;
use crate::motion::sampled::{ModelError, ModelSettings};
use crate::output::{self, Format};
use crate::record::Record;
use crate::scenes::{self, SceneParamError, SceneParams, UnknownScene};
use crate::source::AnyMotion;
use crate::trajectory::{self, TrajectoryError};

/// Duration of a run on an unbounded scene when none is given (s).
pub const DEFAULT_UNBOUNDED_DURATION_S: f64 = 60.0;

/// The temperature frames carry when the scene gives no temperature profile (°C).
pub const DEFAULT_FRAME_CELSIUS: f64 = 25.0;

/// Records per block: large enough to amortise the writer, small enough to stay in cache.
pub const BLOCK: usize = 4096;

/// Where the trajectory comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum SourceSpec {
    /// A built-in scene with its parameters.
    Scene(String, SceneParams),
    /// A trajectory CSV.
    File(PathBuf),
    /// A motion-definition file (gnss-ins-sim CSV).
    MotionDef(PathBuf),
    /// Trajectory samples held in memory (checked as a trajectory file's rows are), named by
    /// `label` in messages: for callers that have the trajectory as arrays (Python).
    Samples {
        /// What the samples are, for messages (`trajectory arrays`).
        label: PathBuf,
        /// The samples, in time order.
        samples: std::sync::Arc<Vec<crate::motion::sampled::Sample>>,
    },
}

/// Everything the engine can refuse, each naming what to fix.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// Bad trajectory file.
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    /// Unknown scene.
    #[error(transparent)]
    UnknownScene(#[from] UnknownScene),
    /// Bad scene parameter.
    #[error(transparent)]
    SceneParam(#[from] SceneParamError),
    /// The model cannot be built from the file (the cause is the error's `source()`).
    #[error("{path}: cannot model the trajectory")]
    Model {
        /// File.
        path: PathBuf,
        /// Cause.
        source: ModelError,
    },
    /// The requested time span is not inside the trajectory.
    #[error(
        "requested IMU span [{}, {}] s is outside the trajectory [{}, {}] s",
        crate::csvio::num(*.from), crate::csvio::num(*.to),
        crate::csvio::num(*.start), crate::csvio::num(*.end)
    )]
    Span {
        /// Requested start.
        from: f64,
        /// Requested end.
        to: f64,
        /// Trajectory start.
        start: f64,
        /// Trajectory end.
        end: f64,
    },
    /// A setting outside its range.
    #[error("`{key}` = {value}: {expected}")]
    Setting {
        /// Setting name.
        key: &'static str,
        /// Value given.
        value: String,
        /// What is expected.
        expected: &'static str,
    },
    /// Time tags too coarse for the record interval (see [`TIME_RESOLUTION`]).
    #[error(
        "times up to {} s are held to {} s, more than 1/{} of the record interval {} s: \
         successive time tags t₀ + k/rate would not be Δt apart (give an earlier --start, \
         e.g. the time since the run began, or a lower --rate)",
        crate::csvio::num(*t), crate::csvio::num(*ulp), 1.0 / TIME_RESOLUTION, crate::csvio::num(*dt)
    )]
    TimeResolution {
        /// Largest |time| of the run (s).
        t: f64,
        /// Spacing of f64 values there (s).
        ulp: f64,
        /// Record interval (s).
        dt: f64,
    },
    /// A record, its error-free counterpart or a side output came out non-finite: stopped
    /// rather than written.
    #[error("record at t = {t} s: {quantity} is {value} {stage}")]
    NonFinite {
        /// Record time (s).
        t: f64,
        /// Column of the record contract (`gyro_x`, `dv_z`, …).
        quantity: &'static str,
        /// The value (NaN or ±inf).
        value: f64,
        /// Where it appeared: in the error-free signal or after the error chain.
        stage: &'static str,
    },
    /// The template's output filter cannot run at this output rate, or is asked for something
    /// it does not provide.
    #[error("output filter: {0}")]
    Filter(String),
    /// The caller asked to stop (an interrupted run).
    #[error("stopped before the end of the run")]
    Stopped,
    /// An external trigger edge that cannot close a sample interval.
    #[error("{0}")]
    Trigger(String),
    /// An aiding sensor cannot give a sample (outside its field table, not finite).
    #[error(transparent)]
    Sensor(#[from] crate::aiding::SampleError),
    /// A magnetometer sample for the frames cannot be taken (outside its field table).
    #[error(transparent)]
    Magnetometer(#[from] crate::aiding::mag_samples::MagError),
    /// The caller gave a number of outputs other than the run writes.
    #[error("{given} outputs given for a run that writes {need}")]
    Outputs {
        /// Outputs given.
        given: usize,
        /// Outputs the run writes.
        need: usize,
    },
    /// Writing failed (the cause is the error's `source()`, not repeated here).
    #[error("writing output")]
    Io(#[from] std::io::Error),
}

/// Builds the motion model of a source.
pub fn build_motion(source: &SourceSpec, model: ModelSettings) -> Result<AnyMotion, EngineError> {
    match source {
        SourceSpec::Scene(name, params) => Ok(AnyMotion::Scene(scenes::build(name, params)??)),
        SourceSpec::File(path) => Ok(AnyMotion::Sampled(trajectory::open_motion(path, model)?)),
        SourceSpec::MotionDef(path) => Ok(AnyMotion::Defined(crate::motiondef::open(path)?)),
        SourceSpec::Samples { label, samples } => {
            let m =
                crate::motion::sampled::SampledMotion::new(samples, model).map_err(|source| {
                    EngineError::Model {
                        path: label.clone(),
                        source,
                    }
                })?;
            Ok(AnyMotion::Sampled(m))
        }
    }
}

/// The time grid of a run: t₀ and the number of records.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// t₀ (s); record k is at t₀ + k/rate.
    pub t0: f64,
    /// IMU rate (Hz).
    pub rate_hz: f64,
    /// Number of records.
    pub count: u64,
}

/// Checks a requested span against the motion and returns the grid.
pub fn plan(
    motion: &impl Motion,
    rate_hz: f64,
    start: Option<f64>,
    duration: Option<f64>,
) -> Result<Grid, EngineError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= 1.0e7) {
        return Err(EngineError::Setting {
            key: "rate",
            value: rate_hz.to_string(),
            expected: "a rate in (0, 1e7] Hz",
        });
    }
    let (m0, m1) = (motion.start(), motion.end());
    let t0 = start.unwrap_or(m0);
    if !t0.is_finite() {
        return Err(EngineError::Setting {
            key: "start",
            value: t0.to_string(),
            expected: "a finite time",
        });
    }
    let duration = match duration {
        Some(d) if d.is_finite() && d > 0.0 => d,
        Some(d) => {
            return Err(EngineError::Setting {
                key: "duration",
                value: d.to_string(),
                expected: "a positive duration in seconds",
            });
        }
        None if m1.is_finite() => m1 - t0,
        None => DEFAULT_UNBOUNDED_DURATION_S,
    };
    // Rounding slack: a span that ends within 1e-9 s of the last sample is still inside.
    let count = (duration * rate_hz + 1e-9).floor();
    let t_last = t0 + count / rate_hz;
    let slack = 1e-9 * m1.abs().max(1.0);
    if t0 < m0 - slack || t_last > m1 + slack || count < 1.0 {
        return Err(EngineError::Span {
            from: t0,
            to: t0 + duration,
            start: m0,
            end: m1,
        });
    }
    check_time_resolution(t0.abs().max(t_last.abs()), 1.0 / rate_hz)?;
    Ok(Grid {
        t0,
        rate_hz,
        count: count as u64,
    })
}

/// Number of records k ≥ 1 of `grid` with t_k = t₀ + k/rate at or before `t` (times computed
/// as the generator computes them, so the last released interval never passes `t`).
pub fn released(grid: &Grid, t: f64) -> u64 {
    let time = |k: u64| grid.t0 + k as f64 / grid.rate_hz;
    if t.is_nan() || t < grid.t0 {
        return 0;
    }
    // Past 2⁵³ records the time of record k no longer moves with k: every record is in.
    const HUGE: f64 = 9.0e15;
    let guess = ((t - grid.t0) * grid.rate_hz).floor();
    if guess >= HUGE {
        return HUGE as u64;
    }
    let mut k = guess as u64;
    while time(k + 1) <= t {
        k += 1;
    }
    while k > 0 && time(k) > t {
        k -= 1;
    }
    k
}

/// Largest spacing of representable times near a run's times, as a fraction of the record
/// interval. A time tag t₀ + k/rate is rounded to the nearest f64, off by up to half that
/// spacing, so successive tags differ from Δt by up to one spacing: at 1/1000 of Δt the tags
/// keep Δt to 0.1 % (t₀ = 1.4e9 s, a Unix time, allows rates up to about 4 kHz).
pub const TIME_RESOLUTION: f64 = 1.0e-3;

/// Refuses a run whose largest |time| `t` is held more coarsely than [`TIME_RESOLUTION`]·`dt`.
fn check_time_resolution(t: f64, dt: f64) -> Result<(), EngineError> {
    // Spacing of f64 values at t: the next representable value above |t|, minus |t|.
    let ulp = f64::from_bits(t.to_bits() + 1) - t;
    if ulp > TIME_RESOLUTION * dt {
        return Err(EngineError::TimeResolution { t, ulp, dt });
    }
    Ok(())
}

/// What the main output carries.
#[derive(Clone, Debug)]
pub enum Encoding {
    /// The record contract: CSV or binary.
    Records(Format),
    /// A protocol's frames, one per record; side files (truth, injected errors) use `side`.
    Frames {
        /// The compiled frame.
        plan: Box<crate::protocol::Plan>,
        /// Counter and GPS time reference.
        state: crate::protocol::EncoderState,
        /// The sensor temperature carried by frames that have one (°C).
        temperature: f64,
        /// Format of the side files.
        side: Format,
    },
}

impl From<Format> for Encoding {
    fn from(f: Format) -> Encoding {
        Encoding::Records(f)
    }
}

impl Encoding {
    /// Format of the side files (truth, injected errors).
    fn side(&self) -> Format {
        match self {
            Encoding::Records(f) => *f,
            Encoding::Frames { side, .. } => *side,
        }
    }

    /// Appends the main output's bytes for `records`, and the end offset of each record's
    /// bytes in `buf` to `ends`; `profile` gives frames their temperature field.
    /// `gaps`: samples skipped before each record (empty: none), which a frame counter
    /// steps over.
    pub fn encode(
        &mut self,
        records: &[Record],
        gaps: &[u32],
        profile: Option<&TemperatureProfile>,
        buf: &mut Vec<u8>,
        ends: &mut Vec<usize>,
    ) {
        self.encode_with_mag(records, gaps, profile, &[], buf, ends);
    }

    /// [`Encoding::encode`] with the magnetic field the frame of record i carries in `mag[i]`
    /// (empty: 0, no magnetometer).
    pub fn encode_with_mag(
        &mut self,
        records: &[Record],
        gaps: &[u32],
        profile: Option<&TemperatureProfile>,
        mag: &[FrameMag],
        buf: &mut Vec<u8>,
        ends: &mut Vec<usize>,
    ) {
        match self {
            Encoding::Records(f) => {
                // One call per block (as fast as before records had ends); each record is one
                // CSV line or 104 bytes, so the ends are found afterwards.
                let start = buf.len();
                output::encode(*f, records, buf);
                match f {
                    Format::Bin => ends.extend((1..=records.len()).map(|i| start + 104 * i)),
                    Format::Csv => ends.extend(
                        (buf[start..].iter().enumerate())
                            .filter(|b| *b.1 == b'\n')
                            .map(|(i, _)| start + i + 1),
                    ),
                }
            }
            Encoding::Frames {
                plan,
                state,
                temperature,
                ..
            } => {
                for (i, r) in records.iter().enumerate() {
                    state.frames += gaps.get(i).copied().unwrap_or(0) as u64;
                    // The sensor temperature the error chain used for this record.
                    let celsius = profile.map_or(*temperature, |p| p.at(r.t));
                    if let Some(m) = mag.get(i) {
                        (state.mag, state.mag_fresh) = (m.field, m.fresh);
                    }
                    plan.encode(r, celsius, state, buf);
                    ends.push(buf.len());
                }
            }
        }
    }
}

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

    /// The field each of the block's first `n` records' frames carry; `false` (production
    /// ended with the error) when a sample cannot be taken.
    fn fill_mag(&mut self, n: usize) -> bool {
        self.mag_block.clear();
        let Some(hold) = self.mag.as_mut() else {
            return true;
        };
        let motion = self.imu.motion();
        let mut error = None;
        for r in &self.block[..n] {
            match hold.at(r.t, motion) {
                Ok(m) => self.mag_block.push(m),
                Err(e) => {
                    error = Some(e);
                    break;
                }
            }
        }
        error.map(|e| self.fail(e.into())).is_none()
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

    /// Generates and corrupts the next block of up to `max` records: (first index, count).
    fn step(&mut self, max: usize) -> Option<(u64, usize)> {
        if self.k > self.count || max == 0 {
            return None;
        }
        if self.trigger.is_some() {
            return self.step_triggered();
        }
        let n = ((self.count - self.k + 1) as usize).min(max);
        if self.block.len() < n {
            self.block.resize(n, Record::default());
        }
        let first = self.k - 1;
        if self.filtered.is_some() {
            return self.step_filtered(first, n);
        }
        match self.timing.as_mut() {
            Some(t) => {
                let timed = t.instants(self.k, n);
                self.imu
                    .fill_timed(self.k, (&timed.gyro, &timed.accel), &mut self.block[..n]);
            }
            None => self.imu.fill(self.k, &mut self.block[..n]),
        }
        if let Err(e) = Producer::check_finite(&self.block[..n], "in the error-free signal") {
            return self.fail(e);
        }
        let chain_rot = self
            .chain
            .as_ref()
            .is_some_and(|c| c.needs_rotation_terms());
        let place_rot = self.places_with_rotation();
        if chain_rot || place_rot {
            if self.rot.len() < n {
                self.rot.resize(n, Default::default());
            }
            // Under timing errors the accelerometers integrate over their true
            // intervals, and so do the lever-arm terms.
            match self.timing.as_ref() {
                Some(t) => self
                    .imu
                    .rotation_terms_timed(&t.block().accel, &mut self.rot[..n]),
                None => self.imu.rotation_terms(self.k, &mut self.rot[..n]),
            }
        }
        if self.keep_truth {
            self.truth.clear();
            self.truth.extend_from_slice(&self.block[..n]);
            // Rates over the nominal Δt, as the records' (timed records too).
            let (rot, dt) = (std::mem::take(&mut self.rot), 1.0 / self.grid.rate_hz);
            self.place_truth(place_rot.then(|| &rot[..n]), dt);
            self.rot = rot;
        }
        if let Some(c) = self.chain.as_mut() {
            if chain_rot {
                c.apply_with(&mut self.block[..n], Some(&self.rot[..n]));
            } else {
                c.apply(&mut self.block[..n]);
            }
            if let Err(e) = Producer::check_finite(&self.block[..n], "after the error chain") {
                return self.fail(e);
            }
        }
        self.k += n as u64;
        let n = match self.timing.as_mut() {
            Some(t) => {
                let comps = (self.chain.as_mut())
                    .filter(|c| !c.components().is_empty())
                    .map(|c| c.components_mut());
                let truth = if self.keep_truth {
                    &mut self.truth[..]
                } else {
                    &mut [][..]
                };
                let kept = t.compact(&mut self.block[..n], truth, comps);
                self.truth.truncate(kept);
                kept
            }
            None => n,
        };
        Some((first, n))
    }

    /// Whether the kept truth is placed ([`Producer::with_truth_place`]) with the motion's
    /// rotation terms (a lever arm).
    fn places_with_rotation(&self) -> bool {
        self.keep_truth && (self.truth_place.as_ref()).is_some_and(|p| p.needs_rotation_terms())
    }

    /// Turns the kept truth into the readings at the unit's place and in its axes, if it has
    /// one; `rot`: the truth records' rotation terms, normalised by `dt` as their rates are.
    fn place_truth(&mut self, rot: Option<&[crate::generator::RotationTerms]>, dt: f64) {
        if let Some(p) = self.truth_place.as_ref() {
            p.place(&mut self.truth, rot, dt);
        }
    }

    /// [`Producer::step`] for a unit with an output filter: the records from the internal-rate
    /// run, the truth from the output-rate generator, the times (if any) from the timing run.
    fn step_filtered(&mut self, first: u64, n: usize) -> Option<(u64, usize)> {
        let f = self.filtered.as_mut()?;
        f.fill(self.k, &mut self.block[..n]);
        if let Err(e) = Producer::check_finite(&self.block[..n], "after the output filter") {
            return self.fail(e);
        }
        if self.keep_truth {
            self.truth.clear();
            self.truth.resize(n, Record::default());
            self.imu.fill(self.k, &mut self.truth);
            if let Err(e) = Producer::check_finite(&self.truth, "in the error-free signal") {
                return self.fail(e);
            }
            let place_rot = self.places_with_rotation();
            if place_rot {
                self.rot.resize(n.max(self.rot.len()), Default::default());
                self.imu.rotation_terms(self.k, &mut self.rot[..n]);
            }
            let (rot, dt) = (std::mem::take(&mut self.rot), 1.0 / self.grid.rate_hz);
            self.place_truth(place_rot.then(|| &rot[..n]), dt);
            self.rot = rot;
        }
        if let Some(t) = self.timing.as_mut() {
            // Nominal instants (the builder allows no clock errors with a filter): only the
            // times are taken, and no sample is skipped.
            t.instants(self.k, n);
            t.compact(&mut self.block[..n], &mut self.truth[..], None);
        }
        self.k += n as u64;
        Some((first, n))
    }

    /// One record over the interval the trigger's next edge closes.
    fn step_triggered(&mut self) -> Option<(u64, usize)> {
        let (lo, hi) = match self.trigger.as_mut()?.next_interval()? {
            Ok(iv) => iv,
            Err(e) => return self.fail(EngineError::Trigger(e)),
        };
        let bounds = [lo, hi];
        let span = hi - lo;
        if self.block.is_empty() {
            self.block.push(Record::default());
        }
        self.imu.fill_between(&bounds, &mut self.block[..1]);
        if let Err(e) = Producer::check_finite(&self.block[..1], "in the error-free signal") {
            return self.fail(e);
        }
        let chain_rot = match (&self.filtered, &self.chain) {
            (Some(f), _) => f.needs_rotation_terms(),
            (None, Some(c)) => c.needs_rotation_terms(),
            (None, None) => false,
        };
        let place_rot = self.places_with_rotation();
        if chain_rot || place_rot {
            self.rot.resize(1.max(self.rot.len()), Default::default());
            self.imu.rotation_terms_timed(&bounds, &mut self.rot[..1]);
            // The generator averages ω ωᵀ over the nominal Δt; the record's rates are means
            // over its own interval, and so must the lever-arm terms be.
            self.rot[0].omega_outer *= 1.0 / (self.grid.rate_hz * span);
        }
        if self.keep_truth {
            self.truth.clear();
            self.truth.push(self.block[0]);
            let rot = std::mem::take(&mut self.rot);
            self.place_truth(place_rot.then(|| &rot[..1]), span);
            self.rot = rot;
        }
        let rot = chain_rot.then(|| &self.rot[..1]);
        if let Some(f) = self.filtered.as_mut() {
            // KVH's 1775 IMU technical manual (§8.26): under external sync (MSYNC) the unit switches
            // its output filter to a uniform averager over the interval between the sync
            // edges. The mean of the internal samples over (previous edge, this edge] is the
            // interval mean of the signal (the generator's exact integral over the interval
            // divided by its length), and the errors the unit adds to those samples average
            // over the same interval: the internal-rate chain acts over it (white noise of
            // density N gives σ = N/√T), then the output LSB and range.
            f.apply_over(&mut self.block[..1], rot, span);
            if let Err(e) = Producer::check_finite(&self.block[..1], "after the error chain") {
                return self.fail(e);
            }
        } else if let Some(c) = self.chain.as_mut() {
            // The errors act over the interval since the previous edge, not the nominal step.
            c.apply_over(&mut self.block[..1], rot, span);
            if let Err(e) = Producer::check_finite(&self.block[..1], "after the error chain") {
                return self.fail(e);
            }
        }
        self.trigger_tov = [hi];
        self.k += 1;
        Some((self.k - 2, 1))
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

/// Runs the job into `out`, calling `progress(records_done)` after each block.
///
/// With an error `chain`, records are corrupted after generation; `truth`, if given, receives
/// the error-free records in the same format and on the same time grid, and `injected` the
/// error each stage added to each record (`output::components_header`).
#[allow(clippy::too_many_arguments)] // the run's inputs, each distinct; a struct would only rename them
pub fn run(
    motion: AnyMotion,
    grid: Grid,
    nodes: usize,
    encoding: impl Into<Encoding>,
    chain: Option<ErrorChain>,
    out: &mut impl Write,
    truth: Option<&mut dyn Write>,
    injected: Option<&mut dyn Write>,
    mut progress: impl FnMut(u64),
) -> Result<(), EngineError> {
    let producer = Producer::new(motion, grid, nodes, encoding, chain, false)?;
    drain(producer, out, truth, injected, |k| {
        progress(k);
        ControlFlow::Continue(())
    })
}

/// Writes the whole run of a producer that has not started into `out` (and the side
/// outputs, as [`run`] does). After each block `progress(records_done)` may stop the run
/// early with `ControlFlow::Break`, which returns [`EngineError::Stopped`]; a non-finite record
/// stops it with [`EngineError::NonFinite`] before anything of its block is written.
pub fn drain(
    mut producer: Producer,
    out: &mut impl Write,
    mut truth: Option<&mut dyn Write>,
    mut injected: Option<&mut dyn Write>,
    mut progress: impl FnMut(u64) -> ControlFlow<()>,
) -> Result<(), EngineError> {
    let format = producer.encoding.side();
    if format == Format::Csv {
        if let Some(t) = truth.as_mut() {
            let gnss = producer.imu.motion().defined().is_some();
            let header = output::csv_header_truth(producer.is_timed(), gnss);
            t.write_all(header.as_bytes())?;
        }
        if let Some(t) = injected.as_mut() {
            t.write_all(output::components_header().as_bytes())?;
        }
    }
    if injected.is_some() {
        producer = producer.with_components();
    }
    producer.set_keep_truth(truth.is_some());
    out.write_all(producer.preamble().as_bytes())?;
    let mut buf = Vec::with_capacity(BLOCK * 104);
    let mut side = Vec::new();
    let mut ends = Vec::with_capacity(BLOCK);
    loop {
        buf.clear();
        ends.clear();
        let Some(b) = producer.next_block(BLOCK, &mut buf, &mut ends) else {
            break;
        };
        if let Some(t) = truth.as_mut() {
            side.clear();
            let gnss = b.motion.defined().map(|m| move |t| m.gnss_visible(t));
            let gnss = gnss.as_ref().map(|g| g as &dyn Fn(f64) -> bool);
            output::encode_truth(format, b.truth, b.times.as_ref(), gnss, &mut side);
            t.write_all(&side)?;
        }
        if let Some(w) = injected.as_mut() {
            side.clear();
            output::encode_components(format, b.records, b.components, &mut side);
            w.write_all(&side)?;
        }
        let done = b.first + b.records.len() as u64;
        out.write_all(&buf)?;
        if progress(done).is_break() {
            return Err(EngineError::Stopped);
        }
    }
    if let Some(e) = producer.take_error() {
        return Err(e);
    }
    out.flush()?;
    if let Some(t) = truth.as_mut() {
        t.flush()?;
    }
    if let Some(t) = injected.as_mut() {
        t.flush()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::SceneParams;

    /// Record ends delimit exactly one record each, in every encoding, and the blocks'
    /// bytes put together are the whole run's.
    #[test]
    fn producer_ends_delimit_records() {
        let source = SourceSpec::Scene("circle".into(), SceneParams::defaults_for("circle"));
        let (_, plan) = crate::protocol::load("kvh1750").unwrap();
        let frames = Encoding::Frames {
            plan: Box::new(plan.clone()),
            state: Default::default(),
            temperature: 25.0,
            side: Format::Csv,
        };
        for (encoding, len) in [
            (Encoding::Records(Format::Bin), Some(104)),
            (Encoding::Records(Format::Csv), None),
            (frames, Some(plan.len())),
        ] {
            let motion = build_motion(&source, ModelSettings::default()).unwrap();
            let grid = plan_grid(&motion);
            let mut whole = Vec::new();
            let m2 = build_motion(&source, ModelSettings::default()).unwrap();
            let e2 = encoding.clone();
            run(m2, grid, 3, e2, None, &mut whole, None, None, |_| {}).unwrap();
            let mut p = Producer::new(motion, grid, 3, encoding, None, false).unwrap();
            let preamble = p.preamble();
            let (mut all, mut n) = (Vec::new(), 0);
            loop {
                let (mut buf, mut ends) = (Vec::new(), Vec::new());
                let Some(b) = p.next_block(7, &mut buf, &mut ends) else {
                    break;
                };
                assert_eq!(ends.len(), b.records.len());
                assert_eq!(*ends.last().unwrap(), buf.len());
                let mut start = 0;
                for &e in &ends {
                    match len {
                        Some(l) => assert_eq!(e - start, l),
                        None => {
                            assert_eq!(buf[start..e].iter().filter(|&&c| c == b'\n').count(), 1)
                        }
                    }
                    start = e;
                }
                n += ends.len();
                all.extend(buf);
            }
            assert_eq!(n, 50);
            assert_eq!([preamble.as_bytes(), &all].concat(), whole);
        }
    }

    /// `--start 1.4e9 --rate 1e7` (issue: 4 195 distinct tags in 10 000 records) is refused
    /// naming the spacing; the same start at 1 kHz, and 1e7 Hz near t = 0, are accepted.
    #[test]
    fn unresolvable_time_tags_are_refused() {
        let motion = build_motion(
            &SourceSpec::Scene("static".into(), SceneParams::defaults_for("static")),
            ModelSettings::default(),
        )
        .unwrap();
        let e = plan(&motion, 1e7, Some(1.4e9), Some(1e-3)).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("held to 2.384185791015625e-7 s") && m.contains("1e-7 s"),
            "{m}"
        );
        let g = plan(&motion, 1e3, Some(1.4e9), Some(1.0)).unwrap();
        // Accepted runs have Δt-spaced tags to 0.1 %.
        let tags: Vec<f64> = (0..=g.count).map(|k| g.t0 + k as f64 / g.rate_hz).collect();
        assert!(
            tags.windows(2)
                .all(|w| ((w[1] - w[0]) * 1e3 - 1.0).abs() <= 1e-3)
        );
        assert!(plan(&motion, 1e7, Some(0.0), Some(1e-3)).is_ok());
        // At 4.4 kHz the 2.4e-7 s spacing is just over 1/1000 of Δt = 2.27e-4 s.
        assert!(plan(&motion, 4.4e3, Some(1.4e9), Some(1.0)).is_err());
    }

    /// A record that comes out NaN (a temperature table that turns NaN after 0.25 s, through
    /// a bias temperature coefficient) ends production at that record's block: the blocks
    /// before it are whole, nothing of its block is encoded, and the error names its time,
    /// quantity and stage.
    #[test]
    fn producer_stops_at_a_non_finite_record() {
        let model = crate::errors::template::parse(
            "name = \"warm\"\ntemperature_ref = \"25 degC\"\n[accel]\nbias_temperature = [\"0.1 mg/degC\"]\n",
            std::path::Path::new("warm.toml"),
        )
        .unwrap();
        let profile = TemperatureProfile::Table(vec![(0.0, 25.0), (0.25, 25.0), (0.35, f64::NAN)]);
        let chain = ErrorChain::new(&model, 10.0, 1).with_temperature(profile, &model);
        let source = SourceSpec::Scene("static".into(), SceneParams::defaults_for("static"));
        let motion = build_motion(&source, ModelSettings::default()).unwrap();
        let grid = plan_grid(&motion);
        let mut p = Producer::new(motion, grid, 3, Format::Csv, Some(chain), false).unwrap();
        let (mut buf, mut ends) = (Vec::new(), Vec::new());
        assert_eq!(
            p.next_block(2, &mut buf, &mut ends).unwrap().records.len(),
            2
        );
        let written = buf.len();
        assert!(p.next_block(2, &mut buf, &mut ends).is_none());
        assert_eq!(buf.len(), written);
        match p.take_error() {
            Some(EngineError::NonFinite {
                t, quantity, stage, ..
            }) => {
                assert!((t - 0.3).abs() < 1e-12, "t = {t}");
                // Only the accelerometers have a temperature stage (none is built for a triad
                // without coefficients), so the first non-finite column is accel_x.
                assert_eq!((quantity, stage), ("accel_x", "after the error chain"));
            }
            other => panic!("expected a non-finite record, got {other:?}"),
        }
        assert!(p.next_block(2, &mut buf, &mut ends).is_none());
    }

    #[test]
    fn released_counts_records_at_or_before() {
        let g = Grid {
            t0: 0.08,
            rate_hz: 400.0,
            count: 1000,
        };
        assert_eq!(released(&g, 0.05), 0);
        assert_eq!(released(&g, 0.08), 0);
        assert_eq!(released(&g, 0.09), 4);
        assert_eq!(released(&g, 0.0925), 5);
        for k in 1..900u64 {
            let t = g.t0 + k as f64 / g.rate_hz;
            assert_eq!(released(&g, t), k, "at t_{k} itself");
        }
    }

    fn plan_grid(motion: &AnyMotion) -> Grid {
        plan(motion, 10.0, None, Some(5.0)).unwrap()
    }
}
