//! The scene file's `[[imu]]` list: one entry per unit of a rig, read as written and turned
//! into [`UnitSpec`]s with errors that name the file and the key (`imu[2].gyro[3].axis`).
//! A single `[imu]` table keeps its meaning (one IMU, `config::ImuSection`).

use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde::de::{self, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};

use super::{ConfigError, ImuSection};
use crate::math::Vec3;
use crate::rig::failure::{FailureKind, FailureSpec, Pick};
use crate::rig::skew::{SkewLayout, SkewSensor};
use crate::rig::{SinkAddr, UnitModel, UnitSpec};
use crate::units::{self, Kind};

/// One `[[imu]]` entry.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct UnitEntry {
    /// Unique name; names the output files.
    pub name: String,
    /// Error template (three-axis IMU); not with `gyro`/`accel`.
    pub model: Option<String>,
    /// Output rate (Hz).
    pub rate_hz: Option<f64>,
    /// Seed of its error terms and failures (default: from the master seed and the name).
    pub seed: Option<u64>,
    /// Mounting: [roll, pitch, yaw] of C_c^b (degrees).
    pub mounting_deg: Option<[f64; 3]>,
    /// Lever arm from the trajectory's reference point to the unit (body frame, m).
    pub lever_arm_m: Option<[f64; 3]>,
    /// `csv`, `bin` or a protocol (skew units: `csv` or an N-channel protocol, e.g. `skew6`).
    pub format: Option<String>,
    /// Output path (default: NAME.csv or NAME.bin in the output directory).
    pub path: Option<PathBuf>,
    /// Single-axis gyros of a skew-redundant unit.
    #[serde(default)]
    pub gyro: Vec<SensorEntry>,
    /// Single-axis accelerometers of a skew-redundant unit.
    #[serde(default)]
    pub accel: Vec<SensorEntry>,
    /// Scheduled sensor failures.
    #[serde(default)]
    pub failure: Vec<FailureEntry>,
    /// Where `run` streams the unit: one sink (`"udp:127.0.0.1:9001"`) or a list.
    pub sink: Option<OneOrMany>,
}

/// A string or a list of strings.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum OneOrMany {
    /// One.
    One(String),
    /// Several.
    Many(Vec<String>),
}

/// One `[[imu.gyro]]` or `[[imu.accel]]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SensorEntry {
    /// Sense axis in the unit's axes (normalised).
    pub axis: [f64; 3],
    /// Position in the unit's axes (m).
    pub position_m: Option<[f64; 3]>,
    /// Constant bias, with a unit (`"2 deg/h"`, `"0.1 mg"`).
    pub bias: Option<String>,
    /// Scale-factor error, with a unit (`"100 ppm"`).
    pub scale_factor: Option<String>,
    /// White-noise density: angle or velocity random walk (`"0.01 deg/sqrt(h)"`).
    pub noise: Option<String>,
}

/// One `[[imu.failure]]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FailureEntry {
    /// `stuck`, `null`, `bias-step`, `bias-ramp`, `scale-factor-jump`, `noise-burst`,
    /// `saturation` or `intermittent`.
    pub kind: String,
    /// A channel (`gyro_2`, `accel_z`), or `random`, `random gyro`, `random accel`.
    pub sensor: String,
    /// Start time (s).
    pub at_s: Option<f64>,
    /// Start time drawn uniformly from [lo, hi] (s).
    pub random_at_s: Option<[f64; 2]>,
    /// Duration (s); default: to the end.
    pub duration_s: Option<f64>,
    /// Magnitude in SI units (rad/s, m/s², per second for a ramp, ratio, probability).
    pub magnitude: Option<f64>,
    /// Magnitude drawn uniformly from [lo, hi].
    pub random_magnitude: Option<[f64; 2]>,
}

impl UnitEntry {
    /// The unit this entry (`imu[index]` of `path`) describes.
    pub fn spec(&self, index: usize, path: &Path) -> Result<UnitSpec, ConfigError> {
        let bad = |key: &str, message: String| ConfigError::Value {
            path: path.to_path_buf(),
            key: format!("imu[{index}].{key}"),
            message,
        };
        let skew = !(self.gyro.is_empty() && self.accel.is_empty());
        let model = match (&self.model, skew) {
            (Some(_), true) => {
                return Err(bad(
                    "model",
                    "give either `model` (a three-axis IMU) or `gyro`/`accel` sensors (a skew-redundant unit), not both".into(),
                ));
            }
            (Some(m), false) => UnitModel::Template(m.clone()),
            (None, false) => UnitModel::Template("ideal".into()),
            (None, true) => {
                let mut layout = SkewLayout::default();
                for (list, kind, out) in [
                    (&self.gyro, "gyro", &mut layout.gyros),
                    (&self.accel, "accel", &mut layout.accels),
                ] {
                    for (j, s) in list.iter().enumerate() {
                        out.push(
                            s.sensor(kind)
                                .map_err(|(k, m)| bad(&format!("{kind}[{j}].{k}"), m))?,
                        );
                    }
                }
                if layout.channels() > 64 {
                    return Err(bad(
                        "gyro",
                        format!("{} sensors: at most 64", layout.channels()),
                    ));
                }
                UnitModel::Skew(layout)
            }
        };
        if skew && self.format.as_deref() == Some("bin") {
            return Err(bad(
                "format",
                "a skew-redundant unit writes `csv` or an N-channel protocol's frames (e.g. `skew6`)".into(),
            ));
        }
        for (key, v) in [
            ("mounting_deg", self.mounting_deg),
            ("lever_arm_m", self.lever_arm_m),
        ] {
            if v.is_some_and(|v| v.iter().any(|x| !x.is_finite())) {
                return Err(bad(key, "expected three finite numbers".into()));
            }
        }
        let mut spec = UnitSpec {
            name: self.name.clone(),
            model,
            rate_hz: self.rate_hz,
            seed: self.seed,
            mounting_deg: self.mounting_deg.unwrap_or_default(),
            lever_arm_m: self.lever_arm_m.unwrap_or_default(),
            format: self.format.clone(),
            path: self.path.clone(),
            failures: Vec::new(),
            sinks: Vec::new(),
        };
        let sinks = match &self.sink {
            None => &[][..],
            Some(OneOrMany::One(s)) => std::slice::from_ref(s),
            Some(OneOrMany::Many(v)) => &v[..],
        };
        for (j, s) in sinks.iter().enumerate() {
            let key = match self.sink {
                Some(OneOrMany::Many(_)) => format!("sink[{j}]"),
                _ => "sink".into(),
            };
            spec.sinks
                .push(SinkAddr::parse_with_protocol(s).map_err(|m| bad(&key, m))?);
        }
        let names = spec.channel_names();
        for (j, f) in self.failure.iter().enumerate() {
            let s = f
                .spec(&names)
                .map_err(|(k, m)| bad(&format!("failure[{j}].{k}"), m))?;
            spec.failures.push(s);
        }
        Ok(spec)
    }
}

impl SensorEntry {
    /// The sensor; errors give the key and the message.
    fn sensor(&self, kind: &str) -> Result<SkewSensor, (&'static str, String)> {
        let a = Vec3::from(self.axis);
        if !(crate::math::all_finite(&a) && a.norm() > 0.0) {
            return Err(("axis", "expected a finite, non-zero vector".into()));
        }
        let p = self.position_m.unwrap_or_default();
        if p.iter().any(|x| !x.is_finite()) {
            return Err(("position_m", "expected three finite numbers".into()));
        }
        let (bias, noise) = match kind {
            "gyro" => (Kind::AngularRate, Kind::AngleRandomWalk),
            _ => (Kind::Acceleration, Kind::VelocityRandomWalk),
        };
        let value = |text: &Option<String>, k: Kind, key: &'static str| match text {
            None => Ok(0.0),
            Some(t) => units::parse(t, k)
                .map(|v| v.0)
                .map_err(|e| (key, format!("`{t}`: {e}"))),
        };
        let noise_density = value(&self.noise, noise, "noise")?;
        if noise_density < 0.0 {
            return Err(("noise", "expected a density ≥ 0".into()));
        }
        let mut s = SkewSensor::along(self.axis);
        s.position_m = Vec3::from(p);
        s.bias = value(&self.bias, bias, "bias")?;
        s.scale_factor = value(&self.scale_factor, Kind::Ratio, "scale_factor")?;
        s.noise_density = noise_density;
        Ok(s)
    }
}

impl FailureEntry {
    /// The failure on a unit with channels `names`; errors give the key and the message.
    fn spec(&self, names: &[String]) -> Result<FailureSpec, (&'static str, String)> {
        let kind = FailureKind::from_name(&self.kind).ok_or_else(|| {
            let all = FailureKind::ALL.map(|k| k.name()).join(", ");
            ("kind", format!("`{}`: expected one of {all}", self.kind))
        })?;
        let among = |prefix: &str| -> Vec<usize> {
            (0..names.len())
                .filter(|&i| names[i].starts_with(prefix))
                .collect()
        };
        let channel = match self.sensor.as_str() {
            "random" => Pick::Random(among("")),
            "random gyro" => Pick::Random(among("gyro_")),
            "random accel" => Pick::Random(among("accel_")),
            s => Pick::Fixed(names.iter().position(|n| n == s).ok_or_else(|| {
                (
                    "sensor",
                    format!(
                        "`{s}`: expected one of {}, `random`, `random gyro`, `random accel`",
                        names.join(", ")
                    ),
                )
            })?),
        };
        let pick =
            |fixed: Option<f64>, random: Option<[f64; 2]>, key: &'static str, need: bool| match (
                fixed, random,
            ) {
                (Some(x), None) => Ok(Pick::Fixed(x)),
                (None, Some(r)) => Ok(Pick::Random(r.to_vec())),
                (None, None) if !need => Ok(Pick::Fixed(0.0)),
                _ => Err((key, format!("give either `{key}` or `random_{key}`"))),
            };
        Ok(FailureSpec {
            kind,
            channel,
            start_s: pick(self.at_s, self.random_at_s, "at_s", true)?,
            duration_s: self.duration_s,
            magnitude: pick(
                self.magnitude,
                self.random_magnitude,
                "magnitude",
                kind.needs_magnitude(),
            )?,
        })
    }
}

/// Deserializes the scene file's `imu`: an `[imu]` table as [`ImuSection`], or an `[[imu]]`
/// list as the default section (the list is read by [`units_of`], which can locate its
/// errors).
pub fn table_or_list<'de, D: Deserializer<'de>>(d: D) -> Result<ImuSection, D::Error> {
    struct TableOrList;
    impl<'de> Visitor<'de> for TableOrList {
        type Value = ImuSection;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("an `[imu]` table or an `[[imu]]` list")
        }
        fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<ImuSection, A::Error> {
            ImuSection::deserialize(de::value::MapAccessDeserializer::new(map))
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<ImuSection, A::Error> {
            while seq.next_element::<IgnoredAny>()?.is_some() {}
            Ok(ImuSection::default())
        }
    }
    d.deserialize_any(TableOrList)
}

/// The scene file seen only for its `[[imu]]` list.
#[derive(Deserialize)]
struct RigFile {
    #[serde(default)]
    imu: Vec<UnitEntry>,
}

/// The `[[imu]]` entries of scene-file `text` (empty when it has an `[imu]` table or none).
pub fn units_of(text: &str) -> Result<Vec<UnitEntry>, toml::de::Error> {
    let is_list = toml::from_str::<toml::Table>(text)?
        .get("imu")
        .is_some_and(|v| v.is_array());
    if !is_list {
        return Ok(Vec::new());
    }
    Ok(toml::from_str::<RigFile>(text)?.imu)
}
