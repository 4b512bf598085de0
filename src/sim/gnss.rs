//! The aiding streams of a simulation: GNSS epochs of its receiver over the run's span, on the
//! same motion and GPS time reference as the IMU records, written in a wire format with their
//! truth, or as streams for the real-time merger.

use std::io::Write;

use super::{SimError, Simulation};
use crate::aiding::gnss::Receiver;
use crate::aiding::stream::{TRUTH_HEADER, truth_row};
use crate::aiding::window::{GnssFrames, GnssWindow};
use crate::aiding::{GnssConfig, GnssEncoder, GnssFormat};
use crate::source::AnyMotion;

impl Simulation {
    /// The GNSS receiver's settings, when the simulation has one (scene file `[gnss]` or
    /// [`super::SimulationBuilder::gnss`]).
    pub fn gnss(&self) -> Option<&GnssConfig> {
        self.gnss.as_ref()
    }

    /// The receiver (the configured one, else the default) with this run's seed; a motion
    /// definition's spans without GNSS visibility are further outages.
    pub fn gnss_receiver(&self) -> Receiver {
        let mut cfg = self.gnss.clone().unwrap_or_default();
        if let Some(m) = self.motion.defined() {
            cfg.outages_s.extend(m.gnss_outages());
        }
        // The settings were checked when the simulation was built; the default is valid.
        Receiver::new(cfg, self.seed).expect("checked GNSS settings")
    }

    /// First and last instants of the run (s): GNSS epochs fall inside.
    pub fn span(&self) -> (f64, f64) {
        let g = self.grid;
        (g.t0, g.t0 + g.count as f64 / g.rate_hz)
    }

    /// An encoder of `format` on this run's GPS time reference.
    pub fn gnss_encoder(&self, format: GnssFormat) -> GnssEncoder {
        let (week, sow) = self.gnss_time.or(self.gps_time).unwrap_or((0, 0.0));
        let leap = self.gnss.as_ref().map_or(18, |g| g.leap_seconds);
        GnssEncoder::new(format, week, sow, leap)
    }

    /// The receiver's epochs in `format` as a stream for the merger, emitted at their
    /// emission times counted from the run's t₀ (as the IMU's frames).
    pub fn gnss_window(&self, format: GnssFormat) -> GnssWindow<AnyMotion> {
        GnssFrames::new(
            self.gnss_receiver(),
            self.motion.clone(),
            self.gnss_encoder(format),
            self.span(),
        )
        .window(self.grid.t0)
    }

    /// The receiver's epochs per second.
    pub fn gnss_rate_hz(&self) -> f64 {
        self.gnss
            .as_ref()
            .map_or(GnssConfig::default().rate_hz, |g| g.rate_hz)
    }

    /// How many GNSS epochs fall in the run (outages included).
    pub fn gnss_epochs(&self) -> u64 {
        crate::aiding::window::epoch_count(self.gnss_rate_hz(), self.span())
    }

    /// Writes the GNSS epochs of the run in each of `outputs`' formats and, if `truth` is
    /// given, their truth CSV; returns the number of epochs.
    pub fn write_gnss(
        &self,
        outputs: &mut [(GnssFormat, &mut dyn Write)],
        mut truth: Option<&mut dyn Write>,
    ) -> Result<u64, SimError> {
        let mut rx = self.gnss_receiver();
        let (t0, t1) = self.span();
        let mut enc: Vec<GnssEncoder> = outputs.iter().map(|o| self.gnss_encoder(o.0)).collect();
        if let Some(w) = truth.as_mut() {
            w.write_all(TRUTH_HEADER.as_bytes()).map_err(io)?;
        }
        let (mut bytes, mut row, mut n) = (Vec::new(), String::new(), 0);
        while let Some(e) = rx.next_epoch(&self.motion, t0, t1) {
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

fn io(e: std::io::Error) -> SimError {
    SimError::Job(crate::job::JobError::Io(e))
}
