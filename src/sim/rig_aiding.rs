//! A rig's aiding sensors (GNSS, odometer, barometer, magnetometer) on its motion, span,
//! master seed and GPS time: the same streams one IMU's simulation of the scene gives.

use super::AidingStreams;
use crate::aiding::GnssConfig;
use crate::aiding::sensors::{SensorKind, SensorRows};
use crate::rig::Rig;
use crate::source::AnyMotion;

impl Rig {
    /// The rig's aiding sensors on its motion, [`Rig::span`], master seed and GPS time: the
    /// same streams a single IMU's simulation of the scene writes.
    pub fn aiding(&self) -> AidingStreams<'_> {
        AidingStreams {
            motion: &self.motion,
            span: self.span(),
            seed: self.seed,
            gps_time: self.gnss_time.or(self.gps_time),
            gnss: self.gnss.as_ref(),
            sensors: self.sensors.clone(),
        }
    }
}

impl Rig {
    /// The GNSS receiver's epochs per second.
    pub fn gnss_rate_hz(&self) -> f64 {
        self.gnss
            .as_ref()
            .map_or(GnssConfig::default().rate_hz, |g| g.rate_hz)
    }

    /// How many GNSS epochs fall in [`Rig::span`] (outages included: they are sent without
    /// a fix).
    pub fn gnss_epochs(&self) -> u64 {
        self.aiding().gnss_epochs()
    }
}

impl Rig {
    /// Sensor `kind`'s rows over [`Rig::span`] (the scene file's table, else the default),
    /// its errors from the rig's master seed.
    pub fn sensor_rows(&self, kind: SensorKind) -> SensorRows<AnyMotion> {
        let span = self.span();
        SensorRows::new(kind, &self.sensors, self.motion.clone(), self.seed, span)
    }
}
