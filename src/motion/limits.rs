//! The physical limits a motion input must respect. They are far beyond any vehicle an IMU
//! rides (heights to beyond geostationary orbit, speeds beyond Earth's escape speed) yet keep
//! every quantity of the kinematics — ECEF position, transport rate, gravity, finite-difference
//! weights, specific force — many orders of magnitude inside the range of `f64`, so a value
//! that passes can never make the signal overflow to NaN or infinity.

use super::knot::Sample;
use crate::csvio::num;

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

/// Checks one sample's time, height and speed.
pub fn check_sample(s: &Sample) -> Result<(), Violation> {
    if s.t.abs() > MAX_ABS_TIME_S {
        return violation(
            "t",
            format!("time {} s is beyond ±{} s", num(s.t), num(MAX_ABS_TIME_S)),
        );
    }
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
}
