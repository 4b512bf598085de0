//! The physical limits a motion input must respect. They are far beyond any vehicle an IMU
//! rides (heights to beyond geostationary orbit, speeds beyond Earth's escape speed) yet keep
//! every quantity of the kinematics — ECEF position, transport rate, gravity, finite-difference
//! weights, specific force — many orders of magnitude inside the range of `f64`, so a value
//! that passes can never make the signal overflow to NaN or infinity.

use super::knot::Sample;
use crate::csvio::num;
use crate::earth::Geodetic;
use crate::math::Vec3;

/// Largest |t| (s): 10¹⁰ s (317 years) holds GPS and Unix times with sub-µs resolution.
pub const MAX_ABS_TIME_S: f64 = 1.0e10;
/// Lowest ellipsoidal height (m): 100 km below the ellipsoid.
pub const MIN_HEIGHT_M: f64 = -1.0e5;
/// Highest ellipsoidal height (m): 100 000 km, 2.8 times the geostationary altitude.
pub const MAX_HEIGHT_M: f64 = 1.0e8;
/// Largest speed relative to the Earth (m/s): 30 km/s, almost three times escape speed.
pub const MAX_SPEED_M_S: f64 = 3.0e4;
/// Shortest time step between samples (s): 1 µs (a 1 MHz trajectory).
pub const MIN_STEP_S: f64 = 1.0e-6;
/// Largest acceleration implied between samples, |Δv^n|/Δt (m/s²): about 10 000 g.
pub const MAX_ACCEL_M_S2: f64 = 1.0e5;
/// Largest angular rate implied between samples, (rotation angle)/Δt (rad/s): 10⁴ rad/s,
/// about 1 600 revolutions per second.
pub const MAX_RATE_RAD_S: f64 = 1.0e4;
/// Disagreement allowed between a position step and the one the velocities imply (m), on top
/// of what [`MAX_ACCEL_M_S2`] allows: positions rounded in a file (1e-5° is 1.1 m) or recorded
/// apart from the velocities, never a jump of kilometres.
pub const POSITION_SLACK_M: f64 = 10.0;

/// A value beyond a limit: the trajectory column it concerns and what is wrong.
#[derive(Clone, Debug, PartialEq)]
pub struct Violation {
    /// The trajectory column (`t`, `h`, `vn`, …) most to blame; empty for the attitude,
    /// which three columns give together.
    pub column: &'static str,
    /// What is wrong, with the value and the limit.
    pub message: String,
}

fn violation(column: &'static str, message: String) -> Result<(), Violation> {
    Err(Violation { column, message })
}

/// Checks a time (a sample's, or a run's start) against [`MAX_ABS_TIME_S`].
pub fn check_time(t: f64) -> Result<(), Violation> {
    if t.is_nan() || t.abs() > MAX_ABS_TIME_S {
        return violation(
            "t",
            format!("time {} s is beyond ±{} s", num(t), num(MAX_ABS_TIME_S)),
        );
    }
    Ok(())
}

/// Checks one sample's time, height and speed.
pub fn check_sample(s: &Sample) -> Result<(), Violation> {
    check_time(s.t)?;
    if !(MIN_HEIGHT_M..=MAX_HEIGHT_M).contains(&s.h) {
        return violation(
            "h",
            format!(
                "height {} m is outside [{}, {}] m",
                num(s.h),
                num(MIN_HEIGHT_M),
                num(MAX_HEIGHT_M)
            ),
        );
    }
    let v = s.v_n;
    let k = (0..3).fold(0, |m, k| if v[k].abs() > v[m].abs() { k } else { m });
    // The largest component first: the norm of a huge velocity would overflow to infinity.
    let speed = if v[k].abs() > MAX_SPEED_M_S {
        v[k].abs()
    } else {
        s.v_n.norm()
    };
    if speed > MAX_SPEED_M_S {
        return violation(
            ["vn", "ve", "vd"][k],
            format!(
                "speed {} m/s is above the limit of {} m/s",
                num(speed),
                num(MAX_SPEED_M_S)
            ),
        );
    }
    Ok(())
}

/// Checks the step from `prev` to `s` (times already increasing): its length and the
/// acceleration and angular rate it implies.
pub fn check_step(prev: &Sample, s: &Sample) -> Result<(), Violation> {
    let dt = s.t - prev.t;
    if dt < MIN_STEP_S {
        return violation(
            "t",
            format!(
                "{} s after the previous sample; samples must be at least {} s apart",
                num(dt),
                num(MIN_STEP_S)
            ),
        );
    }
    let accel = (s.v_n - prev.v_n).norm() / dt;
    if accel > MAX_ACCEL_M_S2 {
        return violation(
            "vn",
            format!(
                "the velocity change from the previous sample implies {} m/s², above the limit of {} m/s²",
                num(accel),
                num(MAX_ACCEL_M_S2)
            ),
        );
    }
    check_position(prev, s, dt)?;
    let dq = prev.q_b_n.conjugate() * s.q_b_n;
    let angle = 2.0 * dq.imag().norm().atan2(dq.w.abs());
    let rate = angle / dt;
    if rate > MAX_RATE_RAD_S {
        return violation(
            "",
            format!(
                "the attitude change (roll, pitch, yaw) from the previous sample implies {} rad/s, above the limit of {} rad/s",
                num(rate),
                num(MAX_RATE_RAD_S)
            ),
        );
    }
    Ok(())
}

/// The position step against the velocities: over a step Δt, a motion whose acceleration
/// stays within A moves (v₀ + v₁)·Δt/2 to within A·Δt²/4 (the trapezoid rule's error bound for
/// a velocity with Lipschitz constant A), so a larger miss — a position jump the velocities do
/// not carry — is beyond the limits. In ECEF, where the positions and velocities are one
/// frame's.
fn check_position(prev: &Sample, s: &Sample, dt: f64) -> Result<(), Violation> {
    let (g0, g1) = (
        Geodetic::from_radians(prev.lat, prev.lon, prev.h),
        Geodetic::from_radians(s.lat, s.lon, s.h),
    );
    let moved = g1.to_ecef() - g0.to_ecef();
    let carried = (g0.c_n_e() * prev.v_n + g1.c_n_e() * s.v_n) * (dt / 2.0);
    let miss = moved - carried;
    let allowed = MAX_ACCEL_M_S2 * dt * dt / 4.0 + POSITION_SLACK_M;
    if miss.norm() <= allowed {
        return Ok(());
    }
    // Blame the column of the miss's largest local-level component.
    let ned = g0.c_n_e().tr_mul(&miss);
    let k = (0..3).fold(0, |m, k| if ned[k].abs() > ned[m].abs() { k } else { m });
    violation(
        ["lat", "lon", "h"][k],
        format!(
            "the position moved {} m from the previous sample, {} m off what the velocities carry it in {} s (at most {} m within the limit of {} m/s²)",
            num(round3(moved.norm())),
            num(round3(miss.norm())),
            num((dt * 1e9).round() / 1e9),
            num(round3(allowed)),
            num(MAX_ACCEL_M_S2)
        ),
    )
}

/// A length for a message: to the millimetre.
fn round3(x: f64) -> f64 {
    (x * 1e3).round() / 1e3
}

/// Checks the derivatives a live state may carry besides its sample: the body rate ω_ib^b
/// (rad/s) against [`MAX_RATE_RAD_S`] and the NED acceleration v̇^n (m/s²) against
/// [`MAX_ACCEL_M_S2`]; columns named as the live CSV names them (`wx`…, `an`…).
pub fn check_given(omega_ib_b: Option<Vec3>, accel_n: Option<Vec3>) -> Result<(), Violation> {
    for (v, limit, names, what, unit) in [
        (
            omega_ib_b,
            MAX_RATE_RAD_S,
            ["wx", "wy", "wz"],
            "body rate",
            "rad/s",
        ),
        (
            accel_n,
            MAX_ACCEL_M_S2,
            ["an", "ae", "ad"],
            "acceleration",
            "m/s²",
        ),
    ] {
        let Some(v) = v else { continue };
        // Per component first: the norm of a huge (or non-finite) vector is not a number to quote.
        if let Some(k) = (0..3).find(|&k| v[k].is_nan() || v[k].abs() > limit) {
            return violation(
                names[k],
                format!(
                    "the given {what} {} {unit} is beyond the limit of {} {unit}",
                    num(v[k]),
                    num(limit)
                ),
            );
        }
        if v.norm() > limit {
            return violation(
                names[0],
                format!(
                    "the given {what} has magnitude {} {unit}, above the limit of {} {unit}",
                    num(v.norm()),
                    num(limit)
                ),
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Vec3, quat_from_euler};

    fn at(t: f64, h: f64, vn: f64, yaw: f64) -> Sample {
        Sample {
            t,
            lat: 0.7,
            lon: 0.1,
            h,
            v_n: Vec3::new(vn, 0.0, 0.0),
            q_b_n: quat_from_euler(0.0, 0.0, yaw),
        }
    }

    #[test]
    fn limits_are_enforced_at_their_values() {
        assert!(check_sample(&at(0.0, MAX_HEIGHT_M, MAX_SPEED_M_S, 0.0)).is_ok());
        let e = check_sample(&at(0.0, 1e160, 0.0, 0.0)).unwrap_err();
        assert_eq!(e.column, "h");
        assert!(
            e.message.contains("1e160 m is outside [-1e5, 1e8] m"),
            "{e:?}"
        );
        let e = check_sample(&at(0.0, 0.0, -3.0001e4, 0.0)).unwrap_err();
        assert_eq!(e.column, "vn");
        let e = check_sample(&at(0.0, 0.0, 1e160, 0.0)).unwrap_err();
        assert!(e.message.contains("speed 1e160 m/s"), "{e:?}");
        let e = check_sample(&at(-2e10, 0.0, 0.0, 0.0)).unwrap_err();
        assert_eq!(e.column, "t");
        // A run's start: 1e300 is quoted as such, not as its 301 digits.
        let e = check_time(1e300).unwrap_err();
        assert_eq!(e.message, "time 1e300 s is beyond ±1e10 s");
        assert!(check_time(f64::NAN).is_err() && check_time(-1e10).is_ok());
        let a = at(0.0, 0.0, 0.0, 0.0);
        // 1 g over 10 ms and 1 rad/s are fine; the limits are exceeded just beyond them.
        assert!(check_step(&a, &at(0.01, 0.0, 0.098, 0.01)).is_ok());
        assert_eq!(
            check_step(&a, &at(1e-7, 0.0, 0.0, 0.0)).unwrap_err().column,
            "t"
        );
        let e = check_step(&a, &at(0.01, 0.0, 1000.1, 0.0)).unwrap_err();
        assert!(e.message.contains("above the limit of 1e5 m/s²"), "{e:?}");
        let e = check_step(&a, &at(1e-4, 0.0, 0.0, 1.0001)).unwrap_err();
        assert_eq!(e.column, "");
        assert!(e.message.contains("above the limit of 1e4 rad/s"), "{e:?}");
    }

    /// A position step must be carried by the velocities to within A·Δt²/4 + the slack: at
    /// 10 ms that is 12.5 m. A height jump of 12.51 m with the vehicle at rest is refused,
    /// 12.49 m is not; a flight at 60 m/s north whose latitude follows its speed passes, and the
    /// same with 9° (1000 km) more latitude is refused naming `lat`.
    #[test]
    fn positions_must_follow_the_velocities() {
        let a = at(0.0, 100.0, 0.0, 0.0);
        assert!(check_step(&a, &at(0.01, 112.49, 0.0, 0.0)).is_ok());
        let e = check_step(&a, &at(0.01, 112.51, 0.0, 0.0)).unwrap_err();
        assert_eq!(e.column, "h");
        assert!(
            e.message
                .contains("12.51 m off what the velocities carry it in 0.01 s (at most 12.5 m"),
            "{e:?}"
        );
        let g = Geodetic::from_radians(a.lat, a.lon, a.h);
        let r_m = crate::earth::radius_meridian(g.sin_lat);
        let flying = |t: f64, extra_lat: f64| Sample {
            lat: a.lat + 60.0 * t / (r_m + a.h) + extra_lat,
            ..at(t, 100.0, 60.0, 0.0)
        };
        assert!(check_step(&flying(0.0, 0.0), &flying(0.01, 0.0)).is_ok());
        let e = check_step(&flying(0.0, 0.0), &flying(0.01, 9f64.to_radians())).unwrap_err();
        assert_eq!(e.column, "lat");
        // 9° of meridian arc from 40° N: 999 km.
        assert!(e.message.contains("the position moved 999105."), "{e:?}");
    }

    /// Given body rates and accelerations are held to the rate and acceleration limits, per
    /// component (so 1e300 and NaN name their column) and in magnitude.
    #[test]
    fn given_rates_and_accelerations_are_limited() {
        let ok = Vec3::new(MAX_RATE_RAD_S, 0.0, 0.0);
        assert!(check_given(Some(ok), Some(Vec3::new(0.0, 0.0, -MAX_ACCEL_M_S2))).is_ok());
        let e = check_given(Some(Vec3::new(1e300, 0.0, 0.0)), None).unwrap_err();
        assert_eq!(e.column, "wx");
        assert!(
            e.message
                .contains("body rate 1e300 rad/s is beyond the limit of 1e4"),
            "{e:?}"
        );
        let e = check_given(Some(Vec3::new(0.0, f64::NAN, 0.0)), None).unwrap_err();
        assert_eq!(e.column, "wy");
        let e = check_given(None, Some(Vec3::new(1e300, 0.0, 0.0))).unwrap_err();
        assert_eq!(e.column, "an");
        let diagonal = Vec3::new(0.8, 0.8, 0.0) * MAX_RATE_RAD_S;
        let e = check_given(Some(diagonal), None).unwrap_err();
        assert!(e.message.contains("magnitude"), "{e:?}");
    }
}
