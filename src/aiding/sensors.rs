//! The odometer's, the barometer's and the magnetometer's samples over a run, as CSV rows
//! with their truth, one sample at a time: the rows `generate` writes to a file and `run`
//! streams to its sinks are the same rows. No I/O.

use std::fmt::Write as _;

use super::SampleError;
use super::baro::{BaroConfig, Barometer};
use super::magnetometer::{MagConfig, Magnetometer};
use super::odometer::{Odometer, OdometerConfig};
use crate::earth::Geodetic;
use crate::math::QuatExt;
use crate::motion::Motion;

/// Header of the odometer CSV.
pub const ODOMETER_HEADER: &str = "t,ticks,delta_ticks,speed_m_s,true_distance_m\n";

/// Header of the barometer CSV.
pub const BARO_HEADER: &str = "t,pressure_pa,altitude_m,true_pressure_pa,true_h_m,bias_pa\n";

/// Header of the magnetometer CSV (tesla; body axes, then the Earth's field in NED).
pub const MAG_HEADER: &str = "t,mag_x,mag_y,mag_z,true_x,true_y,true_z,field_n,field_e,field_d\n";

/// An aiding sensor that writes CSV rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorKind {
    /// Wheel odometer ([`super::odometer`]).
    Odometer,
    /// Barometric altimeter ([`super::baro`]).
    Baro,
    /// Three-axis magnetometer ([`super::magnetometer`]).
    Magnetometer,
}

impl SensorKind {
    /// Every kind, in [`SensorKind::name`] order.
    pub const ALL: [SensorKind; 3] = [
        SensorKind::Odometer,
        SensorKind::Baro,
        SensorKind::Magnetometer,
    ];

    /// The kind's name: its scene-file table and its `generate` / `run` flag.
    pub fn name(self) -> &'static str {
        match self {
            SensorKind::Odometer => "odometer",
            SensorKind::Baro => "baro",
            SensorKind::Magnetometer => "magnetometer",
        }
    }

    /// The CSV header line of its samples.
    pub fn header(self) -> &'static str {
        match self {
            SensorKind::Odometer => ODOMETER_HEADER,
            SensorKind::Baro => BARO_HEADER,
            SensorKind::Magnetometer => MAG_HEADER,
        }
    }
}

/// The aiding sensors of a run, each `None` for the default settings.
#[derive(Clone, Debug, Default)]
pub struct SensorSet {
    /// The scene file's `[odometer]`.
    pub odometer: Option<OdometerConfig>,
    /// The scene file's `[baro]`.
    pub baro: Option<BaroConfig>,
    /// The scene file's `[magnetometer]`.
    pub magnetometer: Option<MagConfig>,
}

impl SensorSet {
    /// Samples per second of sensor `kind`.
    pub fn rate_hz(&self, kind: SensorKind) -> f64 {
        match kind {
            SensorKind::Odometer => self.odometer.clone().unwrap_or_default().rate_hz,
            SensorKind::Baro => self.baro.clone().unwrap_or_default().rate_hz,
            SensorKind::Magnetometer => self.magnetometer.clone().unwrap_or_default().rate_hz,
        }
    }
}

enum Model {
    Odometer(Odometer),
    Baro(Barometer),
    Mag(Magnetometer),
}

/// One sensor's samples over a span `[t0, t1]`, as CSV rows.
pub struct SensorRows<M> {
    model: Model,
    motion: M,
    rate: f64,
    t0: f64,
    /// Index of the next sample and one past the last.
    next: i64,
    end: i64,
}

impl<M: Motion> SensorRows<M> {
    /// Sensor `kind` of `set` on `motion` over `(t0, t1)`, its random streams drawn from
    /// `seed`. The odometer gives a sample at the end of each interval of 1/rate s from t0;
    /// the barometer and magnetometer at whole multiples of 1/rate s of record time in
    /// [t0, t1], as GNSS epochs are placed.
    pub fn new(
        kind: SensorKind,
        set: &SensorSet,
        motion: M,
        seed: u64,
        (t0, t1): (f64, f64),
    ) -> Self {
        let rate = set.rate_hz(kind);
        let model = match kind {
            SensorKind::Odometer => {
                Model::Odometer(Odometer::new(set.odometer.clone().unwrap_or_default()))
            }
            SensorKind::Baro => Model::Baro(Barometer::new(
                set.baro.clone().unwrap_or_default(),
                1.0 / rate,
                seed,
            )),
            SensorKind::Magnetometer => Model::Mag(Magnetometer::new(
                set.magnetometer.clone().unwrap_or_default(),
                seed,
            )),
        };
        let (next, end) = match kind {
            SensorKind::Odometer => (1, ((t1 - t0) * rate + 1e-9).floor() as i64 + 1),
            _ => {
                let mut k = (t0 * rate).ceil() as i64;
                // The quotient k/rate can round below t0 by an ulp.
                if (k as f64) / rate < t0 {
                    k += 1;
                }
                // One past the last k with k/rate ≤ t1, settled on the quotients themselves.
                let mut end = (t1 * rate).floor() as i64 + 1;
                while end > k && ((end - 1) as f64) / rate > t1 {
                    end -= 1;
                }
                while (end as f64) / rate <= t1 {
                    end += 1;
                }
                (k, end.max(k))
            }
        };
        SensorRows {
            model,
            motion,
            rate,
            t0,
            next,
            end,
        }
    }

    /// Samples per second.
    pub fn rate_hz(&self) -> f64 {
        self.rate
    }

    /// The time of the sample [`SensorRows::next_row`] gives next (s); `None` after the last.
    pub fn next_time(&self) -> Option<f64> {
        (self.next < self.end).then(|| match self.model {
            Model::Odometer(_) => self.t0 + self.next as f64 / self.rate,
            Model::Baro(_) | Model::Mag(_) => self.next as f64 / self.rate,
        })
    }

    /// How many samples the span holds.
    pub fn count(&self) -> u64 {
        (self.end - self.next).max(0) as u64
    }

    /// The next sample's CSV row (with its line end), replacing `row`'s contents; returns
    /// its time (s), or `None` after the last. A position outside the magnetometer's field
    /// table or a non-finite value is an error naming the time.
    pub fn next_row(&mut self, row: &mut String) -> Result<Option<f64>, SampleError> {
        if self.next >= self.end {
            return Ok(None);
        }
        let k = self.next;
        self.next += 1;
        row.clear();
        let (t, finite) = match &mut self.model {
            Model::Odometer(odo) => {
                let (a, b) = (
                    self.t0 + (k - 1) as f64 / self.rate,
                    self.t0 + k as f64 / self.rate,
                );
                let s = odo.sample(&self.motion, a, b);
                let _ = writeln!(
                    row,
                    "{},{},{},{},{}",
                    s.t, s.ticks, s.delta_ticks, s.speed_m_s, s.true_distance_m
                );
                (s.t, [s.speed_m_s, s.true_distance_m].map(f64::is_finite))
            }
            Model::Baro(baro) => {
                let t = k as f64 / self.rate;
                let h = self.motion.pose(t).h;
                let s = baro.sample(h);
                let _ = writeln!(
                    row,
                    "{t},{},{},{},{h},{}",
                    s.pa, s.altitude_m, s.true_pa, s.bias_pa
                );
                (t, [s.pa, s.altitude_m].map(f64::is_finite))
            }
            Model::Mag(mag) => {
                let t = k as f64 / self.rate;
                let p = self.motion.pose(t);
                let pos = Geodetic::from_radians(p.lat, p.lon, p.h);
                let field = mag
                    .field_n(&pos)
                    .map_err(|e| SampleError(format!("magnetometer at t = {t} s: {e}")))?;
                let b = p.q_b_n.rotate_inv(field);
                let m = mag.measure(b);
                let _ = write!(row, "{t}");
                for v in m.iter().chain(b.iter()).chain(field.iter()) {
                    let _ = write!(row, ",{v}");
                }
                row.push('\n');
                (t, [m.norm(), field.norm()].map(f64::is_finite))
            }
        };
        if finite.contains(&false) {
            return Err(SampleError(format!(
                "the {} sample at t = {t} s is not finite: {}",
                self.kind().name(),
                row.trim_end()
            )));
        }
        Ok(Some(t))
    }

    /// Which sensor this is.
    pub fn kind(&self) -> SensorKind {
        match self.model {
            Model::Odometer(_) => SensorKind::Odometer,
            Model::Baro(_) => SensorKind::Baro,
            Model::Mag(_) => SensorKind::Magnetometer,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::{self, SceneParams};
    use crate::source::AnyMotion;

    /// The barometer's instants are every whole multiple of 1/rate in [t0, t1], found on
    /// the quotients k/rate themselves (spans whose ends are such quotients, or an ulp off
    /// them, included); the odometer's are the ends of whole intervals after t0.
    #[test]
    fn samples_fall_on_their_instants() {
        let scene = scenes::build("circle", &SceneParams::defaults_for("circle")).unwrap();
        let motion = AnyMotion::Scene(scene.unwrap());
        for (rate, t0, t1) in [
            (10.0, 0.1, 0.3),
            (8.0, 0.0, 2.0),
            (3.0, 0.2, 1.0),
            (10.0, 0.7, 0.7),
        ] {
            let want: Vec<f64> = (0..100)
                .map(|k| k as f64 / rate)
                .filter(|t| (t0..=t1).contains(t))
                .collect();
            let set = SensorSet {
                baro: Some(BaroConfig {
                    rate_hz: rate,
                    ..Default::default()
                }),
                ..Default::default()
            };
            let mut rows = SensorRows::new(SensorKind::Baro, &set, motion.clone(), 1, (t0, t1));
            assert_eq!(rows.count(), want.len() as u64, "{rate} Hz in [{t0}, {t1}]");
            let mut row = String::new();
            for t in &want {
                assert_eq!(rows.next_row(&mut row).unwrap(), Some(*t));
                assert!(row.starts_with(&format!("{t},")) && row.ends_with('\n'));
            }
            assert_eq!(rows.next_row(&mut row).unwrap(), None);
        }
        let set = SensorSet::default();
        let mut odo = SensorRows::new(SensorKind::Odometer, &set, motion, 1, (0.25, 1.0));
        assert_eq!(odo.count(), 7, "10 Hz over 0.75 s: 7 whole intervals");
        let mut row = String::new();
        assert_eq!(odo.next_row(&mut row).unwrap(), Some(0.35));
    }
}
