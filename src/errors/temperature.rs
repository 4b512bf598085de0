//! The IMU's temperature over a run, for the temperature-dependent bias and scale factor:
//! constant, a linear ramp (optionally clamped), a warm-up exponential, or a table of (t, T)
//! read from a CSV file and interpolated linearly. Temperatures in °C.

use std::path::{Path, PathBuf};

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

/// A temperature table that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// Unreadable file.
    #[error("{path}: cannot read")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// A bad line.
    #[error("{path}:{line}: {message}")]
    Line {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// Parses a temperature table: header `t,T` (or `t,temperature`), `#` comments, strictly
/// increasing t, finite values.
pub fn parse_table(text: &str, path: &Path) -> Result<TemperatureProfile, TableError> {
    let err = |line: usize, message: String| TableError::Line {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut rows: Vec<(f64, f64)> = Vec::new();
    let mut header_seen = false;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim().trim_start_matches('\u{feff}');
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if !header_seen {
            if fields != ["t", "T"] && fields != ["t", "temperature"] {
                return Err(err(
                    i + 1,
                    format!("header: expected `t,T`, found `{line}`"),
                ));
            }
            header_seen = true;
            continue;
        }
        if fields.len() != 2 {
            return Err(err(
                i + 1,
                format!("{} fields, expected 2 (t,T)", fields.len()),
            ));
        }
        let mut v = [0.0; 2];
        for (c, (f, name)) in fields.iter().zip(["t", "T"]).enumerate() {
            v[c] = f
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    err(
                        i + 1,
                        format!("column {} (`{name}`): `{f}` is not a finite number", c + 1),
                    )
                })?;
        }
        if let Some(last) = rows.last()
            && v[0] <= last.0
        {
            return Err(err(
                i + 1,
                format!(
                    "column 1 (`t`): {} does not increase (previous {})",
                    v[0], last.0
                ),
            ));
        }
        rows.push((v[0], v[1]));
    }
    if rows.is_empty() {
        return Err(err(text.lines().count().max(1), "no data rows".into()));
    }
    Ok(TemperatureProfile::Table(rows))
}

/// Reads a temperature table file.
pub fn read_table(path: &Path) -> Result<TemperatureProfile, TableError> {
    let text = std::fs::read_to_string(path).map_err(|source| TableError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_table(&text, path)
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
