//! The barometer and the magnetometer of a simulation: setters, and the scene file's `[baro]`
//! and `[magnetometer]` tables checked, with the magnetometer's field table read.

use std::sync::Arc;

use super::{SimError, SimulationBuilder};
use crate::aiding::baro::BaroConfig;
use crate::aiding::field_table::FieldTable;
use crate::aiding::magnetometer::MagConfig;
use crate::aiding::odometer::OdometerConfig;
use crate::aiding::sensors::SensorSet;
use crate::math::{Quat, quat_from_euler};

type Sensors = (Option<BaroConfig>, Option<MagConfig>);

impl SimulationBuilder {
    /// A barometer on the same motion and clock (overrides the scene file's `[baro]`).
    pub fn baro(mut self, cfg: BaroConfig) -> SimulationBuilder {
        self.baro = Some(cfg);
        self
    }

    /// A magnetometer on the same motion and clock (overrides the scene file's
    /// `[magnetometer]`). A `field_table` path is read when the simulation is built (relative
    /// to the scene file when it came from one), unless `table` is already set.
    pub fn magnetometer(mut self, cfg: MagConfig) -> SimulationBuilder {
        self.magnetometer = Some(cfg);
        self
    }

    /// The checked odometer, barometer and magnetometer settings, the field table read.
    pub(super) fn sensor_set(&self) -> Result<SensorSet, SimError> {
        let odometer = self.resolve_aiding(
            &self.odometer,
            &self.file.odometer,
            OdometerConfig::validate,
        )?;
        let (baro, magnetometer) = self.baro_and_magnetometer()?;
        Ok(SensorSet {
            odometer,
            baro,
            magnetometer,
        })
    }

    /// C_b^c of the IMU's case (`imu.mounting_deg`): the axes of the frames' magnetic field.
    pub(super) fn case_rotation(&self) -> Option<Quat> {
        let [roll, pitch, yaw] = self.mounting_deg.or(self.file.imu.mounting_deg)?;
        let q_c_b = quat_from_euler(roll.to_radians(), pitch.to_radians(), yaw.to_radians());
        Some(q_c_b.conjugate())
    }

    /// The checked barometer and magnetometer settings, the field table read.
    pub(super) fn baro_and_magnetometer(&self) -> Result<Sensors, SimError> {
        let baro = self.resolve_aiding(&self.baro, &self.file.baro, BaroConfig::validate)?;
        let mut mag = self.resolve_aiding(
            &self.magnetometer,
            &self.file.magnetometer,
            MagConfig::validate,
        )?;
        if let Some(cfg) = mag.as_mut()
            && cfg.table.is_none()
            && let Some(rel) = &cfg.field_table
        {
            let path = match self.magnetometer.is_some() {
                true => rel.clone(),
                false => self.base().join(rel),
            };
            let place = self
                .file_key(
                    self.magnetometer.is_some(),
                    true,
                    "magnetometer.field_table",
                )
                .unwrap_or_else(|| "`magnetometer.field_table`".into());
            let text = crate::csvio::read_text(&path).map_err(|e| {
                SimError::Invalid(format!("reading {}: {e}", path.display())).at(Some(place))
            })?;
            let table = FieldTable::parse(&text).map_err(|e| {
                SimError::Invalid(format!(
                    "{}:{}: `{}`: {}",
                    path.display(),
                    e.line,
                    e.field,
                    e.message
                ))
            })?;
            cfg.table = Some(Arc::new(table));
        }
        Ok((baro, mag))
    }
}
