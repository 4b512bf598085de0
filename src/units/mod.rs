//! Datasheet units at the edges: `"0.07 deg/sqrt(h)"` → SI, once, when a template is loaded.

pub mod bounds;

use std::f64::consts::PI;

/// Standard gravity used by datasheets for g, mg, µg (m/s²).
pub const G0: f64 = 9.806_65;
const DEG: f64 = PI / 180.0;

/// The unit reports show a channel's rates and amplitudes in — deg/s for a gyro, g for an
/// accelerometer, as data sheets give them — and the factor from SI to it.
pub fn report_unit(gyro: bool) -> (&'static str, f64) {
    if gyro {
        ("deg/s", 180.0 / PI)
    } else {
        ("g", 1.0 / G0)
    }
}

/// The physical quantity a value must express; decides which units are accepted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Angular rate → rad/s.
    AngularRate,
    /// Angle random walk density → rad/√s.
    AngleRandomWalk,
    /// Rate random walk density → rad/s/√s.
    RateRandomWalk,
    /// Acceleration → m/s².
    Acceleration,
    /// Velocity random walk density → m/s/√s.
    VelocityRandomWalk,
    /// Acceleration random walk density → m/s²/√s.
    AccelRandomWalk,
    /// Dimensionless ratio (scale factor) → 1.
    Ratio,
    /// Scale-factor random walk density → 1/√s.
    RatioRandomWalk,
    /// Quadratic scale factor → 1/(m/s²).
    Quadratic,
    /// Angle → rad.
    Angle,
    /// Gyro g-sensitivity → (rad/s)/(m/s²).
    GSensitivity,
    /// Time → s.
    Time,
    /// Rate of change of a ratio (a clock's frequency drift) → 1/s.
    RatioDrift,
    /// Length → m.
    Length,
    /// Frequency → Hz.
    Frequency,
    /// Acceleration PSD → (m/s²)²/Hz.
    AccelPsd,
    /// Angular-rate PSD → (rad/s)²/Hz.
    RatePsd,
    /// Gyro quantization: an angle increment (rad) or a rate (rad/s).
    GyroLsb,
    /// Rate ramp (IEEE Std 952 R of a gyro) → rad/s².
    RateRamp,
    /// Acceleration ramp (R of an accelerometer) → m/s³.
    AccelRamp,
    /// Accelerometer quantization: a velocity increment (m/s) or an acceleration (m/s²).
    AccelLsb,
}

/// A quantization step: on the increment or on the rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lsb {
    /// Step of the increment (rad or m/s).
    Increment(f64),
    /// Step of the rate (rad/s or m/s²).
    Rate(f64),
}

impl Kind {
    /// Units accepted for this kind and their factor to SI; for the LSB kinds, whether the
    /// unit is an increment (true) or a rate.
    fn units(self) -> &'static [(&'static str, f64, bool)] {
        match self {
            Kind::AngularRate => &[
                ("rad/s", 1.0, false),
                ("deg/s", DEG, false),
                ("deg/h", DEG / 3600.0, false),
                ("mrad/s", 1e-3, false),
            ],
            Kind::AngleRandomWalk => &[
                ("deg/sqrt(h)", DEG / 60.0, false),
                ("rad/sqrt(s)", 1.0, false),
                ("deg/h/sqrt(Hz)", DEG / 3600.0, false),
                ("deg/s/sqrt(Hz)", DEG, false),
                ("rad/s/sqrt(Hz)", 1.0, false),
            ],
            Kind::RateRandomWalk => &[
                ("deg/h/sqrt(h)", DEG / 3600.0 / 60.0, false),
                ("deg/s/sqrt(s)", DEG, false),
                ("rad/s/sqrt(s)", 1.0, false),
                ("deg/h^2/sqrt(Hz)", DEG / 3600.0 / 3600.0, false),
            ],
            Kind::Acceleration => &[
                ("m/s^2", 1.0, false),
                ("g", G0, false),
                ("mg", G0 * 1e-3, false),
                ("ug", G0 * 1e-6, false),
            ],
            Kind::VelocityRandomWalk => &[
                ("m/s/sqrt(h)", 1.0 / 60.0, false),
                ("m/s^2/sqrt(Hz)", 1.0, false),
                ("ug/sqrt(Hz)", G0 * 1e-6, false),
                ("mg/sqrt(Hz)", G0 * 1e-3, false),
                ("ft/s/sqrt(h)", 0.3048 / 60.0, false),
            ],
            Kind::AccelRandomWalk => &[
                ("m/s^2/sqrt(s)", 1.0, false),
                ("ug/sqrt(s)", G0 * 1e-6, false),
                ("m/s/h/sqrt(h)", 1.0 / 3600.0 / 60.0, false),
                ("mg/sqrt(h)", G0 * 1e-3 / 60.0, false),
            ],
            Kind::Ratio => &[("ppm", 1e-6, false), ("%", 1e-2, false), ("1", 1.0, false)],
            Kind::RatioDrift => &[
                ("ppm/s", 1e-6, false),
                ("ppm/h", 1e-6 / 3600.0, false),
                ("ppm/day", 1e-6 / 86_400.0, false),
                ("1/s", 1.0, false),
            ],
            Kind::RatioRandomWalk => &[
                ("ppm/sqrt(h)", 1e-6 / 60.0, false),
                ("ppm/sqrt(s)", 1e-6, false),
            ],
            Kind::Quadratic => &[("ug/g^2", 1e-6 / G0, false), ("1/(m/s^2)", 1.0, false)],
            Kind::Angle => &[
                ("rad", 1.0, false),
                ("mrad", 1e-3, false),
                ("urad", 1e-6, false),
                ("deg", DEG, false),
                ("arcsec", DEG / 3600.0, false),
            ],
            Kind::GSensitivity => &[
                ("deg/h/g", DEG / 3600.0 / G0, false),
                ("deg/s/g", DEG / G0, false),
                ("rad/s/(m/s^2)", 1.0, false),
            ],
            Kind::Length => &[("m", 1.0, false), ("cm", 1e-2, false), ("mm", 1e-3, false)],
            Kind::Frequency => &[("Hz", 1.0, false), ("kHz", 1e3, false)],
            Kind::AccelPsd => &[
                ("g^2/Hz", G0 * G0, false),
                ("mg^2/Hz", G0 * G0 * 1e-6, false),
                ("(m/s^2)^2/Hz", 1.0, false),
            ],
            Kind::RatePsd => &[
                ("(rad/s)^2/Hz", 1.0, false),
                ("(deg/s)^2/Hz", DEG * DEG, false),
                ("(deg/h)^2/Hz", DEG * DEG / 3600.0 / 3600.0, false),
            ],
            Kind::Time => &[
                ("s", 1.0, false),
                ("ms", 1e-3, false),
                ("us", 1e-6, false),
                ("ns", 1e-9, false),
                ("min", 60.0, false),
                ("h", 3600.0, false),
            ],
            // Every angle unit of `Angle` is an increment step too.
            Kind::GyroLsb => &[
                ("rad", 1.0, true),
                ("mrad", 1e-3, true),
                ("urad", 1e-6, true),
                ("deg", DEG, true),
                ("arcsec", DEG / 3600.0, true),
                ("deg/s", DEG, false),
                ("rad/s", 1.0, false),
            ],
            Kind::RateRamp => &[
                ("deg/h^2", DEG / 3600.0 / 3600.0, false),
                ("deg/h/h", DEG / 3600.0 / 3600.0, false),
                ("deg/s^2", DEG, false),
                ("rad/s^2", 1.0, false),
            ],
            Kind::AccelRamp => &[
                ("m/s/h^2", 1.0 / 3600.0 / 3600.0, false),
                ("m/s^2/h", 1.0 / 3600.0, false),
                ("ug/h", G0 * 1e-6 / 3600.0, false),
                ("mg/h", G0 * 1e-3 / 3600.0, false),
                ("m/s^3", 1.0, false),
            ],
            Kind::AccelLsb => &[
                ("m/s", 1.0, true),
                ("mm/s", 1e-3, true),
                ("m/s^2", 1.0, false),
                ("mg", G0 * 1e-3, false),
                ("ug", G0 * 1e-6, false),
            ],
        }
    }

    /// The accepted unit names, for error messages.
    pub fn unit_names(self) -> String {
        self.units()
            .iter()
            .map(|u| u.0)
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Why a value could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UnitError {
    /// No number in front of the unit.
    #[error("`{0}` does not start with a number")]
    NotNumber(String),
    /// A unit this quantity does not accept.
    #[error("unknown unit `{unit}` (accepted: {accepted})")]
    UnknownUnit {
        /// The unit found.
        unit: String,
        /// The accepted units.
        accepted: String,
    },
}

/// Parses `"<number> <unit>"` into SI; the flag says whether an LSB unit is an increment.
pub fn parse(text: &str, kind: Kind) -> Result<(f64, bool), UnitError> {
    let t = text.trim();
    let split = t.find(|c: char| c.is_whitespace()).unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let value: f64 = num
        .parse()
        .map_err(|_| UnitError::NotNumber(text.to_string()))?;
    if !value.is_finite() {
        return Err(UnitError::NotNumber(text.to_string()));
    }
    let unit: String = unit.chars().filter(|c| !c.is_whitespace()).collect();
    let unit = unit.replace('µ', "u").replace('√', "sqrt");
    kind.units()
        .iter()
        .find(|u| u.0.eq_ignore_ascii_case(&unit) || (u.0 == "1" && unit.is_empty()))
        .map(|u| (value * u.1, u.2))
        .ok_or(UnitError::UnknownUnit {
            unit,
            accepted: kind.unit_names(),
        })
}

/// A `"number unit"` value of `kind` in SI, within the physical bounds of its kind.
pub fn quantity(v: &toml::Value, kind: Kind) -> Result<f64, String> {
    let s = v.as_str().ok_or_else(|| {
        format!(
            "expected a string \"value unit\" (units: {})",
            kind.unit_names()
        )
    })?;
    let x = parse(s, kind).map_err(|e| e.to_string())?.0;
    bounds::check(s, kind, x, false)?;
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_shows_gyros_in_deg_per_s_and_accelerometers_in_g() {
        let (u, f) = report_unit(true);
        assert_eq!((u, f * PI), ("deg/s", 180.0));
        let (u, f) = report_unit(false);
        assert_eq!((u, f * G0), ("g", 1.0));
    }

    #[test]
    fn conversions() {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs();
        assert!(close(
            parse("1 deg/h", Kind::AngularRate).unwrap().0,
            PI / 180.0 / 3600.0
        ));
        // 1 deg/√h = 60 deg/h/√Hz.
        let a = parse("1 deg/sqrt(h)", Kind::AngleRandomWalk).unwrap().0;
        let b = parse("60 deg/h/sqrt(Hz)", Kind::AngleRandomWalk).unwrap().0;
        assert!(close(a, b));
        assert!(close(
            parse("1 m/s/sqrt(h)", Kind::VelocityRandomWalk).unwrap().0,
            1.0 / 60.0
        ));
        assert!(close(
            parse("100 ug", Kind::Acceleration).unwrap().0,
            9.80665e-4
        ));
        assert_eq!(parse("2 urad", Kind::GyroLsb).unwrap(), (2e-6, true));
        // An increment step in degrees, as in rad and arcsec (issue 23: `deg` was refused).
        assert_eq!(parse("0.5 deg", Kind::GyroLsb).unwrap(), (0.5 * DEG, true));
        assert_eq!(parse("3 mrad", Kind::GyroLsb).unwrap(), (3e-3, true));
        assert!(!parse("0.01 deg/s", Kind::GyroLsb).unwrap().1);
        assert!(matches!(
            parse("1 furlong", Kind::Angle),
            Err(UnitError::UnknownUnit { .. })
        ));
        assert!(matches!(
            parse("x deg", Kind::Angle),
            Err(UnitError::NotNumber(_))
        ));
    }
}
