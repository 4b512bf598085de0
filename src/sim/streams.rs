//! The aiding sensors of a run (GNSS, odometer, barometer, magnetometer) on its motion, span,
//! master seed and GPS time: one view shared by a single IMU's [`Simulation`] and a
//! [`crate::rig::Rig`], so both write the same streams for the same scene.

use std::io::Write;

use super::{SimError, Simulation};
use crate::aiding::gnss::Receiver;
use crate::aiding::sensors::{SensorKind, SensorRows, SensorSet};
use crate::aiding::{GnssConfig, GnssEncoder, GnssFormat};
use crate::source::AnyMotion;

/// A run's aiding sensors: each writer uses the configured sensor, else the default one.
#[derive(Clone)]
pub struct AidingStreams<'a> {
    /// The motion every stream samples.
    pub motion: &'a AnyMotion,
    /// First and last instants of the run (s): samples and epochs fall inside.
    pub span: (f64, f64),
    /// The master seed the sensors' random errors draw from.
    pub seed: u64,
    /// True GPS week and second of record time 0, when given (the GNSS streams' reference).
    pub gps_time: Option<(u32, f64)>,
    /// The GNSS receiver's settings (scene file `[gnss]`).
    pub gnss: Option<&'a GnssConfig>,
    /// The odometer's, barometer's and magnetometer's settings (scene file).
    pub sensors: SensorSet,
}

impl AidingStreams<'_> {
    /// Sensor `kind`'s rows over the run (the configured sensor, else the default).
    pub fn sensor_rows(&self, kind: SensorKind) -> SensorRows<AnyMotion> {
        SensorRows::new(
            kind,
            &self.sensors,
            self.motion.clone(),
            self.seed,
            self.span,
        )
    }

    /// Writes sensor `kind`'s samples over the run as CSV (header, then a row per sample);
    /// returns the number of samples.
    pub fn write_sensor(&self, kind: SensorKind, out: &mut dyn Write) -> Result<u64, SimError> {
        super::sensors::write_rows(self.sensor_rows(kind), out)
    }

    /// Writes the odometer's samples ([`AidingStreams::write_sensor`]).
    pub fn write_odometer(&self, out: &mut dyn Write) -> Result<u64, SimError> {
        self.write_sensor(SensorKind::Odometer, out)
    }

    /// Writes the barometer's samples ([`AidingStreams::write_sensor`]).
    pub fn write_baro(&self, out: &mut dyn Write) -> Result<u64, SimError> {
        self.write_sensor(SensorKind::Baro, out)
    }

    /// Writes the magnetometer's samples ([`AidingStreams::write_sensor`]).
    pub fn write_magnetometer(&self, out: &mut dyn Write) -> Result<u64, SimError> {
        self.write_sensor(SensorKind::Magnetometer, out)
    }
}

impl Simulation {
    /// The run's aiding sensors on its motion, span, seed and GPS time.
    pub fn aiding(&self) -> AidingStreams<'_> {
        AidingStreams {
            motion: &self.motion,
            span: self.span(),
            seed: self.seed,
            gps_time: self.gnss_time.or(self.gps_time),
            gnss: self.gnss.as_ref(),
            sensors: self.sensors(),
        }
    }

    /// The GNSS receiver's settings, when the simulation has one (scene file `[gnss]` or
    /// [`super::SimulationBuilder::gnss`]).
    pub fn gnss(&self) -> Option<&GnssConfig> {
        self.gnss.as_ref()
    }

    /// First and last instants of the run (s): GNSS epochs fall inside.
    pub fn span(&self) -> (f64, f64) {
        let g = self.grid;
        (g.t0, g.t0 + g.count as f64 / g.rate_hz)
    }

    /// The receiver with this run's seed ([`AidingStreams::gnss_receiver`]).
    pub fn gnss_receiver(&self) -> Receiver {
        self.aiding().gnss_receiver()
    }

    /// An encoder of `format` on this run's GPS time reference.
    pub fn gnss_encoder(&self, format: GnssFormat) -> GnssEncoder {
        self.aiding().gnss_encoder(format)
    }

    /// Writes the run's GNSS epochs ([`AidingStreams::write_gnss`]).
    pub fn write_gnss(
        &self,
        outputs: &mut [(GnssFormat, &mut dyn Write)],
        truth: Option<&mut dyn Write>,
    ) -> Result<u64, SimError> {
        self.aiding().write_gnss(outputs, truth)
    }
}
