//! [`SimulationBuilder`]: a scene file (optional) and setters over it, resolved into a
//! [`Simulation`]. Every value that came from the file and is refused names the file's key.

mod aiding;
mod rig;

use std::path::{Path, PathBuf};

use super::{Output, SimError, Simulation};
use crate::aiding::GnssConfig;
use crate::aiding::gnss::ConfigError as AidingConfigError;
use crate::aiding::odometer::OdometerConfig;
use crate::aiding::sensors::SensorSet;
use crate::config::{self, SceneFile};
use crate::engine::{self, EngineError, Grid, SourceSpec};
use crate::errors::ErrorChain;
use crate::errors::filtered::FilteredChain;
use crate::errors::temperature::TemperatureProfile;
use crate::errors::template::ImuModel;
use crate::errors::vibration::{Vibration, VibrationSpec};
use crate::generator::DEFAULT_NODES;
use crate::motion::Motion;
use crate::motion::causal::CausalMotion;
use crate::motion::sampled::{Degree, ModelSettings};
use crate::output::Format;
use crate::protocol::{self, FaultInjector, FaultSpec};
use crate::scenes;
use crate::source::AnyMotion;

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

    /// The source and whether its scene name and its parameters came from the scene file.
    fn source(&self) -> Result<(SourceSpec, bool, bool), SimError> {
        let t = &self.file.trajectory;
        let label = self.file_label();
        let from_params = t.params.is_some() && self.trajectory.is_none();
        if let Some(path) = &self.trajectory {
            return Ok((SourceSpec::File(path.clone()), false, false));
        }
        if let Some(path) = &self.motion_def {
            return Ok((SourceSpec::MotionDef(path.clone()), false, false));
        }
        if let Some((label, samples)) = &self.samples {
            let samples = samples.clone();
            let label = label.clone();
            return Ok((SourceSpec::Samples { label, samples }, false, false));
        }
        let embedded = self.file.motion.is_some() && self.scene.is_none();
        if embedded {
            if t.scene.is_some() || t.file.is_some() || t.motion_def.is_some() {
                return Err(SimError::Invalid(
                    "a `[motion]` table is the trajectory: remove `trajectory.scene`, \
                     `trajectory.file` and `trajectory.motion_def`"
                        .into(),
                )
                .at(Some(label.display().to_string())));
            }
            return Ok((SourceSpec::MotionDef(label.clone()), false, false));
        }
        if let (None, Some(m)) = (&self.scene, &t.motion_def) {
            if t.scene.is_some() || t.file.is_some() {
                return Err(SimError::Invalid(
                    "give one of `scene`, `file` and `motion_def`".into(),
                )
                .at(Some(format!("{}: `trajectory`", label.display()))));
            }
            return Ok((SourceSpec::MotionDef(self.base().join(m)), false, false));
        }
        if let Some(s) = &self.scene {
            let params = config::scene_params(s, t.params.as_ref()).map_err(|m| {
                SimError::Invalid(m).at(Some(format!("{}: `trajectory.params`", label.display())))
            })?;
            return Ok((SourceSpec::Scene(s.clone(), params), false, from_params));
        }
        let spec = match (&t.scene, &t.file) {
            (Some(_), Some(_)) => {
                return Err(
                    SimError::Invalid("give either `scene` or `file`, not both".into())
                        .at(Some(format!("{}: `trajectory`", label.display()))),
                );
            }
            (_, Some(f)) => SourceSpec::File(self.base().join(f)),
            (Some(s), None) => SourceSpec::Scene(s.clone(), self.file.scene_params(s, &label)?),
            (None, None) => SourceSpec::Scene(
                scenes::DEFAULT.into(),
                self.file.scene_params(scenes::DEFAULT, &label)?,
            ),
        };
        Ok((spec, t.scene.is_some(), from_params))
    }

    /// The motion-model settings of a trajectory file (interpolation and stencil).
    pub fn model_settings(&self) -> Result<ModelSettings, SimError> {
        let e = &self.file.engine;
        let at = self.file_key(
            self.interpolation.is_some(),
            e.interpolation.is_some(),
            "engine.interpolation",
        );
        let interp = (self.interpolation.clone())
            .or(e.interpolation.clone())
            .unwrap_or_else(|| "quintic".into());
        let degree = match interp.as_str() {
            "cubic" => Degree::Cubic,
            "quintic" => Degree::Quintic,
            other => {
                return Err(SimError::Invalid(format!(
                    "interpolation `{other}`: expected `cubic` or `quintic`"
                ))
                .at(at));
            }
        };
        let at = self.file_key(
            self.stencil.is_some(),
            e.stencil.is_some(),
            "engine.stencil",
        );
        let stencil = (self.stencil.or(e.stencil)).unwrap_or(ModelSettings::default().stencil);
        if !(3..=15).contains(&stencil) {
            return Err(
                SimError::Invalid(format!("stencil {stencil}: expected 3 to 15 samples")).at(at),
            );
        }
        Ok(ModelSettings { degree, stencil })
    }

    /// The motion model of the source alone (for commands that need only the reference
    /// trajectory); errors name the scene-file key or the trajectory file.
    pub fn motion(&self) -> Result<AnyMotion, SimError> {
        if let Some(m) = &self.live {
            return Ok(AnyMotion::Live(m.clone()));
        }
        let (source, scene_from_file, params_from_file) = self.source()?;
        let model = self.model_settings()?;
        engine::build_motion(&source, model).map_err(|e| {
            let label = self.file_label();
            let place = match &e {
                EngineError::UnknownScene(_) if scene_from_file => {
                    Some(format!("{}: `trajectory.scene`", label.display()))
                }
                EngineError::SceneParam(p) if params_from_file => Some(format!(
                    "{}: `trajectory.params.{}`",
                    label.display(),
                    p.key
                )),
                _ => None,
            };
            SimError::from(e).at(place)
        })
    }

    /// The IMU model: setter, then the scene file's `imu.model`, then the default.
    fn resolve_imu(&self) -> Result<ImuModel, SimError> {
        let file = &self.file.imu.model;
        let at = self.file_key(self.imu.is_some(), file.is_some(), "imu.model");
        let name = match &self.imu {
            Some(Imu::Model(m)) => return Ok((**m).clone()),
            Some(Imu::Named(n)) => n.clone(),
            None => file.clone().unwrap_or_else(|| self.default_imu.clone()),
        };
        super::load_template(&name).map_err(|e| e.at(at))
    }

    /// The output encoding: a protocol file, else `csv`, `bin` or a built-in protocol.
    fn output(&self) -> Result<Output, SimError> {
        if let Some(p) = &self.protocol_file {
            return triad_frames(protocol::load(&p.to_string_lossy())?.1, None);
        }
        let file = &self.file.output.format;
        let at = self.file_key(self.format.is_some(), file.is_some(), "output.format");
        let name = (self.format.clone())
            .or(file.clone())
            .unwrap_or_else(|| self.default_format.clone());
        if let Some(f) = Format::from_name(&name) {
            return Ok(Output::Records(f));
        }
        let builtin = protocol::builtin_names();
        if builtin.contains(&name.as_str()) {
            return triad_frames(protocol::load(&name)?.1, at);
        }
        Err(SimError::Invalid(format!(
            "output format `{name}`: expected `csv`, `bin` or a protocol ({})",
            builtin.join(", ")
        ))
        .at(at))
    }

    /// The places (scene-file keys, trajectory file) that set the span, for span errors.
    fn span_place(&self, source: &SourceSpec) -> Option<String> {
        let mut place = Vec::new();
        let o = &self.file.output;
        let keys: Vec<String> = [
            (
                "output.start_s",
                self.start.is_none() && o.start_s.is_some(),
            ),
            (
                "output.duration_s",
                self.duration.is_none() && o.duration_s.is_some(),
            ),
        ]
        .into_iter()
        .filter(|k| k.1)
        .map(|k| format!("`{}`", k.0))
        .collect();
        if let (Some(f), false) = (&self.file_path, keys.is_empty()) {
            place.push(format!("{}: {}", f.display(), keys.join(", ")));
        }
        if let SourceSpec::File(path)
        | SourceSpec::MotionDef(path)
        | SourceSpec::Samples { label: path, .. } = source
        {
            place.push(path.display().to_string());
        }
        (!place.is_empty()).then(|| place.join(": "))
    }

    /// The time grid; refuses a rate, start or duration that cannot be, saying which and why.
    fn grid(&self, motion: &AnyMotion, source: &SourceSpec, rate: Rate) -> Result<Grid, SimError> {
        let o = &self.file.output;
        let start = self.start.or(o.start_s);
        let duration = self.duration.or(o.duration_s);
        let at_start = self.file_key(self.start.is_some(), o.start_s.is_some(), "output.start_s");
        let at_duration = self.file_key(
            self.duration.is_some(),
            o.duration_s.is_some(),
            "output.duration_s",
        );
        let setting = |key: &str, value: f64, expected: &str| {
            SimError::Invalid(format!("`{key}` = {}: {expected}", short_number(value)))
        };
        if !(rate.hz.is_finite() && rate.hz > 0.0 && rate.hz <= 1.0e7) {
            return Err(setting("rate", rate.hz, "a rate in (0, 1e7] Hz").at(rate.place));
        }
        if let Some(t0) = start.filter(|t| !t.is_finite()) {
            return Err(setting("start", t0, "a finite time").at(at_start));
        }
        let duration = match duration {
            Some(d) if !(d.is_finite() && d > 0.0) => {
                return Err(
                    setting("duration", d, "a positive duration in seconds").at(at_duration)
                );
            }
            Some(d) if (d * rate.hz + 1e-9) < 1.0 => {
                return Err(SimError::Invalid(format!(
                    "`duration` = {} s is shorter than one sample at {} Hz ({} s): no record to write",
                    short_number(d),
                    short_number(rate.hz),
                    short_number(1.0 / rate.hz)
                ))
                .at(at_duration));
            }
            None if !motion.end().is_finite() => Some(self.unbounded_duration),
            d => d,
        };
        engine::plan(motion, rate.hz, start, duration).map_err(|e| {
            let place = match &e {
                EngineError::Span { .. } => self.span_place(source),
                EngineError::Setting { key, .. } => match *key {
                    "rate" => rate.place.clone(),
                    "start" => at_start.clone(),
                    "duration" => at_duration.clone(),
                    _ => None,
                },
                _ => None,
            };
            SimError::from(e).at(place)
        })
    }

    /// The error chain of `imu` with the temperature, mounting, lever arm and vibration;
    /// `None` when nothing would change the error-free records. A unit with an output filter
    /// gets its filtered chain instead (the second item), its stages at the internal rate.
    fn chain(
        &self,
        imu: &ImuModel,
        rate_hz: f64,
        seed: u64,
        temperature: Option<&TemperatureProfile>,
        warnings: &mut Vec<String>,
    ) -> Result<(Option<ErrorChain>, Option<FilteredChain>), SimError> {
        let Some(spec) = &imu.output_filter else {
            let chain = ErrorChain::new(imu, rate_hz, seed);
            let chain = self.configure(chain, imu, rate_hz, seed, temperature, warnings)?;
            return Ok(((!chain.is_empty()).then_some(chain), None));
        };
        let filtered = FilteredChain::new(imu, rate_hz, seed).map_err(|e| {
            SimError::Invalid(format!("template `{}`: [output_filter]: {e}", imu.name))
        })?;
        let internal = spec.internal_rate_hz;
        let inner = ErrorChain::new(&FilteredChain::inner_model(imu), internal, seed);
        let inner = self.configure(inner, imu, internal, seed, temperature, warnings)?;
        Ok((None, Some(filtered.map_inner(|_| inner))))
    }

    /// `chain` (of `imu` at `rate_hz`) with the temperature, mounting, lever arm and vibration.
    fn configure(
        &self,
        mut chain: ErrorChain,
        imu: &ImuModel,
        rate_hz: f64,
        seed: u64,
        temperature: Option<&TemperatureProfile>,
        warnings: &mut Vec<String>,
    ) -> Result<ErrorChain, SimError> {
        if let Some(p) = temperature {
            chain = chain.with_temperature(p.clone(), imu);
        }
        let f = &self.file.imu;
        let mounting = self.mounting_deg.or(f.mounting_deg);
        let lever_arm = self.lever_arm_m.or(f.lever_arm_m);
        for (key, v, given) in [
            ("imu.mounting_deg", mounting, self.mounting_deg.is_some()),
            ("imu.lever_arm_m", lever_arm, self.lever_arm_m.is_some()),
        ] {
            if v.is_some_and(|v| v.iter().any(|x| !x.is_finite())) {
                let e = SimError::Invalid("expected three finite numbers".into());
                let name = key.trim_start_matches("imu.");
                return Err(match self.file_key(given, true, key) {
                    Some(place) => e.at(Some(place)),
                    None => e.at(Some(format!("`{name}`"))),
                });
            }
        }
        if let Some([roll, pitch, yaw]) = mounting {
            // The file gives the case's attitude in the body (C_c^b); the chain wants C_b^c.
            let q_c_b = crate::math::quat_from_euler(
                roll.to_radians(),
                pitch.to_radians(),
                yaw.to_radians(),
            );
            chain = chain.with_mounting(q_c_b.conjugate());
        }
        if let Some(r) = lever_arm {
            chain = chain.with_lever_arm(crate::math::Vec3::from(r));
        }
        if let Some(v) = self.build_vibration(rate_hz, seed, warnings)? {
            chain = chain.with_vibration(v);
        }
        if imu.grade != "ideal" && !imu.has_error_figures() {
            warnings.push(format!(
                "template `{}` has no error figures (no public source was found; see its file): the output is error-free apart from the interface's quantization and range",
                imu.name
            ));
        }
        Ok(chain)
    }

    /// The vibration (setter, else the scene file's `[vibration]`) for records at `rate_hz`,
    /// its random streams from `seed`; `None` when there is none. A table cut at Nyquist
    /// adds a warning.
    fn build_vibration(
        &self,
        rate_hz: f64,
        seed: u64,
        warnings: &mut Vec<String>,
    ) -> Result<Option<Vibration>, SimError> {
        let label = self.file_label();
        let spec = match &self.vibration {
            Some(v) => v.clone(),
            None => self.file.vibration.spec(&label)?,
        };
        if spec.is_empty() {
            return Ok(None);
        }
        let place = format!("{}: `vibration`", label.display());
        let v = Vibration::new(&spec, 1.0 / rate_hz, seed)
            .map_err(|e| SimError::Invalid(e.to_string()).at(Some(place)))?;
        for s in v.random_summaries() {
            if let Some(f) = s.truncated_at_hz {
                let w = format!(
                    "random vibration on {} {} cut at the Nyquist frequency {f} Hz",
                    s.sensor.name(),
                    ["x", "y", "z"][s.axis]
                );
                if !warnings.contains(&w) {
                    warnings.push(w);
                }
            }
        }
        Ok(Some(v))
    }

    /// The scene file's `[faults]` plus the faults set in code, checked against the output.
    fn faults(
        &self,
        output: &Output,
        rate: f64,
        seed: u64,
    ) -> Result<Option<FaultInjector>, SimError> {
        let label = self.file_label();
        let section = &self.file.faults;
        let mut specs = section.specs(&label, rate)?;
        let from_file = specs.len();
        for f in &self.faults {
            f.validate(rate).map_err(|e| {
                SimError::Invalid(e.to_string()).at(Some(format!("fault {}", f.kind.name())))
            })?;
        }
        specs.extend(self.faults.iter().cloned());
        if specs.is_empty() {
            return Ok(None);
        }
        let Output::Frames(plan) = output else {
            return Err(SimError::Invalid(
                "faults apply to protocol frames: choose a protocol as the output format".into(),
            ));
        };
        for (i, s) in specs.iter().enumerate() {
            if let Err(e) = plan.supports(s.kind) {
                let place = if i < from_file {
                    format!("{}: `faults.event[{i}].kind`", label.display())
                } else {
                    format!("fault {}", s.kind.name())
                };
                return Err(SimError::Invalid(e.to_string()).at(Some(place)));
            }
        }
        Ok(Some(FaultInjector::new(
            specs,
            rate,
            section.seed.unwrap_or(seed),
        )))
    }

    /// Gauss–Legendre nodes per interval: setter, then `engine.quadrature_nodes`, then 3.
    fn nodes(&self) -> Result<usize, SimError> {
        let e = &self.file.engine;
        let at = self.file_key(
            self.nodes.is_some(),
            e.quadrature_nodes.is_some(),
            "engine.quadrature_nodes",
        );
        let nodes = (self.nodes.or(e.quadrature_nodes)).unwrap_or(DEFAULT_NODES);
        if !(1..=crate::quadrature::MAX_NODES).contains(&nodes) {
            return Err(SimError::Invalid(format!(
                "quadrature {nodes}: expected 1 to 16 Gauss–Legendre nodes"
            ))
            .at(at));
        }
        Ok(nodes)
    }

    /// Resolves every setting (setters over the scene file over the defaults) and assembles
    /// the simulation: motion, grid, error chain and encoding.
    pub fn build(self) -> Result<Simulation, SimError> {
        let label = self.file_label();
        if self.is_rig() {
            return Err(SimError::Invalid(format!(
                "{}: lists `[[imu]]` units (a rig): this command runs one IMU; `generate` writes a rig (docs/rig.md)",
                label.display()
            )));
        }
        let (source, _, _) = self.source()?;
        let mut imu = self.resolve_imu()?;
        if let Some(t) = &self.file.timing {
            imu.timing.apply_table(t).map_err(|e| {
                SimError::Invalid(e.message).at(Some(format!(
                    "{}: `timing.{}`",
                    label.display(),
                    e.key
                )))
            })?;
        }
        let seed = (self.seed.or(self.file.imu.seed)).unwrap_or(crate::rng::DEFAULT_SEED);
        let temperature = match &self.temperature {
            Some(p) => Some(p.clone()),
            None => self.file.temperature.profile(&label, &self.base())?,
        };
        let mut output = self.output()?;
        let nodes = self.nodes()?;
        let rate_in_file = self.file.imu.rate_hz.is_some();
        let protocol_hz = match &output {
            Output::Frames(p) => p.rate_hz,
            Output::Records(_) => None,
        };
        // A unit with an output filter has its rate built in (the internal rate is a multiple
        // of it): it outranks the nominal rate of a protocol nobody chose (a command's
        // default), not that of one the user asked for.
        let chosen = self.format.is_some()
            || self.protocol_file.is_some()
            || self.file.output.format.is_some();
        let (first, second) = if imu.output_filter.is_some() && !chosen {
            (imu.rate_hz, protocol_hz)
        } else {
            (protocol_hz, imu.rate_hz)
        };
        let rate = Rate {
            hz: (self.rate.or(self.file.imu.rate_hz))
                .or(first)
                .or(second)
                .unwrap_or(DEFAULT_RATE_HZ),
            place: self.file_key(self.rate.is_some(), rate_in_file, "imu.rate_hz"),
        };
        let motion = self.motion()?;
        let mut grid = self.grid(&motion, &source, rate.clone())?;
        let timing = self.timing(&imu, &motion, &mut grid, seed)?;
        if let Output::Frames(plan) = &mut output {
            plan.set_rate(grid.rate_hz)
                .map_err(|e| SimError::Invalid(e).at(rate.place.clone()))?;
        }
        let faults = self.faults(&output, grid.rate_hz, seed)?;
        let gnss = self.resolve_aiding(&self.gnss, &self.file.gnss, GnssConfig::validate)?;
        let SensorSet {
            odometer,
            baro,
            magnetometer,
        } = self.sensor_set()?;
        let mut warnings = Vec::new();
        let (chain, filtered) = self.chain(
            &imu,
            grid.rate_hz,
            seed,
            temperature.as_ref(),
            &mut warnings,
        )?;
        Ok(Simulation {
            motion,
            grid,
            nodes,
            output,
            chain,
            filtered,
            imu,
            seed,
            temperature,
            faults,
            gps_time: self.gps_time,
            gnss_time: None,
            gnss,
            odometer,
            baro,
            magnetometer,
            case_rotation: self.case_rotation(),
            output_path: self.file.output.path.clone(),
            warnings,
            timing,
        })
    }

    /// The timing errors of `imu` over `grid`, if it has any. The sensor's instants stray
    /// from the grid by up to [`crate::timing::TimingModel::margin`]: a run that would reach
    /// past the motion's end by that much is shortened when no duration was asked for, and
    /// refused when one was.
    fn timing(
        &self,
        imu: &ImuModel,
        motion: &AnyMotion,
        grid: &mut Grid,
        seed: u64,
    ) -> Result<Option<crate::engine::timed::TimedRun>, SimError> {
        let model = imu.timing;
        let filter = imu.output_filter.as_ref();
        if model.is_zero() && filter.is_none() {
            return Ok(None);
        }
        if filter.is_some() && !model.emission_only() {
            return Err(SimError::Invalid(format!(
                "template `{}` has an [output_filter] and sampling-clock timing errors (clock, jitter, skew or missing samples): with a filter only `latency`, `latency_spread` and late frames are modelled yet",
                imu.name
            )));
        }
        let duration = grid.count as f64 / grid.rate_hz;
        let margin = model.margin(duration);
        let end = grid.t0 + duration + margin;
        if end > motion.end() {
            if self.duration.or(self.file.output.duration_s).is_some() {
                return Err(SimError::Invalid(format!(
                    "with the IMU's timing errors its samples may fall up to {} s after the grid's end, past the trajectory's end {} s: give a duration at least that much shorter",
                    short_number(margin),
                    short_number(motion.end())
                )));
            }
            let fit = ((motion.end() - margin - grid.t0) * grid.rate_hz).floor();
            if fit < 1.0 {
                return Err(SimError::Invalid(format!(
                    "the trajectory is too short for the IMU's timing errors (margin {} s)",
                    short_number(margin)
                )));
            }
            grid.count = fit as u64;
        }
        let span = (motion.start() - grid.t0, motion.end() - grid.t0);
        let duration = grid.count as f64 / grid.rate_hz;
        let sensor = crate::timing::SensorTiming::new(model, grid.rate_hz, duration, seed, span)
            .map_err(|e| SimError::Invalid(format!("{}: {e}", imu.name)))?;
        let offset = filter.map_or(0.0, |f| f.validity_offset_s(grid.rate_hz));
        Ok(Some(
            crate::engine::timed::TimedRun::new(sensor, grid.rate_hz, grid.t0)
                .with_validity_offset(offset),
        ))
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
