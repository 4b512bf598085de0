//! Reading a reference trajectory from CSV: `t,lat,lon,h,vn,ve,vd,roll,pitch,yaw`
//! (s, deg, deg, m ellipsoidal, m/s NED, deg ZYX Euler with yaw from north). Lines starting
//! with `#` are comments. Every problem is reported with file, line and column.

use std::path::{Path, PathBuf};

use crate::math::{Vec3, quat_from_euler};
use crate::motion::sampled::Sample;

/// The required columns, in the order they are stored in a [`Sample`].
pub const COLUMNS: [&str; 10] = [
    "t", "lat", "lon", "h", "vn", "ve", "vd", "roll", "pitch", "yaw",
];

/// What is wrong with a trajectory file, and where.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    /// The file could not be read. The cause is the error's `source()` (not repeated here, so
    /// an error chain printed with `{:#}` names it once).
    #[error("{path}: cannot read")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// A problem at a place in the file.
    #[error("{path}:{line}: {problem}")]
    At {
        /// File.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        problem: Problem,
    },
    /// The file has a header but too few data rows.
    #[error("{path}: {got} samples, but the motion model needs at least {need}")]
    TooFewSamples {
        /// File.
        path: PathBuf,
        /// Samples found.
        got: usize,
        /// Samples needed.
        need: usize,
    },
}

/// A problem found on one line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Problem {
    /// No header line before the end of the file.
    #[error("no header line (expected `t,lat,lon,h,vn,ve,vd,roll,pitch,yaw`)")]
    NoHeader,
    /// A required column is absent from the header.
    #[error("header: missing column `{0}` (expected `t,lat,lon,h,vn,ve,vd,roll,pitch,yaw`)")]
    MissingColumn(&'static str),
    /// The header names a column we do not know.
    #[error(
        "header: column {index}: unknown column `{name}` (expected `t,lat,lon,h,vn,ve,vd,roll,pitch,yaw`)"
    )]
    UnknownColumn {
        /// 1-based column number.
        index: usize,
        /// Its name.
        name: String,
    },
    /// The header names a column twice.
    #[error("header: column {index}: `{name}` appears twice")]
    DuplicateColumn {
        /// 1-based column number.
        index: usize,
        /// Its name.
        name: String,
    },
    /// Wrong number of fields on a data line: column `index` (named `name` when it is a
    /// header column) is the first one missing or the first one extra.
    #[error(
        "column {index}{}: {got} fields, expected {expected}",
        match (name, got < expected) {
            (Some(n), true) => format!(" (`{n}`) is missing"),
            (_, true) => " is missing".to_string(),
            (_, false) => " is extra".to_string(),
        }
    )]
    FieldCount {
        /// 1-based column number of the first missing or extra field.
        index: usize,
        /// Its header name, if it is a header column.
        name: Option<&'static str>,
        /// Fields found.
        got: usize,
        /// Fields expected.
        expected: usize,
    },
    /// A field that is not a number.
    #[error("column {index} (`{name}`): `{value}` is not a number")]
    NotNumeric {
        /// 1-based column number.
        index: usize,
        /// Column name.
        name: &'static str,
        /// The text found.
        value: String,
    },
    /// NaN or infinity.
    #[error("column {index} (`{name}`): `{value}` is not finite")]
    NotFinite {
        /// 1-based column number.
        index: usize,
        /// Column name.
        name: &'static str,
        /// The text found.
        value: String,
    },
    /// Latitude beyond ±90°.
    #[error("column {index} (`lat`): {value} is outside [-90, 90] degrees")]
    LatitudeRange {
        /// 1-based column number.
        index: usize,
        /// Value found.
        value: f64,
    },
    /// Time not strictly after the previous sample's.
    #[error("column {index} (`t`): {value} does not increase (previous sample at {previous})")]
    NonIncreasingTime {
        /// 1-based column number.
        index: usize,
        /// This time.
        value: f64,
        /// Previous time.
        previous: f64,
    },
}

/// Parses trajectory CSV text; `path` is used in error messages only.
pub fn parse(text: &str, path: &Path) -> Result<Vec<Sample>, TrajectoryError> {
    let at = |line: usize, problem: Problem| TrajectoryError::At {
        path: path.to_path_buf(),
        line,
        problem,
    };
    // A UTF-8 byte-order mark (spreadsheet exports) is not part of the first column's name.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (hline, header) = lines
        .next()
        .ok_or_else(|| at(text.lines().count().max(1), Problem::NoHeader))?;
    // order[c] = index into COLUMNS of file column c.
    let mut order = Vec::new();
    for (c, name) in header.split(',').map(str::trim).enumerate() {
        let Some(k) = COLUMNS.iter().position(|n| *n == name) else {
            return Err(at(
                hline,
                Problem::UnknownColumn {
                    index: c + 1,
                    name: name.to_string(),
                },
            ));
        };
        if order.contains(&k) {
            return Err(at(
                hline,
                Problem::DuplicateColumn {
                    index: c + 1,
                    name: name.to_string(),
                },
            ));
        }
        order.push(k);
    }
    if let Some(missing) = COLUMNS.iter().enumerate().find(|(k, _)| !order.contains(k)) {
        return Err(at(hline, Problem::MissingColumn(missing.1)));
    }
    let mut samples: Vec<Sample> = Vec::new();
    for (ln, line) in lines {
        let mut vals = [0.0; 10];
        let mut n = 0;
        for (c, field) in line.split(',').enumerate() {
            n += 1;
            if c >= order.len() {
                continue;
            }
            let field = field.trim();
            let k = order[c];
            let name = COLUMNS[k];
            let v: f64 = field.parse().map_err(|_| {
                at(
                    ln,
                    Problem::NotNumeric {
                        index: c + 1,
                        name,
                        value: field.to_string(),
                    },
                )
            })?;
            if !v.is_finite() {
                return Err(at(
                    ln,
                    Problem::NotFinite {
                        index: c + 1,
                        name,
                        value: field.to_string(),
                    },
                ));
            }
            if k == 1 && v.abs() > 90.0 {
                return Err(at(
                    ln,
                    Problem::LatitudeRange {
                        index: c + 1,
                        value: v,
                    },
                ));
            }
            vals[k] = v;
        }
        if n != order.len() {
            return Err(at(
                ln,
                Problem::FieldCount {
                    index: n.min(order.len()) + 1,
                    name: order.get(n).map(|&k| COLUMNS[k]),
                    got: n,
                    expected: order.len(),
                },
            ));
        }
        if let Some(prev) = samples.last()
            && vals[0] <= prev.t
        {
            let index = order.iter().position(|&k| k == 0).unwrap_or(0) + 1;
            return Err(at(
                ln,
                Problem::NonIncreasingTime {
                    index,
                    value: vals[0],
                    previous: prev.t,
                },
            ));
        }
        let [t, lat, lon, h, vn, ve, vd, roll, pitch, yaw] = vals;
        samples.push(Sample {
            t,
            lat: lat.to_radians(),
            lon: lon.to_radians(),
            h,
            v_n: Vec3::new(vn, ve, vd),
            q_b_n: quat_from_euler(roll.to_radians(), pitch.to_radians(), yaw.to_radians()),
        });
    }
    Ok(samples)
}

/// Reads and parses a trajectory file.
pub fn read(path: &Path) -> Result<Vec<Sample>, TrajectoryError> {
    let text = std::fs::read_to_string(path).map_err(|source| TrajectoryError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text, path)
}

/// Formats samples as trajectory CSV (shortest round-trip numbers), e.g. to save a scene.
pub fn format_row(
    out: &mut String,
    t: f64,
    lat_deg: f64,
    lon_deg: f64,
    h: f64,
    v_n: Vec3,
    rpy_deg: (f64, f64, f64),
) {
    let vals = [
        t,
        lat_deg,
        lon_deg,
        h,
        v_n.x(),
        v_n.y(),
        v_n.z(),
        rpy_deg.0,
        rpy_deg.1,
        rpy_deg.2,
    ];
    let mut buf = ryu::Buffer::new();
    for (i, v) in vals.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(buf.format(*v));
    }
    out.push('\n');
}

/// Trajectory CSV of `motion` sampled at t₀ + k/rate for k = 0..=count (degrees, shortest
/// round-trip decimals), preceded by `# comment` when given.
pub fn sample_motion(
    motion: &impl crate::motion::Motion,
    t0: f64,
    rate_hz: f64,
    count: u64,
    comment: Option<&str>,
) -> String {
    let mut text = String::new();
    if let Some(c) = comment {
        text.push_str("# ");
        text.push_str(c);
        text.push('\n');
    }
    text.push_str(&COLUMNS.join(","));
    text.push('\n');
    for k in 0..=count {
        let p = motion.pose(t0 + k as f64 / rate_hz);
        let (r, pi, y) = crate::math::euler_from_quat(p.q_b_n);
        format_row(
            &mut text,
            p.t,
            p.lat.to_degrees(),
            p.lon.to_degrees(),
            p.h,
            p.v_n,
            (r.to_degrees(), pi.to_degrees(), y.to_degrees()),
        );
    }
    text
}
