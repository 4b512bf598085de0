//! Scenes at a fixed place on the Earth: the static IMU (the paper's Fig. 4 case) and classic
//! coning motion; plus a flight along a meridian straight over the pole.

use crate::earth::{self, E2};
use crate::kinematics::{NedState, Sensed, sense_ned};
use crate::math::{Mat3, Quat, QuatExt, Vec3};
use crate::motion::{Motion, Pose};

/// A vehicle at rest at one place, optionally in classic coning motion.
#[derive(Clone, Debug)]
pub struct FixedScene {
    lat: f64,
    lon: f64,
    h: f64,
    sin_lat: f64,
    cos_lat: f64,
    gravity: f64,
    q_ref: Quat,
    c_ref: Mat3,
    coning: Option<(f64, f64)>,
}

impl FixedScene {
    /// At rest at (lat, lon, h) with attitude `q_b_n`; `coning` = (half-cone angle β rad,
    /// angular frequency Ω rad/s) about body x, relative to `q_b_n`.
    pub fn new(lat: f64, lon: f64, h: f64, q_b_n: Quat, coning: Option<(f64, f64)>) -> Self {
        let (sin_lat, cos_lat) = lat.sin_cos();
        FixedScene {
            lat,
            lon,
            h,
            sin_lat,
            cos_lat,
            gravity: earth::normal_gravity(sin_lat, h),
            q_ref: q_b_n,
            c_ref: q_b_n.to_mat(),
            coning,
        }
    }

    /// Attitude C_b^n and ω_nb^b at t. Coning: C_b^n = C_ref·Exp(β[0, cos Ωt, sin Ωt]), whose
    /// body rate is Ω[−2 sin²(β/2), −sin β sin Ωt, sin β cos Ωt].
    #[inline]
    fn attitude(&self, t: f64) -> (Quat, Mat3, Vec3) {
        match self.coning {
            None => (self.q_ref, self.c_ref, Vec3::zeros()),
            Some((beta, w)) => {
                let (s, c) = (w * t).sin_cos();
                let (sh, ch) = (0.5 * beta).sin_cos();
                let q = self.q_ref * Quat::new(ch, 0.0, sh * c, sh * s);
                let sb = beta.sin();
                let omega = Vec3::new(-2.0 * w * sh * sh, -w * sb * s, w * sb * c);
                (q, q.to_mat(), omega)
            }
        }
    }
}

/// The span methods of a scene that starts at 0, never ends and is one smooth piece.
macro_rules! one_endless_piece {
    () => {
        fn start(&self) -> f64 {
            0.0
        }
        fn end(&self) -> f64 {
            f64::INFINITY
        }
        fn piece_at(&self, _t: f64, _hint: usize) -> usize {
            0
        }
        fn piece_end(&self, _piece: usize) -> f64 {
            f64::INFINITY
        }
    };
}

impl Motion for FixedScene {
    one_endless_piece!();
    #[inline]
    fn sense(&self, _piece: usize, t: f64) -> Sensed {
        let (_, c_b_n, omega_nb_b) = self.attitude(t);
        sense_ned(&NedState {
            sin_lat: self.sin_lat,
            cos_lat: self.cos_lat,
            h: self.h,
            r_n: earth::radius_meridian(self.sin_lat),
            r_e: earth::radius_prime_vertical(self.sin_lat),
            gravity: self.gravity,
            v_n: Vec3::zeros(),
            v_dot_n: Vec3::zeros(),
            c_b_n,
            omega_nb_b,
        })
    }
    fn pose(&self, t: f64) -> Pose {
        Pose {
            t,
            lat: self.lat,
            lon: self.lon,
            h: self.h,
            v_n: Vec3::zeros(),
            q_b_n: self.attitude(t).0,
        }
    }
    fn is_stationary(&self) -> bool {
        self.coning.is_none()
    }
}

/// Level flight along a meridian through the north pole and on down the other side.
///
/// Position is the "extended" latitude μ(t) = μ₀ + ċ t (past 90° the vehicle is at latitude
/// 180° − μ on the opposite meridian, heading south). In the NED frame that follows the
/// vehicle, v^n = [(R_N(μ)+h)ċ, 0, 0] and ω_en^n = [0, −ċ, 0] stay finite at the pole.
#[derive(Clone, Debug)]
pub struct PolarScene {
    lon0: f64,
    h: f64,
    mu0: f64,
    mu_rate: f64,
}

impl PolarScene {
    /// Starts at extended latitude `mu0` (rad) on meridian `lon0`, height `h`, moving at
    /// `mu_rate` rad/s of latitude.
    pub fn new(lon0: f64, h: f64, mu0: f64, mu_rate: f64) -> PolarScene {
        PolarScene {
            lon0,
            h,
            mu0,
            mu_rate,
        }
    }

    #[inline]
    fn state(&self, t: f64) -> NedState {
        let mu = self.mu0 + self.mu_rate * t;
        let (s, c) = mu.sin_cos();
        let w = 1.0 - E2 * s * s;
        let rn = earth::radius_meridian(s);
        let drn = 3.0 * E2 * rn * s * c / w;
        NedState {
            sin_lat: s,
            cos_lat: c,
            h: self.h,
            r_n: rn,
            r_e: earth::radius_prime_vertical(s),
            gravity: earth::normal_gravity(s, self.h),
            v_n: Vec3::new((rn + self.h) * self.mu_rate, 0.0, 0.0),
            v_dot_n: Vec3::new(drn * self.mu_rate * self.mu_rate, 0.0, 0.0),
            c_b_n: Mat3::identity(),
            omega_nb_b: Vec3::zeros(),
        }
    }
}

impl Motion for PolarScene {
    one_endless_piece!();
    #[inline]
    fn sense(&self, _piece: usize, t: f64) -> Sensed {
        sense_ned(&self.state(t))
    }
    fn pose(&self, t: f64) -> Pose {
        let s = self.state(t);
        // Map the extended latitude back to an ordinary one: past a pole the vehicle is on
        // the opposite meridian with north and east reversed (heading 180°).
        // atan2 keeps full precision next to the pole, where asin(sin μ) loses half the digits.
        let lat = s.sin_lat.atan2(s.cos_lat.abs());
        let flipped = s.cos_lat < 0.0;
        let (lon, yaw, sign) = if flipped {
            (self.lon0 + std::f64::consts::PI, std::f64::consts::PI, -1.0)
        } else {
            (self.lon0, 0.0, 1.0)
        };
        let lon = (lon + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
            - std::f64::consts::PI;
        Pose {
            t,
            lat,
            lon,
            h: s.h,
            v_n: Vec3::new(s.v_n.x * sign, 0.0, 0.0),
            q_b_n: crate::math::quat_from_euler(0.0, 0.0, yaw),
        }
    }
}
