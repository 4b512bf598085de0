//! The built-in templates' headline figures as one table (`imu-emu templates`): bias
//! instability, turn-on bias and white noise of each sensor, each template's typical profile on
//! its own row under it.

use std::f64::consts::PI;
use std::fmt::Write;

use super::ImuModel;
use super::template::{self, TemplateError};

/// The table, with its two header lines and the closing note on what BI and TO mean.
pub fn table() -> Result<String, TemplateError> {
    let mut out = String::new();
    let head = [
        [
            "name", "grade", "gyro BI", "gyro TO", "ARW", "accel BI", "accel TO", "VRW",
        ],
        [
            "",
            "",
            "deg/h",
            "deg/h",
            "deg/sqrt(h)",
            "ug",
            "ug",
            "m/s/sqrt(h)",
        ],
    ];
    for (i, h) in head.iter().enumerate() {
        let tail = if i == 0 { "  description" } else { "" };
        let _ = writeln!(
            out,
            "{:<17} {:<11} {:>12} {:>10} {:>13} {:>12} {:>10} {:>13}{tail}",
            h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7]
        );
    }
    let typical = template::typical_names();
    for name in template::builtin_names() {
        row(&mut out, &template::load(name)?);
        if typical.contains(&name) {
            row(
                &mut out,
                &template::load(&format!("{name}:{}", template::TYPICAL))?,
            );
        }
    }
    out.push_str(
        "\nBI: bias instability; TO: turn-on bias, the 1σ of the constant bias drawn at each \
         start (largest axis), which often dominates a low-cost unit's navigation error.\n\
         `--imu NAME` uses the datasheet figures (the default); `--imu NAME:typical` the \
         figures read from a public recording of a real unit (docs/fidelity.md).\n",
    );
    Ok(out)
}

/// One template's row: x-axis figures, the largest axis's turn-on bias.
fn row(out: &mut String, m: &ImuModel) {
    let deg_h = 180.0 / PI * 3600.0;
    let ug = 1e6 / crate::units::G0;
    let largest = |v: [f64; 3]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let _ = writeln!(
        out,
        "{:<17} {:<11} {:>12.3} {:>10.1} {:>13.4} {:>12.1} {:>10.0} {:>13.4}  {}",
        m.name,
        m.grade,
        m.gyro.bias_instability[0] * deg_h,
        largest(m.gyro.bias_turn_on) * deg_h,
        m.gyro.noise[0] * 180.0 / PI * 60.0,
        m.accel.bias_instability[0] * ug,
        largest(m.accel.bias_turn_on) * ug,
        m.accel.noise[0] * 60.0,
        m.description
    );
}

#[cfg(test)]
mod tests {
    /// The ln200 row carries its template's figures converted: ARW 0.07 deg/√h is written
    /// as 0.0700 (rad/√s → deg/√h is ×180/π×60), and every built-in template has a row.
    #[test]
    fn every_template_has_a_row_in_display_units() {
        let t = super::table().unwrap();
        for name in crate::errors::template::builtin_names() {
            assert!(
                t.lines().any(|l| l.starts_with(&format!("{name} "))),
                "{name}"
            );
        }
        let m = crate::errors::template::load("ln200").unwrap();
        let arw = m.gyro.noise[0] * 180.0 / std::f64::consts::PI * 60.0;
        let row = t.lines().find(|l| l.starts_with("ln200 ")).unwrap();
        assert!(row.contains(&format!("{arw:.4}")), "{row}");
    }
}
