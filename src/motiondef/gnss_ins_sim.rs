//! gnss-ins-sim's motion-definition CSV (<https://github.com/Aceinna/gnss-ins-sim>, MIT),
//! read as it is:
//!
//! ```text
//! ini lat (deg),ini lon (deg),ini alt (m),ini vx_body (m/s),ini vy_body (m/s),ini vz_body (m/s),ini yaw (deg),ini pitch (deg),ini roll (deg)
//! 32,120,0,10,0,0,90,0,0
//! command type,yaw (deg),pitch (deg),roll (deg),vx_body (m/s),vy_body (m/s),vz_body (m/s),command duration (s),GPS visibility
//! 1,-15,0,0,0,0,0,6,0
//! ```
//!
//! Row 2 is the start: position, body velocity, ZYX Euler angles. Each command row has a type
//! and six values (angles in degrees, velocities in m/s), a duration and GNSS visibility
//! (gnss-ins-sim's `psim/sim/pathgen.py` gives the meaning of each type):
//!
//! * 1 — the values are Euler-angle rates (°/s) and body accelerations (m/s²), held for the
//!   duration;
//! * 2 — absolute attitude and absolute body velocity to reach;
//! * 3 — attitude and velocity changes relative to the start of the command;
//! * 4 — absolute attitude, relative velocity; 5 — relative attitude, absolute velocity.
//!
//! Types 2–5 end when the target is reached (at most after the duration), within the
//! mobility limits [`MOBILITY`]. Empty cells (the `reserved` columns of older files) are 0.

use std::path::Path;

use super::profile::{CHANNELS, Mobility, Profile};
use super::{DefinedMotion, Segment};
use crate::csvio::{CsvLines, FileError, clip, num, parse_finite};
use crate::motion::limits;

/// gnss-ins-sim's maneuver capability in its path-generation example:
/// [max acceleration 1 m/s², max angular acceleration 0.5 rad/s², max angular rate 2 rad/s].
pub const MOBILITY: Mobility = Mobility {
    max_accel: 1.0,
    max_angular_accel: 0.5,
    max_rate: 2.0,
};

/// Names of the start row's columns, for messages.
const START: [&str; 9] = [
    "ini lat",
    "ini lon",
    "ini alt",
    "ini vx_body",
    "ini vy_body",
    "ini vz_body",
    "ini yaw",
    "ini pitch",
    "ini roll",
];

/// Names of a command row's columns, for messages.
const COMMAND: [&str; 9] = [
    "command type",
    "yaw",
    "pitch",
    "roll",
    "vx_body",
    "vy_body",
    "vz_body",
    "command duration",
    "GPS visibility",
];

/// Longest total duration of a motion definition (s): ten days.
const MAX_TOTAL_S: f64 = 864_000.0;

/// Parses the cells of one row (at least `required` of them); the empty cells whose indices
/// `optional` lists are 0.
fn cells(
    lines: &CsvLines<impl std::io::BufRead>,
    names: &[&str; 9],
    required: usize,
    optional: &[usize],
) -> Result<[f64; 9], FileError> {
    let fields: Vec<&str> = lines.fields().collect();
    if fields.len() < required || fields.len() > 9 {
        return Err(lines.error(format!(
            "{} columns: expected {required} to 9 ({})",
            fields.len(),
            names.join(", ")
        )));
    }
    let mut out = [0.0; 9];
    for (c, f) in fields.iter().enumerate() {
        let f = f.trim();
        if f.is_empty() && optional.contains(&c) {
            continue;
        }
        out[c] = parse_finite(f).map_err(|m| lines.error(m).in_column(c + 1, names[c]))?;
    }
    Ok(out)
}

/// Reads a gnss-ins-sim motion-definition file with its example's limits [`MOBILITY`].
pub fn read(path: &Path) -> Result<DefinedMotion, FileError> {
    read_with(path, &MOBILITY)
}

/// Reads a gnss-ins-sim motion-definition file with the type 2–5 limits `mobility`.
pub fn read_with(path: &Path, mobility: &Mobility) -> Result<DefinedMotion, FileError> {
    let mut lines = CsvLines::open(path)?;
    let expect_header = |lines: &mut CsvLines<_>, what: &str| -> Result<(), FileError> {
        if !lines.advance()? {
            return Err(lines.error(format!("missing the {what} header line")));
        }
        let first = lines.fields().next().unwrap_or("").trim().to_string();
        if first.parse::<f64>().is_ok() {
            return Err(lines.error(format!(
                "expected the {what} header line (gnss-ins-sim's motion definition starts \
                 with `ini lat (deg),…`, its commands with `command type,…`), found {}",
                clip(lines.current())
            )));
        }
        Ok(())
    };
    expect_header(&mut lines, "start")?;
    if !lines.advance()? {
        return Err(
            lines.error("missing the start row (lat, lon, alt, vx, vy, vz, yaw, pitch, roll)")
        );
    }
    let s = cells(&lines, &START, 9, &[])?;
    if s[0].abs() > 90.0 {
        return Err(lines
            .error(format!("latitude {}° is beyond ±90°", num(s[0])))
            .in_column(1, START[0]));
    }
    if !(limits::MIN_HEIGHT_M..=limits::MAX_HEIGHT_M).contains(&s[2]) {
        return Err(lines
            .error(format!("height {} m is outside [−1e5, 1e8] m", num(s[2])))
            .in_column(3, START[2]));
    }
    let r = f64::to_radians;
    let origin = [r(s[0]), r(s[1]), s[2]];
    let mut profile = Profile::new(0.0, [r(s[6]), r(s[7]), r(s[8]), s[3], s[4], s[5]]);
    expect_header(&mut lines, "command")?;
    let mut segments = Vec::new();
    while lines.advance()? {
        if lines.current().trim().is_empty() {
            continue;
        }
        let c = cells(&lines, &COMMAND, 8, &[5, 6, 8])?;
        let line = lines.line_no();
        let kind = c[0];
        if !(kind.fract() == 0.0 && (1.0..=5.0).contains(&kind)) {
            return Err(lines
                .error(format!("command type {}: expected 1 to 5", num(kind)))
                .in_column(1, COMMAND[0]));
        }
        let duration = c[7];
        if !(duration >= 0.0 && profile.time() + duration <= MAX_TOTAL_S) {
            return Err(lines
                .error(format!(
                    "duration {} s: expected ≥ 0 s, the whole definition at most {} s",
                    num(duration),
                    num(MAX_TOTAL_S)
                ))
                .in_column(8, COMMAND[7]));
        }
        let mut v: [f64; CHANNELS] = std::array::from_fn(|k| c[k + 1]);
        for a in v.iter_mut().take(3) {
            *a = r(*a);
        }
        check_command(&lines, kind as u8, &v)?;
        profile.set_segment(segments.len());
        let t0 = profile.time();
        let now = profile.values();
        let (rel_att, rel_vel) = match kind as u8 {
            1 => (false, false),
            2 => (false, false),
            3 => (true, true),
            4 => (false, true),
            _ => (true, false),
        };
        if kind as u8 == 1 {
            profile.rates(v, duration);
        } else {
            let target: [f64; CHANNELS] = std::array::from_fn(|k| {
                let rel = if k < 3 { rel_att } else { rel_vel };
                if rel { now[k] + v[k] } else { v[k] }
            });
            profile.reach(target, mobility, duration);
        }
        segments.push(Segment {
            line,
            span: (t0, profile.time()),
            gnss_visible: c[8] != 0.0,
        });
    }
    if profile.pieces().is_empty() {
        return Err(FileError::file(
            path,
            "no command takes any time: a motion definition needs at least one command with a \
             positive duration",
        ));
    }
    Ok(DefinedMotion::new(origin, profile.into_pieces(), segments))
}

/// Refuses rates and accelerations beyond the limits of the kinematics.
fn check_command(
    lines: &CsvLines<impl std::io::BufRead>,
    kind: u8,
    v: &[f64; CHANNELS],
) -> Result<(), FileError> {
    for (k, x) in v.iter().enumerate() {
        let bad = if kind == 1 {
            if k < 3 {
                x.abs() > limits::MAX_RATE_RAD_S
            } else {
                x.abs() > limits::MAX_ACCEL_M_S2
            }
        } else {
            k >= 3 && x.abs() > limits::MAX_SPEED_M_S
        };
        if bad {
            return Err(lines
                .error(format!(
                    "{} is beyond the limits of the kinematics (rates 1e4 rad/s, accelerations \
                     1e5 m/s², speeds 3e4 m/s)",
                    num(if k < 3 { x.to_degrees() } else { *x })
                ))
                .in_column(k + 2, COMMAND[k + 1]));
        }
    }
    Ok(())
}
