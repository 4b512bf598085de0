//! Reading six-channel IMU data for analysis, streaming (one line / one chunk at a time):
//! our CSV and binary output, a protocol frame stream, or any CSV with a time column and
//! gyro and accelerometer columns mapped by name or by position, in stated units.
//! The only module of `analysis` that does I/O.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use crate::csvio::{CsvLines, FileError, clip, parse_finite};
use crate::protocol::spec::Source;
use crate::protocol::{Plan, StreamDecoder, StreamStats};

/// What a CSV column holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Time (s).
    Time,
    /// Angular rate, axis 0–2.
    Gyro(usize),
    /// Specific force, axis 0–2.
    Accel(usize),
    /// Ignored.
    Skip,
}

impl Role {
    /// Parses a column role: `t`/`time`, `gx`/`gyro_x`, `ax`/`accel_x`, …, or `-` to skip.
    pub fn from_name(s: &str) -> Option<Role> {
        let s = s.trim().to_ascii_lowercase();
        let axis = |c: &str| match c {
            "x" => Some(0),
            "y" => Some(1),
            "z" => Some(2),
            _ => None,
        };
        Some(match s.as_str() {
            "t" | "time" => Role::Time,
            "-" | "_" | "skip" => Role::Skip,
            _ => {
                if let Some(a) = s.strip_prefix("gyro_").or(s.strip_prefix('g')) {
                    Role::Gyro(axis(a)?)
                } else if let Some(a) = s.strip_prefix("accel_").or(s.strip_prefix('a')) {
                    Role::Accel(axis(a)?)
                } else {
                    return None;
                }
            }
        })
    }
}

/// How to read a CSV file.
#[derive(Clone, Debug, PartialEq)]
pub struct CsvOptions {
    /// Role of each column in order; None: from the header names (ours by default).
    pub columns: Option<Vec<Role>>,
    /// Factor from the file's gyro unit to rad/s.
    pub gyro_scale: f64,
    /// Factor from the file's accelerometer unit to m/s².
    pub accel_scale: f64,
}

impl Default for CsvOptions {
    fn default() -> Self {
        CsvOptions {
            columns: None,
            gyro_scale: 1.0,
            accel_scale: 1.0,
        }
    }
}

/// The encoding of the input.
pub enum InputFormat {
    /// Text with optional header.
    Csv(CsvOptions),
    /// Our binary records (13 little-endian f64 each).
    Bin,
    /// Frames of a protocol.
    Frames(Plan),
}

/// What was read besides the samples.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReadSummary {
    /// Samples delivered.
    pub samples: u64,
    /// Frame-stream tally (frames input only).
    pub frames: Option<StreamStats>,
    /// Channels (gyro x y z, accel x y z) the input has no column for; their values are
    /// delivered as 0 (a CSV of one gyro axis, say).
    pub missing: [bool; 6],
}

/// Input that cannot be analysed, with the file, line and field at fault.
pub type ReadError = FileError;

const CHANNEL_NAMES: [&str; 6] = [
    "gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z",
];

/// The first channel of a sample `v` (rad/s, m/s²) beyond what any sensor of its kind
/// measures — the template bounds of [`crate::units::bounds`], 10⁴ rad/s and 10⁷ m/s² — and
/// why, for a message. Such a sample is a corrupt or mis-scaled input whose statistics would
/// describe only the corruption (a fit of frames carrying 1e30 rad/s wrote a template that
/// no reader loads).
pub fn implausible(v: &[f64; 6]) -> Option<(usize, String)> {
    use crate::units::Kind;
    (0..6).find_map(|i| {
        let (kind, sensor) = match i {
            0..3 => (Kind::AngularRate, "gyro"),
            _ => (Kind::Acceleration, "accelerometer"),
        };
        let (max, unit) = crate::units::bounds::max_magnitude(kind, false)?;
        (v[i].abs() > max).then(|| {
            let (x, max) = (crate::csvio::num(v[i]), crate::csvio::num(max));
            let why = format!(
                "{} is {x} {unit}, beyond the {max} {unit} no {sensor} measures",
                CHANNEL_NAMES[i]
            );
            (i, why)
        })
    })
}

/// Reads `path` and calls `sample(t, [gx, gy, gz, ax, ay, az])` for each sample, in SI.
/// `t` is NaN when the input has no time; `dt` (if known) turns frame increments into rates.
pub fn read(
    path: &Path,
    format: &InputFormat,
    dt: Option<f64>,
    mut sample: impl FnMut(f64, &[f64; 6]),
) -> Result<ReadSummary, ReadError> {
    let io = |source| FileError::io(path, source);
    let file = File::open(path).map_err(io)?;
    match format {
        InputFormat::Csv(o) => read_csv(path, BufReader::with_capacity(1 << 16, file), o, sample),
        InputFormat::Bin => {
            crate::input::check_whole_records(path)?;
            let bytes = file.metadata().map_err(io)?.len();
            let mut r = BufReader::with_capacity(1 << 16, file);
            let mut rec = [0u8; crate::output::BIN_RECORD_BYTES];
            let mut n = 0u64;
            loop {
                match read_full(&mut r, &mut rec).map_err(io)? {
                    0 => break,
                    crate::output::BIN_RECORD_BYTES => {}
                    _ => {
                        return Err(FileError::file(
                            path,
                            format!(
                                "{bytes} bytes is not a whole number of {}-byte records (record {n} is cut short)",
                                crate::output::BIN_RECORD_BYTES
                            ),
                        ));
                    }
                }
                let v = crate::output::decode_bin(&rec);
                // A corrupt file: a NaN or ∞ would make every statistic of its channel one.
                if let Some(i) = (0..7).find(|&i| !v[i].is_finite()) {
                    return Err(FileError::file(
                        path,
                        format!(
                            "record {n}: {} is {}, not a finite number",
                            crate::record::COLUMNS[i],
                            v[i]
                        ),
                    ));
                }
                let s = std::array::from_fn(|i| v[i + 1]);
                if let Some((_, why)) = implausible(&s) {
                    return Err(FileError::file(path, format!("record {n}: {why}")));
                }
                sample(v[0], &s);
                n += 1;
            }
            Ok(ReadSummary {
                samples: n,
                ..Default::default()
            })
        }
        InputFormat::Frames(plan) => read_frames(path, file, plan.clone(), dt, sample),
    }
}

/// Fills `buf` as far as the input allows; returns the bytes read (short only at the end).
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// The used columns as (index, role), and every column's display name.
type ColumnMap = (Vec<(usize, Role)>, Vec<String>);

/// The source and factor of each of the six rates, and the time source if any.
type FrameLayout = (Vec<(Source, f64)>, Option<Source>);

fn read_csv(
    path: &Path,
    r: impl BufRead,
    o: &CsvOptions,
    mut sample: impl FnMut(f64, &[f64; 6]),
) -> Result<ReadSummary, ReadError> {
    let mut lines = CsvLines::new(r, path);
    // (column index, role) of the columns used, and their display names.
    let mut map: Option<ColumnMap> = None;
    let mut missing = [false; 6];
    let mut n = 0u64;
    while lines.advance()? {
        let fields: Vec<&str> = lines.fields().collect();
        if map.is_none() {
            let header = fields.iter().any(|f| f.parse::<f64>().is_err());
            let (roles, names): (Vec<Role>, Vec<String>) = match (&o.columns, header) {
                (Some(roles), _) => (
                    roles.clone(),
                    (0..roles.len())
                        .map(|i| {
                            if header {
                                fields
                                    .get(i)
                                    .map_or(format!("#{}", i + 1), |s| s.to_string())
                            } else {
                                role_name(roles[i])
                            }
                        })
                        .collect(),
                ),
                (None, true) => (
                    fields
                        .iter()
                        .map(|f| Role::from_name(f).unwrap_or(Role::Skip))
                        .collect(),
                    fields.iter().map(|s| s.to_string()).collect(),
                ),
                (None, false) => {
                    let ours = crate::record::COLUMNS;
                    (
                        ours.iter()
                            .map(|f| Role::from_name(f).unwrap_or(Role::Skip))
                            .collect(),
                        ours.iter().map(|s| s.to_string()).collect(),
                    )
                }
            };
            let mut used = Vec::new();
            for want in [
                Role::Gyro(0),
                Role::Gyro(1),
                Role::Gyro(2),
                Role::Accel(0),
                Role::Accel(1),
                Role::Accel(2),
                Role::Time,
            ] {
                match roles.iter().position(|r| *r == want) {
                    Some(i) => used.push((i, want)),
                    None => match want {
                        Role::Gyro(a) => missing[a] = true,
                        Role::Accel(a) => missing[3 + a] = true,
                        _ => {}
                    },
                }
            }
            // A recording of some axes only (one gyro on a rate table) is analysed as such;
            // one of none is a column mapping gone wrong.
            if missing.iter().all(|&m| m) {
                return Err(FileError::file(
                    path,
                    format!(
                        "no gyro or accelerometer column (columns: {}; map them with --columns, e.g. t,gx,gy,gz,ax,ay,az)",
                        names
                            .iter()
                            .take(20)
                            .map(|n| clip(n))
                            .collect::<Vec<_>>()
                            .join(",")
                    ),
                ));
            }
            map = Some((used, names));
            if header {
                continue;
            }
        }
        let (used, names) = map.as_ref().expect("set above");
        let need = used.iter().map(|u| u.0 + 1).max().unwrap_or(0);
        if fields.len() < need {
            let got = fields.len();
            return Err(lines.error(format!("{got} fields, the column mapping needs {need}")));
        }
        let mut v = [0.0; 6];
        let mut t = f64::NAN;
        for &(i, role) in used {
            let x = parse_finite(fields[i]).map_err(|m| {
                let name = names.get(i).map_or("", String::as_str);
                lines.error(m).in_column(i + 1, name)
            })?;
            match role {
                Role::Gyro(a) => v[a] = x * o.gyro_scale,
                Role::Accel(a) => v[3 + a] = x * o.accel_scale,
                Role::Time => t = x,
                Role::Skip => {}
            }
        }
        if let Some((ch, why)) = implausible(&v) {
            let role = if ch < 3 {
                Role::Gyro(ch)
            } else {
                Role::Accel(ch - 3)
            };
            let i = used.iter().find(|u| u.1 == role).map_or(0, |u| u.0);
            let name = names.get(i).map_or("", String::as_str);
            return Err(lines.error(why).in_column(i + 1, name));
        }
        sample(t, &v);
        n += 1;
    }
    Ok(ReadSummary {
        samples: n,
        frames: None,
        missing,
    })
}

fn role_name(r: Role) -> String {
    match r {
        Role::Time => "time".into(),
        Role::Gyro(a) => CHANNEL_NAMES[a].into(),
        Role::Accel(a) => CHANNEL_NAMES[3 + a].into(),
        Role::Skip => "-".into(),
    }
}

fn read_frames(
    path: &Path,
    mut file: File,
    plan: Plan,
    dt: Option<f64>,
    mut sample: impl FnMut(f64, &[f64; 6]),
) -> Result<ReadSummary, ReadError> {
    let mut dec = StreamDecoder::new(plan);
    let mut buf = vec![0u8; 1 << 16];
    let mut n = 0u64;
    // Chosen from the first frame: each axis from its rate, else its increment over Δt.
    let mut layout: Option<Result<FrameLayout, ReadError>> = None;
    // A frame whose rate decodes to a NaN, ∞ or a value no sensor measures (a float field's
    // bits): the first one, by frame.
    let mut not_finite: Option<ReadError> = None;
    let mut each = |d: &crate::protocol::Decoded| {
        let l = layout.get_or_insert_with(|| frame_layout(path, d, dt));
        if let Ok((sources, time)) = l {
            let v: [f64; 6] =
                std::array::from_fn(|i| d.get(sources[i].0).unwrap_or(f64::NAN) * sources[i].1);
            if let Some(i) = (0..6).find(|&i| d.get(sources[i].0).is_some_and(|x| !x.is_finite())) {
                not_finite = Some(FileError::file(
                    path,
                    format!(
                        "frame {n}: {} is {}, not a finite number",
                        CHANNEL_NAMES[i], v[i]
                    ),
                ));
                return false;
            }
            if let Some((_, why)) = implausible(&v) {
                not_finite = Some(FileError::file(path, format!("frame {n}: {why}")));
                return false;
            }
            let t = time.and_then(|s| d.get(s)).unwrap_or(f64::NAN);
            sample(t, &v);
            n += 1;
        }
        l.is_ok()
    };
    loop {
        let k = file
            .read(&mut buf)
            .map_err(|source| FileError::io(path, source))?;
        let mut ok = true;
        if k == 0 {
            // The end of the file confirms the frames still waiting for their run.
            dec.finish_frames(|d| ok &= each(d));
            break;
        }
        dec.feed(&buf[..k], |d| ok &= each(d));
        if !ok {
            break;
        }
    }
    if let Some(Err(e)) = layout {
        return Err(e);
    }
    if let Some(e) = not_finite {
        return Err(e);
    }
    Ok(ReadSummary {
        samples: n,
        frames: Some(dec.stats()),
        ..Default::default()
    })
}

/// Which decoded values give the six rates (with their factor) and the time.
fn frame_layout(
    path: &Path,
    d: &crate::protocol::Decoded,
    dt: Option<f64>,
) -> Result<FrameLayout, ReadError> {
    let mut sources = Vec::with_capacity(6);
    for (i, (rate, inc)) in (0..3)
        .map(|a| (Source::Gyro(a), Source::DTheta(a)))
        .chain((0..3).map(|a| (Source::Accel(a), Source::Dv(a))))
        .enumerate()
    {
        if d.get(rate).is_some() {
            sources.push((rate, 1.0));
        } else if d.get(inc).is_some() {
            let dt = dt.ok_or_else(|| {
                FileError::file(
                    path,
                    format!(
                        "the protocol's frames carry no rate for {} (its increments need the sampling rate: give --rate)",
                        CHANNEL_NAMES[i]
                    ),
                )
            })?;
            sources.push((inc, 1.0 / dt));
        } else {
            return Err(FileError::file(
                path,
                format!(
                    "the protocol's frames carry no rate or increment for {}",
                    CHANNEL_NAMES[i]
                ),
            ));
        }
    }
    let time = [Source::Time, Source::GpsSeconds]
        .into_iter()
        .find(|s| d.get(*s).is_some());
    Ok((sources, time))
}

/// Parses a `--columns` list such as `t,gx,gy,gz,ax,ay,az` (`-` skips a column).
pub fn parse_columns(s: &str) -> Result<Vec<Role>, String> {
    s.split(',')
        .map(|c| {
            Role::from_name(c).ok_or_else(|| {
                format!(
                    "unknown column role `{c}` (t, gx, gy, gz, ax, ay, az, gyro_x, …, or - to skip)"
                )
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roles() {
        assert_eq!(Role::from_name("gyro_y"), Some(Role::Gyro(1)));
        assert_eq!(Role::from_name("AZ"), Some(Role::Accel(2)));
        assert_eq!(Role::from_name("time"), Some(Role::Time));
        assert_eq!(Role::from_name("dtheta_x"), None);
        assert_eq!(Role::from_name("gw"), None);
        assert!(parse_columns("t,gx,foo").unwrap_err().contains("`foo`"));
    }
}
