//! The odometer's, the barometer's and the magnetometer's samples over a simulation's span,
//! from the same motion and seed as the IMU records: written as CSV with their truth
//! (`generate`), or as streams for the real-time merger (`run`), the same rows either way.

use std::io::Write;

use super::{SimError, Simulation};
use crate::aiding::sensors::{SensorKind, SensorRows, SensorSet};
use crate::engine::EngineError;
use crate::source::AnyMotion;

impl Simulation {
    /// The configured aiding sensors (scene file `[odometer]`, `[baro]`, `[magnetometer]`).
    pub fn sensors(&self) -> SensorSet {
        SensorSet {
            odometer: self.odometer.clone(),
            baro: self.baro.clone(),
            magnetometer: self.magnetometer.clone(),
        }
    }

    /// Sensor `kind`'s rows over the run (the configured sensor, else the default).
    pub fn sensor_rows(&self, kind: SensorKind) -> SensorRows<AnyMotion> {
        SensorRows::new(
            kind,
            &self.sensors(),
            self.motion.clone(),
            self.seed,
            self.span(),
        )
    }

    /// Writes sensor `kind`'s samples over the run as CSV (header, then a row per sample);
    /// returns the number of samples.
    pub fn write_sensor(&self, kind: SensorKind, out: &mut dyn Write) -> Result<u64, SimError> {
        write_rows(self.sensor_rows(kind), out)
    }

    /// Writes the odometer's samples over the run (CSV, one row per sample at the end of each
    /// interval of 1/rate s from the start); the configured odometer, else the default.
    /// Returns the number of samples.
    pub fn write_odometer(&self, out: &mut dyn Write) -> Result<u64, SimError> {
        self.write_sensor(SensorKind::Odometer, out)
    }

    /// Writes the barometer's samples over the run (CSV,
    /// [`crate::aiding::sensors::BARO_HEADER`]); the configured barometer (scene file
    /// `[baro]`), else the default. Returns the number of samples.
    pub fn write_baro(&self, out: &mut dyn Write) -> Result<u64, SimError> {
        self.write_sensor(SensorKind::Baro, out)
    }

    /// Writes the magnetometer's samples over the run (CSV,
    /// [`crate::aiding::sensors::MAG_HEADER`]); the configured magnetometer (scene file
    /// `[magnetometer]`), else the default. Returns the number of samples; a position outside
    /// the field table is an error naming the time.
    pub fn write_magnetometer(&self, out: &mut dyn Write) -> Result<u64, SimError> {
        self.write_sensor(SensorKind::Magnetometer, out)
    }

    /// The magnetometer's settings, when the simulation has one.
    pub fn magnetometer(&self) -> Option<&crate::aiding::magnetometer::MagConfig> {
        self.magnetometer.as_ref()
    }
}

/// Writes the header and every row of `rows` to `out`; returns the number of rows.
pub(crate) fn write_rows(
    mut rows: SensorRows<AnyMotion>,
    out: &mut dyn Write,
) -> Result<u64, SimError> {
    let io = |e| SimError::Job(crate::engine::EngineError::Io(e));
    out.write_all(rows.kind().header().as_bytes()).map_err(io)?;
    let (mut row, mut n) = (String::new(), 0);
    while rows
        .next_row(&mut row)
        .map_err(EngineError::from)?
        .is_some()
    {
        out.write_all(row.as_bytes()).map_err(io)?;
        n += 1;
    }
    Ok(n)
}
