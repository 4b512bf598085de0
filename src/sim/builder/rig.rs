//! The rig form of the builder: the scene file's `[[imu]]` list and the units added in code,
//! on the builder's motion, span, quadrature and master seed.

use super::{Rate, SimulationBuilder};
use crate::aiding::GnssConfig;
use crate::aiding::mag_samples::MagHold;
use crate::engine::Encoding;
use crate::errors::ErrorChain;
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
        if self.file.timing.is_some() {
            // Never run the units without the timing errors the scene file names.
            return Err(SimError::Invalid(format!(
                "`timing`: {NO_TIMING} (a scene file's [timing] applies to one `[imu]`)"
            ))
            .at(Some(format!("{}: `timing`", label.display()))));
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
                    Some(super::super::load_template(t).map_err(|e| e.at(Some(place("model"))))?)
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
            let grid = self.grid(&motion, &source, rate)?;
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
            let vibration = (self.build_vibration(grid.rate_hz, master, &mut warnings))
                .map_err(|e| e.at(Some(place("rate_hz"))))?;
            let frames = plan.is_some();
            let body = match (&spec.model, template) {
                (UnitModel::Skew(layout), _) => Body::Skew {
                    errors: ChannelErrors::of(layout, grid.rate_hz, seed),
                    layout: layout.clone(),
                    frames: plan.map(|p| Box::new((p, EncoderState::default()))),
                    vibration: vibration.map(Box::new),
                },
                (UnitModel::Template(_), Some(t)) => {
                    if t.output_filter.is_some() {
                        // Never run a unit without the filter its template names.
                        return Err(SimError::Invalid(format!(
                            "template `{}` has an [output_filter]: rig units do not run output filters yet (a single IMU does)",
                            t.name
                        ))
                        .at(Some(place("model"))));
                    }
                    if !t.timing.is_zero() {
                        return Err(SimError::Invalid(format!(
                            "template `{}` has [timing] errors: {NO_TIMING}",
                            t.name
                        ))
                        .at(Some(place("model"))));
                    }
                    let mut chain = ErrorChain::new(&t, grid.rate_hz, seed);
                    if let Some(p) = &temperature {
                        chain = chain.with_temperature(p.clone(), &t);
                    }
                    if let Some(v) = vibration {
                        chain = chain.with_vibration(v.in_axes(placement.c_b_c));
                    }
                    let encoding = match plan {
                        Some(plan) => Encoding::Frames {
                            plan: Box::new(plan),
                            state: EncoderState::default(),
                            temperature: DEFAULT_FRAME_CELSIUS,
                            side: Format::Csv,
                        },
                        None => {
                            Encoding::Records(Format::from_name(&format).unwrap_or(Format::Csv))
                        }
                    };
                    Body::Triad {
                        chain: (!chain.is_empty()).then(|| Box::new(chain)),
                        encoding: Box::new(encoding),
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
                (Some(cfg), Body::Triad { .. }) if frames => Some(Box::new(MagHold::in_axes(
                    cfg.clone(),
                    seed,
                    grid.t0,
                    placement.c_b_c,
                ))),
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

/// Why a rig refuses timing errors: its units on one grid share the error-free signal at the
/// grid's instants, where a unit with its own clock, jitter or latency needs its own.
const NO_TIMING: &str = "rig units do not model timing errors yet (a single IMU does; docs/rig.md)";

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
