//! The magnetometer's samples over a run, in order, and the latest of them at an IMU record's
//! time: what an IMU frame's magnetic-field fields carry. The stream `generate --magnetometer`
//! writes and the frames draw on the same sequence of samples (one noise draw per sample, in
//! order), so a frame carries exactly a sample of the stream.

use super::field_table::OutsideTable;
use super::magnetometer::{MagConfig, Magnetometer};
use crate::earth::Geodetic;
use crate::math::{Mat3, Quat, QuatExt, Vec3};
use crate::motion::Motion;

/// One magnetometer sample (T).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MagSample {
    /// Sample time: a whole multiple of 1/rate of record time (s).
    pub t: f64,
    /// The measurement S B^b + b_hard + noise, body axes.
    pub measured: Vec3,
    /// The true body-axis field B^b.
    pub true_b: Vec3,
    /// The Earth's field at the vehicle, NED.
    pub field_n: Vec3,
}

/// A sample's position is outside the magnetometer's field table.
#[derive(Debug, thiserror::Error)]
#[error("magnetometer at t = {t} s: {source}")]
pub struct MagError {
    /// Sample time (s).
    pub t: f64,
    /// Where the position fell.
    #[source]
    pub source: OutsideTable,
}

/// Index k of the first instant k/`rate` at or after `t0`, as the GNSS epochs are placed.
pub fn first_index(rate: f64, t0: f64) -> i64 {
    let k = (t0 * rate).ceil() as i64;
    // The quotient k/rate can round below t0 by an ulp.
    if (k as f64) / rate < t0 { k + 1 } else { k }
}

/// The samples at k/rate from the first instant at or after t₀, each computed once, in order.
#[derive(Clone, Debug)]
pub struct MagSampler {
    mag: Magnetometer,
    rate: f64,
    k: i64,
}

impl MagSampler {
    /// The magnetometer `cfg` (noise streams of master seed `seed`) sampling from `t0` (s).
    pub fn new(cfg: MagConfig, seed: u64, t0: f64) -> MagSampler {
        let rate = cfg.rate_hz;
        MagSampler {
            mag: Magnetometer::new(cfg, seed),
            rate,
            k: first_index(rate, t0),
        }
    }

    /// Time of the next sample (s).
    pub fn next_time(&self) -> f64 {
        self.k as f64 / self.rate
    }

    /// The next sample of the vehicle following `motion` (draws its noise).
    pub fn next_sample<M: Motion + ?Sized>(&mut self, motion: &M) -> Result<MagSample, MagError> {
        let t = self.next_time();
        let p = motion.pose(t);
        let pos = Geodetic::from_radians(p.lat, p.lon, p.h);
        let field_n = (self.mag.field_n(&pos)).map_err(|source| MagError { t, source })?;
        let true_b = p.q_b_n.rotate_inv(field_n);
        self.k += 1;
        Ok(MagSample {
            t,
            measured: self.mag.measure(true_b),
            true_b,
            field_n,
        })
    }
}

/// The magnetic field a frame carries, and whether no earlier frame carried it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameMag {
    /// The latest sample's measurement in the IMU's axes (T); 0 before the first sample.
    pub field: Vec3,
    /// The sample is new since the previous frame.
    pub fresh: bool,
}

/// The latest sample at or before each record's time, as a unit that reads its magnetometer
/// at its own rate puts the last reading into every frame.
#[derive(Clone, Debug)]
pub struct MagHold {
    sampler: MagSampler,
    /// C_b^c: body to the IMU's case (its mounting), `None` when they coincide.
    c_b_c: Option<Mat3>,
    current: Vec3,
}

impl MagHold {
    /// Samples of `cfg` (seed `seed`) from `t0`, turned into the IMU case's axes by
    /// `q_b_c` (C_b^c; `None`: the body's axes).
    pub fn new(cfg: MagConfig, seed: u64, t0: f64, q_b_c: Option<Quat>) -> MagHold {
        MagHold::in_axes(cfg, seed, t0, q_b_c.map(|q| q.to_mat()))
    }

    /// [`MagHold::new`] with the case's axes given as the matrix C_b^c.
    pub fn in_axes(cfg: MagConfig, seed: u64, t0: f64, c_b_c: Option<Mat3>) -> MagHold {
        MagHold {
            sampler: MagSampler::new(cfg, seed, t0),
            c_b_c,
            current: Vec3::zeros(),
        }
    }

    /// The field for a frame at record time `t` (non-decreasing from call to call): every
    /// sample up to `t` is taken in order, so none of the stream's noise draws is skipped.
    pub fn at<M: Motion + ?Sized>(&mut self, t: f64, motion: &M) -> Result<FrameMag, MagError> {
        let mut fresh = false;
        while self.sampler.next_time() <= t {
            let m = self.sampler.next_sample(motion)?.measured;
            self.current = self.c_b_c.map_or(m, |c| c * m);
            fresh = true;
        }
        Ok(FrameMag {
            field: self.current,
            fresh,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes;
    use crate::source::AnyMotion;

    fn circle() -> AnyMotion {
        AnyMotion::Scene(
            scenes::build("circle", &scenes::SceneParams::defaults_for("circle"))
                .unwrap()
                .unwrap(),
        )
    }

    /// The hold steps to each sample at its instant, exactly: records at 100 Hz with samples
    /// at 10 Hz see a new sample on every tenth record, the sampler's own sequence.
    #[test]
    fn hold_carries_each_sample_from_its_instant() {
        let motion = circle();
        let cfg = MagConfig {
            noise_t: 1e-7,
            ..MagConfig::default()
        };
        let mut reference = MagSampler::new(cfg.clone(), 3, 0.0);
        let samples: Vec<MagSample> = (0..11)
            .map(|_| reference.next_sample(&motion).unwrap())
            .collect();
        let mut hold = MagHold::new(cfg, 3, 0.0, None);
        for k in 1..=100 {
            let t = k as f64 / 100.0;
            let f = hold.at(t, &motion).unwrap();
            let j = k / 10;
            assert_eq!(f.field, samples[j].measured, "record {k}");
            assert_eq!(f.fresh, k == 1 || k % 10 == 0, "record {k}");
        }
    }

    /// The first instant is at or after t₀ even where k/rate rounds below it, and a hold
    /// whose first sample lies after a record carries 0, not yet fresh.
    #[test]
    fn first_instant_and_before_it() {
        assert_eq!(first_index(10.0, 0.0), 0);
        assert_eq!(first_index(10.0, 0.05), 1);
        assert_eq!(first_index(3.0, 1.0 / 3.0), 1);
        let k = first_index(10.0, 0.3);
        assert!(k as f64 / 10.0 >= 0.3 && (k - 1) as f64 / 10.0 < 0.3);
        let motion = circle();
        let mut hold = MagHold::new(MagConfig::default(), 1, 0.05, None);
        let f = hold.at(0.06, &motion).unwrap();
        assert_eq!(f, FrameMag::default());
        assert!(hold.at(0.1, &motion).unwrap().fresh);
    }
}
