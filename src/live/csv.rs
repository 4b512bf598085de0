//! States as text lines: the columns of a trajectory file (`t,lat,lon,h,vn,ve,vd,roll,pitch,
//! yaw`; s, deg, deg, m, m/s, deg) in any order, plus optional exact derivatives the
//! simulation knows: `wx,wy,wz` (body angular rate ω_ib^b, deg/s) and `an,ae,ad` (time
//! derivative of the NED velocity, m/s²). A header line names the columns and may be sent at
//! any time (again over UDP, where a receiver can join late); it is read as a trajectory
//! file's header is ([`crate::csvio::header_columns`], a UTF-8 byte-order mark dropped).
//! Without one the ten trajectory columns are assumed in their file order; after a refused
//! one (and none taken before it) the rows are refused, not read in that assumed order.
//! `#` starts a comment line. Instead of `t`, the
//! time tag can be GPS time: `gps_week` (whole weeks since 1980-01-06) and `gps_sow` (seconds
//! of week, [0, 604800)), taken as GPS seconds since the GPS epoch, week·604800 + sow, as the
//! binary datagram's week and time tag are (GPS time has no leap seconds).

use super::{Decoded, Malformed};
use crate::csvio::{header_columns, num, parse_finite, strip_bom};
use crate::math::{Vec3, quat_from_euler};
use crate::motion::causal::LiveSample;
use crate::motion::sampled::Sample;
use crate::trajectory::COLUMNS;

/// The optional columns, in groups of three that come together.
pub const EXTRA_COLUMNS: [&str; 6] = ["wx", "wy", "wz", "an", "ae", "ad"];

/// The GPS time tag's columns, which replace `t`.
pub const GPS_COLUMNS: [&str; 2] = ["gps_week", "gps_sow"];

/// Number of known columns: the trajectory's, the extras, then the GPS time tag's.
const KNOWN: usize = 18;
/// Index of `gps_week` among the known columns (`gps_sow` follows).
const GPS: usize = 16;
/// Seconds in a GPS week.
const WEEK_S: f64 = 604_800.0;

/// Longest line taken (bytes): as long as the largest datagram, a hundred times a state line
/// with every column at full precision. A stream's longer line is cut by
/// [`super::transport::Receiver`] after one byte more, so it holds no more than this per line.
pub const MAX_LINE_BYTES: usize = 65_536;

/// The decoder's view of the columns: where each known column is in a line.
#[derive(Clone, Debug)]
pub struct CsvDecoder {
    /// File column of each known column (`None`: absent).
    at: [Option<usize>; KNOWN],
    width: usize,
    /// GPS time tags count from the start of this GPS week (see [`super::binary::decode_since`]).
    pub epoch_week: u32,
    /// A header has been taken: the columns are the sender's, not the default.
    headed: bool,
    /// A header was refused before any was taken: the rows' order is unknown, and reading
    /// them in the default order would swap columns without a word.
    unknown_layout: bool,
}

impl Default for CsvDecoder {
    fn default() -> Self {
        let mut at = [None; KNOWN];
        for (i, a) in at.iter_mut().enumerate().take(COLUMNS.len()) {
            *a = Some(i);
        }
        CsvDecoder {
            at,
            width: COLUMNS.len(),
            epoch_week: 0,
            headed: false,
            unknown_layout: false,
        }
    }
}

fn name_of(k: usize) -> &'static str {
    if k < COLUMNS.len() {
        COLUMNS[k]
    } else if k < GPS {
        EXTRA_COLUMNS[k - COLUMNS.len()]
    } else {
        GPS_COLUMNS[k - GPS]
    }
}

impl CsvDecoder {
    /// Decodes one line (without or with its line end).
    pub fn decode(&mut self, line: &[u8]) -> Result<Option<Decoded>, Malformed> {
        let decoded = self.decode_tag(line)?;
        Ok(decoded.map(|(mut d, week)| {
            if let Some(w) = week {
                d.state.sample.t = super::since_week(w, self.epoch_week, d.state.sample.t);
            }
            d
        }))
    }

    /// [`CsvDecoder::decode`], with the time tag as sent: the state's time is `gps_sow` with
    /// the `gps_week` returned, or `t` when there is none.
    pub fn decode_tag(&mut self, line: &[u8]) -> Result<Option<(Decoded, Option<u32>)>, Malformed> {
        if line.len() > MAX_LINE_BYTES {
            return Err(Malformed::at(
                MAX_LINE_BYTES,
                format!(
                    "line longer than {MAX_LINE_BYTES} bytes (is this a stream of state lines?); the rest of it is skipped"
                ),
            ));
        }
        let text = std::str::from_utf8(line)
            .map_err(|e| Malformed::at(e.valid_up_to(), "not UTF-8 text"))?;
        let line_text = text.trim_end_matches(['\n', '\r']);
        let text = strip_bom(line_text);
        // Offsets in messages count the mark's bytes: they are the line's as sent.
        let mark = line_text.len() - text.len();
        let shift = |mut e: Malformed| {
            e.offset += mark;
            e
        };
        let trimmed = text.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            return Ok(None);
        }
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        // A line without a number is a header; one with numbers is a state, however damaged
        // its first field (a state's damage is not a header's).
        if fields.iter().all(|f| f.parse::<f64>().is_err()) {
            let taken = self.header(&fields);
            self.unknown_layout = taken.is_err() && (self.unknown_layout || !self.headed);
            self.headed |= taken.is_ok();
            return taken.map(|()| None).map_err(shift);
        }
        if self.unknown_layout {
            return Err(Malformed::at(
                0,
                "the sender's columns are unknown: its header was refused (see that line), and its rows are not read in a guessed order until a header is taken",
            ));
        }
        self.data(text, &fields).map(Some).map_err(shift)
    }

    fn header(&mut self, fields: &[&str]) -> Result<(), Malformed> {
        let known: Vec<&str> = (0..KNOWN).map(name_of).collect();
        let expected = format!(
            "(expected `{}` and optionally `{}`; `{}` for `t`)",
            COLUMNS.join(","),
            EXTRA_COLUMNS.join(","),
            GPS_COLUMNS.join(",")
        );
        let found = header_columns(fields, &known, &expected).map_err(|m| Malformed::at(0, m))?;
        let mut at = [None; KNOWN];
        at.copy_from_slice(&found);
        match (at[0].is_some(), at[GPS].is_some(), at[GPS + 1].is_some()) {
            (_, true, false) | (_, false, true) => {
                return Err(Malformed::at(
                    0,
                    "header: `gps_week` and `gps_sow` come together".to_string(),
                ));
            }
            (true, true, true) => {
                return Err(Malformed::at(
                    0,
                    "header: give the time as `t` or as `gps_week,gps_sow`, not both".to_string(),
                ));
            }
            _ => {}
        }
        let gps = at[GPS].is_some();
        if let Some(k) = (0..COLUMNS.len()).find(|&k| at[k].is_none() && !(k == 0 && gps)) {
            return Err(Malformed::at(
                0,
                format!("header: missing column `{}`", name_of(k)),
            ));
        }
        for g in [10, 13] {
            let n = (g..g + 3).filter(|&k| at[k].is_some()).count();
            if n != 0 && n != 3 {
                return Err(Malformed::at(
                    0,
                    format!(
                        "header: `{}` come together: give all three or none",
                        EXTRA_COLUMNS[g - 10..g - 7].join(",")
                    ),
                ));
            }
        }
        self.at = at;
        self.width = fields.len();
        Ok(())
    }

    fn data(&self, text: &str, fields: &[&str]) -> Result<(Decoded, Option<u32>), Malformed> {
        if fields.len() != self.width {
            return Err(Malformed::at(
                0,
                format!("{} fields, expected {}", fields.len(), self.width),
            ));
        }
        // Byte offset of each field, for the message.
        let mut offsets = Vec::with_capacity(fields.len());
        let mut o = 0;
        for f in text.split(',') {
            offsets.push(o);
            o += f.len() + 1;
        }
        let mut v = [f64::NAN; KNOWN];
        for (k, slot) in v.iter_mut().enumerate() {
            let Some(c) = self.at[k] else { continue };
            let x = parse_finite(fields[c]).map_err(|m| {
                Malformed::at(
                    offsets[c],
                    format!("column {} (`{}`): {m}", c + 1, name_of(k)),
                )
            })?;
            let bad_week = k == GPS && !(x >= 0.0 && x.fract() == 0.0 && x < 65536.0);
            let bad_sow = k == GPS + 1 && !(0.0..WEEK_S).contains(&x);
            if bad_week || bad_sow {
                let want = if bad_week {
                    "a whole number of weeks ≥ 0"
                } else {
                    "seconds of week in [0, 604800)"
                };
                return Err(Malformed::at(
                    offsets[c],
                    format!(
                        "column {} (`{}`): {}: expected {want}",
                        c + 1,
                        name_of(k),
                        num(x)
                    ),
                ));
            }
            if k == 1 && x.abs() > 90.0 {
                return Err(Malformed::at(
                    offsets[c],
                    format!(
                        "column {} (`lat`): {} is outside [-90, 90] degrees",
                        c + 1,
                        num(x)
                    ),
                ));
            }
            *slot = x;
        }
        let group = |g: usize| {
            self.at[g]
                .is_some()
                .then(|| Vec3::new(v[g], v[g + 1], v[g + 2]))
        };
        // The week was checked to be a whole number in [0, 65536).
        let (t, week) = match self.at[GPS] {
            Some(_) => (v[GPS + 1], Some(v[GPS] as u32)),
            None => (v[0], None),
        };
        let sample = Sample {
            t,
            lat: v[1].to_radians(),
            lon: v[2].to_radians(),
            h: v[3],
            v_n: Vec3::new(v[4], v[5], v[6]),
            q_b_n: quat_from_euler(v[7].to_radians(), v[8].to_radians(), v[9].to_radians()),
        };
        let d = Decoded {
            seq: None,
            state: LiveSample {
                sample,
                omega_ib_b: group(10).map(|w| w * (std::f64::consts::PI / 180.0)),
                accel_n: group(13),
            },
        };
        Ok((d, week))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_columns_header_and_extras() {
        let mut d = CsvDecoder::default();
        let s = d.decode(b"1.5,45,7,100,1,2,3,0,0,90\n").unwrap().unwrap();
        assert_eq!(s.state.sample.t, 1.5);
        assert_eq!(s.state.sample.lat, 45f64.to_radians());
        assert_eq!(s.state.sample.v_n, Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(s.state.omega_ib_b, None);
        assert_eq!(d.decode(b"# comment\n").unwrap(), None);
        assert_eq!(d.decode(b"\n").unwrap(), None);
        // Another order, with both extra groups.
        let head = b"yaw,t,lat,lon,h,vn,ve,vd,roll,pitch,an,ae,ad,wx,wy,wz";
        assert_eq!(d.decode(head).unwrap(), None);
        let s = d
            .decode(b"90,2,45,7,100,1,2,3,0,0,0.5,0,-0.5,180,0,0")
            .unwrap()
            .unwrap();
        assert_eq!(s.state.sample.t, 2.0);
        assert_eq!(s.state.accel_n, Some(Vec3::new(0.5, 0.0, -0.5)));
        assert_eq!(
            s.state.omega_ib_b,
            Some(Vec3::new(std::f64::consts::PI, 0.0, 0.0))
        );
    }

    /// Bad lines name the column and its byte offset; the decoder keeps working after them.
    #[test]
    fn malformed_lines_name_column_and_offset() {
        let mut d = CsvDecoder::default();
        let e = d.decode(b"1.5,45,7,1x0,1,2,3,0,0,90").unwrap_err();
        assert_eq!(e.offset, 9);
        assert!(e.message.contains("column 4 (`h`)"), "{e:?}");
        let e = d.decode(b"1.5,95,7,1,1,2,3,0,0,90").unwrap_err();
        assert!(e.message.contains("outside [-90, 90]"), "{e:?}");
        let e = d.decode(b"1.5,45,7").unwrap_err();
        assert_eq!(e.message, "3 fields, expected 10");
        let e = d.decode(b"1.5,45,7,1,nan,2,3,0,0,90").unwrap_err();
        assert!(e.message.contains("not finite"), "{e:?}");
        let e = d.decode(b"1.5,45,\xff").unwrap_err();
        assert_eq!(e.offset, 7);
        // A damaged first field is a damaged state, not a header.
        let e = d.decode(b"1.x5,45,7,1,1,2,3,0,0,90").unwrap_err();
        assert_eq!(e.message, "column 1 (`t`): `1.x5` is not a number");
        let e = d
            .decode(b"t,lat,lon,h,vn,ve,vd,roll,pitch,yaw,wx")
            .unwrap_err();
        assert!(e.message.contains("give all three"), "{e:?}");
        let e = d.decode(b"t,lat,lon,h,vn,ve,vd,roll,pitch").unwrap_err();
        assert!(e.message.contains("missing column `yaw`"), "{e:?}");
        // These headers were refused before any was taken: the rows' order is unknown.
        let e = d.decode(b"1.5,45,7,1,1,2,3,0,0,90").unwrap_err();
        assert!(e.message.contains("columns are unknown"), "{e:?}");
        assert_eq!(d.decode(COLUMNS.join(",").as_bytes()).unwrap(), None);
        assert!(d.decode(b"1.5,45,7,1,1,2,3,0,0,90").unwrap().is_some());
    }

    /// A byte-order mark and a header in another order (issue 38: the mark made the header a
    /// malformed line and the rows were read in the default order, latitude and longitude
    /// swapped): read as a trajectory file's; offsets count the mark's bytes.
    #[test]
    fn a_byte_order_mark_and_another_order() {
        let mut d = CsvDecoder::default();
        let head = "\u{feff}t,lon,lat,h,vn,ve,vd,roll,pitch,yaw";
        assert_eq!(d.decode(head.as_bytes()).unwrap(), None);
        let s = d.decode(b"2,7,45,100,1,2,3,0,0,90").unwrap().unwrap();
        assert_eq!(s.state.sample.lat, 45f64.to_radians());
        assert_eq!(s.state.sample.lon, 7f64.to_radians());
        // A mark on a data line (each datagram written as `utf-8-sig`).
        let s = d
            .decode("\u{feff}3,7,45,100,1,2,3,0,0,90".as_bytes())
            .unwrap()
            .unwrap();
        assert_eq!(s.state.sample.t, 3.0);
        let e = d
            .decode("\u{feff}3,7,4x,100,1,2,3,0,0,90".as_bytes())
            .unwrap_err();
        assert_eq!(e.offset, 3 + 4);
        // Refused before any header was taken, e.g. a name the trajectory reader refuses too:
        // the rows are refused, not read in the default order.
        let mut d = CsvDecoder::default();
        let e = d
            .decode(b"time,lon,lat,h,vn,ve,vd,roll,pitch,yaw")
            .unwrap_err();
        assert!(
            e.message.contains("column 1: unknown column `time`"),
            "{e:?}"
        );
        assert!(d.decode(b"2,7,45,100,1,2,3,0,0,90").is_err());
    }

    /// `gps_week,gps_sow` instead of `t`: the time is GPS seconds since the GPS epoch; a
    /// fractional or negative week, seconds of week outside [0, 604800) and headers with both
    /// or half of the time tags are refused naming the column and its byte offset.
    #[test]
    fn gps_week_and_seconds_time_tags() {
        let mut d = CsvDecoder::default();
        let head = b"gps_week,gps_sow,lat,lon,h,vn,ve,vd,roll,pitch,yaw";
        assert_eq!(d.decode(head).unwrap(), None);
        let s = d
            .decode(b"2400,345600.25,45,7,100,1,2,3,0,0,90")
            .unwrap()
            .unwrap();
        assert_eq!(s.state.sample.t, 2400.0 * 604_800.0 + 345_600.25);
        assert_eq!(s.state.sample.h, 100.0);
        let e = d.decode(b"2400.5,1,45,7,100,1,2,3,0,0,90").unwrap_err();
        assert_eq!(e.offset, 0);
        assert!(e.message.contains("column 1 (`gps_week`): 2400.5"), "{e:?}");
        let e = d.decode(b"2400,604800,45,7,100,1,2,3,0,0,90").unwrap_err();
        assert_eq!(e.offset, 5);
        assert!(e.message.contains("column 2 (`gps_sow`)"), "{e:?}");
        let e = d.decode(b"-1,5,45,7,100,1,2,3,0,0,90").unwrap_err();
        assert!(e.message.contains("whole number of weeks"), "{e:?}");
        let e = d
            .decode(b"t,gps_week,gps_sow,lat,lon,h,vn,ve,vd,roll,pitch,yaw")
            .unwrap_err();
        assert!(e.message.contains("not both"), "{e:?}");
        let e = d
            .decode(b"gps_week,lat,lon,h,vn,ve,vd,roll,pitch,yaw")
            .unwrap_err();
        assert!(e.message.contains("come together"), "{e:?}");
        // The header in force is still the GPS one.
        assert!(d.decode(b"2400,0,45,7,100,1,2,3,0,0,90").unwrap().is_some());
    }
}
