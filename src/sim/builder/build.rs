//! Resolving a builder's settings (setters over the scene file over the defaults) into a
//! [`Simulation`]: the motion source, model settings, IMU, output encoding, span and grid,
//! error chain with temperature, mounting and vibration, faults and sampling timing.

use super::{DEFAULT_RATE_HZ, Imu, Rate, SimulationBuilder, short_number, triad_frames};
use crate::aiding::GnssConfig;
use crate::aiding::sensors::SensorSet;
use crate::config;
use crate::engine::{self, EngineError, Grid, SourceSpec};
use crate::errors::ErrorChain;
use crate::errors::filtered::FilteredChain;
use crate::errors::temperature::TemperatureProfile;
use crate::errors::template::ImuModel;
use crate::errors::vibration::Vibration;
use crate::generator::DEFAULT_NODES;
use crate::motion::Motion;
use crate::motion::sampled::{Degree, ModelSettings};
use crate::output::Format;
use crate::protocol::{self, FaultInjector};
use crate::scenes;
use crate::sim::{Output, SimError, Simulation};
use crate::source::AnyMotion;

impl SimulationBuilder {
    /// The source and whether its scene name and its parameters came from the scene file.
    pub(super) fn source(&self) -> Result<(SourceSpec, bool, bool), SimError> {
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
    pub(super) fn resolve_imu(&self) -> Result<ImuModel, SimError> {
        let file = &self.file.imu.model;
        let at = self.file_key(self.imu.is_some(), file.is_some(), "imu.model");
        let name = match &self.imu {
            Some(Imu::Model(m)) => return Ok((**m).clone()),
            Some(Imu::Named(n)) => n.clone(),
            None => file.clone().unwrap_or_else(|| self.default_imu.clone()),
        };
        crate::sim::load_template(&name).map_err(|e| e.at(at))
    }

    /// The output encoding: a protocol file, else `csv`, `bin` or a built-in protocol.
    pub(super) fn output(&self) -> Result<Output, SimError> {
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
    pub(super) fn span_place(&self, source: &SourceSpec) -> Option<String> {
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
    pub(super) fn grid(
        &self,
        motion: &AnyMotion,
        source: &SourceSpec,
        rate: Rate,
    ) -> Result<Grid, SimError> {
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
    pub(super) fn chain(
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
    pub(super) fn configure(
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
    pub(super) fn build_vibration(
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
    pub(super) fn faults(
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
    pub(super) fn nodes(&self) -> Result<usize, SimError> {
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
        // A unit with an output filter has its rate built in (its filter's output, decimated or
        // read by its host): it outranks the nominal rate of a protocol nobody chose (a
        // command's default), not that of one the user asked for.
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
    pub(super) fn timing(
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
        // Under an output filter the clock ticks at the internal rate.
        let read = match filter {
            Some(f) => f.check(grid.rate_hz).map_err(|e| {
                SimError::Invalid(format!("template `{}`: [output_filter]: {e}", imu.name))
            })?,
            None => crate::timing::ReadRatio::integer(1),
        };
        let sensor =
            crate::timing::SensorTiming::decimated(model, grid.rate_hz, read, duration, seed, span)
                .map_err(|e| {
                    SimError::Invalid(format!("template `{}`: [timing]: {e}", imu.name))
                })?;
        // Each sensor's records are valid at its own filter's delay (`tov`, `tov_accel`).
        let offset = filter.map_or([0.0; 2], |f| {
            [false, true].map(|a| f.sensor(a).validity_offset_s(grid.rate_hz))
        });
        Ok(Some(
            crate::engine::timed::TimedRun::new(sensor, grid.rate_hz, grid.t0)
                .with_validity_offset(offset),
        ))
    }
}
