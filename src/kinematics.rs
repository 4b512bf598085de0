//! What an ideal IMU senses: equations (1) and (2) of the seed paper, in two equivalent
//! formulations.
//!
//! * [`sense_ned`] — the paper's local-level form,
//!   ω_ib^b = ω_nb^b + C_n^b(ω_ie^n + ω_en^n) and
//!   f^b = C_n^b(v̇^n + (2ω_ie^n + ω_en^n) × v^n − g^n). Used by the analytic scenes.
//! * [`sense_ecef`] — the Earth-fixed form,
//!   ω_ib^b = ω_eb^b + C_e^b ω_ie^e and f^b = C_e^b(r̈^e + 2ω_ie^e × ṙ^e − g^e), which has no
//!   singularity at the poles. Used by trajectories read from files.
//!
//! g is WGS-84 normal gravity (gravitation plus centrifugal), so both forms are exact.

use crate::earth::{self, Geodetic};
use crate::math::{Mat3, Quat, QuatExt, Vec3};

/// Error-free IMU output at one instant: angular rate ω_ib^b (rad/s), specific force f^b (m/s²).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sensed {
    /// ω_ib^b, body angular rate relative to inertial space, in body axes (rad/s).
    pub omega_ib_b: Vec3,
    /// f^b, specific force in body axes (m/s²).
    pub f_b: Vec3,
}

/// Vehicle state in local-level (NED) form.
#[derive(Clone, Copy, Debug)]
pub struct NedState {
    /// sin φ of the (possibly extended, past-the-pole) latitude.
    pub sin_lat: f64,
    /// cos φ of the same latitude.
    pub cos_lat: f64,
    /// Ellipsoidal height (m).
    pub h: f64,
    /// Meridian radius of curvature R_N at this latitude (m).
    pub r_n: f64,
    /// Prime-vertical radius of curvature R_E at this latitude (m).
    pub r_e: f64,
    /// Normal gravity γ(φ, h) (m/s²).
    pub gravity: f64,
    /// Velocity relative to the Earth in NED, v^n (m/s).
    pub v_n: Vec3,
    /// Its time derivative v̇^n (m/s²).
    pub v_dot_n: Vec3,
    /// C_b^n.
    pub c_b_n: Mat3,
    /// ω_nb^b (rad/s).
    pub omega_nb_b: Vec3,
}

/// Equations (1)–(2) in NED form.
#[inline]
pub fn sense_ned(s: &NedState) -> Sensed {
    let w_ie = earth::omega_ie_n(s.sin_lat, s.cos_lat);
    let w_en = earth::transport_rate(s.sin_lat, s.cos_lat, s.r_n + s.h, s.r_e + s.h, s.v_n);
    let g = s.gravity;
    let w_in = w_ie + w_en;
    let omega_ib_b = s.omega_nb_b + s.c_b_n.tr_mul(&w_in);
    let mut a = s.v_dot_n + (w_ie * 2.0 + w_en).cross(&s.v_n);
    a[2] -= g;
    Sensed {
        omega_ib_b,
        f_b: s.c_b_n.tr_mul(&a),
    }
}

/// Vehicle state in Earth-fixed (ECEF) form.
#[derive(Clone, Copy, Debug)]
pub struct EcefState {
    /// Geodetic position (for gravity).
    pub pos: Geodetic,
    /// ṙ^e (m/s).
    pub v_e: Vec3,
    /// r̈^e (m/s²).
    pub a_e: Vec3,
    /// C_b^e as a unit quaternion.
    pub q_b_e: Quat,
    /// ω_eb^b (rad/s).
    pub omega_eb_b: Vec3,
}

/// Equations (1)–(2) in ECEF form.
#[inline]
pub fn sense_ecef(s: &EcefState) -> Sensed {
    let w_ie_e = Vec3::new(0.0, 0.0, earth::OMEGA_IE);
    let g = earth::normal_gravity(s.pos.sin_lat, s.pos.h);
    // f^e = r̈ + 2 ω_ie × ṙ − g^e with g^e = −γ·up.
    let f_e = s.a_e + (w_ie_e * 2.0).cross(&s.v_e) + s.pos.up_e() * g;
    Sensed {
        omega_ib_b: s.omega_eb_b + s.q_b_e.rotate_inv(w_ie_e),
        f_b: s.q_b_e.rotate_inv(f_e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::quat_from_euler;

    /// Worked check (docs/signals.md): static, level, heading north at 41° N, 0 m.
    #[test]
    fn static_41n_matches_design_worked_check() {
        let lat = 41f64.to_radians();
        let s = NedState {
            sin_lat: lat.sin(),
            cos_lat: lat.cos(),
            h: 0.0,
            r_n: earth::radius_meridian(lat.sin()),
            r_e: earth::radius_prime_vertical(lat.sin()),
            gravity: earth::normal_gravity(lat.sin(), 0.0),
            v_n: Vec3::zeros(),
            v_dot_n: Vec3::zeros(),
            c_b_n: Mat3::identity(),
            omega_nb_b: Vec3::zeros(),
        };
        let out = sense_ned(&s);
        assert!((out.omega_ib_b.x - 5.50343e-5).abs() < 5e-11);
        assert_eq!(out.omega_ib_b.y, 0.0);
        assert!((out.omega_ib_b.z + 4.78406e-5).abs() < 5e-11);
        assert!((out.f_b.z + 9.802590).abs() < 5e-7);
    }

    /// The NED and ECEF forms agree for a moving, rotating, tilted vehicle. Both take the
    /// transport rate from `earth::omega_en_n` here (a consistency check of the two forms);
    /// tests/closed_form.rs repeats it with a transport rate computed independently from
    /// φ̇ and λ̇.
    #[test]
    fn ned_and_ecef_forms_agree() {
        let pos = Geodetic::from_radians(0.9, -1.3, 1234.0);
        let v_n = Vec3::new(80.0, -35.0, 3.0);
        let v_dot_n = Vec3::new(0.4, 2.5, -0.3);
        let q_b_n = quat_from_euler(0.3, -0.2, 2.4);
        let omega_nb_b = Vec3::new(0.1, -0.05, 0.2);
        let ned = sense_ned(&NedState {
            sin_lat: pos.sin_lat,
            cos_lat: pos.cos_lat,
            h: pos.h,
            r_n: earth::radius_meridian(pos.sin_lat),
            r_e: earth::radius_prime_vertical(pos.sin_lat),
            gravity: earth::normal_gravity(pos.sin_lat, pos.h),
            v_n,
            v_dot_n,
            c_b_n: q_b_n.to_mat(),
            omega_nb_b,
        });
        let c_n_e = pos.c_n_e();
        let w_en = earth::omega_en_n(pos.sin_lat, pos.cos_lat, pos.h, v_n);
        let ecef = sense_ecef(&EcefState {
            pos,
            v_e: c_n_e * v_n,
            a_e: c_n_e * (v_dot_n + w_en.cross(&v_n)),
            q_b_e: pos.q_n_e() * q_b_n,
            omega_eb_b: omega_nb_b + q_b_n.rotate_inv(w_en),
        });
        assert!((ned.omega_ib_b - ecef.omega_ib_b).amax() < 1e-17);
        assert!((ned.f_b - ecef.f_b).amax() < 1e-14);
    }
}
