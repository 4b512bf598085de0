//! A whole simulation in one value: the source (built-in scene or trajectory file), the time
//! grid, the error chain with the scene's temperature, mounting, lever arm and vibration, and
//! the output encoding (records or a protocol's frames), assembled by [`SimulationBuilder`]
//! from a scene file, from code, or both (setters override the file).
//!
//! ```no_run
//! use imu_emu::sim::Simulation;
//! let sim = Simulation::builder()
//!     .scene("circle")
//!     .imu("ln200")
//!     .format("kvh1750")
//!     .duration(10.0)
//!     .build()?;
//! let mut out = std::fs::File::create("circle.kvh")?;
//! sim.write(&mut out)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod builder;
mod gnss;
mod rig_aiding;
mod sensors;
pub mod source_choice;
mod streams;

use std::io::Write;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

pub use builder::SimulationBuilder;
pub use source_choice::SourceChoice;
pub use streams::AidingStreams;

use crate::aiding::GnssConfig;
use crate::aiding::mag_samples::MagHold;
use crate::config::ConfigError;
use crate::engine::filtered::FilteredImu;
use crate::engine::{self, Encoding, EngineError, Grid, Producer};
use crate::errors::filtered::FilteredChain;
use crate::errors::temperature::TemperatureProfile;
use crate::errors::template::{ImuModel, TemplateError};
use crate::errors::{ErrorChain, template};
use crate::output::Format;
use crate::protocol::{EncoderState, FaultInjector, Plan, SpecError};
use crate::record::Record;
use crate::source::AnyMotion;

/// Why a simulation cannot be assembled or run. Values that came from a scene file are
/// wrapped in [`SimError::At`], which names the file and the key.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The scene file cannot be read or parsed, or one of its sections is unusable.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The IMU template cannot be loaded.
    #[error(transparent)]
    Template(#[from] TemplateError),
    /// The protocol cannot be loaded.
    #[error(transparent)]
    Protocol(#[from] SpecError),
    /// The trajectory, the span or the production failed.
    #[error(transparent)]
    Job(#[from] EngineError),
    /// A setting outside what it can be: names the setting and what is expected.
    #[error("{0}")]
    Invalid(String),
    /// The error `source` of a value that came from `place` (`FILE: `key``, or a file).
    #[error("{place}")]
    At {
        /// The scene-file key or the file the value came from.
        place: String,
        /// What is wrong with it.
        #[source]
        source: Box<SimError>,
    },
}

impl SimError {
    /// This error located at `place`, if any.
    pub fn at(self, place: Option<String>) -> SimError {
        match place {
            Some(place) => SimError::At {
                place,
                source: Box::new(self),
            },
            None => self,
        }
    }

    /// The underlying error without the places that wrap it.
    pub fn root(&self) -> &SimError {
        match self {
            SimError::At { source, .. } => source.root(),
            e => e,
        }
    }
}

/// What the main output carries: the record contract or a protocol's frames.
#[derive(Clone, Debug)]
pub enum Output {
    /// CSV or binary records.
    Records(Format),
    /// Frames of a compiled protocol.
    Frames(Plan),
}

/// The side outputs of [`Simulation::write_with`].
#[derive(Default)]
pub struct SideOutputs<'a> {
    /// Receives the error-free records (same grid; CSV for a frame stream).
    pub truth: Option<&'a mut dyn Write>,
    /// Receives the error each stage injected into each record.
    pub injected: Option<&'a mut dyn Write>,
}

/// An assembled simulation, ready to produce records or frames.
pub struct Simulation {
    motion: AnyMotion,
    grid: Grid,
    nodes: usize,
    output: Output,
    chain: Option<ErrorChain>,
    /// The chain of a unit with an output filter (then `chain` is `None`).
    filtered: Option<FilteredChain>,
    imu: ImuModel,
    seed: u64,
    temperature: Option<TemperatureProfile>,
    faults: Option<FaultInjector>,
    gps_time: Option<(u32, f64)>,
    /// True GPS time of record time 0 for the GNSS streams, when the frames' reference is not
    /// GPS time (`--time-base utc`); else the GNSS streams use `gps_time`.
    gnss_time: Option<(u32, f64)>,
    gnss: Option<GnssConfig>,
    odometer: Option<crate::aiding::odometer::OdometerConfig>,
    baro: Option<crate::aiding::baro::BaroConfig>,
    magnetometer: Option<crate::aiding::magnetometer::MagConfig>,
    /// C_b^c of the IMU's case (its mounting), the axes of the frames' magnetic field.
    case_rotation: Option<crate::math::Quat>,
    output_path: Option<PathBuf>,
    warnings: Vec<String>,
    timing: Option<crate::engine::timed::TimedRun>,
}

impl Simulation {
    /// A builder with the library defaults (survey scene, ideal IMU, CSV records, 400 Hz).
    pub fn builder() -> SimulationBuilder {
        SimulationBuilder::default()
    }

    /// A builder that starts from a scene file (TOML; `examples/survey.toml` documents every
    /// key): its setters override the file.
    pub fn from_scene_file(path: impl AsRef<Path>) -> Result<SimulationBuilder, SimError> {
        SimulationBuilder::default().scene_file(path)
    }

    /// The time grid: t₀, rate and number of records.
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// The motion model of the source.
    pub fn motion(&self) -> &AnyMotion {
        &self.motion
    }

    /// The IMU model (template) of the error chain.
    pub fn imu(&self) -> &ImuModel {
        &self.imu
    }

    /// The master seed of the random error processes.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Whether the records differ from the error-free ones (an error chain is applied).
    pub fn has_errors(&self) -> bool {
        self.chain.is_some() || self.filtered.is_some()
    }

    /// The main output.
    pub fn output(&self) -> &Output {
        &self.output
    }

    /// The protocol of the frames, when the output is frames.
    pub fn plan(&self) -> Option<&Plan> {
        match &self.output {
            Output::Frames(p) => Some(p),
            Output::Records(_) => None,
        }
    }

    /// The sensor temperature profile, when the scene gives one.
    pub fn temperature(&self) -> Option<&TemperatureProfile> {
        self.temperature.as_ref()
    }

    /// The fault injector of the frames (its tally counts what was injected).
    pub fn faults(&self) -> Option<&FaultInjector> {
        self.faults.as_ref()
    }

    /// Sets the GPS time of record time t = 0 (week, seconds of week): frames' GPS-time
    /// fields carry it plus the record's time tag (a time base chosen after building).
    pub fn set_gps_time(&mut self, week: u32, seconds_of_week: f64) {
        self.gps_time = Some((week, seconds_of_week));
    }

    /// Sets the true GPS time of record time t = 0 for the GNSS streams only, when the frames'
    /// reference ([`Simulation::set_gps_time`]) is another scale (UTC): a receiver's NMEA UTC
    /// and UBX GPS time of week come from GPS time whatever the IMU's frames carry.
    pub fn set_gnss_gps_time(&mut self, week: u32, seconds_of_week: f64) {
        self.gnss_time = Some((week, seconds_of_week));
    }

    /// The GPS time (week, seconds of week) of record time 0, when one was set.
    pub fn gps_time(&self) -> Option<(u32, f64)> {
        self.gps_time
    }

    /// The scene file's `output.path`, if it gives one.
    pub fn output_path(&self) -> Option<&Path> {
        self.output_path.as_deref()
    }

    /// Things worth telling the user that do not stop the run (a template without error
    /// figures, random vibration cut at the Nyquist frequency).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The encoding of the main output.
    pub fn encoding(&self) -> Encoding {
        match &self.output {
            Output::Records(f) => Encoding::Records(*f),
            Output::Frames(plan) => self.frames_encoding(plan.clone()),
        }
    }

    /// Frames of `plan` with this simulation's GPS time reference and faults; side files in
    /// CSV. For further streams of the same records in another protocol.
    pub fn frames_encoding(&self, plan: Plan) -> Encoding {
        Encoding::Frames {
            plan: Box::new(plan),
            state: EncoderState {
                gps_week0: self.gps_time.map_or(0, |g| g.0),
                gps_sow0: self.gps_time.map_or(0.0, |g| g.1),
                faults: self.faults.clone().map(Box::new),
                ..Default::default()
            },
            temperature: DEFAULT_FRAME_CELSIUS,
            side: Format::Csv,
        }
    }

    /// The block-wise producer of the run (records → error chain → encoding), as the
    /// real-time emulator drives it.
    pub fn producer(self) -> Result<Producer, SimError> {
        let encoding = self.encoding();
        let mag = (self.magnetometer.clone())
            .map(|cfg| MagHold::new(cfg, self.seed, self.grid.t0, self.case_rotation));
        let filtered = match self.filtered {
            Some(c) => Some(
                FilteredImu::new(self.motion.clone(), self.grid, self.nodes, c)
                    .map_err(EngineError::Filter)?,
            ),
            None => None,
        };
        let p = Producer::new(
            self.motion,
            self.grid,
            self.nodes,
            encoding,
            self.chain,
            false,
        )?;
        Ok(p.with_temperature(self.temperature)
            .with_timing(self.timing)
            .with_filter(filtered)
            .with_magnetometer(mag))
    }

    /// The records, block by block, without any wire encoding.
    pub fn records(self) -> Result<RecordBlocks, SimError> {
        Ok(RecordBlocks {
            producer: self.producer()?,
        })
    }

    /// Writes the whole run (records or frames) into `out`.
    pub fn write(self, out: &mut impl Write) -> Result<(), SimError> {
        self.write_with(out, SideOutputs::default(), |_| ControlFlow::Continue(()))
    }

    /// Writes the whole run into `out` and the side outputs; `progress(records_done)` is
    /// called after each block and may stop the run ([`EngineError::Stopped`]).
    pub fn write_with(
        self,
        out: &mut impl Write,
        side: SideOutputs<'_>,
        progress: impl FnMut(u64) -> ControlFlow<()>,
    ) -> Result<(), SimError> {
        let producer = self.producer()?;
        engine::drain(producer, out, side.truth, side.injected, progress)?;
        Ok(())
    }
}

pub use crate::engine::DEFAULT_FRAME_CELSIUS;

/// The records of a simulation, one block (up to [`engine::BLOCK`] records) per item.
pub struct RecordBlocks {
    producer: Producer,
}

impl Iterator for RecordBlocks {
    type Item = Result<Vec<Record>, SimError>;

    fn next(&mut self) -> Option<Self::Item> {
        match self.producer.next_records(engine::BLOCK) {
            Some(b) => Some(Ok(b.records.to_vec())),
            None => self.producer.take_error().map(|e| Err(e.into())),
        }
    }
}

/// The template `name` (built-in or file).
fn load_template(name: &str) -> Result<ImuModel, SimError> {
    Ok(template::load(name)?)
}
