//! The injected error components over time (the seed paper's Fig. 5): from the columns of a
//! `--truth-errors` file (`t`, then `GROUP_SENSOR_AXIS`), one panel per sensor axis (gyro x y z
//! in deg/h, accelerometer x y z in mg), one line per error group that is not zero
//! throughout. Long records are thinned to at most `max_points` per line by keeping, in each
//! stretch, the sample farthest from zero, so spikes and the envelope stay visible.

use crate::plot::{Panel, Series};
use crate::units::G0;

/// Why a `--truth-errors` file cannot be plotted; each message names the file.
#[derive(Debug, thiserror::Error)]
pub enum ErrorPlotError {
    /// The file cannot be read.
    #[error("{0}: cannot read")]
    Read(String, #[source] std::io::Error),
    /// Its contents are not a `--truth-errors` table.
    #[error("{0}")]
    Invalid(String),
}

/// The six panels of the `--truth-errors` CSV at `path` (see [`error_panels`]): a header,
/// then rows of finite numbers, one per header column; `#` lines are comments.
pub fn file_panels(
    path: &std::path::Path,
    max_points: usize,
) -> Result<Vec<Panel>, ErrorPlotError> {
    let name = path.display();
    let text =
        std::fs::read_to_string(path).map_err(|e| ErrorPlotError::Read(name.to_string(), e))?;
    let invalid = |m: String| ErrorPlotError::Invalid(format!("{name}: {m}"));
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| invalid("empty file".into()))?
        .split(',')
        .map(str::trim)
        .collect();
    let mut rows = Vec::new();
    for (i, line) in lines.enumerate() {
        let row = line
            .split(',')
            .map(|v| v.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect::<Option<Vec<f64>>>();
        match row {
            Some(r) if r.len() == header.len() => rows.push(r),
            _ => {
                return Err(invalid(format!(
                    "line {}: expected {} finite numbers",
                    i + 2,
                    header.len()
                )));
            }
        }
    }
    if rows.is_empty() {
        return Err(invalid("no data rows".into()));
    }
    error_panels(&header, &rows, max_points).map_err(invalid)
}

const DEG_H: f64 = std::f64::consts::PI / 180.0 / 3600.0;

/// The six panels of the injected errors; `header` names the columns of `rows`.
pub fn error_panels(
    header: &[&str],
    rows: &[Vec<f64>],
    max_points: usize,
) -> Result<Vec<Panel>, String> {
    if header.first() != Some(&"t") {
        return Err("the first column must be `t` (a --truth-errors file)".into());
    }
    let t: Vec<f64> = rows.iter().map(|r| r[0]).collect();
    let mut panels = Vec::new();
    for (sensor, unit, scale) in [("gyro", "deg/h", DEG_H), ("accel", "mg", G0 * 1e-3)] {
        for axis in ["x", "y", "z"] {
            let suffix = format!("_{sensor}_{axis}");
            let mut series = Vec::new();
            for (c, name) in header.iter().enumerate().skip(1) {
                let Some(group) = name.strip_suffix(suffix.as_str()) else {
                    continue;
                };
                if rows.iter().all(|r| r[c] == 0.0) {
                    continue;
                }
                let (x, y) = thin(&t, rows, c, max_points.max(2));
                series.push(Series {
                    label: group.to_string(),
                    x,
                    y: y.iter().map(|v| v / scale).collect(),
                    color: series.len(),
                    ..Series::default()
                });
            }
            panels.push(Panel {
                title: format!("{sensor} {axis}: injected errors"),
                x_label: "t (s)".into(),
                y_label: format!("error ({unit})"),
                series,
                ..Panel::default()
            });
        }
    }
    if panels.iter().all(|p| p.series.is_empty()) && header.len() < 7 {
        return Err("no GROUP_gyro_x … GROUP_accel_z columns (a --truth-errors file)".into());
    }
    Ok(panels)
}

/// Column c against t, at most about n points: the sample of largest magnitude per stretch.
fn thin(t: &[f64], rows: &[Vec<f64>], c: usize, n: usize) -> (Vec<f64>, Vec<f64>) {
    let step = rows.len().div_ceil(n).max(1);
    rows.chunks(step)
        .enumerate()
        .map(|(i, chunk)| {
            let (j, r) = chunk
                .iter()
                .enumerate()
                .max_by(|a, b| a.1[c].abs().total_cmp(&b.1[c].abs()))
                .expect("chunks are not empty");
            (t[i * step + j], r[c])
        })
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Panels per sensor axis in deg/h and mg, all-zero groups left out, thinning keeps the
    /// largest-magnitude sample of each stretch; a file that is not a truth-errors file is refused.
    #[test]
    fn panels_units_and_thinning() {
        let header = [
            "t",
            "bias_gyro_x",
            "bias_gyro_y",
            "bias_gyro_z",
            "bias_accel_x",
            "bias_accel_y",
            "bias_accel_z",
            "noise_gyro_x",
            "noise_gyro_y",
            "noise_gyro_z",
            "noise_accel_x",
            "noise_accel_y",
            "noise_accel_z",
        ];
        let rows: Vec<Vec<f64>> = (0..100)
            .map(|k| {
                let mut r = vec![0.0; 13];
                r[0] = k as f64 * 0.01;
                r[1] = DEG_H; // 1 deg/h
                r[4] = G0 * 1e-3; // 1 mg
                r[7] = if k == 37 { -5.0 * DEG_H } else { 0.1 * DEG_H };
                r
            })
            .collect();
        let p = error_panels(&header, &rows, 10).unwrap();
        assert_eq!(p.len(), 6);
        assert_eq!(p[0].series.len(), 2); // bias and noise on gyro x
        assert_eq!(p[1].series.len(), 0); // gyro y: all zero
        assert_eq!(p[3].series.len(), 1);
        assert!((p[0].series[0].y[0] - 1.0).abs() < 1e-12);
        assert!((p[3].series[0].y[0] - 1.0).abs() < 1e-12);
        assert_eq!(p[0].series[1].x.len(), 10);
        assert!((p[0].series[1].y[3] + 5.0).abs() < 1e-12);
        assert!((p[0].series[1].x[3] - 0.37).abs() < 1e-12);
        assert!(error_panels(&["time", "a"], &rows, 10).is_err());
    }
}
