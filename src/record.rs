//! The output record of the IMU: increments over (t_{k−1}, t_k] and their interval means.

use crate::math::Vec3;

/// One IMU output record k, time-tagged at the end of its interval.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Record {
    /// t_k = t₀ + k·Δt (s), formed from the integer k.
    pub t: f64,
    /// Interval-mean angular rate Δθ_k/Δt (rad/s).
    pub gyro: Vec3,
    /// Interval-mean specific force Δv_k/Δt (m/s²).
    pub accel: Vec3,
    /// Δθ_k = ∫ ω_ib^b dt over the interval (rad); raw, no coning compensation.
    pub dtheta: Vec3,
    /// Δv_k = ∫ f^b dt over the interval (m/s); raw, no sculling compensation.
    pub dv: Vec3,
    /// Status bits ([`FLAG_GYRO_SATURATED`], …) set by the error model; not part of the
    /// CSV/binary contract. Frames with a status word carry them.
    pub flags: u8,
}

/// Record flag: a gyro axis was saturated.
pub const FLAG_GYRO_SATURATED: u8 = 1;
/// Record flag: an accelerometer axis was saturated.
pub const FLAG_ACCEL_SATURATED: u8 = 2;
/// Record flag: a value of the record is not a measurement (not finite): a sensor failure, which
/// frames with a status word report as their built-in-test failure.
pub const FLAG_INVALID: u8 = 4;
/// Record flag: the motion behind the record no longer follows its live input (stale or
/// holding); frames with a status word report it as their built-in-test failure, frames
/// without one are still sent.
pub const FLAG_STALE: u8 = 8;

/// Column names of the output contract, in order.
pub const COLUMNS: [&str; 13] = [
    "t", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z", "dtheta_x", "dtheta_y",
    "dtheta_z", "dv_x", "dv_y", "dv_z",
];

impl Record {
    /// The record of 13 values in the order of [`COLUMNS`] (no flags).
    pub fn from_values(v: &[f64; 13]) -> Record {
        let v3 = |i: usize| crate::math::Vec3::new(v[i], v[i + 1], v[i + 2]);
        Record {
            t: v[0],
            gyro: v3(1),
            accel: v3(4),
            dtheta: v3(7),
            dv: v3(10),
            flags: 0,
        }
    }

    /// The 13 values in the order of [`COLUMNS`].
    #[inline]
    pub fn values(&self) -> [f64; 13] {
        let (g, a, d, v) = (self.gyro, self.accel, self.dtheta, self.dv);
        [
            self.t, g[0], g[1], g[2], a[0], a[1], a[2], d[0], d[1], d[2], v[0], v[1], v[2],
        ]
    }
}
