//! [`SimulationBuilder`]: a scene file (optional) and setters over it, resolved into a
//! [`Simulation`]. Every value that came from the file and is refused names the file's key.

mod aiding;
mod build;
mod rig;

use std::path::{Path, PathBuf};

use super::{Output, SimError};
use crate::aiding::GnssConfig;
use crate::aiding::gnss::ConfigError as AidingConfigError;
use crate::aiding::odometer::OdometerConfig;
use crate::config::SceneFile;
use crate::engine::{self, SourceSpec};
use crate::errors::temperature::TemperatureProfile;
use crate::errors::template::ImuModel;
use crate::errors::vibration::VibrationSpec;
use crate::motion::causal::CausalMotion;
use crate::motion::sampled::{Degree, ModelSettings};
use crate::protocol::{self, FaultSpec};

/// The IMU of a builder: a template name or file, or a model built in code.
#[derive(Clone, Debug)]
enum Imu {
    Named(String),
    Model(Box<ImuModel>),
}

/// Settings of a simulation: a scene file's values, overridden by the setters.
#[derive(Clone, Debug)]
pub struct SimulationBuilder {
    file: SceneFile,
    file_path: Option<PathBuf>,
    scene: Option<String>,
    trajectory: Option<PathBuf>,
    motion_def: Option<PathBuf>,
    /// Trajectory samples held in memory (label, samples).
    samples: Option<(PathBuf, std::sync::Arc<Vec<crate::motion::sampled::Sample>>)>,
    imu: Option<Imu>,
    rate: Option<f64>,
    start: Option<f64>,
    duration: Option<f64>,
    format: Option<String>,
    protocol_file: Option<PathBuf>,
    gps_time: Option<(u32, f64)>,
    faults: Vec<FaultSpec>,
    seed: Option<u64>,
    nodes: Option<usize>,
    interpolation: Option<String>,
    stencil: Option<usize>,
    temperature: Option<TemperatureProfile>,
    mounting_deg: Option<[f64; 3]>,
    lever_arm_m: Option<[f64; 3]>,
    vibration: Option<VibrationSpec>,
    units: Vec<crate::rig::UnitSpec>,
    gnss: Option<GnssConfig>,
    odometer: Option<OdometerConfig>,
    baro: Option<crate::aiding::baro::BaroConfig>,
    magnetometer: Option<crate::aiding::magnetometer::MagConfig>,
    default_imu: String,
    default_format: String,
    unbounded_duration: f64,
    live: Option<CausalMotion>,
}

impl Default for SimulationBuilder {
    fn default() -> SimulationBuilder {
        SimulationBuilder {
            file: SceneFile::default(),
            file_path: None,
            scene: None,
            trajectory: None,
            motion_def: None,
            samples: None,
            imu: None,
            rate: None,
            start: None,
            duration: None,
            format: None,
            protocol_file: None,
            gps_time: None,
            faults: Vec::new(),
            seed: None,
            nodes: None,
            interpolation: None,
            stencil: None,
            temperature: None,
            mounting_deg: None,
            lever_arm_m: None,
            vibration: None,
            units: Vec::new(),
            gnss: None,
            odometer: None,
            baro: None,
            magnetometer: None,
            default_imu: "ideal".into(),
            default_format: "csv".into(),
            unbounded_duration: engine::DEFAULT_UNBOUNDED_DURATION_S,
            live: None,
        }
    }
}

/// A sampled model's settings in words (`quintic, stencil 9`).
fn model_words(m: ModelSettings) -> String {
    let degree = if m.degree == Degree::Quintic {
        "quintic"
    } else {
        "cubic"
    };
    format!("{degree}, stencil {}", m.stencil)
}

/// The default IMU rate when neither a setting, the protocol nor the template gives one (Hz).
pub const DEFAULT_RATE_HZ: f64 = 400.0;

/// A number for a message: at most 17 significant digits, exponent form when large or small
/// (a 1e300 rate is not 301 digits).
pub fn short_number(x: f64) -> String {
    let a = x.abs();
    if x.is_finite() && a != 0.0 && !(1e-4..1e15).contains(&a) {
        format!("{x:e}")
    } else {
        x.to_string()
    }
}

impl SimulationBuilder {
    /// Reads the scene file at `path`; the setters called afterwards override its values.
    pub fn scene_file(mut self, path: impl AsRef<Path>) -> Result<SimulationBuilder, SimError> {
        let path = path.as_ref();
        self.file = SceneFile::read(path)?;
        self.file_path = Some(path.to_path_buf());
        Ok(self)
    }

    /// A built-in scene (`scenes::NAMES`), with the scene file's `[trajectory.params]` if any.
    pub fn scene(mut self, name: impl Into<String>) -> SimulationBuilder {
        self.scene = Some(name.into());
        self.trajectory = None;
        self.motion_def = None;
        self.samples = None;
        self
    }

    /// A trajectory CSV (`t,lat,lon,h,vn,ve,vd,roll,pitch,yaw`) instead of a scene.
    pub fn trajectory(mut self, path: impl Into<PathBuf>) -> SimulationBuilder {
        self.trajectory = Some(path.into());
        self.scene = None;
        self.motion_def = None;
        self.samples = None;
        self
    }

    /// A motion-definition file (gnss-ins-sim's motion-definition CSV) instead of a scene.
    pub fn motion_def(mut self, path: impl Into<PathBuf>) -> SimulationBuilder {
        self.motion_def = Some(path.into());
        self.scene = None;
        self.trajectory = None;
        self.samples = None;
        self
    }

    /// Trajectory samples held in memory instead of a scene or a file, modelled as a
    /// trajectory file's rows are; `label` names them in messages. The caller checks them as
    /// [`crate::trajectory::parse`] does (e.g. by building them with it).
    pub fn trajectory_samples(
        mut self,
        label: impl Into<PathBuf>,
        samples: Vec<crate::motion::sampled::Sample>,
    ) -> SimulationBuilder {
        self.samples = Some((label.into(), std::sync::Arc::new(samples)));
        self.scene = None;
        self.trajectory = None;
        self.motion_def = None;
        self
    }

    /// A live motion (states pushed by the caller as they arrive) instead of a scene or a
    /// file; the run starts at [`SimulationBuilder::start`] or the model's first knot.
    pub fn live_motion(mut self, motion: CausalMotion) -> SimulationBuilder {
        self.live = Some(motion);
        self
    }

    /// The IMU error model: a built-in template name or a template file.
    pub fn imu(mut self, name_or_path: impl Into<String>) -> SimulationBuilder {
        self.imu = Some(Imu::Named(name_or_path.into()));
        self
    }

    /// The IMU error model, built in code.
    pub fn imu_model(mut self, model: ImuModel) -> SimulationBuilder {
        self.imu = Some(Imu::Model(Box::new(model)));
        self
    }

    /// The IMU output rate (Hz).
    pub fn rate(mut self, hz: f64) -> SimulationBuilder {
        self.rate = Some(hz);
        self
    }

    /// The start time t₀ (s).
    pub fn start(mut self, t0: f64) -> SimulationBuilder {
        self.start = Some(t0);
        self
    }

    /// The duration (s).
    pub fn duration(mut self, seconds: f64) -> SimulationBuilder {
        self.duration = Some(seconds);
        self
    }

    /// The output: `csv`, `bin`, or a built-in protocol's name.
    pub fn format(mut self, name: impl Into<String>) -> SimulationBuilder {
        self.format = Some(name.into());
        self
    }

    /// Frames of the protocol described in a spec file (overrides [`Self::format`]).
    pub fn protocol_file(mut self, path: impl Into<PathBuf>) -> SimulationBuilder {
        self.protocol_file = Some(path.into());
        self
    }

    /// The GPS time (week, seconds of week) of record time 0, for frames with GPS time.
    pub fn gps_time(mut self, week: u32, seconds_of_week: f64) -> SimulationBuilder {
        self.gps_time = Some((week, seconds_of_week));
        self
    }

    /// A fault injected into the frames, in addition to the scene file's `[faults]`.
    pub fn fault(mut self, spec: FaultSpec) -> SimulationBuilder {
        self.faults.push(spec);
        self
    }

    /// The master seed of every random error process.
    pub fn seed(mut self, seed: u64) -> SimulationBuilder {
        self.seed = Some(seed);
        self
    }

    /// Gauss–Legendre nodes per interval (1 to 16).
    pub fn quadrature_nodes(mut self, nodes: usize) -> SimulationBuilder {
        self.nodes = Some(nodes);
        self
    }

    /// Motion-model polynomials of a trajectory file: `cubic` or `quintic`.
    pub fn interpolation(mut self, name: impl Into<String>) -> SimulationBuilder {
        self.interpolation = Some(name.into());
        self
    }

    /// Finite-difference stencil (samples, 3 to 15) of a trajectory file's knot derivatives.
    pub fn stencil(mut self, samples: usize) -> SimulationBuilder {
        self.stencil = Some(samples);
        self
    }

    /// The sensor temperature over the run (overrides the scene file's `[temperature]`).
    pub fn temperature(mut self, profile: TemperatureProfile) -> SimulationBuilder {
        self.temperature = Some(profile);
        self
    }

    /// The case's attitude in the body, [roll, pitch, yaw] of C_c^b in degrees.
    pub fn mounting_deg(mut self, roll_pitch_yaw: [f64; 3]) -> SimulationBuilder {
        self.mounting_deg = Some(roll_pitch_yaw);
        self
    }

    /// The lever arm from the trajectory's reference point to the IMU, case frame (m).
    pub fn lever_arm_m(mut self, arm: [f64; 3]) -> SimulationBuilder {
        self.lever_arm_m = Some(arm);
        self
    }

    /// The vibration of the IMU (overrides the scene file's `[vibration]`).
    pub fn vibration(mut self, spec: VibrationSpec) -> SimulationBuilder {
        self.vibration = Some(spec);
        self
    }

    /// A GNSS receiver on the same motion and clock (overrides the scene file's `[gnss]`).
    pub fn gnss(mut self, cfg: GnssConfig) -> SimulationBuilder {
        self.gnss = Some(cfg);
        self
    }

    /// An odometer on the same motion and clock (overrides the scene file's `[odometer]`).
    pub fn odometer(mut self, cfg: OdometerConfig) -> SimulationBuilder {
        self.odometer = Some(cfg);
        self
    }

    /// An aiding sensor's settings: the setter's, else the scene file's table, checked by
    /// `validate`; errors name the scene file's key.
    fn resolve_aiding<T: Clone>(
        &self,
        given: &Option<T>,
        in_file: &Option<T>,
        validate: impl Fn(&T) -> Result<(), AidingConfigError>,
    ) -> Result<Option<T>, SimError> {
        let Some(cfg) = given.clone().or(in_file.clone()) else {
            return Ok(None);
        };
        validate(&cfg).map_err(|e| {
            let key = format!("{}.{}", e.table, e.key);
            let place = self.file_key(given.is_some(), true, &key);
            SimError::Invalid(e.message).at(Some(place.unwrap_or_else(|| format!("`{key}`"))))
        })?;
        Ok(Some(cfg))
    }

    /// The IMU template and the output used when neither a setter nor the scene file names
    /// one (library default: `ideal`, `csv`).
    pub fn defaults(mut self, imu: &str, format: &str) -> SimulationBuilder {
        self.default_imu = imu.into();
        self.default_format = format.into();
        self
    }

    /// The duration of a run on an unbounded scene when none is given (s).
    pub fn unbounded_duration(mut self, seconds: f64) -> SimulationBuilder {
        self.unbounded_duration = seconds;
        self
    }

    /// Whether a setter chose the trajectory (a scene, a trajectory file or a motion
    /// definition), over the scene file's `[trajectory]`.
    pub fn has_source(&self) -> bool {
        self.scene.is_some()
            || self.trajectory.is_some()
            || self.motion_def.is_some()
            || self.samples.is_some()
    }

    /// The trajectory in words (`scene survey`, `trajectory file f.csv (quintic, stencil 9)`,
    /// `motion definition m.csv`), for a run's description.
    pub fn source_label(&self) -> Result<String, SimError> {
        let m = self.model_settings()?;
        Ok(match self.source()?.0 {
            SourceSpec::Scene(name, _) => format!("scene {name}"),
            SourceSpec::File(p) => format!("trajectory file {} ({})", p.display(), model_words(m)),
            SourceSpec::Samples { label, .. } => {
                format!("{} ({})", label.display(), model_words(m))
            }
            SourceSpec::MotionDef(p) => format!("motion definition {}", p.display()),
        })
    }

    /// Whether the trajectory is sampled (a trajectory file), the only motion the
    /// interpolation and stencil settings shape (a live motion's too).
    pub fn is_sampled(&self) -> Result<bool, SimError> {
        Ok(matches!(
            self.source()?.0,
            SourceSpec::File(_) | SourceSpec::Samples { .. }
        ))
    }

    /// Whether a setter (a flag) chose the interpolation or the stencil; the scene file's
    /// `[engine]` keys are defaults for whatever trajectory file the scene is run with.
    pub fn model_settings_given(&self) -> bool {
        self.interpolation.is_some() || self.stencil.is_some()
    }

    /// Gauss–Legendre nodes per interval this builder resolves to.
    pub fn quadrature(&self) -> Result<usize, SimError> {
        self.nodes()
    }

    /// The start and the duration (s) a setter or the scene file gives, each `None` when
    /// neither does (the motion's start; its end, or the run's default length).
    pub fn span_given(&self) -> (Option<f64>, Option<f64>) {
        let o = &self.file.output;
        (self.start.or(o.start_s), self.duration.or(o.duration_s))
    }

    /// Whether a GPS time of record time 0 was given (setter or nothing else: the scene file
    /// has no such key).
    pub fn gps_time_given(&self) -> bool {
        self.gps_time.is_some()
    }

    /// The scene file's `output.path`, if it gives one.
    pub fn output_path(&self) -> Option<&Path> {
        self.file.output.path.as_deref()
    }

    /// The scene file's contents (empty when none was read).
    pub fn scene_contents(&self) -> &SceneFile {
        &self.file
    }

    /// The scene file, if one was read.
    pub fn scene_file_path(&self) -> Option<&Path> {
        self.file_path.as_deref()
    }

    /// `FILE: `key`` when a value came from the scene file (`given`: set in code instead).
    fn file_key(&self, given: bool, in_file: bool, key: &str) -> Option<String> {
        match (&self.file_path, given || !in_file) {
            (Some(p), false) => Some(format!("{}: `{key}`", p.display())),
            _ => None,
        }
    }

    /// The scene file's path, or `<settings>` for messages about values set in code.
    fn file_label(&self) -> PathBuf {
        self.file_path
            .clone()
            .unwrap_or_else(|| PathBuf::from("<settings>"))
    }

    /// The directory that relative paths in the scene file are resolved against.
    fn base(&self) -> PathBuf {
        (self.file_path.as_deref().and_then(Path::parent))
            .map(Path::to_path_buf)
            .unwrap_or_default()
    }
}

/// The IMU rate and the scene-file key it came from, if it did.
#[derive(Clone)]
struct Rate {
    hz: f64,
    place: Option<String>,
}

/// A three-axis IMU's frames; an N-channel protocol (a skew-redundant unit's) is refused.
fn triad_frames(plan: protocol::Plan, at: Option<String>) -> Result<Output, SimError> {
    match plan.channels() {
        None => Ok(Output::Frames(plan)),
        Some((g, a)) => Err(SimError::Invalid(format!(
            "protocol `{}` carries {g} gyro and {a} accelerometer single-axis channels: it is the frame of a skew-redundant unit, a rig's `[[imu]]` entry with `[[imu.gyro]]`/`[[imu.accel]]` sensors (docs/rig.md)",
            plan.name
        ))
        .at(at)),
    }
}
