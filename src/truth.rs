//! Reference values for the error-free signal, computed without the engine's kinematics:
//! closed forms (static anywhere on the planet, classic coning, a meridian flight over the
//! pole) and equations (1)–(2) evaluated from their definition on a scene's pose, with the
//! attitude, velocity and position differentiated numerically. `imu-emu validate` measures the
//! engine against them (the paper's §4.1 checks); the tests check them in turn.
//!
//! The Earth model here is written out again from the WGS-84 defining constants ([`wgs84`]),
//! so a wrong constant or formula in `crate::earth`, which the engine uses, shows as a
//! disagreement instead of cancelling out.

use crate::generator::IdealImu;
use crate::math::{Mat3, QuatExt, Vec3};
use crate::motion::Motion;
use crate::record::Record;
use crate::scenes::{self, SceneParams};
use crate::source::AnyMotion;

/// WGS-84 written from its definition (NIMA TR8350.2, 3rd ed.: chapter 3 for the defining and
/// derived constants, chapter 4 for normal gravity and its height correction), sharing
/// nothing with `crate::earth`.
pub mod wgs84 {
    use crate::math::Vec3;

    /// Semi-major axis a (m), defining.
    pub const A: f64 = 6_378_137.0;
    /// Flattening f, defining (1/f = 298.257223563).
    pub const F: f64 = 1.0 / 298.257_223_563;
    /// Earth rotation rate ω (rad/s), defining.
    pub const OMEGA: f64 = 7.292_115e-5;
    /// GM (m³/s²), defining.
    pub const GM: f64 = 3.986_004_418e14;
    /// Normal gravity at the equator γ_e (m/s²), derived constant of the standard.
    const GAMMA_EQUATOR: f64 = 9.780_325_335_9;
    /// Somigliana's k = b γ_p/(a γ_e) − 1, derived constant of the standard.
    const SOMIGLIANA: f64 = 0.001_931_852_652_41;

    /// e² = 2f − f².
    pub fn e2() -> f64 {
        2.0 * F - F * F
    }

    /// m = ω² a² b / GM, computed from the defining constants (the standard tabulates
    /// 0.00344978650684).
    pub fn m() -> f64 {
        let b = A - A * F;
        OMEGA * OMEGA * A * A * b / GM
    }

    /// Normal gravity γ(φ, h) = γ₀(φ)[1 − (2/a)(1 + f + m − 2f sin²φ)h + 3h²/a²] with
    /// Somigliana's γ₀ = γ_e(1 + k sin²φ)/√(1 − e² sin²φ).
    pub fn gamma(sin_lat: f64, h: f64) -> f64 {
        let s2 = sin_lat.powi(2);
        let g0 = GAMMA_EQUATOR * (1.0 + SOMIGLIANA * s2) / (1.0 - e2() * s2).sqrt();
        let first = 2.0 * h * (1.0 + F + m() - 2.0 * F * s2) / A;
        g0 * (1.0 - first + 3.0 * (h / A).powi(2))
    }

    /// Meridian radius of curvature R_N = a(1 − e²)/(1 − e² sin²φ)^{3/2}.
    pub fn radius_meridian(sin_lat: f64) -> f64 {
        A * (1.0 - e2()) / (1.0 - e2() * sin_lat.powi(2)).powf(1.5)
    }

    /// Earth rate in NED, [ω cos φ, 0, −ω sin φ].
    pub fn earth_rate_ned(sin_lat: f64, cos_lat: f64) -> Vec3 {
        Vec3::new(OMEGA * cos_lat, 0.0, -OMEGA * sin_lat)
    }
}

/// Static, level, heading north at latitude `lat` (rad) and height `h`: the gyro senses Earth
/// rate [Ω cos φ, 0, −Ω sin φ] and the accelerometer [0, 0, −γ(φ, h)].
pub fn static_level(lat: f64, h: f64) -> (Vec3, Vec3) {
    let (s, c) = lat.sin_cos();
    (
        wgs84::earth_rate_ned(s, c),
        Vec3::new(0.0, 0.0, -wgs84::gamma(s, h)),
    )
}

/// Equations (1)–(2) from the definition on the pose of `m` at `t`: Ω_ib^b = C_n^b Ċ_b^n +
/// C_n^b Ω_in^n C_b^n and f^b = C_n^b(v̇^n + (2Ω_ie^n + Ω_en^n) v^n − g^n), with Ċ_b^n, v̇^n and
/// the latitude and longitude rates by 6th-order central differences of step `d`. The
/// transport rate is the n frame's rotation over the Earth, ω_en^n = [λ̇ cos φ, −φ̇, −λ̇ sin φ],
/// from those rates — not from v^n and the radii of curvature as the engine computes it, so a
/// velocity inconsistent with the position shows too. Truncation is ~d⁶ f⁽⁷⁾/140 and
/// round-off ~(pose noise ≈ 2e-15)/d: pick `d` for the motion's bandwidth (10 ms for vehicle
/// motion below ~1 Hz gives ~2e-13 rad/s). The differences must not straddle a model
/// breakpoint or pass within d·v of a pole.
pub fn by_definition(m: &impl Motion, t: f64, d: f64) -> (Vec3, Vec3) {
    let w = [(1.0, 45.0 / 60.0), (2.0, -9.0 / 60.0), (3.0, 1.0 / 60.0)];
    let pose = m.pose(t);
    let c = pose.q_b_n.to_mat();
    let mut cdot = Mat3::zeros();
    let mut vdot = Vec3::zeros();
    let (mut lat_dot, mut lon_dot) = (0.0, 0.0);
    let pi = std::f64::consts::PI;
    for (k, wk) in w {
        let (pp, pm) = (m.pose(t + k * d), m.pose(t - k * d));
        let (cp, cm) = (pp.q_b_n.to_mat(), pm.q_b_n.to_mat());
        cdot += (cp - cm).map(|x| wk * x / d);
        vdot += (pp.v_n - pm.v_n) * (wk / d);
        lat_dot += wk * (pp.lat - pm.lat) / d;
        // Longitude may wrap at ±180° between the two instants.
        lon_dot += wk * ((pp.lon - pm.lon + pi).rem_euclid(2.0 * pi) - pi) / d;
    }
    let (s, co) = pose.lat.sin_cos();
    let v = pose.v_n;
    let w_ie = wgs84::earth_rate_ned(s, co);
    let w_en = Vec3::new(lon_dot * co, -lat_dot, -lon_dot * s);
    // Ω_nb^b = C_n^b Ċ_b^n; its skew part is ω_nb^b.
    let om = c.transpose() * cdot;
    let w_nb = Vec3::new(
        0.5 * (om[(2, 1)] - om[(1, 2)]),
        0.5 * (om[(0, 2)] - om[(2, 0)]),
        0.5 * (om[(1, 0)] - om[(0, 1)]),
    );
    let mut a = vdot + (w_ie * 2.0 + w_en).cross(&v);
    a[2] -= wgs84::gamma(s, pose.h);
    (w_nb + c.tr_mul(&(w_ie + w_en)), c.tr_mul(&a))
}

/// Δθ over [t0, t1] of classic coning about body x (half-angle `beta` rad at `om` rad/s,
/// C_b^n = Exp(β n(t)), n = (0, cos Ωt, sin Ωt)) at latitude `lat`: the body's own coning
/// [−2Ω sin²(β/2)Δt, sin β Δcos Ωt, sin β Δsin Ωt] plus ∫C_n^b ω_ie^n dt, both in closed form.
pub fn coning_dtheta(beta: f64, om: f64, lat: f64, t0: f64, t1: f64) -> Vec3 {
    let (wx, wy, wz) = (wgs84::OMEGA * lat.cos(), 0.0, -wgs84::OMEGA * lat.sin());
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
    let e2 = wgs84::e2();
    let w = 1.0 - e2 * s * s;
    let drn = 3.0 * wgs84::A * (1.0 - e2) * e2 * s * co / w.powf(2.5);
    let vn = (wgs84::radius_meridian(s) + h) * c;
    (
        wgs84::earth_rate_ned(s, co) + Vec3::new(0.0, -c, 0.0),
        Vec3::new(
            c * c * drn,
            -2.0 * wgs84::OMEGA * s * vn,
            c * vn - wgs84::gamma(s, h),
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
                eg = eg.max((r.gyro - g).amax());
                ea = ea.max((r.accel - a).amax());
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
/// against the definition at 300 instants spread over the run; `coning` increments at 1 kHz
/// against [`coning_dtheta`] (bound: a few ulp of the phase, as sin β·Ω t·ε); `polar` against
/// [`polar_meridian`] through the pole (1e-18 rad/s, 4e-15 m/s² — 2 ulp of γ).
///
/// The definition's bounds are ~3× the round-off of its numerical derivatives measured on each
/// scene (`cargo test --release --lib truth:: -- --nocapture` prints them): straight 3.1e-15
/// rad/s and 3.1e-13 m/s² (only the longitude moves), circle 1.3e-13 and 5.7e-12, survey
/// 2.4e-13 and 1.4e-11 — all well inside the project's error-free targets, 1e-12 rad/s and
/// 1e-10 m/s².
pub fn scene_checks() -> Vec<Check> {
    let mut out = Vec::new();
    for (name, gyro_bound, accel_bound) in [
        ("straight", 1e-14, 1e-12),
        ("circle", 4e-13, 2e-11),
        ("survey", 8e-13, 5e-11),
    ] {
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
            eg = eg.max((s.omega_ib_b - g).amax());
            ea = ea.max((s.f_b - a).amax());
            n += 1;
        }
        out.push(Check {
            name: name.into(),
            reference: "definition (eq. 1–2, numerical derivatives of the pose)",
            samples: n,
            gyro: eg,
            accel: ea,
            gyro_bound,
            accel_bound,
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
        eg = eg.max((r.dtheta - want).amax());
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
    let rn_pole = wgs84::radius_meridian(1.0) + p.h_m;
    let c = p.speed_m_s / rn_pole;
    let mu0 = std::f64::consts::FRAC_PI_2 - 60.0 * c;
    let (mut eg, mut ea) = (0.0f64, 0.0f64);
    let instants = [0.0, 30.0, 59.999, 60.0, 60.0001, 90.0, 119.0];
    for t in instants {
        let s = m.sense(0, t);
        let (g, a) = polar_meridian(mu0 + c * t, c, p.h_m);
        eg = eg.max((s.omega_ib_b - g).amax());
        ea = ea.max((s.f_b - a).amax());
    }
    out.push(Check {
        name: "polar (through the pole)".into(),
        reference: "closed form",
        samples: instants.len(),
        gyro: eg,
        accel: ea,
        gyro_bound: 1e-18,
        accel_bound: 4e-15,
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The independent WGS-84 agrees with the engine's `crate::earth`: m from the defining
    /// constants with the standard's table to half its last digit (measured 8.4e-16), γ and R_N
    /// to 4 ulp (both are a handful of roundings of the same closed forms), and a wrong constant
    /// in either (a digit of k or γ_e, f for 1/f) would be ~1e-10 relative or worse.
    #[test]
    fn independent_wgs84_agrees_with_the_engine() {
        use crate::earth;
        assert!((wgs84::m() - 0.003_449_786_506_84).abs() < 5e-15);
        assert!((wgs84::e2() - earth::E2).abs() <= f64::EPSILON * earth::E2);
        assert_eq!(wgs84::OMEGA, earth::OMEGA_IE);
        for lat_deg in (-90..=90).step_by(5) {
            let (s, c) = f64::from(lat_deg).to_radians().sin_cos();
            for h in [-400.0, 0.0, 1000.0, 10_000.0, 40_000.0] {
                let (ours, engine) = (wgs84::gamma(s, h), earth::normal_gravity(s, h));
                assert!(
                    (ours - engine).abs() <= 4.0 * f64::EPSILON * engine,
                    "γ at {lat_deg}°, {h} m: {ours} vs {engine}"
                );
            }
            let (ours, engine) = (wgs84::radius_meridian(s), earth::radius_meridian(s));
            assert!(
                (ours - engine).abs() <= 4.0 * f64::EPSILON * engine,
                "R_N {lat_deg}°"
            );
            let d = wgs84::earth_rate_ned(s, c) - earth::omega_ie_n(s, c);
            assert!(d.amax() <= f64::EPSILON * wgs84::OMEGA, "ω_ie {lat_deg}°");
        }
    }

    #[test]
    fn every_error_free_check_passes() {
        for c in static_grid(100.0).into_iter().chain(scene_checks()) {
            println!("{c:?}");
            assert!(c.pass(), "{c:?}");
            assert!(c.samples > 0, "{c:?}");
        }
    }
}
