//! The GNSS epochs of a run's receiver over its span, on the same motion and GPS time
//! reference as the IMU records: written in a wire format with their truth, or as streams
//! for the real-time merger.

use std::io::Write;

use super::streams::AidingStreams;
use super::{SimError, Simulation};
use crate::aiding::gnss::{Receiver, epoch_count, grid_phase};
use crate::aiding::stream::{TRUTH_HEADER, truth_row};
use crate::aiding::{GnssConfig, GnssEncoder, GnssFormat};

impl AidingStreams<'_> {
    /// The receiver (the configured one, else the default) with this run's seed; a motion
    /// definition's spans without GNSS visibility are further outages.
    pub fn gnss_receiver(&self) -> Receiver {
        let mut cfg = self.gnss.cloned().unwrap_or_default();
        if let Some(m) = self.motion.defined() {
            cfg.outages_s.extend(m.gnss_outages());
        }
        // The settings were checked when the simulation was built; the default is valid.
        let rx = Receiver::new(cfg, self.seed).expect("checked GNSS settings");
        match self.gps_time {
            Some((_, sow)) => rx.on_gps_grid(sow),
            None => rx,
        }
    }

    /// How many GNSS epochs fall in the run (outages included: they are sent without a fix).
    pub fn gnss_epochs(&self) -> u64 {
        let rate = self
            .gnss
            .map_or(GnssConfig::default().rate_hz, |g| g.rate_hz);
        let phase = self.gps_time.map_or(0.0, |(_, sow)| grid_phase(rate, sow));
        epoch_count(rate, phase, self.span)
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

impl Simulation {
    /// The receiver's epochs per second.
    pub fn gnss_rate_hz(&self) -> f64 {
        self.gnss
            .as_ref()
            .map_or(GnssConfig::default().rate_hz, |g| g.rate_hz)
    }

    /// How many GNSS epochs fall in the run (outages included).
    pub fn gnss_epochs(&self) -> u64 {
        self.aiding().gnss_epochs()
    }
}

pub(super) fn io(e: std::io::Error) -> SimError {
    SimError::Job(crate::engine::EngineError::Io(e))
}
