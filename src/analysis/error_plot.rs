//! The injected error components over time (the seed paper's Fig. 5): from the columns of a
//! `--truth-errors` file (`t`, then `GROUP_SENSOR_AXIS`), one panel per sensor axis (gyro x y z
//! in deg/h, accelerometer x y z in mg), one line per error group that is not zero
//! throughout. Long records are thinned as they are read to at most `max_points` per line
//! (at least half as many) by keeping, in each stretch, the sample farthest from zero, so
//! spikes and the envelope stay visible and the memory does not grow with the file.

use crate::csvio::CsvLines;
use crate::plot::{Panel, Series};
use crate::units::G0;

/// Why a `--truth-errors` file cannot be plotted; each message names the file.
#[derive(Debug, thiserror::Error)]
pub enum ErrorPlotError {
    /// The file cannot be read, or a line of it is not text of a bounded length.
    #[error(transparent)]
    Read(#[from] crate::csvio::FileError),
    /// Its contents are not a `--truth-errors` table.
    #[error("{0}")]
    Invalid(String),
}

/// Most points per line: far more than a plot has pixels across; the thinning holds twice
/// this many per error column.
pub const MAX_POINTS: usize = 100_000;

/// Most columns of a `--truth-errors` file (one `t` and six per error group: a few dozen).
pub const MAX_COLUMNS: usize = 1024;

/// The six panels of the `--truth-errors` CSV at `path` (see [`error_panels`]): a header,
/// then rows of finite numbers, one per header column; `#` lines are comments. Streamed: the
/// memory is that of `max_points` per line, whatever the file's length.
pub fn file_panels(
    path: &std::path::Path,
    max_points: usize,
) -> Result<Vec<Panel>, ErrorPlotError> {
    let name = path.display();
    let invalid = |m: String| ErrorPlotError::Invalid(format!("{name}: {m}"));
    if max_points > MAX_POINTS {
        return Err(ErrorPlotError::Invalid(format!(
            "--points {max_points}: at most {MAX_POINTS} points per line"
        )));
    }
    let mut lines = CsvLines::open(path)?;
    let Some(header) = lines.next_fields()? else {
        return Err(invalid("empty file".into()));
    };
    let header: Vec<String> = header.into_iter().map(str::to_string).collect();
    if header.len() > MAX_COLUMNS {
        return Err(invalid(format!(
            "{} columns; a --truth-errors file has at most {MAX_COLUMNS}",
            header.len()
        )));
    }
    let mut thin = Thinner::new(header.len(), max_points);
    let mut row = Vec::with_capacity(header.len());
    while lines.advance()? {
        row.clear();
        row.extend(
            lines
                .fields()
                .map_while(|v| v.parse::<f64>().ok().filter(|x| x.is_finite())),
        );
        if row.len() != header.len() || lines.fields().count() != header.len() {
            return Err(invalid(format!(
                "line {}: expected {} finite numbers",
                lines.line_no(),
                header.len()
            )));
        }
        thin.push(&row);
    }
    if thin.rows == 0 {
        return Err(invalid("no data rows".into()));
    }
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    error_panels(&header, &thin.finish()).map_err(invalid)
}

const DEG_H: f64 = std::f64::consts::PI / 180.0 / 3600.0;

/// Each column's samples, thinned as they stream in: the sample of largest magnitude of
/// each stretch of `step` rows, the stretch doubling (neighbouring stretches merged)
/// whenever twice the wanted points are held; pure, no allocation per row.
pub struct Thinner {
    n: usize,
    step: u64,
    rows: u64,
    /// Rows in the stretch being filled.
    filling: u64,
    /// Per column (0 is `t`, unused): the finished stretches' (t, value).
    kept: Vec<Vec<(f64, f64)>>,
    /// Per column: the stretch being filled.
    open: Vec<(f64, f64)>,
    /// Per column: some value is not zero.
    nonzero: Vec<bool>,
}

impl Thinner {
    /// For rows of `columns` values (`t` first), at most `n` (at least 2) points per column.
    pub fn new(columns: usize, n: usize) -> Thinner {
        let n = n.max(2);
        Thinner {
            n,
            step: 1,
            rows: 0,
            filling: 0,
            kept: (0..columns).map(|_| Vec::with_capacity(2 * n)).collect(),
            open: vec![(0.0, 0.0); columns],
            nonzero: vec![false; columns],
        }
    }

    /// Takes one row (`t` first).
    pub fn push(&mut self, row: &[f64]) {
        let t = row[0];
        for (c, &v) in row.iter().enumerate().skip(1) {
            self.nonzero[c] |= v != 0.0;
            if self.filling == 0 || v.abs() > self.open[c].1.abs() {
                self.open[c] = (t, v);
            }
        }
        self.rows += 1;
        self.filling += 1;
        if self.filling == self.step {
            self.filling = 0;
            for (k, o) in self.kept.iter_mut().zip(&self.open).skip(1) {
                k.push(*o);
            }
            if self.kept.get(1).is_some_and(|k| k.len() == 2 * self.n) {
                self.halve();
                self.step *= 2;
            }
        }
    }

    /// Merges neighbouring stretches, keeping the larger magnitude of each pair.
    fn halve(&mut self) {
        for k in self.kept.iter_mut().skip(1) {
            let half = k.len().div_ceil(2);
            for i in 0..half {
                let a = k[2 * i];
                k[i] = match k.get(2 * i + 1) {
                    Some(b) if b.1.abs() > a.1.abs() => *b,
                    _ => a,
                };
            }
            k.truncate(half);
        }
    }

    /// Each column's points, at most `n`, and whether it is zero throughout (`None`).
    pub fn finish(mut self) -> Vec<Option<(Vec<f64>, Vec<f64>)>> {
        if self.filling > 0 {
            for (k, o) in self.kept.iter_mut().zip(&self.open).skip(1) {
                k.push(*o);
            }
        }
        while self.kept.get(1).is_some_and(|k| k.len() > self.n) {
            self.halve();
        }
        self.kept
            .into_iter()
            .zip(self.nonzero)
            .map(|(k, nz)| nz.then(|| k.into_iter().unzip()))
            .collect()
    }
}

/// The six panels of the injected errors; `header` names the columns, `columns` holds each
/// one's thinned (t, value) points, `None` for one that is zero throughout.
pub fn error_panels(
    header: &[&str],
    columns: &[Option<(Vec<f64>, Vec<f64>)>],
) -> Result<Vec<Panel>, String> {
    if header.first() != Some(&"t") {
        return Err("the first column must be `t` (a --truth-errors file)".into());
    }
    let mut panels = Vec::new();
    for (sensor, unit, scale) in [("gyro", "deg/h", DEG_H), ("accel", "mg", G0 * 1e-3)] {
        for axis in ["x", "y", "z"] {
            let suffix = format!("_{sensor}_{axis}");
            let mut series = Vec::new();
            for (c, name) in header.iter().enumerate().skip(1) {
                let Some(group) = name.strip_suffix(suffix.as_str()) else {
                    continue;
                };
                let Some((x, y)) = &columns[c] else {
                    continue;
                };
                series.push(Series {
                    label: group.to_string(),
                    x: x.clone(),
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
        let mut thin = Thinner::new(13, 10);
        for k in 0..100 {
            let mut r = vec![0.0; 13];
            r[0] = k as f64 * 0.01;
            r[1] = DEG_H; // 1 deg/h
            r[4] = G0 * 1e-3; // 1 mg
            r[7] = if k == 37 { -5.0 * DEG_H } else { 0.1 * DEG_H };
            thin.push(&r);
        }
        let columns = thin.finish();
        let p = error_panels(&header, &columns).unwrap();
        assert_eq!(p.len(), 6);
        assert_eq!(p[0].series.len(), 2); // bias and noise on gyro x
        assert_eq!(p[1].series.len(), 0); // gyro y: all zero
        assert_eq!(p[3].series.len(), 1);
        assert!((p[0].series[0].y[0] - 1.0).abs() < 1e-12);
        assert!((p[3].series[0].y[0] - 1.0).abs() < 1e-12);
        // 100 rows in stretches of 16 (the last of 4): 7 points, the spike in the third.
        assert_eq!(p[0].series[1].x.len(), 7);
        assert!((p[0].series[1].y[2] + 5.0).abs() < 1e-12);
        assert!((p[0].series[1].x[2] - 0.37).abs() < 1e-12);
        assert!(error_panels(&["time", "a"], &columns[..2]).is_err());
    }

    /// Whatever the number of rows: at most n points, at least half of them (or every row),
    /// in time order, and the largest magnitude among them.
    #[test]
    fn thinning_is_bounded_and_keeps_the_peak() {
        for rows in [1usize, 2, 3, 17, 1000, 12_345] {
            for n in [2usize, 3, 10, 4000] {
                let mut thin = Thinner::new(2, n);
                let peak = rows * 7 / 11;
                for k in 0..rows {
                    let v = if k == peak { -9.0 } else { (k % 5) as f64 };
                    thin.push(&[k as f64, v]);
                }
                let (x, y) = thin.finish().remove(1).unwrap();
                let at = (rows, n);
                assert!(
                    x.len() <= n && x.len() >= rows.min(n / 2),
                    "{at:?}: {}",
                    x.len()
                );
                assert!(x.windows(2).all(|w| w[0] < w[1]), "{at:?}");
                assert!(y.contains(&-9.0) && x.contains(&(peak as f64)), "{at:?}");
            }
        }
    }
}
