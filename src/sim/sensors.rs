//! The barometer's and the magnetometer's samples over a run's span, from the same motion and
//! seed as the IMU records, written as CSV with their truth.

use std::fmt::Write as _;
use std::io::Write;

use super::SimError;
use super::gnss::io;
use super::streams::AidingStreams;
use crate::aiding::baro::Barometer;
use crate::aiding::mag_samples::{MagSampler, first_index};
use crate::motion::Motion;

/// Header of the barometer CSV.
pub const BARO_HEADER: &str = "t,pressure_pa,altitude_m,true_pressure_pa,true_h_m,bias_pa\n";

/// Header of the magnetometer CSV (tesla; body axes, then the Earth's field in NED).
pub const MAG_HEADER: &str = "t,mag_x,mag_y,mag_z,true_x,true_y,true_z,field_n,field_e,field_d\n";

/// The sample instants at whole multiples of 1/`rate` s of record time in [t0, t1], as the
/// GNSS epochs are placed.
fn instants(rate: f64, t0: f64, t1: f64) -> impl Iterator<Item = f64> {
    (first_index(rate, t0)..)
        .map(move |k| k as f64 / rate)
        .take_while(move |t| *t <= t1)
}

impl AidingStreams<'_> {
    /// Writes the barometer's samples over the run (CSV, [`BARO_HEADER`]); the configured
    /// barometer (scene file `[baro]`), else the default. Returns the number of samples.
    pub fn write_baro(&self, out: &mut dyn Write) -> Result<u64, SimError> {
        let cfg = self.baro.cloned().unwrap_or_default();
        let rate = cfg.rate_hz;
        let mut baro = Barometer::new(cfg, 1.0 / rate, self.seed);
        let (t0, t1) = self.span;
        out.write_all(BARO_HEADER.as_bytes()).map_err(io)?;
        let (mut row, mut n) = (String::new(), 0);
        for t in instants(rate, t0, t1) {
            let h = self.motion.pose(t).h;
            let s = baro.sample(h);
            row.clear();
            let _ = writeln!(
                row,
                "{t},{},{},{},{h},{}",
                s.pa, s.altitude_m, s.true_pa, s.bias_pa
            );
            out.write_all(row.as_bytes()).map_err(io)?;
            n += 1;
        }
        Ok(n)
    }

    /// Writes the magnetometer's samples over the run (CSV, [`MAG_HEADER`]); the configured
    /// magnetometer (scene file `[magnetometer]`), else the default. Returns the number of
    /// samples; a position outside the field table is an error naming the time.
    pub fn write_magnetometer(&self, out: &mut dyn Write) -> Result<u64, SimError> {
        let cfg = self.magnetometer.cloned().unwrap_or_default();
        let (t0, t1) = self.span;
        let mut sampler = MagSampler::new(cfg, self.seed, t0);
        out.write_all(MAG_HEADER.as_bytes()).map_err(io)?;
        let (mut row, mut n) = (String::new(), 0);
        while sampler.next_time() <= t1 {
            let s =
                (sampler.next_sample(self.motion)).map_err(|e| SimError::Invalid(e.to_string()))?;
            row.clear();
            let _ = write!(row, "{}", s.t);
            for v in s.measured.iter().chain(&s.true_b).chain(&s.field_n) {
                let _ = write!(row, ",{v}");
            }
            row.push('\n');
            out.write_all(row.as_bytes()).map_err(io)?;
            n += 1;
        }
        Ok(n)
    }
}
