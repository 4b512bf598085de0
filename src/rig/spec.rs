//! A unit of a rig as described — in a scene file's `[[imu]]` entry (`crate::config::rig`) or
//! in code — before it is built.

use std::path::PathBuf;

use super::failure::FailureSpec;
use super::skew::SkewLayout;
use crate::output::SinkAddr;

/// What a unit is: a three-axis IMU with an error template, or a skew-redundant unit.
#[derive(Clone, Debug, PartialEq)]
pub enum UnitModel {
    /// A template name or file.
    Template(String),
    /// Single-axis sensors.
    Skew(SkewLayout),
}

/// A unit of a rig as given (scene file or code), before it is built.
#[derive(Clone, Debug, PartialEq)]
pub struct UnitSpec {
    /// Unique name ([A-Za-z0-9_-]); names the output files.
    pub name: String,
    /// The unit's sensors and error terms.
    pub model: UnitModel,
    /// Output rate (Hz); default: the protocol's, else the template's, else 400 Hz.
    pub rate_hz: Option<f64>,
    /// Seed; default: from the master seed and the name.
    pub seed: Option<u64>,
    /// Mounting: [roll, pitch, yaw] of C_c^b (degrees).
    pub mounting_deg: [f64; 3],
    /// Lever arm (body frame, m).
    pub lever_arm_m: [f64; 3],
    /// `csv`, `bin` or a protocol; default `csv`.
    pub format: Option<String>,
    /// Output path.
    pub path: Option<PathBuf>,
    /// Failures.
    pub failures: Vec<FailureSpec>,
    /// Where `imu-emu run` streams the unit, each with the protocol its frames are in when it
    /// is not the unit's own `format` (`,protocol=NAME`).
    pub sinks: Vec<(SinkAddr, Option<String>)>,
}

impl UnitSpec {
    /// A three-axis IMU named `name` with template `model` at the reference point.
    pub fn imu(name: &str, model: &str) -> UnitSpec {
        UnitSpec::new(name, UnitModel::Template(model.into()))
    }

    /// A skew-redundant unit named `name` at the reference point.
    pub fn skew(name: &str, layout: SkewLayout) -> UnitSpec {
        UnitSpec::new(name, UnitModel::Skew(layout))
    }

    fn new(name: &str, model: UnitModel) -> UnitSpec {
        UnitSpec {
            name: name.into(),
            model,
            rate_hz: None,
            seed: None,
            mounting_deg: [0.0; 3],
            lever_arm_m: [0.0; 3],
            format: None,
            path: None,
            failures: Vec::new(),
            sinks: Vec::new(),
        }
    }

    /// The channel names failures refer to.
    pub fn channel_names(&self) -> Vec<String> {
        match &self.model {
            UnitModel::Template(_) => crate::record::COLUMNS[1..7]
                .iter()
                .map(|s| s.to_string())
                .collect(),
            UnitModel::Skew(l) => l.channel_names(),
        }
    }
}
