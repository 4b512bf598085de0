//! The GNSS epochs of a run's receiver over its span, on the same motion and GPS time
//! reference as the IMU records, written in a wire format with their truth; and the
//! odometer's samples.

use std::fmt::Write as _;
use std::io::Write;

use super::SimError;
use super::streams::AidingStreams;
use crate::aiding::gnss::Receiver;
use crate::aiding::odometer::Odometer;
use crate::aiding::stream::{TRUTH_HEADER, truth_row};
use crate::aiding::{GnssEncoder, GnssFormat};

impl AidingStreams<'_> {
    /// The receiver (the configured one, else the default) with this run's seed; a motion
    /// definition's spans without GNSS visibility are further outages.
    pub fn gnss_receiver(&self) -> Receiver {
        let mut cfg = self.gnss.cloned().unwrap_or_default();
        if let Some(m) = self.motion.defined() {
            cfg.outages_s.extend(m.gnss_outages());
        }
        // The settings were checked when the simulation was built; the default is valid.
        Receiver::new(cfg, self.seed).expect("checked GNSS settings")
    }

    /// An encoder of `format` on this run's GPS time reference.
    pub fn gnss_encoder(&self, format: GnssFormat) -> GnssEncoder {
        let (week, sow) = self.gps_time.unwrap_or((0, 0.0));
        let leap = self.gnss.map_or(18, |g| g.leap_seconds);
        GnssEncoder::new(format, week, sow, leap)
    }

    /// Writes the GNSS epochs of the run in each of `outputs`' formats and, if `truth` is
    /// given, their truth CSV; returns the number of epochs.
    pub fn write_gnss(
        &self,
        outputs: &mut [(GnssFormat, &mut dyn Write)],
        mut truth: Option<&mut dyn Write>,
    ) -> Result<u64, SimError> {
        let mut rx = self.gnss_receiver();
        let (t0, t1) = self.span;
        let mut enc: Vec<GnssEncoder> = outputs.iter().map(|o| self.gnss_encoder(o.0)).collect();
        if let Some(w) = truth.as_mut() {
            w.write_all(TRUTH_HEADER.as_bytes()).map_err(io)?;
        }
        let (mut bytes, mut row, mut n) = (Vec::new(), String::new(), 0);
        while let Some(e) = rx.next_epoch(self.motion, t0, t1) {
            for (enc, (_, w)) in enc.iter_mut().zip(outputs.iter_mut()) {
                bytes.clear();
                enc.encode(&e, &mut bytes);
                w.write_all(&bytes).map_err(io)?;
            }
            if let Some(w) = truth.as_mut() {
                row.clear();
                truth_row(&e, &mut row);
                w.write_all(row.as_bytes()).map_err(io)?;
            }
            n += 1;
        }
        Ok(n)
    }
}

/// Header of the odometer CSV.
pub const ODOMETER_HEADER: &str = "t,ticks,delta_ticks,speed_m_s,true_distance_m\n";

impl AidingStreams<'_> {
    /// Writes the odometer's samples over the run (CSV, one row per sample at the end of each
    /// interval of 1/rate s from the start); the configured odometer, else the default.
    /// Returns the number of samples.
    pub fn write_odometer(&self, out: &mut dyn Write) -> Result<u64, SimError> {
        let cfg = self.odometer.cloned().unwrap_or_default();
        let rate = cfg.rate_hz;
        let mut odo = Odometer::new(cfg);
        let (t0, t1) = self.span;
        out.write_all(ODOMETER_HEADER.as_bytes()).map_err(io)?;
        let count = ((t1 - t0) * rate + 1e-9).floor() as u64;
        let mut row = String::new();
        for k in 1..=count {
            let (a, b) = (t0 + (k - 1) as f64 / rate, t0 + k as f64 / rate);
            let s = odo.sample(self.motion, a, b);
            row.clear();
            let _ = writeln!(
                row,
                "{},{},{},{},{}",
                s.t, s.ticks, s.delta_ticks, s.speed_m_s, s.true_distance_m
            );
            out.write_all(row.as_bytes()).map_err(io)?;
        }
        Ok(count)
    }
}

pub(super) fn io(e: std::io::Error) -> SimError {
    SimError::Job(crate::job::JobError::Io(e))
}
