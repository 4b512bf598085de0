//! Reading GNSS fixes back from the truth CSV `generate --gnss-truth` writes (columns by
//! header name, any order): per epoch its time, whether the receiver had a fix, and the
//! reported (`meas_*`) antenna position and velocity. Every problem names the file, line and
//! column.

use std::path::Path;

use crate::csvio::{CsvLines, FileError, parse_finite};
use crate::math::Vec3;
use crate::nav::aided::GnssFix;

/// The columns read, in [`GnssFix`] order after `t` and `fix`.
const COLUMNS: [&str; 8] = [
    "t", "fix", "meas_lat", "meas_lon", "meas_h", "meas_vn", "meas_ve", "meas_vd",
];

/// The fix names the truth file uses (see [`crate::aiding::stream::fix_name`]); `none` is an outage.
const FIX_NAMES: [&str; 5] = [
    "none",
    "autonomous",
    "differential",
    "rtk-float",
    "rtk-fixed",
];

/// One epoch of the file: its time, and the fix (`None` in an outage).
pub type FixEpoch = (f64, Option<GnssFix>);

/// Reads every epoch of `path`; each fix gets the σ's given (the file does not carry them).
/// Epoch times must increase.
pub fn read_fixes(
    path: &Path,
    sigma_pos: Vec3,
    sigma_vel: Vec3,
) -> Result<Vec<FixEpoch>, FileError> {
    let mut lines = CsvLines::open(path)?;
    if !lines.advance()? {
        return Err(lines.error("no header line (expected a `generate --gnss-truth` CSV)"));
    }
    let header: Vec<&str> = lines.fields().collect();
    let mut col = [0usize; 8];
    for (c, name) in col.iter_mut().zip(COLUMNS) {
        *c = header.iter().position(|h| *h == name).ok_or_else(|| {
            lines.error(format!(
                "header: missing column `{name}` (expected a `generate --gnss-truth` CSV)"
            ))
        })?;
    }
    let width = header.len();
    let mut out = Vec::new();
    while lines.advance()? {
        let fields: Vec<&str> = lines.fields().collect();
        if fields.len() != width {
            let problem = format!("{} fields, expected {width}", fields.len());
            return Err(lines.error(problem));
        }
        let num = |i: usize| {
            parse_finite(fields[col[i]])
                .map_err(|m| lines.error(m).in_column(col[i] + 1, COLUMNS[i]))
        };
        let t = num(0)?;
        if let Some(&(prev, _)) = out.last()
            && t <= prev
        {
            return Err(lines
                .error(format!(
                    "t = {t} s does not follow the previous epoch's {prev} s"
                ))
                .in_column(col[0] + 1, "t"));
        }
        let fix = fields[col[1]];
        if !FIX_NAMES.contains(&fix) {
            return Err(lines
                .error(format!("`{fix}`: expected one of {}", FIX_NAMES.join(", ")))
                .in_column(col[1] + 1, "fix"));
        }
        let epoch = if fix == "none" {
            None
        } else {
            Some(GnssFix {
                t,
                lat: num(2)?.to_radians(),
                lon: num(3)?.to_radians(),
                h: num(4)?,
                v_n: Vec3::new(num(5)?, num(6)?, num(7)?),
                sigma_pos,
                sigma_vel,
            })
        };
        out.push((t, epoch));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Vec<FixEpoch>, String> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("g.csv");
        std::fs::write(&p, text).unwrap();
        read_fixes(&p, Vec3::repeat(1.0), Vec3::repeat(0.1)).map_err(|e| e.to_string())
    }

    const HEAD: &str = "k,t,fix,meas_vd,meas_lat,meas_lon,meas_h,meas_vn,meas_ve\n";

    #[test]
    fn reads_fixes_and_outages_by_column_name() {
        let f = read(&format!(
            "{HEAD}0,0.5,autonomous,-1,45,7,100,2,3\n1,1,none,0,0,0,0,0,0\n"
        ))
        .unwrap();
        assert_eq!(f.len(), 2);
        let g = f[0].1.unwrap();
        assert_eq!(
            (g.t, g.lat, g.lon, g.h),
            (0.5, 45f64.to_radians(), 7f64.to_radians(), 100.0)
        );
        assert_eq!(g.v_n, Vec3::new(2.0, 3.0, -1.0));
        assert_eq!(g.sigma_vel, Vec3::repeat(0.1));
        assert_eq!(f[1], (1.0, None));
    }

    #[test]
    fn bad_input_names_line_and_column() {
        let e = read("k,t,fix\n").unwrap_err();
        assert!(e.contains("missing column `meas_lat`"), "{e}");
        let e = read(&format!("{HEAD}0,0.5,autonomous,-1,45,x,100,2,3\n")).unwrap_err();
        assert!(e.contains(":2") && e.contains("meas_lon"), "{e}");
        let e = read(&format!("{HEAD}0,0.5,maybe,-1,45,7,100,2,3\n")).unwrap_err();
        assert!(e.contains("`maybe`") && e.contains("fix"), "{e}");
        let e = read(&format!(
            "{HEAD}0,1,none,0,0,0,0,0,0\n0,1,none,0,0,0,0,0,0\n"
        ))
        .unwrap_err();
        assert!(e.contains("does not follow"), "{e}");
        let e = read(&format!("{HEAD}0,1,none,0,0,0,0,0\n")).unwrap_err();
        assert!(e.contains("8 fields, expected 9"), "{e}");
        let e = read(&format!("{HEAD}0,inf,none,0,0,0,0,0,0\n")).unwrap_err();
        assert!(e.contains("column 2"), "{e}");
    }
}
