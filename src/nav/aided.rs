//! A loosely coupled GNSS/INS navigator: the strapdown [`Navigator`] carries the whole state,
//! and a 15-state error-state Kalman filter estimates its position, velocity and attitude
//! errors and the gyro and accelerometer biases from GNSS position and velocity fixes, then
//! feeds them back (closed loop). Pure math, no I/O.
//!
//! Error state (estimate − truth), in the local north-east-down frame:
//! x = [δr (m), δv (m/s), ψ (rad), δb_g (rad/s), δb_a (m/s²)], with the attitude error
//! C̃_b^n = (I + [ψ×]) C_b^n. The navigator is fed the increments less the estimated biases,
//! so a bias error δb makes the corrected rate and specific force wrong by −δb. Linearised
//! (the local-navigation-frame model of P. D. Groves, *Principles of GNSS, Inertial, and
//! Multisensor Integrated Navigation Systems*, 2nd ed., §14.2, without the transport-rate
//! terms, which are of order v/R):
//!
//! * δṙ = δv
//! * δv̇ = −[f^n×] ψ − C_b^n δb_a + diag(−g/R, −g/R, 2g/R) δr  (Schuler and vertical gravity
//!   feedback)
//! * ψ̇ = −[ω_ie^n×] ψ − C_b^n δb_g
//! * δḃ_g = w_g, δḃ_a = w_a (random walks)
//!
//! The covariance is propagated over blocks of records with Φ = I + F Δt and
//! Q = diag(0, σ_vrw², σ_arw², σ_gbrw², σ_abrw²) Δt. A fix of the antenna at lever arm l
//! (body) measures the navigator's antenna position r + C_b^n l and velocity
//! v + C_b^n (ω_eb^b × l); its innovation (predicted − measured) is
//! H x + noise with
//!
//! * position rows: [I, 0, −[(C_b^n l)×], 0, 0]
//! * velocity rows: [0, I, −[(C_b^n(ω_eb^b × l))×], C_b^n [l×], 0]
//!
//! The gain K = P Hᵀ (H P Hᵀ + R)⁻¹, the estimate δx̂ = K y, the Joseph form
//! P ← (I − KH) P (I − KH)ᵀ + K R Kᵀ; the estimate is removed from the navigator (position,
//! velocity, attitude exp(−ψ)) and added to the bias estimates, and the error state is zero
//! again.

use nalgebra::{SMatrix, SVector};

use super::strapdown::{NavState, Navigator, Settings, SettingsError};
use crate::earth::{self, Geodetic, ecef_to_geodetic};
use crate::math::{Mat3, Quat, QuatExt, Vec3};

type Mat15 = SMatrix<f64, 15, 15>;
type Mat6x15 = SMatrix<f64, 6, 15>;

/// The filter's model of the IMU and its start: noise densities and initial uncertainties.
#[derive(Clone, Debug, PartialEq)]
pub struct AidedConfig {
    /// Antenna from the IMU reference point, body axes (m).
    pub lever_arm_m: [f64; 3],
    /// Gyro angle random walk (rad/√s).
    pub gyro_arw: f64,
    /// Accelerometer velocity random walk (m/s/√s).
    pub accel_vrw: f64,
    /// Gyro bias random walk (rad/s/√s).
    pub gyro_bias_rw: f64,
    /// Accelerometer bias random walk (m/s²/√s).
    pub accel_bias_rw: f64,
    /// Initial σ of position (m), velocity (m/s), attitude (rad), gyro bias (rad/s) and
    /// accelerometer bias (m/s²).
    pub initial_sigma: [f64; 5],
    /// Covariance propagation interval (s): records are grouped into blocks this long.
    pub propagation_s: f64,
}

impl Default for AidedConfig {
    /// A tactical-grade IMU's model (0.1 °/√h, 0.05 m/s/√h, biases of 10 °/h and 1 mg) and
    /// a start known to 10 m, 1 m/s, 1°.
    fn default() -> AidedConfig {
        let deg_h = std::f64::consts::PI / 180.0 / 3600.0;
        AidedConfig {
            lever_arm_m: [0.0; 3],
            gyro_arw: 0.1 * std::f64::consts::PI / 180.0 / 60.0,
            accel_vrw: 0.05 / 60.0,
            gyro_bias_rw: 1e-2 * deg_h,
            accel_bias_rw: 1e-5,
            initial_sigma: [10.0, 1.0, 1f64.to_radians(), 10.0 * deg_h, 1e-2],
            propagation_s: 0.05,
        }
    }
}

/// One GNSS fix: the antenna's position and velocity at a time of validity, with the σ's
/// the receiver reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssFix {
    /// Time of validity (s, record time).
    pub t: f64,
    /// Latitude, longitude (rad), ellipsoidal height (m).
    pub lat: f64,
    /// Longitude (rad).
    pub lon: f64,
    /// Ellipsoidal height (m).
    pub h: f64,
    /// Velocity, NED (m/s).
    pub v_n: Vec3,
    /// Position σ, NED (m).
    pub sigma_pos: Vec3,
    /// Velocity σ, NED (m/s).
    pub sigma_vel: Vec3,
}

impl GnssFix {
    /// The fix a receiver reports in epoch `e`, with its σ's; `None` in an outage.
    pub fn from_epoch(e: &crate::aiding::GnssEpoch) -> Option<GnssFix> {
        let m = &e.measured;
        (e.fix != crate::aiding::Fix::None).then_some(GnssFix {
            t: e.t,
            lat: m.lat,
            lon: m.lon,
            h: m.h,
            v_n: m.v_n,
            sigma_pos: e.sigma_pos,
            sigma_vel: e.sigma_vel,
        })
    }
}

/// The GNSS-aided navigator.
#[derive(Clone, Debug)]
pub struct AidedNavigator {
    nav: Navigator,
    cfg: AidedConfig,
    lever: Vec3,
    p: Mat15,
    bg: Vec3,
    ba: Vec3,
    dt: f64,
    /// Records per covariance block, and the specific force and time summed in this one.
    block: u64,
    pending: u64,
    dv_sum: Vec3,
    /// The last corrected angular rate (rad/s).
    omega: Vec3,
}

impl AidedNavigator {
    /// A navigator at `initial` for records at `rate_hz`, with the filter's model `cfg`.
    pub fn new(
        initial: NavState,
        rate_hz: f64,
        settings: Settings,
        cfg: AidedConfig,
    ) -> Result<AidedNavigator, SettingsError> {
        let nav = Navigator::new(initial, rate_hz, settings)?;
        let mut p = Mat15::zeros();
        for (k, s) in cfg.initial_sigma.iter().enumerate() {
            for i in 0..3 {
                p[(3 * k + i, 3 * k + i)] = s * s;
            }
        }
        let dt = 1.0 / rate_hz;
        Ok(AidedNavigator {
            nav,
            lever: Vec3::from(cfg.lever_arm_m),
            block: ((cfg.propagation_s * rate_hz).round() as u64).max(1),
            cfg,
            p,
            bg: Vec3::zeros(),
            ba: Vec3::zeros(),
            dt,
            pending: 0,
            dv_sum: Vec3::zeros(),
            omega: Vec3::zeros(),
        })
    }

    /// The current navigation state.
    pub fn state(&self) -> NavState {
        self.nav.state()
    }

    /// The strapdown navigator inside (its state, settings and record history).
    pub fn navigator(&self) -> &Navigator {
        &self.nav
    }

    /// The estimated gyro (rad/s) and accelerometer (m/s²) biases.
    pub fn biases(&self) -> (Vec3, Vec3) {
        (self.bg, self.ba)
    }

    /// The σ of each error state (position m NED, velocity m/s, attitude rad, biases).
    pub fn sigmas(&self) -> [f64; 15] {
        std::array::from_fn(|i| self.p[(i, i)].sqrt())
    }

    /// Integrates one record's increments, less the estimated biases.
    pub fn step(&mut self, dtheta: Vec3, dv: Vec3) {
        let dtheta = dtheta - self.bg * self.dt;
        let dv = dv - self.ba * self.dt;
        self.nav.step(dtheta, dv);
        self.omega = dtheta / self.dt;
        self.dv_sum += dv;
        self.pending += 1;
        if self.pending == self.block {
            self.propagate();
        }
    }

    /// Propagates the covariance over the records since the last propagation.
    fn propagate(&mut self) {
        if self.pending == 0 {
            return;
        }
        let span = self.pending as f64 * self.dt;
        let (geo, c) = self.local();
        let f_n = c * (self.dv_sum / span);
        let g = earth::normal_gravity(geo.sin_lat, geo.h);
        let r = (earth::radius_meridian(geo.sin_lat) * earth::radius_prime_vertical(geo.sin_lat))
            .sqrt()
            + geo.h;
        let w_ie = earth::omega_ie_n(geo.sin_lat, geo.cos_lat);
        let mut f = Mat15::zeros();
        f.fixed_view_mut::<3, 3>(0, 3).copy_from(&Mat3::identity());
        f.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&Mat3::from_diagonal(&Vec3::new(
                -g / r,
                -g / r,
                2.0 * g / r,
            )));
        f.fixed_view_mut::<3, 3>(3, 6)
            .copy_from(&-f_n.cross_matrix());
        f.fixed_view_mut::<3, 3>(3, 12).copy_from(&-c);
        f.fixed_view_mut::<3, 3>(6, 6)
            .copy_from(&-w_ie.cross_matrix());
        f.fixed_view_mut::<3, 3>(6, 9).copy_from(&-c);
        let phi = Mat15::identity() + f * span;
        let mut q = SVector::<f64, 15>::zeros();
        let cfg = &self.cfg;
        for (k, s) in [
            cfg.accel_vrw,
            cfg.gyro_arw,
            cfg.gyro_bias_rw,
            cfg.accel_bias_rw,
        ]
        .iter()
        .enumerate()
        {
            for i in 0..3 {
                q[3 + 3 * k + i] = s * s * span;
            }
        }
        self.p = phi * self.p * phi.transpose() + Mat15::from_diagonal(&q);
        self.pending = 0;
        self.dv_sum = Vec3::zeros();
    }

    /// The geodetic position and C_b^n of the current state.
    fn local(&self) -> (Geodetic, Mat3) {
        let s = self.nav.state();
        let geo = ecef_to_geodetic(s.r_e);
        let c = geo.c_n_e().transpose() * s.q_b_e.to_mat();
        (geo, c)
    }

    /// Applies a GNSS fix at the current state's time: a Kalman update of the error state,
    /// fed back into the navigator and the bias estimates. Returns the innovation
    /// (predicted − measured: position m NED, velocity m/s NED).
    pub fn update(&mut self, fix: &GnssFix) -> [f64; 6] {
        self.propagate();
        let s = self.nav.state();
        let (geo, c) = self.local();
        let c_n_e = geo.c_n_e();
        let w_eb = self.omega - c.transpose() * earth::omega_ie_n(geo.sin_lat, geo.cos_lat);
        let l_n = c * self.lever;
        let lv_n = c * w_eb.cross(&self.lever);
        let meas = Geodetic::from_radians(fix.lat, fix.lon, fix.h);
        let dp = c_n_e.transpose() * (s.r_e + c_n_e * l_n - meas.to_ecef());
        let dv = c_n_e.transpose() * s.v_e + lv_n - fix.v_n;
        let y = SVector::<f64, 6>::from_iterator(dp.iter().chain(dv.iter()).copied());
        let mut h = Mat6x15::zeros();
        h.fixed_view_mut::<3, 3>(0, 0).copy_from(&Mat3::identity());
        h.fixed_view_mut::<3, 3>(0, 6)
            .copy_from(&-l_n.cross_matrix());
        h.fixed_view_mut::<3, 3>(3, 3).copy_from(&Mat3::identity());
        h.fixed_view_mut::<3, 3>(3, 6)
            .copy_from(&-lv_n.cross_matrix());
        h.fixed_view_mut::<3, 3>(3, 9)
            .copy_from(&(c * self.lever.cross_matrix()));
        let r = SMatrix::<f64, 6, 6>::from_diagonal(&SVector::<f64, 6>::from_iterator(
            fix.sigma_pos
                .iter()
                .chain(fix.sigma_vel.iter())
                .map(|s| s * s),
        ));
        let pht = self.p * h.transpose();
        let Some(s_inv) = (h * pht + r).try_inverse() else {
            return y.into();
        };
        let k = pht * s_inv;
        let x = k * y;
        let ikh = Mat15::identity() - k * h;
        self.p = ikh * self.p * ikh.transpose() + k * r * k.transpose();
        self.p = (self.p + self.p.transpose()) * 0.5;
        let v3 = |i: usize| Vec3::new(x[i], x[i + 1], x[i + 2]);
        let psi_e = c_n_e * v3(6);
        let corrected = NavState {
            t: s.t,
            r_e: s.r_e - c_n_e * v3(0),
            v_e: s.v_e - c_n_e * v3(3),
            q_b_e: (Quat::from_rotvec(-psi_e) * s.q_b_e).normalized(),
        };
        self.nav.reset(&corrected);
        self.bg -= v3(9);
        self.ba -= v3(12);
        y.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::Pose;

    fn level_pose() -> Pose {
        Pose {
            t: 0.0,
            lat: 0.7,
            lon: 0.2,
            h: 100.0,
            v_n: Vec3::zeros(),
            q_b_n: crate::math::quat_from_euler(0.0, 0.0, 0.5),
        }
    }

    /// With a far larger position uncertainty than the fix's σ, one update moves the
    /// navigator's antenna onto the fix: a fix 3 m north, 4 m east, 2 m up of the true
    /// antenna (lever arm 1 m forward, 0.5 m up) moves the state by that much, to the gain's
    /// 1 − σ²/(σ² + P) = 1 − 10⁻¹⁰ times (10⁻⁹ m); a flipped innovation sign would move it
    /// the other way.
    #[test]
    fn update_moves_the_antenna_onto_a_precise_fix() {
        let pose = level_pose();
        let cfg = AidedConfig {
            lever_arm_m: [1.0, 0.0, -0.5],
            initial_sigma: [1e4, 1e-3, 1e-9, 1e-12, 1e-12],
            ..AidedConfig::default()
        };
        let mut a =
            AidedNavigator::new(NavState::from_pose(&pose), 100.0, Settings::default(), cfg)
                .unwrap();
        let geo = Geodetic::from_radians(pose.lat, pose.lon, pose.h);
        let c_n_e = geo.c_n_e();
        let l_n = pose.q_b_n.rotate(Vec3::new(1.0, 0.0, -0.5));
        let shift = Vec3::new(3.0, 4.0, -2.0);
        let fix_e = geo.to_ecef() + c_n_e * (l_n + shift);
        let fg = ecef_to_geodetic(fix_e);
        let fix = GnssFix {
            t: 0.0,
            lat: fg.lat(),
            lon: fg.lon(),
            h: fg.h,
            v_n: Vec3::zeros(),
            sigma_pos: Vec3::repeat(0.1),
            sigma_vel: Vec3::repeat(1.0),
        };
        let y = a.update(&fix);
        for i in 0..3 {
            assert!((y[i] + shift[i]).abs() < 1e-8, "{y:?}");
        }
        let moved = c_n_e.transpose() * (a.state().r_e - geo.to_ecef());
        assert!((moved - shift).amax() < 1e-6, "{moved:?}");
        // The posterior σ of position is the fix's (P ≫ R).
        let s = a.sigmas();
        assert!((s[0] - 0.1).abs() < 1e-6, "{s:?}");
    }
}
