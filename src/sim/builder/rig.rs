//! The rig form of the builder: the scene file's `[[imu]]` list and the units added in code,
//! on the builder's motion, span, quadrature and master seed.

use super::{Rate, SimulationBuilder};
use crate::aiding::GnssConfig;
use crate::aiding::mag_samples::MagHold;
use crate::engine::filtered::FilteredImu;
use crate::engine::{Encoding, EngineError, Producer};
use crate::errors::ErrorChain;
use crate::errors::filtered::FilteredChain;
use crate::errors::temperature::TemperatureProfile;
use crate::errors::template::ImuModel;
use crate::output::Format;
use crate::protocol::{self, EncoderState};
use crate::rig::failure::FailureSet;
use crate::rig::skew::ChannelErrors;
use crate::rig::{Body, Placement, Rig, Unit};
use crate::rig::{UnitModel, UnitSpec};
use crate::rng::{fnv1a64, splitmix64};
use crate::sim::{DEFAULT_FRAME_CELSIUS, SimError};

impl SimulationBuilder {
    /// Adds a unit to the rig (after the scene file's `[[imu]]` entries).
    pub fn unit(mut self, spec: UnitSpec) -> SimulationBuilder {
        self.units.push(spec);
        self
    }

    /// The rig's units as described (the scene file's `[[imu]]` entries, then those added in
    /// code), each with where it was given (`FILE: `imu[i]``, or `None` from code).
    pub fn unit_specs(&self) -> Result<Vec<(Option<usize>, UnitSpec)>, SimError> {
        let label = self.file_label();
        let mut specs = Vec::new();
        for (i, e) in self.file.rig.iter().enumerate() {
            specs.push((Some(i), e.spec(i, &label)?));
        }
        specs.extend(self.units.iter().cloned().map(|s| (None, s)));
        Ok(specs)
    }

    /// The units whose template has an output filter, as messages name them (`unit `nav``,
    /// or `template `NAME`` for a single IMU), found without the motion (a live run's signal
    /// before its first state).
    pub fn filtered_units(&self) -> Result<Vec<String>, SimError> {
        if !self.is_rig() {
            let t = self.resolve_imu()?;
            let named = (t.output_filter.is_some()).then(|| format!("template `{}`", t.name));
            return Ok(named.into_iter().collect());
        }
        let mut out = Vec::new();
        for (_, u) in self.unit_specs()? {
            if let UnitModel::Template(t) = &u.model
                && super::super::load_template(t)?.output_filter.is_some()
            {
                out.push(format!("unit `{}`", u.name));
            }
        }
        Ok(out)
    }

    /// Whether the scene file lists `[[imu]]` units or units were added in code: then
    /// [`SimulationBuilder::build_rig`] is the way to build.
    pub fn is_rig(&self) -> bool {
        !(self.file.rig.is_empty() && self.units.is_empty())
    }

    /// Resolves the rig: the motion, the span and quadrature of the builder, and every unit
    /// (the scene file's `[[imu]]` entries, then those added with [`Self::unit`]). A unit's
    /// rate is its own, else the builder's [`Self::rate`], else its protocol's nominal rate,
    /// else its template's, else 400 Hz. A unit's
    /// seed defaults to one drawn from the master seed and its name, so two units of the
    /// same template have independent errors.
    pub fn build_rig(self) -> Result<Rig, SimError> {
        let label = self.file_label();
        let single = [
            ("imu", self.imu.is_some()),
            ("format", self.format.is_some()),
            ("protocol file", self.protocol_file.is_some()),
            ("fault", !self.faults.is_empty()),
        ];
        if let Some((what, _)) = single.iter().find(|x| x.1) {
            return Err(SimError::Invalid(format!(
                "the {what} setting (--{}) describes one IMU, and {} lists `[[imu]]` units: give each unit its `model`, `format` and `[[imu.failure]]` entries",
                what.replace(' ', "-"),
                label.display()
            )));
        }
        let specs = self.unit_specs()?;
        if specs.is_empty() {
            return Err(SimError::Invalid(
                "a rig needs at least one unit (`[[imu]]` in the scene file)".into(),
            ));
        }
        let (source, _, _) = self.source()?;
        let motion = self.motion()?;
        let nodes = self.nodes()?;
        let master = (self.seed.or(self.file.imu.seed)).unwrap_or(crate::rng::DEFAULT_SEED);
        let temperature = match &self.temperature {
            Some(p) => Some(p.clone()),
            None => self.file.temperature.profile(&label, &self.base())?,
        };
        let sensors = self.sensor_set()?;
        let mut warnings = Vec::new();
        let mut units: Vec<Unit> = Vec::new();
        for (index, spec) in specs {
            let place = |key: &str| match index {
                Some(i) => format!("{}: `imu[{i}].{key}`", label.display()),
                None => format!("unit `{}`: `{key}`", spec.name),
            };
            let name_ok = !spec.name.is_empty()
                && (spec.name.chars()).all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
            if !name_ok || units.iter().any(|u| u.name == spec.name) {
                let why = if name_ok {
                    "used by another unit"
                } else {
                    "expected letters, digits, `_` or `-`"
                };
                return Err(
                    SimError::Invalid(format!("`{}`: {why}", spec.name)).at(Some(place("name")))
                );
            }
            let seed = spec
                .seed
                .unwrap_or_else(|| splitmix64(master ^ fnv1a64(&format!("unit/{}", spec.name))));
            let format = spec.format.clone().unwrap_or_else(|| "csv".into());
            let mut plan = match Format::from_name(&format) {
                Some(_) => None,
                None if protocol::builtin_names().contains(&format.as_str()) => {
                    Some(protocol::load(&format)?.1)
                }
                None => {
                    let e = SimError::Invalid(format!(
                        "`{format}`: expected `csv`, `bin` or a protocol"
                    ));
                    return Err(e.at(Some(place("format"))));
                }
            };
            let template = match &spec.model {
                UnitModel::Template(t) => {
                    let mut t =
                        super::super::load_template(t).map_err(|e| e.at(Some(place("model"))))?;
                    // The scene file's [timing] is every three-axis unit's, over its template's
                    // own, key by key (as for one `[imu]`).
                    if let Some(table) = &self.file.timing {
                        t.timing.apply_table(table).map_err(|e| {
                            SimError::Invalid(e.message).at(Some(format!(
                                "{}: `timing.{}`",
                                label.display(),
                                e.key
                            )))
                        })?;
                    }
                    Some(t)
                }
                UnitModel::Skew(_) if self.file.timing.is_some() => {
                    // Never run a unit without the timing errors the scene file names.
                    return Err(SimError::Invalid(format!(
                        "applies to every unit of the rig, and unit `{}` is skew-redundant: its single-axis sensors have no sampling-clock model (give the three-axis units' templates a [timing] table instead)",
                        spec.name
                    ))
                    .at(Some(format!("{}: `timing`", label.display()))));
                }
                UnitModel::Skew(_) => None,
            };
            let hz = (spec.rate_hz.or(self.rate))
                .or(plan.as_ref().and_then(|p| p.rate_hz))
                .or(template.as_ref().and_then(|t| t.rate_hz))
                .unwrap_or(super::DEFAULT_RATE_HZ);
            let rate = Rate {
                hz,
                place: Some(place("rate_hz")),
            };
            let mut grid = self.grid(&motion, &source, rate)?;
            // A unit with timing errors or an output filter samples on its own clock (its
            // grid may be shortened by the clock's margin), as one IMU does.
            let own = template
                .as_ref()
                .is_some_and(|t| t.output_filter.is_some() || !t.timing.is_zero());
            let timing = match &template {
                Some(t) if own => (self.timing(t, &motion, &mut grid, seed))
                    .map_err(|e| e.at(Some(place("model"))))?,
                _ => None,
            };
            if let Some(p) = plan.as_mut() {
                p.set_rate(grid.rate_hz)
                    .map_err(|e| SimError::Invalid(e).at(Some(place("rate_hz"))))?;
            }
            if let Some(p) = &plan {
                channels_fit(p, &spec.model).map_err(|e| {
                    SimError::Invalid(format!("`{format}`: {e}")).at(Some(place("format")))
                })?;
            }
            let placement = Placement::new(spec.mounting_deg, spec.lever_arm_m);
            // The body's vibration from the master seed: every unit on one time grid senses
            // the same realization, in its own axes.
            let vibration = match own {
                false => (self.build_vibration(grid.rate_hz, master, &mut warnings))
                    .map_err(|e| e.at(Some(place("rate_hz"))))?,
                true => None,
            };
            let frames = plan.is_some();
            let body = match (&spec.model, template) {
                (UnitModel::Skew(layout), _) => Body::Skew {
                    errors: ChannelErrors::of(layout, grid.rate_hz, seed),
                    layout: layout.clone(),
                    frames: plan.map(|p| Box::new((p, EncoderState::default()))),
                    vibration: vibration.map(Box::new),
                },
                (UnitModel::Template(_), Some(t)) if own => {
                    let (chain, filtered) = self
                        .unit_chain(
                            &t,
                            grid.rate_hz,
                            seed,
                            master,
                            temperature.as_ref(),
                            &placement,
                            spec.mounting_deg,
                            &mut warnings,
                        )
                        .map_err(|e| e.at(Some(place("model"))))?;
                    let filtered = match filtered {
                        Some(c) => Some(
                            FilteredImu::new(motion.clone(), grid, nodes, c)
                                .map_err(|e| SimError::from(EngineError::Filter(e)))
                                .map_err(|e| e.at(Some(place("rate_hz"))))?,
                        ),
                        None => None,
                    };
                    let producer =
                        Producer::new(motion.clone(), grid, nodes, Format::Bin, chain, false)?
                            .with_timing(timing)
                            .with_filter(filtered)
                            .with_truth_place(Box::new(placement.clone()));
                    Body::Produced {
                        producer: Box::new(producer),
                        encoding: Box::new(encoding(plan, &format)),
                        last_tov: 0.0,
                    }
                }
                (UnitModel::Template(_), Some(t)) => {
                    let mut chain = ErrorChain::new(&t, grid.rate_hz, seed);
                    if let Some(p) = &temperature {
                        chain = chain.with_temperature(p.clone(), &t);
                    }
                    if let Some(v) = vibration {
                        chain = chain.with_vibration(v.in_axes(placement.c_b_c));
                    }
                    Body::Triad {
                        chain: (!chain.is_empty()).then(|| Box::new(chain)),
                        encoding: Box::new(encoding(plan, &format)),
                    }
                }
                (UnitModel::Template(_), None) => unreachable!("a template unit has its template"),
            };
            let channels = spec.channel_names().len();
            let mut failures = Vec::new();
            for (j, f) in spec.failures.iter().enumerate() {
                let r = f.resolve(j, seed, channels).map_err(|(key, m)| {
                    SimError::Invalid(m).at(Some(place(&format!("failure[{j}].{key}"))))
                })?;
                failures.push(r);
            }
            // The unit's own magnetometer: its noise from the unit's seed (units differ; a unit
            // whose seed is the master seed draws the single IMU's samples).
            let mag = match (&sensors.magnetometer, &body) {
                (Some(cfg), Body::Triad { .. } | Body::Produced { .. }) if frames => {
                    Some(Box::new(MagHold::in_axes(
                        cfg.clone(),
                        seed,
                        grid.t0,
                        placement.c_b_c,
                    )))
                }
                _ => None,
            };
            let model = match &spec.model {
                UnitModel::Template(t) => format!("template {t}"),
                UnitModel::Skew(l) => format!(
                    "skew-redundant, {} gyros and {} accelerometers",
                    l.gyros.len(),
                    l.accels.len()
                ),
            };
            units.push(Unit {
                name: spec.name.clone(),
                model,
                grid,
                temperature: temperature.clone(),
                mag,
                place: placement,
                body,
                failures: FailureSet::new(failures, channels, seed),
                seed,
                path: spec.path.clone(),
                sinks: spec.sinks.clone(),
                flags: 0,
                triggered: false,
                extra: Vec::new(),
            });
        }
        let gnss = self.resolve_aiding(&self.gnss, &self.file.gnss, GnssConfig::validate)?;
        let mut rig = Rig {
            motion,
            nodes,
            units,
            warnings,
            gnss,
            sensors,
            seed: master,
            gps_time: None,
            gnss_time: None,
        };
        if let Some((week, sow)) = self.gps_time {
            rig.set_gps_time(week, sow);
        }
        Ok(rig)
    }
}

impl SimulationBuilder {
    /// The error chain of a producer-backed unit with template `t` at `rate_hz`: the
    /// template's chain — or, with an output filter, its filtered chain, whose internal-rate
    /// stages get these — with the temperature, the unit's mounting and lever arm (turned
    /// into its case frame) and the body's vibration (from the `master` seed, in the unit's
    /// axes, on the grid the chain runs at), as [`SimulationBuilder::chain`] builds one IMU's
    /// with its `[imu]` mounting and lever arm.
    #[allow(clippy::too_many_arguments)] // the unit's parts, each distinct
    fn unit_chain(
        &self,
        t: &ImuModel,
        rate_hz: f64,
        seed: u64,
        master: u64,
        temperature: Option<&TemperatureProfile>,
        place: &Placement,
        mounting_deg: [f64; 3],
        warnings: &mut Vec<String>,
    ) -> Result<(Option<ErrorChain>, Option<FilteredChain>), SimError> {
        let mut configure = |mut chain: ErrorChain, hz: f64| -> Result<ErrorChain, SimError> {
            if let Some(p) = temperature {
                chain = chain.with_temperature(p.clone(), t);
            }
            if place.c_b_c.is_some() {
                // C_c^b from the angles, as one IMU's `mounting_deg`; the chain wants C_b^c.
                let [r, p, y] = mounting_deg.map(f64::to_radians);
                chain = chain.with_mounting(crate::math::quat_from_euler(r, p, y).conjugate());
            }
            chain = chain.with_lever_arm(place.to_case(place.lever_b));
            if let Some(v) = self.build_vibration(hz, master, warnings)? {
                chain = chain.with_vibration(v.in_axes(place.c_b_c));
            }
            Ok(chain)
        };
        let Some(spec) = &t.output_filter else {
            let chain = configure(ErrorChain::new(t, rate_hz, seed), rate_hz)?;
            return Ok(((!chain.is_empty()).then_some(chain), None));
        };
        let filtered = FilteredChain::new(t, rate_hz, seed).map_err(|e| {
            SimError::Invalid(format!("template `{}`: [output_filter]: {e}", t.name))
        })?;
        let internal = spec.internal_rate_hz;
        let inner = ErrorChain::new(&FilteredChain::inner_model(t), internal, seed);
        let inner = configure(inner, internal)?;
        Ok((None, Some(filtered.map_inner(|_| inner))))
    }
}

/// A three-axis unit's encoding: the frames of `plan`, or the records `format` names.
fn encoding(plan: Option<protocol::Plan>, format: &str) -> Encoding {
    match plan {
        Some(plan) => Encoding::Frames {
            plan: Box::new(plan),
            state: EncoderState::default(),
            temperature: DEFAULT_FRAME_CELSIUS,
            side: Format::Csv,
        },
        None => Encoding::Records(Format::from_name(format).unwrap_or(Format::Csv)),
    }
}

/// A protocol's frames suit the unit: an N-channel frame carries exactly a skew unit's
/// channels (none dropped, none made up), a three-axis frame goes with a three-axis IMU.
fn channels_fit(plan: &protocol::Plan, model: &UnitModel) -> Result<(), String> {
    match (model, plan.channels()) {
        (UnitModel::Skew(_), Some((g, a))) if plan.carries_triad() => Err(format!(
            "carries three-axis fields next to its {g} gyro and {a} accelerometer channels; a skew-redundant unit has no three-axis reading"
        )),
        (UnitModel::Skew(l), Some((g, a))) if (g, a) != (l.gyros.len(), l.accels.len()) => {
            Err(format!(
                "carries {g} gyro and {a} accelerometer channels; the unit has {} and {}",
                l.gyros.len(),
                l.accels.len()
            ))
        }
        (UnitModel::Skew(_), None) => Err(
            "is a three-axis IMU's frame; a skew-redundant unit writes `csv` or an N-channel protocol's frames (e.g. `skew6`)".into(),
        ),
        (UnitModel::Template(_), Some((g, a))) => Err(format!(
            "carries {g} gyro and {a} accelerometer single-axis channels: it is a skew-redundant unit's frame (give the unit `[[imu.gyro]]`/`[[imu.accel]]` sensors)"
        )),
        _ => Ok(()),
    }
}
