//! Reference values for the error-free signal, computed without the engine's kinematics:
//! closed forms (static anywhere on the planet, classic coning, a meridian flight over the
//! pole) and equations (1)–(2) evaluated from their definition on a scene's pose, with the
//! attitude and velocity differentiated numerically. `imu-emu validate` measures the engine
//! against them (the paper's §4.1 checks); the tests check them in turn.

use crate::earth::{self, OMEGA_IE};
use crate::generator::IdealImu;
use crate::math::{Mat3, Vec3};
use crate::motion::Motion;
use crate::record::Record;
use crate::scenes::{self, SceneParams};
use crate::source::AnyMotion;

/// Static, level, heading north at latitude `lat` (rad) and height `h`: the gyro senses Earth
/// rate [Ω cos φ, 0, −Ω sin φ] and the accelerometer [0, 0, −γ(φ, h)].
pub fn static_level(lat: f64, h: f64) -> (Vec3, Vec3) {
    let (s, c) = lat.sin_cos();
    (
        Vec3::new(OMEGA_IE * c, 0.0, -OMEGA_IE * s),
        Vec3::new(0.0, 0.0, -earth::normal_gravity(s, h)),
    )
}

/// Equations (1)–(2) from the definition on the pose of `m` at `t`: Ω_ib^b = C_n^b Ċ_b^n +
/// C_n^b Ω_in^n C_b^n and f^b = C_n^b(v̇^n + (2Ω_ie^n + Ω_en^n) v^n − g^n), with Ċ_b^n and v̇^n
/// by 6th-order central differences of step `d`. Truncation is ~d⁶ f⁽⁷⁾/140 and round-off
/// ~(pose noise ≈ 2e-15)/d: pick `d` for the motion's bandwidth (10 ms for vehicle motion
/// below ~1 Hz gives ~2e-13 rad/s). The differences must not straddle a model breakpoint.
pub fn by_definition(m: &impl Motion, t: f64, d: f64) -> (Vec3, Vec3) {
    let w = [(1.0, 45.0 / 60.0), (2.0, -9.0 / 60.0), (3.0, 1.0 / 60.0)];
    let pose = m.pose(t);
    let c = pose.q_b_n.to_mat();
    let mut cdot = [[0.0; 3]; 3];
    let mut vdot = Vec3::ZERO;
    for (k, wk) in w {
        let (pp, pm) = (m.pose(t + k * d), m.pose(t - k * d));
        let (cp, cm) = (pp.q_b_n.to_mat(), pm.q_b_n.to_mat());
        for (row, (rp, rm)) in cdot.iter_mut().zip(cp.0.iter().zip(cm.0.iter())) {
            for (x, (a, b)) in row.iter_mut().zip(rp.iter().zip(rm.iter())) {
                *x += wk * (a - b) / d;
            }
        }
        vdot += (pp.v_n - pm.v_n) * (wk / d);
    }
    let (s, co) = pose.lat.sin_cos();
    let v = pose.v_n;
    let w_ie = earth::omega_ie_n(s, co);
    let w_en = earth::omega_en_n(s, co, pose.h, v);
    // Ω_nb^b = C_n^b Ċ_b^n; its skew part is ω_nb^b.
    let om = c.transpose().mul_mat(&Mat3(cdot)).0;
    let w_nb = Vec3::new(
        0.5 * (om[2][1] - om[1][2]),
        0.5 * (om[0][2] - om[2][0]),
        0.5 * (om[1][0] - om[0][1]),
    );
    let mut a = vdot + (w_ie * 2.0 + w_en).cross(v);
    a.0[2] -= earth::normal_gravity(s, pose.h);
    (w_nb + c.tr_mul_vec(w_ie + w_en), c.tr_mul_vec(a))
}

/// Δθ over [t0, t1] of classic coning about body x (half-angle `beta` rad at `om` rad/s,
/// C_b^n = Exp(β n(t)), n = (0, cos Ωt, sin Ωt)) at latitude `lat`: the body's own coning
/// [−2Ω sin²(β/2)Δt, sin β Δcos Ωt, sin β Δsin Ωt] plus ∫C_n^b ω_ie^n dt, both in closed form.
pub fn coning_dtheta(beta: f64, om: f64, lat: f64, t0: f64, t1: f64) -> Vec3 {
    let (wx, wy, wz) = (OMEGA_IE * lat.cos(), 0.0, -OMEGA_IE * lat.sin());
    let (cb, sb) = (beta.cos(), beta.sin());
    // Antiderivatives of cos, sin, cos², sin cos, sin² of Ωt.
    let prim = |t: f64| -> Vec3 {
        let (s, c) = (om * t).sin_cos();
        let ic = s / om;
        let is = -c / om;
        let icc = t / 2.0 + (2.0 * om * t).sin() / (4.0 * om);
        let iss = t / 2.0 - (2.0 * om * t).sin() / (4.0 * om);
        let isc = s * s / (2.0 * om);
        let x = -2.0 * om * (beta / 2.0).sin().powi(2) * t + wx * cb * t - sb * (wz * ic - wy * is);
        let y = sb * c + wy * cb * t + (1.0 - cb) * (wy * icc + wz * isc) - sb * (wx * is);
        let z = sb * s + wz * cb * t + (1.0 - cb) * (wy * isc + wz * iss) + sb * (wx * ic);
        Vec3::new(x, y, z)
    };
    prim(t1) - prim(t0)
}

/// The meridian flight of the `polar` scene at extended latitude μ (rad) with constant rate
/// ċ = μ̇ (rad/s) at height `h`: ω = [Ω cos μ, −ċ, −Ω sin μ], f = [ċ² dR_N/dμ, −2Ω sin μ v_N,
/// ċ v_N − γ] with v_N = (R_N + h) ċ, finite through μ = 90°.
pub fn polar_meridian(mu: f64, c: f64, h: f64) -> (Vec3, Vec3) {
    let (s, co) = mu.sin_cos();
    let w = 1.0 - earth::E2 * s * s;
    let drn = 3.0 * earth::A * (1.0 - earth::E2) * earth::E2 * s * co / w.powf(2.5);
    let vn = (earth::radius_meridian(s) + h) * c;
    (
        Vec3::new(OMEGA_IE * co, -c, -OMEGA_IE * s),
        Vec3::new(
            c * c * drn,
            -2.0 * OMEGA_IE * s * vn,
            c * vn - earth::normal_gravity(s, h),
        ),
    )
}

/// One error-free check: the engine's largest deviation from a reference, and its bound.
#[derive(Clone, Debug, PartialEq)]
pub struct Check {
    /// What was compared.
    pub name: String,
    /// How the reference was obtained.
    pub reference: &'static str,
    /// Instants or records compared.
    pub samples: usize,
    /// Largest |Δω| (rad/s), or |ΔΔθ| (rad) for increment checks.
    pub gyro: f64,
    /// Largest |Δf| (m/s²); NaN where the check has no accelerometer part.
    pub accel: f64,
    /// Bound on `gyro`.
    pub gyro_bound: f64,
    /// Bound on `accel`.
    pub accel_bound: f64,
}

impl Check {
    /// True when both deviations are within their bounds.
    pub fn pass(&self) -> bool {
        self.gyro <= self.gyro_bound && (self.accel.is_nan() || self.accel <= self.accel_bound)
    }
}

fn scene(name: &str, p: &SceneParams) -> AnyMotion {
    // Built-in names with checked parameters: an error here is a bug in this module.
    AnyMotion::Scene(
        scenes::build(name, p)
            .expect("built-in scene parameters are valid")
            .expect("built-in scene name"),
    )
}

fn records(m: AnyMotion, rate: f64, n: usize) -> Vec<Record> {
    let mut imu = IdealImu::new(m, rate, 0.0, n as u64, crate::generator::DEFAULT_NODES);
    let mut out = vec![Record::default(); n];
    imu.fill(1, &mut out);
    out
}

/// Static, level IMUs on a grid of latitudes (both poles included) and heights, records at
/// `rate_hz` against [`static_level`]. Bounds: a few ulp of the values (1e-19 rad/s on
/// ~7e-5 rad/s, 4e-15 m/s² on ~9.8 m/s²).
pub fn static_grid(rate_hz: f64) -> Vec<Check> {
    let mut out = Vec::new();
    for lat_deg in [-90.0, -60.0, -41.0, 0.0, 41.0, 60.0, 89.9999, 90.0] {
        for h in [0.0, 10_000.0] {
            let p = SceneParams {
                lat_deg,
                h_m: h,
                ..SceneParams::defaults_for("static")
            };
            let (g, a) = static_level(f64::to_radians(lat_deg), h);
            let rs = records(scene("static", &p), rate_hz, 10);
            let (mut eg, mut ea) = (0.0f64, 0.0f64);
            for r in &rs {
                eg = eg.max((r.gyro - g).max_abs());
                ea = ea.max((r.accel - a).max_abs());
            }
            out.push(Check {
                name: format!("static {lat_deg}° h {h} m"),
                reference: "closed form",
                samples: rs.len(),
                gyro: eg,
                accel: ea,
                gyro_bound: 1e-19,
                accel_bound: 4e-15,
            });
        }
    }
    out
}

/// Every built-in dynamic scene against its reference: `straight`, `circle` and `survey`
/// against the definition at 300 instants spread over the run (bounds 1e-12 rad/s and
/// 1e-10 m/s², the project's error-free targets); `coning` increments at 1 kHz against
/// [`coning_dtheta`] (bound: a few ulp of the phase, as sin β·Ω t·ε); `polar` against
/// [`polar_meridian`] through the pole (1e-18 rad/s, 1e-14 m/s²).
pub fn scene_checks() -> Vec<Check> {
    let mut out = Vec::new();
    for name in ["straight", "circle", "survey"] {
        let m = scene(name, &SceneParams::defaults_for(name));
        let dur = if name == "survey" { 600.0 } else { 60.0 };
        let (mut eg, mut ea, mut n) = (0.0f64, 0.0f64, 0);
        for i in 0..300 {
            let t = 0.05 + (dur - 0.1) * i as f64 / 299.0;
            if m.piece_at(t - 0.035, 0) != m.piece_at(t + 0.035, 0) {
                continue;
            }
            let s = m.sense(m.piece_at(t, 0), t);
            let (g, a) = by_definition(&m, t, 1e-2);
            eg = eg.max((s.omega_ib_b - g).max_abs());
            ea = ea.max((s.f_b - a).max_abs());
            n += 1;
        }
        out.push(Check {
            name: name.into(),
            reference: "definition (eq. 1–2, numerical derivatives of the pose)",
            samples: n,
            gyro: eg,
            accel: ea,
            gyro_bound: 1e-12,
            accel_bound: 1e-10,
        });
    }
    let p = SceneParams::defaults_for("coning");
    let (rate, n) = (1000.0, 1000);
    let rs = records(scene("coning", &p), rate, n);
    let (beta, om) = (
        p.cone_half_angle_deg.to_radians(),
        2.0 * std::f64::consts::PI * p.cone_hz,
    );
    let lat = p.lat_deg.to_radians();
    let mut eg = 0.0f64;
    for (i, r) in rs.iter().enumerate() {
        let want = coning_dtheta(beta, om, lat, i as f64 / rate, (i + 1) as f64 / rate);
        eg = eg.max((r.dtheta - want).max_abs());
    }
    out.push(Check {
        name: "coning (Δθ)".into(),
        reference: "closed form",
        samples: n,
        gyro: eg,
        accel: f64::NAN,
        gyro_bound: 4.0 * beta.sin() * om * (n as f64 / rate) * f64::EPSILON + 1e-19,
        accel_bound: f64::NAN,
    });
    let p = SceneParams::defaults_for("polar");
    let m = scene("polar", &p);
    let rn_pole = earth::radius_meridian(1.0) + p.h_m;
    let c = p.speed_m_s / rn_pole;
    let mu0 = std::f64::consts::FRAC_PI_2 - 60.0 * c;
    let (mut eg, mut ea) = (0.0f64, 0.0f64);
    let instants = [0.0, 30.0, 59.999, 60.0, 60.0001, 90.0, 119.0];
    for t in instants {
        let s = m.sense(0, t);
        let (g, a) = polar_meridian(mu0 + c * t, c, p.h_m);
        eg = eg.max((s.omega_ib_b - g).max_abs());
        ea = ea.max((s.f_b - a).max_abs());
    }
    out.push(Check {
        name: "polar (through the pole)".into(),
        reference: "closed form",
        samples: instants.len(),
        gyro: eg,
        accel: ea,
        gyro_bound: 1e-18,
        accel_bound: 1e-14,
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_error_free_check_passes() {
        for c in static_grid(100.0).into_iter().chain(scene_checks()) {
            assert!(c.pass(), "{c:?}");
            assert!(c.samples > 0, "{c:?}");
        }
    }
}
