//! Published Allan deviation tables: a CSV of τ and σ per axis, read into an [`Analysis`] so
//! that `fit` and `analyze --reference` treat the curve as they treat a recording's.
//!
//! Format (docs/fit.md): a header `tau_s,gx_deg_h,…`, one row per τ. The τ column is
//! `tau_<time unit>`; every other column is `<channel>[_lo|_hi]_<unit>`, the channel one of
//! gx gy gz ax ay az (or `g` / `a`: a figure published for every axis of the sensor), the unit
//! written with `_` for `/` and `s2` for `s^2` (`deg_h`, `rad_s`, `ug`, `m_s2`). `_lo`/`_hi`
//! columns give a stated range around σ (over units, axes or a confidence level: the table's
//! own). An empty field means "not given at this τ". Comment lines `# record_length = 6 h`
//! and `# rate = 400 Hz` state the record's length and sampling rate.
//!
//! The model the fit uses is discrete (cluster sizes m of a sampling interval Δt): Δt is the
//! stated rate's period, else the smallest τ, and every τ must be a multiple of it.
//!
//! Uncertainty. A table that states no band gets the χ² band of the overlapping estimator
//! (NIST SP 1065 Table 5) for its record length; when the length is not stated the shortest
//! record that can give the table's longest τ is assumed, T = 2m_max·Δt (an Allan variance
//! at m needs 2m + 1 phase points, the ends of 2m samples), which gives the fewest degrees of freedom the
//! table is compatible with, so the intervals are as wide as the table allows.

use std::io::BufRead;
use std::path::Path;

use super::analyzer::{Analysis, ChannelAnalysis};
use super::confidence::{adev_interval, edf};
use super::fit::fit;
use super::octave_adev::{AdevPoint, CONFIDENCE};
use super::psd::Psd;
use super::stats::Stats;
use crate::csvio::{CsvLines, FileError, clip};
use crate::units::{self, Kind};

/// Relative mismatch allowed between a τ and the nearest multiple of Δt (tables print τ
/// with four or more significant digits).
const TAU_GRID_TOLERANCE: f64 = 1e-3;

/// Channel names of a table's header, in [`super::analyzer::CHANNELS`] order.
const NAMES: [&str; 6] = ["gx", "gy", "gz", "ax", "ay", "az"];

/// What the command line adds to a table.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TableOptions {
    /// Sampling rate of the recording the table was computed from (Hz).
    pub rate: Option<f64>,
    /// Length of that recording (s).
    pub record_length: Option<f64>,
}

/// One row of a channel: τ, σ and the stated range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TablePoint {
    /// Cluster size m = τ/Δt.
    pub m: usize,
    /// σ (SI rate unit).
    pub adev: f64,
    /// Stated range (lo, hi), when the table gives one.
    pub range: Option<(f64, f64)>,
}

/// A parsed table.
#[derive(Clone, Debug, PartialEq)]
pub struct AdevTable {
    /// Sampling interval (s).
    pub dt: f64,
    /// Record length in samples (stated, or the shortest the table allows).
    pub samples: usize,
    /// Whether the record length was stated (table or command line).
    pub length_stated: bool,
    /// Points of each channel (empty: not in the table).
    pub channels: [Vec<TablePoint>; 6],
}

/// Whether `header` (a CSV's first non-comment line) is an ADEV table's.
pub fn is_table_header(header: &str) -> bool {
    header
        .split(',')
        .next()
        .is_some_and(|f| f.trim().to_ascii_lowercase().starts_with("tau_"))
}

/// What one header column holds.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Role {
    Sigma,
    Lo,
    Hi,
}

struct Column {
    channels: std::ops::Range<usize>,
    role: Role,
    scale: f64,
}

/// A column header `<channel>[_lo|_hi]_<unit>`.
fn column(name: &str) -> Result<Column, String> {
    let lower = name.trim().to_ascii_lowercase();
    let (chan, rest) = lower.split_once('_').ok_or_else(|| {
        format!(
            "expected <channel>_<unit> (e.g. gx_deg_h), got {}",
            clip(name)
        )
    })?;
    let channels = match chan {
        "g" => 0..3,
        "a" => 3..6,
        c => match NAMES.iter().position(|n| *n == c) {
            Some(i) => i..i + 1,
            None => {
                return Err(format!(
                    "unknown channel `{chan}` (gx gy gz ax ay az, or g / a for every axis)"
                ));
            }
        },
    };
    let (role, unit) = match rest.split_once('_') {
        Some(("lo", u)) => (Role::Lo, u),
        Some(("hi", u)) => (Role::Hi, u),
        _ => (Role::Sigma, rest),
    };
    let kind = if channels.start < 3 {
        Kind::AngularRate
    } else {
        Kind::Acceleration
    };
    let scale = unit_scale(unit, kind)?;
    Ok(Column {
        channels,
        role,
        scale,
    })
}

/// The SI factor of a header unit (`deg_h` → deg/h, `m_s2` → m/s^2).
fn unit_scale(unit: &str, kind: Kind) -> Result<f64, String> {
    let mut u = unit.replace('_', "/");
    if let Some(stem) = u.strip_suffix("s2") {
        u = format!("{stem}s^2");
    }
    units::parse(&format!("1 {u}"), kind)
        .map(|v| v.0)
        .map_err(|e| format!("unit `{unit}`: {e}"))
}

/// A `# key = value` comment's stated quantity, when it is one the table may state.
fn stated(line: &str, opts: &mut TableOptions, path: &Path, no: u64) -> Result<(), FileError> {
    let Some((key, value)) = line.trim_start_matches('#').split_once('=') else {
        return Ok(());
    };
    let key = key.trim();
    let (kind, slot) = match key {
        "record_length" => (Kind::Time, &mut opts.record_length),
        "rate" => (Kind::Frequency, &mut opts.rate),
        _ => return Ok(()),
    };
    let v = units::parse(value.trim(), kind)
        .map(|v| v.0)
        .map_err(|e| FileError::line(path, no, format!("{key}: {e}")))?;
    // units::parse refuses a non-finite number.
    if v <= 0.0 {
        return Err(FileError::line(
            path,
            no,
            format!(
                "{key}: expected a positive value, got {}",
                clip(value.trim())
            ),
        ));
    }
    // The command line wins over the table.
    slot.get_or_insert(v);
    Ok(())
}

/// Parses the table `text` read from `path`; `opts` (the command line) overrides what the
/// table states.
pub fn parse(text: &str, path: &Path, opts: TableOptions) -> Result<AdevTable, FileError> {
    read(CsvLines::new(text.as_bytes(), path), opts)
}

/// Reads the table at `path` line by line (each line bounded as every table's is); `opts`
/// (the command line) overrides what the table states.
pub fn read_file(path: &Path, opts: TableOptions) -> Result<AdevTable, FileError> {
    read(CsvLines::open(path)?, opts)
}

fn read(mut lines: CsvLines<impl BufRead>, opts: TableOptions) -> Result<AdevTable, FileError> {
    let path = lines.path().to_path_buf();
    let path = path.as_path();
    let mut opts = opts;
    let mut header: Option<(Vec<Column>, f64)> = None;
    let mut names: Vec<String> = Vec::new();
    // (line, τ, fields) of every data row, parsed once the header is known.
    let mut rows: Vec<(u64, f64, Vec<Option<f64>>)> = Vec::new();
    while lines.advance_raw()? {
        let line = lines.raw().trim();
        let no = lines.line_no();
        if line.starts_with('#') {
            stated(line, &mut opts, path, no)?;
            continue;
        }
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let Some((cols, tau_scale)) = &header else {
            let tau_unit = fields[0].get(4..).unwrap_or("");
            if !is_table_header(line) {
                return Err(
                    FileError::line(path, no, "expected a header starting with tau_s")
                        .in_column(1, fields[0]),
                );
            }
            let tau_scale = units::parse(&format!("1 {tau_unit}"), Kind::Time)
                .map_err(|e| FileError::line(path, no, e.to_string()).in_column(1, fields[0]))?
                .0;
            let cols = fields[1..]
                .iter()
                .enumerate()
                .map(|(j, f)| {
                    column(f).map_err(|e| FileError::line(path, no, e).in_column(j + 2, f))
                })
                .collect::<Result<Vec<_>, _>>()?;
            if cols.is_empty() {
                return Err(FileError::line(path, no, "no σ columns after tau"));
            }
            header = Some((cols, tau_scale));
            names = fields.iter().map(|f| f.to_string()).collect();
            continue;
        };
        if fields.len() != cols.len() + 1 {
            return Err(FileError::line(
                path,
                no,
                format!("{} fields, the header has {}", fields.len(), cols.len() + 1),
            ));
        }
        let value = |j: usize| -> Result<Option<f64>, FileError> {
            let f = fields[j];
            if f.is_empty() && j > 0 {
                return Ok(None);
            }
            let bad = |m: &str| FileError::line(path, no, format!("{m}, got {}", clip(f)));
            let v: f64 = f.parse().map_err(|_| bad("expected a number"))?;
            if !(v.is_finite() && v > 0.0) {
                return Err(bad("expected a positive finite number"));
            }
            Ok(Some(v))
        };
        let name = |j: usize| names[j].as_str();
        let tau = value(0)
            .map_err(|e| e.in_column(1, name(0)))?
            .expect("τ is never empty")
            * tau_scale;
        if let Some(prev) = rows.last().map(|r| r.1)
            && tau <= prev
        {
            return Err(FileError::line(
                path,
                no,
                format!("τ must increase down the table: {tau} s after {prev} s"),
            )
            .in_column(1, name(0)));
        }
        let vals = (1..fields.len())
            .map(|j| {
                value(j)
                    .map(|v| v.map(|v| v * cols[j - 1].scale))
                    .map_err(|e| e.in_column(j + 1, name(j)))
            })
            .collect::<Result<Vec<_>, _>>()?;
        rows.push((no, tau, vals));
    }
    let Some((cols, _)) = header else {
        return Err(FileError::file(path, "no header (tau_s,gx_deg_h,…)"));
    };
    if rows.is_empty() {
        return Err(FileError::file(path, "no rows after the header"));
    }
    let dt = opts.rate.map_or(rows[0].1, |r| 1.0 / r);
    let mut channels: [Vec<TablePoint>; 6] = Default::default();
    let header_name = |j: usize| names[j].as_str();
    for (no, tau, vals) in &rows {
        let m = (tau / dt).round();
        if m < 1.0 || ((m * dt) / tau - 1.0).abs() > TAU_GRID_TOLERANCE {
            return Err(FileError::line(
                path,
                *no,
                format!(
                    "τ = {tau} s is not a multiple of Δt = {dt} s (give the recording's rate with --rate or `# rate = … Hz`)"
                ),
            )
            .in_column(1, header_name(0)));
        }
        for ch in 0..6 {
            let find = |role: Role| {
                cols.iter()
                    .zip(vals)
                    .enumerate()
                    .find(|(_, (c, v))| c.role == role && c.channels.contains(&ch) && v.is_some())
                    .map(|(j, (_, v))| (j + 2, v.unwrap()))
            };
            let Some((_, sigma)) = find(Role::Sigma) else {
                continue;
            };
            let range = match (find(Role::Lo), find(Role::Hi)) {
                (None, None) => None,
                (Some((_, lo)), Some((_, hi))) if lo <= sigma && sigma <= hi => Some((lo, hi)),
                (Some((j, _)), Some(_)) | (Some((j, _)), None) | (None, Some((j, _))) => {
                    return Err(FileError::line(
                        path,
                        *no,
                        format!(
                            "{}: a stated range needs both _lo and _hi, with lo ≤ σ ≤ hi",
                            NAMES[ch]
                        ),
                    )
                    .in_column(j, header_name(j - 1)));
                }
            };
            channels[ch].push(TablePoint {
                m: m as usize,
                adev: sigma,
                range,
            });
        }
    }
    let m_max = channels.iter().flatten().map(|p| p.m).max().unwrap_or(1);
    let (samples, length_stated) = match opts.record_length {
        Some(t) => {
            let n = (t / dt).round() as usize;
            if n < 2 * m_max {
                return Err(FileError::file(
                    path,
                    format!(
                        "record length {t} s is shorter than the 2τ the longest τ ({} s) needs",
                        m_max as f64 * dt
                    ),
                ));
            }
            (n, true)
        }
        None => (2 * m_max, false),
    };
    Ok(AdevTable {
        dt,
        samples,
        length_stated,
        channels,
    })
}

impl AdevTable {
    /// Adds the channels of `other` (a per-sensor file) to this table: same Δt, no channel
    /// in both; the record is the longer of the two.
    pub fn merge(&mut self, other: AdevTable, path: &Path) -> Result<(), FileError> {
        if (other.dt / self.dt - 1.0).abs() > TAU_GRID_TOLERANCE {
            return Err(FileError::file(
                path,
                format!(
                    "Δt {} s differs from the first table's {} s",
                    other.dt, self.dt
                ),
            ));
        }
        for (ch, pts) in other.channels.into_iter().enumerate() {
            if pts.is_empty() {
                continue;
            }
            if !self.channels[ch].is_empty() {
                return Err(FileError::file(
                    path,
                    format!("channel {} is also in the first table", NAMES[ch]),
                ));
            }
            self.channels[ch] = pts;
        }
        self.samples = self.samples.max(other.samples);
        self.length_stated |= other.length_stated;
        Ok(())
    }

    /// The table as an analysis: each channel's points with their bands (the stated range,
    /// else the 68 % χ² band of the record length, edf of the noise type the IEEE term fit
    /// says dominates), and that fit. No statistics and no PSD.
    pub fn analysis(&self) -> Analysis {
        let phases = self.samples + 1;
        let channels = self
            .channels
            .iter()
            .map(|pts| {
                let points = |noise: &dyn Fn(f64) -> super::confidence::NoiseType| {
                    pts.iter()
                        .map(|p| {
                            let tau = p.m as f64 * self.dt;
                            let e = edf(noise(tau), phases, p.m);
                            let (lo, hi) = p
                                .range
                                .unwrap_or_else(|| adev_interval(p.adev, e, CONFIDENCE));
                            AdevPoint {
                                m: p.m,
                                tau,
                                adev: p.adev,
                                terms: (self.samples - 2 * p.m + 1) as u64,
                                edf: e,
                                lo,
                                hi,
                            }
                        })
                        .collect::<Vec<_>>()
                };
                let first = points(&|_| super::confidence::NoiseType::WhiteRate);
                let f = fit(&first, self.samples);
                ChannelAnalysis {
                    stats: Stats::default(),
                    adev: points(&|tau| f.dominant(tau)),
                    psd: Psd {
                        freq: Vec::new(),
                        density: Vec::new(),
                        segments: 0,
                    },
                    fit: f,
                    trend: None,
                    lattice: None,
                }
            })
            .collect();
        Analysis {
            samples: self.samples as u64,
            dt: self.dt,
            step_range: (f64::NAN, f64::NAN),
            step_at: [(0, f64::NAN); 2],
            blocks: None,
            t_first: f64::NAN,
            channels,
            transients: None,
            dropped: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(text: &str) -> Result<AdevTable, FileError> {
        parse(text, Path::new("t.csv"), TableOptions::default())
    }

    fn error(text: &str) -> String {
        parse_str(text).unwrap_err().to_string()
    }

    /// Units, `g`/`a` for every axis, stated ranges, empty fields and the stated length.
    #[test]
    fn reads_units_ranges_and_stated_length() {
        let t = parse_str(
            "# LN-200-like\n# record_length = 6 h\n# rate = 100 Hz\n\
             tau_s,g_deg_h,g_lo_deg_h,g_hi_deg_h,az_ug\n0.01,36,35,37,\n0.02,25.5,25,26,100\n",
        )
        .unwrap();
        assert_eq!(t.dt, 0.01);
        assert_eq!(t.samples, 2_160_000);
        assert!(t.length_stated);
        let deg_h = std::f64::consts::PI / 180.0 / 3600.0;
        for ch in 0..3 {
            assert_eq!(t.channels[ch].len(), 2);
            let p = t.channels[ch][0];
            assert_eq!(p.m, 1);
            assert!((p.adev / (36.0 * deg_h) - 1.0).abs() < 1e-15);
            let (lo, hi) = p.range.unwrap();
            assert!((lo / (35.0 * deg_h) - 1.0).abs() < 1e-15);
            assert!((hi / (37.0 * deg_h) - 1.0).abs() < 1e-15);
        }
        assert!(t.channels[3].is_empty() && t.channels[4].is_empty());
        assert_eq!(t.channels[5].len(), 1);
        assert_eq!(t.channels[5][0].m, 2);
        assert!((t.channels[5][0].adev / (100e-6 * crate::units::G0) - 1.0).abs() < 1e-15);
        let a = t.analysis();
        assert_eq!(a.channels[0].adev[0].lo, t.channels[0][0].range.unwrap().0);
    }

    /// No stated length: the shortest record that gives the longest τ, T = 2m_max·Δt;
    /// the bands then come from that record's edf.
    #[test]
    fn unstated_length_is_the_shortest_possible() {
        let t = parse_str("tau_s,gx_rad_s\n0.5,1e-3\n1,7e-4\n2,5e-4\n").unwrap();
        assert_eq!((t.dt, t.samples, t.length_stated), (0.5, 8, false));
        let p = t.analysis().channels[0].adev[2];
        assert!(p.lo < p.adev && p.adev < p.hi);
        let longer = parse(
            "tau_s,gx_rad_s\n0.5,1e-3\n1,7e-4\n2,5e-4\n",
            Path::new("t.csv"),
            TableOptions {
                rate: None,
                record_length: Some(1000.0),
            },
        )
        .unwrap();
        let q = longer.analysis().channels[0].adev[2];
        assert!(q.hi - q.lo < p.hi - p.lo);
    }

    /// Each bad table names file, line, column and what is wrong.
    #[test]
    fn bad_tables_are_named() {
        let cases = [
            (
                "tau_s,gx_deg_h\n1,3\n1,2\n",
                "t.csv:3: column 1 (`tau_s`): τ must increase down the table: 1 s after 1 s",
            ),
            (
                "tau_s,gx_deg_h\n1,3\n2,-2\n",
                "t.csv:3: column 2 (`gx_deg_h`): expected a positive finite number, got `-2`",
            ),
            (
                "tau_s,gx_deg_furlong\n1,3\n",
                "t.csv:1: column 2 (`gx_deg_furlong`): unit `deg_furlong`",
            ),
            (
                "tau_s,gq_deg_h\n1,3\n",
                "t.csv:1: column 2 (`gq_deg_h`): unknown channel `gq`",
            ),
            (
                "tau_s,gx_deg_h\n1,3,4\n",
                "t.csv:2: 3 fields, the header has 2",
            ),
            (
                "tau_s,gx_deg_h\n1,x\n",
                "t.csv:2: column 2 (`gx_deg_h`): expected a number, got `x`",
            ),
            (
                "tau_s,gx_deg_h\n1,3\n1.5,2\n",
                "t.csv:3: column 1 (`tau_s`): τ = 1.5 s is not a multiple of Δt = 1 s",
            ),
            (
                "tau_s,gx_deg_h,gx_lo_deg_h,gx_hi_deg_h\n1,3,3.5,4\n",
                "t.csv:2: column 3 (`gx_lo_deg_h`): gx: a stated range needs both _lo and _hi, with lo ≤ σ ≤ hi",
            ),
            (
                "# record_length = 3 s\ntau_s,gx_deg_h\n1,3\n2,2\n",
                "t.csv: record length 3 s is shorter than the 2τ",
            ),
            ("# rate = fast\ntau_s,gx_deg_h\n1,3\n", "t.csv:1: rate:"),
            (
                "time,gx\n1,3\n",
                "t.csv:1: column 1 (`time`): expected a header starting with tau_s",
            ),
            ("tau_s,gx_deg_h\n", "t.csv: no rows after the header"),
        ];
        for (text, want) in cases {
            let e = error(text);
            assert!(e.starts_with(want), "{text:?}\n got  {e}\n want {want}");
        }
    }
}
