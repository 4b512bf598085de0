//! The IMU's temperature over a run, for the temperature-dependent bias and scale factor:
//! constant, a linear ramp (optionally clamped), a warm-up exponential, or a table of (t, T)
//! read from a CSV file and interpolated linearly. Temperatures in °C.

use std::path::Path;

use crate::csvio::{CsvLines, clip, num, parse_finite};

/// A temperature profile T(t).
#[derive(Clone, Debug, PartialEq)]
pub enum TemperatureProfile {
    /// T(t) = T₀.
    Constant(f64),
    /// T(t) = T₀ + ṫ·t, clamped to `limit` once reached (when given).
    Ramp {
        /// Temperature at t = 0 (°C).
        start: f64,
        /// Rate (°C/s).
        rate: f64,
        /// Temperature at which the ramp stops (°C).
        limit: Option<f64>,
    },
    /// Warm-up: T(t) = T_f + (T₀ − T_f)·e^{−t/τ}.
    Warmup {
        /// Temperature at t = 0 (°C).
        start: f64,
        /// Final temperature (°C).
        end: f64,
        /// Time constant (s).
        tau: f64,
    },
    /// Linear interpolation in a table of (t, T), held constant outside it.
    Table(Vec<(f64, f64)>),
}

impl TemperatureProfile {
    /// T(t) in °C.
    pub fn at(&self, t: f64) -> f64 {
        match self {
            TemperatureProfile::Constant(c) => *c,
            TemperatureProfile::Ramp { start, rate, limit } => {
                let v = start + rate * t;
                match limit {
                    Some(l) if (*rate > 0.0 && v > *l) || (*rate < 0.0 && v < *l) => *l,
                    _ => v,
                }
            }
            TemperatureProfile::Warmup { start, end, tau } => {
                end + (start - end) * (-t / tau).exp()
            }
            TemperatureProfile::Table(rows) => {
                let i = rows.partition_point(|r| r.0 <= t);
                if i == 0 {
                    return rows[0].1;
                }
                if i == rows.len() {
                    return rows[rows.len() - 1].1;
                }
                let (a, b) = (rows[i - 1], rows[i]);
                a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
            }
        }
    }
}

/// A temperature table that cannot be used (file, line, column).
pub type TableError = crate::csvio::FileError;

/// Parses a temperature table: header `t,T` (or `t,temperature`), `#` comments, strictly
/// increasing t, finite values.
pub fn parse_table(text: &str, path: &Path) -> Result<TemperatureProfile, TableError> {
    table(CsvLines::new(text.as_bytes(), path))
}

/// Reads a temperature table file.
pub fn read_table(path: &Path) -> Result<TemperatureProfile, TableError> {
    table(CsvLines::open(path)?)
}

fn table<R: std::io::BufRead>(mut lines: CsvLines<R>) -> Result<TemperatureProfile, TableError> {
    if !lines.advance()? {
        return Err(lines.error("no header line (expected `t,T`)"));
    }
    let header: Vec<&str> = lines.fields().collect();
    if header != ["t", "T"] && header != ["t", "temperature"] {
        let found = clip(lines.current());
        return Err(lines.error(format!("header: expected `t,T`, found {found}")));
    }
    let mut rows: Vec<(f64, f64)> = Vec::new();
    while lines.advance()? {
        let fields: Vec<&str> = lines.fields().collect();
        if fields.len() != 2 {
            let n = fields.len();
            return Err(lines.error(format!("{n} fields, expected 2 (t,T)")));
        }
        let mut v = [0.0; 2];
        for (c, (f, name)) in fields.iter().zip(["t", "T"]).enumerate() {
            v[c] = parse_finite(f).map_err(|m| lines.error(m).in_column(c + 1, name))?;
        }
        if let Some(last) = rows.last()
            && v[0] <= last.0
        {
            let m = format!("{} does not increase (previous {})", num(v[0]), num(last.0));
            return Err(lines.error(m).in_column(1, "t"));
        }
        rows.push((v[0], v[1]));
    }
    if rows.is_empty() {
        return Err(lines.error("no data rows"));
    }
    Ok(TemperatureProfile::Table(rows))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profiles() {
        assert_eq!(TemperatureProfile::Constant(20.0).at(5.0), 20.0);
        let r = TemperatureProfile::Ramp {
            start: 20.0,
            rate: 0.5,
            limit: Some(30.0),
        };
        assert_eq!(r.at(10.0), 25.0);
        assert_eq!(r.at(100.0), 30.0);
        let w = TemperatureProfile::Warmup {
            start: 20.0,
            end: 45.0,
            tau: 100.0,
        };
        assert!((w.at(100.0) - (45.0 - 25.0 / std::f64::consts::E)).abs() < 1e-12);
        let t = parse_table("# lab run\nt,T\n0,20\n10,30\n", Path::new("x.csv")).unwrap();
        assert_eq!(t.at(5.0), 25.0);
        assert_eq!(t.at(-1.0), 20.0);
        assert_eq!(t.at(99.0), 30.0);
        let e = parse_table("t,T\n0,20\n0,21\n", Path::new("x.csv"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("x.csv:3") && e.contains("does not increase"),
            "{e}"
        );
    }
}
