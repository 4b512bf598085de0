//! Sanity bounds of template values and compact number formatting for messages.
//!
//! A template value beyond its bound is refused with the file, the key, the value as written
//! and the bound. The bounds are far outside any real IMU, consumer MEMS included, and sit
//! where the model stops meaning anything (a scale-factor error of −100 % cancels the signal)
//! or where products with other figures approach overflow; they only catch typos and unit
//! mistakes (`1e300 deg/sqrt(h)`). Magnitudes, in SI:
//!
//! | quantity | bound | for comparison |
//! |---|---|---|
//! | angular rate (bias, turn-on, instability, Gauss–Markov σ, range) | 10⁴ rad/s (5.7·10⁵ deg/s) | consumer gyro full scale ±2000 deg/s |
//! | acceleration (same terms) | 10⁷ m/s² (≈ 10⁶ g) | shock-rated accelerometers ≈ 10⁵ g |
//! | angle random walk | 1 rad/√s (3438 deg/√h) | consumer MEMS ≈ 0.1–1 deg/√h |
//! | rate random walk | 1 rad/s/√s | consumer MEMS ≈ 10⁻⁴ rad/s/√s |
//! | velocity random walk | 100 m/s/√s (≈ 10 g/√Hz) | consumer MEMS ≈ 300 µg/√Hz |
//! | acceleration random walk | 100 m/s²/√s | |
//! | scale factor (constant, turn-on, σ, asymmetry) | 1 (100 %) | consumer MEMS ≈ 1–3 % |
//! | scale-factor random walk, clock frequency random walk | 1 /√s | |
//! | clock frequency drift | 1 /s | crystals age ≈ 1 ppm a year |
//! | quadratic scale factor | 1 /(m/s²) (error = signal at 1 m/s²) | ≈ 10 µg/g² |
//! | misalignment angle | 0.2 rad (11°): the model is first order in small angles | consumer ≈ 1–2° |
//! | g-sensitivity | 1 (rad/s)/(m/s²) (≈ 560 deg/s/g) | consumer ≈ 0.1 deg/s/g |
//! | time (τ, band) | 10⁹ s (32 years) | |
//! | size effect (offset of one accelerometer, also usable as a lever arm) | 100 m | millimetres; lever arms of large ships tens of metres |
//! | LSB of an increment | 1 rad, 1000 m/s | 2⁻¹⁹ rad, 2⁻¹⁴ m/s |
//! | temperature coefficient of power k | the bound of its quantity per °C^k | |
//! | `rate_hz` | 10⁷ Hz | |
//! | `temperature_ref` | −273.15 … 1000 °C | |
//!
//! An LSB on the rate takes the bound of the rate. Every value must also be finite after the
//! conversion to SI.

use crate::units::Kind;

/// Largest `rate_hz` (Hz).
pub const MAX_RATE_HZ: f64 = 1e7;
/// Accepted `temperature_ref` range (°C).
pub const TEMPERATURE_REF_C: (f64, f64) = (-273.15, 1000.0);

/// The largest magnitude (SI) and its SI unit for a template value of `kind`; `increment`
/// selects the increment bound of an LSB kind. `None`: no bound but finiteness.
pub fn max_magnitude(kind: Kind, increment: bool) -> Option<(f64, &'static str)> {
    Some(match kind {
        Kind::AngularRate => (1e4, "rad/s"),
        Kind::Acceleration => (1e7, "m/s^2"),
        Kind::AngleRandomWalk => (1.0, "rad/sqrt(s)"),
        Kind::RateRandomWalk => (1.0, "rad/s/sqrt(s)"),
        Kind::VelocityRandomWalk => (100.0, "m/s/sqrt(s)"),
        Kind::AccelRandomWalk => (100.0, "m/s^2/sqrt(s)"),
        Kind::Ratio => (1.0, "(ratio)"),
        Kind::RatioRandomWalk => (1.0, "1/sqrt(s)"),
        Kind::RatioDrift => (1.0, "1/s"),
        Kind::Quadratic => (1.0, "1/(m/s^2)"),
        Kind::Angle => (0.2, "rad"),
        Kind::GSensitivity => (1.0, "(rad/s)/(m/s^2)"),
        Kind::Time => (1e9, "s"),
        Kind::RateRamp => (1e3, "rad/s^2"),
        Kind::AccelRamp => (1e5, "m/s^3"),
        Kind::Length => (100.0, "m"),
        Kind::GyroLsb if increment => (1.0, "rad"),
        Kind::GyroLsb => (1e4, "rad/s"),
        Kind::AccelLsb if increment => (1e3, "m/s"),
        Kind::AccelLsb => (1e7, "m/s^2"),
        Kind::Frequency | Kind::AccelPsd | Kind::RatePsd => return None,
    })
}

/// Checks `si`, the value of `text` (`"number unit"`, as written) in SI, against the bound of
/// `kind`; the message echoes `text` and states the bound in the text's unit and in SI.
pub fn check(text: &str, kind: Kind, si: f64, increment: bool) -> Result<(), String> {
    let text = text.trim();
    if !si.is_finite() {
        return Err(format!("`{text}` is too large to represent in SI units"));
    }
    let Some((max, si_unit)) = max_magnitude(kind, increment) else {
        return Ok(());
    };
    if si.abs() <= max {
        return Ok(());
    }
    // The bound in the unit as written: the text's number over its SI value gives the factor.
    let (num, unit) = text.split_once(char::is_whitespace).unwrap_or((text, ""));
    let in_unit = num
        .parse::<f64>()
        .ok()
        // Not when the text is in the SI unit already (factor 1).
        .filter(|n| *n != 0.0 && !unit.trim().is_empty() && *n != si)
        .map(|n| format!("{} {} = ", compact(max * n / si), unit.trim()))
        .unwrap_or_default();
    Err(format!(
        "`{text}` is out of range: the accepted magnitude is at most {in_unit}{} {si_unit} \
         (far beyond any real IMU; a unit or exponent typo?)",
        compact(max)
    ))
}

/// A number in at most four significant digits (`3438`, `0.01235`, `1e300`, `-2.5e-7`), for
/// messages: `{}` of an f64 can run to hundreds of digits.
pub fn compact(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || !a.is_finite() {
        return format!("{x}");
    }
    if (1e-3..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{x:.digits$}");
        if s.contains('.') {
            return s.trim_end_matches('0').trim_end_matches('.').to_string();
        }
        return s;
    }
    let s = format!("{x:.3e}");
    let (m, e) = s.split_once('e').unwrap_or((&s, "0"));
    let m = if m.contains('.') {
        m.trim_end_matches('0').trim_end_matches('.')
    } else {
        m
    };
    format!("{m}e{e}")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Numbers stay short whatever their size, and keep four significant digits.
    #[test]
    fn compact_numbers() {
        assert_eq!(compact(1e300), "1e300");
        assert_eq!(compact(3437.746770784939), "3438");
        assert_eq!(compact(0.012345678), "0.01235");
        assert_eq!(compact(-2.5e-7), "-2.5e-7");
        assert_eq!(compact(100.0), "100");
        assert_eq!(compact(123456.0), "1.235e5");
        assert_eq!(compact(0.0), "0");
        assert!(compact(f64::MAX).len() <= 12);
    }

    /// The bound is stated in the unit the value was written in, and in SI.
    #[test]
    fn bound_in_the_written_unit() {
        // 1e300 deg/√h in rad/√s: 1e300·(π/180)/60.
        let si = 1e300 * std::f64::consts::PI / 180.0 / 60.0;
        let e = check("1e300 deg/sqrt(h)", Kind::AngleRandomWalk, si, false).unwrap_err();
        assert!(e.contains("`1e300 deg/sqrt(h)`"), "{e}");
        // 1 rad/√s = 180/π·60 deg/√h = 3437.7 deg/√h.
        assert!(e.contains("3438 deg/sqrt(h) = 1 rad/sqrt(s)"), "{e}");
        assert!(e.len() < 200, "{e}");
        assert!(check("0.07 deg/sqrt(h)", Kind::AngleRandomWalk, 2e-5, false).is_ok());
        assert!(check("1 g", Kind::Acceleration, f64::INFINITY, false).is_err());
        let e = check("200 m", Kind::Length, 200.0, false).unwrap_err();
        assert!(e.contains("at most 100 m (far"), "{e}");
    }
}
