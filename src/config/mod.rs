//! The scene file (TOML): which trajectory, which IMU, what rate, where the output goes, and
//! the engine settings. Every key is optional; command-line flags override the file.
//! `examples/survey.toml` is a commented example.

pub mod rig;
pub mod run;

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::scenes::SceneParams;

/// A parsed scene file.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Trajectory source.
    #[serde(default)]
    pub trajectory: TrajectorySection,
    /// IMU model and rate (`[imu]`); an `[[imu]]` list (a rig) leaves it at its default and
    /// fills [`SceneFile::rig`].
    #[serde(default, deserialize_with = "rig::table_or_list")]
    pub imu: ImuSection,
    /// The units of a rig (`[[imu]]` entries; empty for a single `[imu]`).
    #[serde(skip)]
    pub rig: Vec<rig::UnitEntry>,
    /// Output.
    #[serde(default)]
    pub output: OutputSection,
    /// Motion model and quadrature settings.
    #[serde(default)]
    pub engine: EngineSection,
    /// The IMU's temperature over the run.
    #[serde(default)]
    pub temperature: TemperatureSection,
    /// Vibration of the IMU (sinusoids and random from PSD tables), in the case axes.
    #[serde(default)]
    pub vibration: VibrationSection,
    /// Faults injected into protocol frames.
    #[serde(default)]
    pub faults: FaultsSection,
    /// The IMU's timing errors, overriding the template's `[timing]` key by key.
    pub timing: Option<toml::Table>,
    /// A native motion definition (`imu_emu::motiondef::native`), checked when it is read.
    pub motion: Option<toml::Table>,
    /// The GNSS receiver next to the IMU (`[gnss]`; docs/aiding.md).
    #[serde(default)]
    pub gnss: Option<crate::aiding::GnssConfig>,
    /// The odometer (`[odometer]`; docs/aiding.md).
    #[serde(default)]
    pub odometer: Option<crate::aiding::odometer::OdometerConfig>,
    /// The barometer (`[baro]`; docs/aiding.md).
    #[serde(default)]
    pub baro: Option<crate::aiding::baro::BaroConfig>,
    /// The magnetometer (`[magnetometer]`; docs/aiding.md).
    #[serde(default)]
    pub magnetometer: Option<crate::aiding::magnetometer::MagConfig>,
    /// How `run` goes and where its streams go (`[run]`; docs/run.md).
    #[serde(default)]
    pub run: Option<run::RunSection>,
}

/// `[faults]`: faults injected into protocol frames (`[[faults.event]]` entries).
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FaultsSection {
    /// Seed of the rate-based faults (default: the IMU seed).
    pub seed: Option<u64>,
    /// The fault entries.
    #[serde(default)]
    pub event: Vec<FaultEntry>,
}

/// One `[[faults.event]]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FaultEntry {
    /// `corrupt-check`, `drop`, `duplicate`, `stale-counter` or `status`.
    pub kind: String,
    /// Record times (s) at which the fault hits the first frame at or after each.
    pub at_s: Option<Vec<f64>>,
    /// Mean events per second, drawn independently per frame.
    pub rate_per_s: Option<f64>,
    /// `status` only: how long each failure lasts (s); default one frame.
    pub duration_s: Option<f64>,
}

impl FaultsSection {
    /// The fault specs, checked against the frame rate (Hz); errors name `faults.event[i].key`.
    pub fn specs(
        &self,
        path: &Path,
        frame_rate: f64,
    ) -> Result<Vec<crate::protocol::FaultSpec>, ConfigError> {
        use crate::protocol::faults::{FaultKind, FaultSpec, When};
        let bad = |key: String, message: String| ConfigError::Value {
            path: path.to_path_buf(),
            key,
            message,
        };
        let mut out = Vec::new();
        for (i, e) in self.event.iter().enumerate() {
            let key = format!("faults.event[{i}]");
            let kind = FaultKind::from_name(&e.kind).ok_or_else(|| {
                bad(
                    format!("{key}.kind"),
                    format!(
                        "`{}`: expected one of {}",
                        e.kind,
                        FaultKind::ALL.map(|k| k.name()).join(", ")
                    ),
                )
            })?;
            let when = match (&e.at_s, e.rate_per_s) {
                (Some(t), None) => When::At(t.clone()),
                (None, Some(r)) => When::Rate(r),
                _ => {
                    return Err(bad(
                        key,
                        "give either `at_s = [times]` or `rate_per_s`".into(),
                    ));
                }
            };
            let field = match when {
                When::At(_) => "at_s",
                When::Rate(_) => "rate_per_s",
            };
            let spec = FaultSpec {
                kind,
                when,
                duration_s: e.duration_s.unwrap_or(0.0),
            };
            spec.validate(frame_rate).map_err(|m| {
                let field = if e.duration_s.is_some() && m.to_string().contains("duration") {
                    "duration_s"
                } else {
                    field
                };
                bad(format!("{key}.{field}"), m.to_string())
            })?;
            out.push(spec);
        }
        Ok(out)
    }
}

/// `[vibration]`: `[[vibration.sine]]` and `[[vibration.random]]` entries.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct VibrationSection {
    /// Sinusoids.
    #[serde(default)]
    pub sine: Vec<SineEntry>,
    /// Random vibrations.
    #[serde(default)]
    pub random: Vec<RandomEntry>,
}

/// One `[[vibration.sine]]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SineEntry {
    /// `accel` or `gyro`.
    pub sensor: String,
    /// `x`, `y` or `z`.
    pub axis: String,
    /// Peak amplitude with unit (`"0.5 g"`, `"2 deg/s"`).
    pub amplitude: String,
    /// Frequency with unit (`"25 Hz"`).
    pub frequency: String,
    /// Phase with unit (`"30 deg"`), default 0.
    pub phase: Option<String>,
}

/// One `[[vibration.random]]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RandomEntry {
    /// `accel` or `gyro`.
    pub sensor: String,
    /// `x`, `y` or `z`.
    pub axis: String,
    /// Breakpoints `[["20 Hz", "0.01 g^2/Hz"], …]`, log-log interpolated.
    pub psd: Vec<[String; 2]>,
}

impl VibrationSection {
    /// The vibration this section describes (empty when absent).
    pub fn spec(
        &self,
        path: &Path,
    ) -> Result<crate::errors::vibration::VibrationSpec, ConfigError> {
        use crate::errors::vibration::{Random, Sensor, Sine, VibrationSpec};
        use crate::units::{self, Kind};
        let bad = |key: String, message: String| ConfigError::Value {
            path: path.to_path_buf(),
            key,
            message,
        };
        let sensor = |s: &str, key: &str| match s {
            "accel" => Ok(Sensor::Accel),
            "gyro" => Ok(Sensor::Gyro),
            _ => Err(bad(
                format!("{key}.sensor"),
                format!("`{s}`: expected `accel` or `gyro`"),
            )),
        };
        let axis = |s: &str, key: &str| match s {
            "x" => Ok(0),
            "y" => Ok(1),
            "z" => Ok(2),
            _ => Err(bad(
                format!("{key}.axis"),
                format!("`{s}`: expected `x`, `y` or `z`"),
            )),
        };
        let value = |text: &str, kind: Kind, key: String| {
            units::parse(text, kind)
                .map(|v| v.0)
                .map_err(|e| bad(key, e.to_string()))
        };
        let mut spec = VibrationSpec::default();
        for (i, e) in self.sine.iter().enumerate() {
            let key = format!("vibration.sine[{i}]");
            let sensor = sensor(&e.sensor, &key)?;
            let kind = if sensor == Sensor::Accel {
                Kind::Acceleration
            } else {
                Kind::AngularRate
            };
            spec.sines.push(Sine {
                sensor,
                axis: axis(&e.axis, &key)?,
                amplitude: match value(&e.amplitude, kind, format!("{key}.amplitude"))? {
                    a if a < 0.0 => {
                        return Err(bad(
                            format!("{key}.amplitude"),
                            format!(
                                "`{}` must be ≥ 0 (use the phase for the sign)",
                                e.amplitude.trim()
                            ),
                        ));
                    }
                    a => a,
                },
                freq_hz: value(&e.frequency, Kind::Frequency, format!("{key}.frequency"))?,
                phase_rad: match &e.phase {
                    Some(p) => value(p, Kind::Angle, format!("{key}.phase"))?,
                    None => 0.0,
                },
            });
        }
        for (i, e) in self.random.iter().enumerate() {
            let key = format!("vibration.random[{i}]");
            let sensor = sensor(&e.sensor, &key)?;
            let kind = if sensor == Sensor::Accel {
                Kind::AccelPsd
            } else {
                Kind::RatePsd
            };
            let psd = e
                .psd
                .iter()
                .enumerate()
                .map(|(j, [f, p])| {
                    let row = format!("{key}.psd[{j}]");
                    let f = value(f, Kind::Frequency, row.clone())?;
                    let psd = value(p, kind, row.clone())?;
                    // Refused here, where the value is still as the user wrote it.
                    if psd <= 0.0 {
                        return Err(bad(
                            row,
                            format!(
                                "PSD `{}` must be positive (the table is interpolated log-log; \
                                 end the table instead of writing 0)",
                                p.trim()
                            ),
                        ));
                    }
                    Ok((f, psd))
                })
                .collect::<Result<Vec<_>, ConfigError>>()?;
            spec.randoms.push(Random {
                sensor,
                axis: axis(&e.axis, &key)?,
                psd,
            });
        }
        Ok(spec)
    }
}

/// `[temperature]`: the IMU temperature profile (°C) driving the templates' temperature terms.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TemperatureSection {
    /// `constant`, `ramp`, `warmup` or `file`.
    pub profile: Option<String>,
    /// Constant temperature (°C).
    pub celsius: Option<f64>,
    /// Start temperature of `ramp` and `warmup` (°C).
    pub start_celsius: Option<f64>,
    /// Ramp rate (°C/s).
    pub rate_celsius_per_s: Option<f64>,
    /// Temperature where the ramp stops (°C).
    pub limit_celsius: Option<f64>,
    /// Final temperature of `warmup` (°C).
    pub end_celsius: Option<f64>,
    /// Warm-up time constant (s).
    pub tau_s: Option<f64>,
    /// CSV of `t,T` for `file`, relative to the scene file.
    pub file: Option<PathBuf>,
}

impl TemperatureSection {
    /// The profile this section describes; `None` when absent (the model's reference
    /// temperature applies). `base` resolves a relative `file`.
    pub fn profile(
        &self,
        path: &Path,
        base: &Path,
    ) -> Result<Option<crate::errors::temperature::TemperatureProfile>, ConfigError> {
        use crate::errors::temperature::{TemperatureProfile as P, read_table};
        let Some(kind) = &self.profile else {
            return Ok(None);
        };
        let need = |v: Option<f64>, key: &str| -> Result<f64, ConfigError> {
            v.filter(|x| x.is_finite())
                .ok_or_else(|| ConfigError::Value {
                    path: path.to_path_buf(),
                    key: format!("temperature.{key}"),
                    message: format!("required by profile `{kind}` (a finite number)"),
                })
        };
        let p = match kind.as_str() {
            "constant" => P::Constant(need(self.celsius, "celsius")?),
            "ramp" => P::Ramp {
                start: need(self.start_celsius, "start_celsius")?,
                rate: need(self.rate_celsius_per_s, "rate_celsius_per_s")?,
                limit: self.limit_celsius,
            },
            "warmup" => {
                let tau = need(self.tau_s, "tau_s")?;
                if tau <= 0.0 {
                    return Err(ConfigError::Value {
                        path: path.to_path_buf(),
                        key: "temperature.tau_s".into(),
                        message: "must be positive".into(),
                    });
                }
                P::Warmup {
                    start: need(self.start_celsius, "start_celsius")?,
                    end: need(self.end_celsius, "end_celsius")?,
                    tau,
                }
            }
            "file" => {
                let f = self.file.as_ref().ok_or_else(|| ConfigError::Value {
                    path: path.to_path_buf(),
                    key: "temperature.file".into(),
                    message: "required by profile `file`".into(),
                })?;
                read_table(&base.join(f)).map_err(|e| ConfigError::Value {
                    path: path.to_path_buf(),
                    key: "temperature.file".into(),
                    message: format!("{e:#}"),
                })?
            }
            other => {
                return Err(ConfigError::Value {
                    path: path.to_path_buf(),
                    key: "temperature.profile".into(),
                    message: format!("`{other}`: expected constant, ramp, warmup or file"),
                });
            }
        };
        Ok(Some(p))
    }
}

/// `[trajectory]`: a built-in scene (with optional parameters) or a CSV file.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TrajectorySection {
    /// Built-in scene name.
    pub scene: Option<String>,
    /// Trajectory CSV path, relative to the scene file.
    pub file: Option<PathBuf>,
    /// Motion-definition file (gnss-ins-sim CSV), relative to the scene file.
    pub motion_def: Option<PathBuf>,
    /// Scene parameters overriding the scene's defaults.
    pub params: Option<toml::Table>,
}

/// `[imu]`.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ImuSection {
    /// IMU model: a template name or a template file.
    pub model: Option<String>,
    /// Output rate (Hz).
    pub rate_hz: Option<f64>,
    /// Master seed of the error model.
    pub seed: Option<u64>,
    /// Mounting of the IMU case in the body: [roll, pitch, yaw] of C_c^b in degrees.
    pub mounting_deg: Option<[f64; 3]>,
    /// Lever arm from the trajectory's reference point to the IMU, in the IMU case frame (m).
    pub lever_arm_m: Option<[f64; 3]>,
    /// Where `run` streams the IMU: one sink (`"pty:imu.pty"`, with `,protocol=NAME` for
    /// another wire format) or a list.
    pub sink: Option<rig::OneOrMany>,
}

/// `[output]`.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// `csv` or `bin`.
    pub format: Option<String>,
    /// Output path (relative to the current directory), or `-` for stdout.
    pub path: Option<PathBuf>,
    /// Start time t₀ (s); default: the trajectory's start.
    pub start_s: Option<f64>,
    /// Duration (s); default: to the trajectory's end (60 s for unbounded scenes).
    pub duration_s: Option<f64>,
}

/// `[engine]`.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EngineSection {
    /// Gauss–Legendre nodes per interval.
    pub quadrature_nodes: Option<usize>,
    /// `cubic` or `quintic`.
    pub interpolation: Option<String>,
    /// Finite-difference stencil size.
    pub stencil: Option<usize>,
}

/// A scene file that cannot be used, with the place and key at fault.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// Unreadable file (the cause is the error's `source()`, not repeated here).
    #[error("{path}: cannot read")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// TOML syntax or schema error.
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong (names the key).
        message: String,
    },
    /// A value that parses but is not acceptable.
    #[error("{path}: `{key}`: {message}")]
    Value {
        /// File.
        path: PathBuf,
        /// Dotted key.
        key: String,
        /// What is wrong.
        message: String,
    },
}

impl SceneFile {
    /// Parses scene-file text; `path` is used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<SceneFile, ConfigError> {
        let located = |e: toml::de::Error| {
            let (line, column) = e
                .span()
                .map_or((1, 1), |s| crate::csvio::line_col(text, s.start));
            let message = e.message().trim();
            ConfigError::Parse {
                path: path.to_path_buf(),
                line,
                column,
                message: match e.span().and_then(|s| key_at(text, s.start)) {
                    Some(key) => format!("`{key}`: {message}"),
                    None => message.to_string(),
                },
            }
        };
        let mut file: SceneFile = toml::from_str(text).map_err(located)?;
        file.rig = rig::units_of(text).map_err(located)?;
        // `[trajectory.params]` is kept as a table (the defaults depend on the scene); check its
        // keys and types now, while an error can still point at the line.
        if file.trajectory.params.is_some() {
            toml::from_str::<ParamsCheck>(text).map_err(located)?;
        }
        Ok(file)
    }

    /// Reads and parses a scene file.
    pub fn read(path: &Path) -> Result<SceneFile, ConfigError> {
        let text = crate::csvio::read_text(path).map_err(|source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        SceneFile::parse(&text, path)
    }

    /// Scene parameters: the scene's defaults overridden by `[trajectory.params]`.
    pub fn scene_params(&self, scene: &str, path: &Path) -> Result<SceneParams, ConfigError> {
        scene_params(scene, self.trajectory.params.as_ref()).map_err(|message| ConfigError::Value {
            path: path.to_path_buf(),
            key: "trajectory.params".into(),
            message,
        })
    }
}

/// The scene file seen only for its `[trajectory.params]`, typed, to locate bad keys and types.
/// Deserialized for its errors only: the values are never read.
#[allow(dead_code)]
#[derive(Deserialize)]
struct ParamsCheck {
    trajectory: Option<ParamsCheckTrajectory>,
}

/// See [`ParamsCheck`].
#[allow(dead_code)]
#[derive(Deserialize)]
struct ParamsCheckTrajectory {
    params: Option<SceneParams>,
}

/// Scene `scene`'s defaults with the keys of `overrides` replaced; unknown keys are errors.
pub fn scene_params(scene: &str, overrides: Option<&toml::Table>) -> Result<SceneParams, String> {
    let defaults = SceneParams::defaults_for(scene);
    let Some(over) = overrides else {
        return Ok(defaults);
    };
    let mut base = toml::Table::try_from(&defaults).map_err(|e| e.to_string())?;
    for (k, v) in over {
        base.insert(k.clone(), v.clone());
    }
    toml::Value::Table(base)
        .try_into()
        .map_err(|e: toml::de::Error| e.message().trim().to_string())
}

/// The dotted key of the `key = value` line (or `[table]` header) holding byte `offset`, e.g.
/// `imu.rate_hz`: serde's messages for a wrong type do not name the key, so the error does.
/// A plain reading of the line and the last table header above it; `None` if unclear.
fn key_at(text: &str, offset: usize) -> Option<String> {
    let start = text
        .get(..offset.min(text.len()))?
        .rfind('\n')
        .map_or(0, |i| i + 1);
    let line = text[start..].lines().next().unwrap_or("").trim();
    let header = |l: &str| {
        l.strip_prefix('[').and_then(|h| {
            let h = h.trim_start_matches('[');
            h.find(']').map(|end| h[..end].trim().to_string())
        })
    };
    if line.starts_with('[') {
        return header(line);
    }
    let (key, _) = line.split_once('=')?;
    let key = key.trim();
    if key.is_empty() || key.starts_with('#') {
        return None;
    }
    let table = text[..start]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .and_then(header);
    Some(match table {
        Some(t) if !t.is_empty() => format!("{t}.{key}"),
        _ => key.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A negative PSD or amplitude is echoed as written, not in converted SI units.
    #[test]
    fn vibration_sign_errors_echo_the_text() {
        let v = VibrationSection {
            sine: Vec::new(),
            random: vec![RandomEntry {
                sensor: "accel".into(),
                axis: "z".into(),
                psd: vec![
                    ["20 Hz".into(), "0.01 g^2/Hz".into()],
                    ["80 Hz".into(), "-0.01 g^2/Hz".into()],
                ],
            }],
        };
        let e = v.spec(Path::new("s.toml")).unwrap_err().to_string();
        assert!(
            e.contains("s.toml") && e.contains("vibration.random[0].psd[1]"),
            "{e}"
        );
        assert!(e.contains("`-0.01 g^2/Hz`") && !e.contains("0.0096"), "{e}");
        let v = VibrationSection {
            sine: vec![SineEntry {
                sensor: "accel".into(),
                axis: "x".into(),
                amplitude: "-0.5 g".into(),
                frequency: "25 Hz".into(),
                phase: None,
            }],
            random: Vec::new(),
        };
        let e = v.spec(Path::new("s.toml")).unwrap_err().to_string();
        assert!(
            e.contains("vibration.sine[0].amplitude") && e.contains("`-0.5 g`"),
            "{e}"
        );
    }
}
