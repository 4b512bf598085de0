//! Live motion input for hardware-in-the-loop runs: states of a vehicle simulation arriving
//! over UDP, TCP, a pipe or a file, decoded ([`csv`], [`binary`], [`mavlink`]), checked and
//! counted ([`stats`]; lost CSV states told from their time steps, [`lost`]), for the causal
//! motion model ([`crate::motion::causal`]), with the map from the sender's clock to the
//! host's ([`clockmap`]). The run follows them ([`crate::run`]). docs/live-input.md is the
//! user's guide and specifies the binary datagram.
//!
//! Decoding is pure (bytes in, states out); [`transport`] is the only I/O.

pub mod binary;
pub mod clockmap;
pub mod csv;
pub mod lost;
pub mod mavlink;
pub mod stats;
pub mod transport;

use std::sync::OnceLock;

use crate::motion::causal::LiveSample;
use crate::timebase::LeapTable;

/// The wire format of the incoming states.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputFormat {
    /// Text lines with the trajectory CSV columns (and optional extras).
    Csv,
    /// The binary datagram of docs/live-input.md.
    Binary,
    /// MAVLink 2 `HIL_STATE_QUATERNION` (message 115).
    Mavlink,
}

impl InputFormat {
    /// The format named `csv`, `bin` or `mavlink`.
    pub fn from_name(name: &str) -> Option<InputFormat> {
        match name {
            "csv" => Some(InputFormat::Csv),
            "bin" | "binary" => Some(InputFormat::Binary),
            "mavlink" => Some(InputFormat::Mavlink),
            _ => None,
        }
    }
}

/// One decoded state and the sequence number it carried, if its format has one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decoded {
    /// The sender's sequence number (binary: 32 bits, MAVLink: 8 bits).
    pub seq: Option<u64>,
    /// The state.
    pub state: LiveSample,
}

/// What the input's time tags are taken as.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeBase {
    /// As sent: simulation seconds, or GPS week and seconds counted from a GPS week (see
    /// [`Decoder`]); MAVLink's `time_usec` in seconds, whatever its origin.
    #[default]
    Sim,
    /// GPS time only: GPS week and seconds as on [`TimeBase::Sim`]; MAVLink's `time_usec` must
    /// be Unix time and is converted to GPS time; a tag in simulation seconds (or MAVLink time
    /// since boot) is refused.
    Gps,
}

/// MAVLink `time_usec` values above this (µs; 2001-09-09 as Unix time, 31 years as an
/// uptime) are Unix time, below it time since boot: the rule PX4 and ArduPilot apply to the
/// field the common message set defines as "UNIX Epoch time or time since system boot".
pub const UNIX_USEC_MIN: u64 = 1_000_000_000_000_000;

/// Microseconds in a GPS week.
const WEEK_US: i64 = 604_800_000_000;

/// A message that could not be decoded: what is wrong and where inside the message (byte
/// offset for binary formats, column for CSV).
#[derive(Clone, Debug, PartialEq)]
pub struct Malformed {
    /// Byte offset inside the message of the offending part (0 when the whole is wrong).
    pub offset: usize,
    /// What is wrong.
    pub message: String,
    /// The message is sound but its time tag does not fit the decoder's [`TimeBase`]: a
    /// setting of the sender or of the run is wrong, and every message will be refused, so
    /// the run stops rather than counting them.
    pub fatal: bool,
}

impl Malformed {
    fn at(offset: usize, message: impl Into<String>) -> Malformed {
        Malformed {
            offset,
            message: message.into(),
            fatal: false,
        }
    }

    fn time_base(offset: usize, message: impl Into<String>) -> Malformed {
        Malformed {
            fatal: true,
            ..Malformed::at(offset, message)
        }
    }
}

/// Seconds since the start of GPS week `epoch` of second `sow` of week `week`: the week
/// difference is an exact integer and `sow` keeps its own resolution, where GPS seconds since
/// 1980 (≈ 1.4e9) only resolve 2.4e-7 s in an f64.
pub fn since_week(week: u32, epoch: u32, sow: f64) -> f64 {
    (f64::from(week) - f64::from(epoch)) * 604_800.0 + sow
}

/// GPS week and microseconds of week of the Unix time `unix_us` (µs since 1970-01-01 UTC),
/// with GPS − UTC from `leap`; in integers, so no digit is lost.
pub fn unix_us_to_gps(unix_us: u64, leap: &LeapTable) -> (u32, i64) {
    let gps_us = leap
        .utc_to_gps_ns(i128::from(unix_us) * 1000)
        .div_euclid(1000) as i64;
    (
        gps_us.div_euclid(WEEK_US) as u32,
        gps_us.rem_euclid(WEEK_US),
    )
}

/// Decodes messages of one format on a [`TimeBase`]; the CSV decoder remembers the last
/// header. GPS time tags become seconds since the start of the decoder's epoch week: one
/// given, or the first GPS week seen.
pub struct Decoder {
    kind: Kind,
    base: TimeBase,
    epoch_week: Option<u32>,
}

enum Kind {
    Csv(Box<csv::CsvDecoder>),
    Binary,
    Mavlink,
}

impl Decoder {
    /// A decoder for `format` on the simulation time base; GPS time tags count from the
    /// first GPS week seen.
    pub fn new(format: InputFormat) -> Decoder {
        Decoder::with_base(format, TimeBase::Sim, None)
    }

    /// A decoder for `format` whose GPS time tags (binary week + seconds, CSV
    /// `gps_week,gps_sow`) become seconds since the start of GPS week `epoch_week`: exact to
    /// 1e-10 s, where seconds since 1980 in an f64 resolve only 2.4e-7 s.
    pub fn since_week(format: InputFormat, epoch_week: u32) -> Decoder {
        Decoder::with_base(format, TimeBase::Sim, Some(epoch_week))
    }

    /// A decoder for `format` on time base `base`, counting GPS time from the start of
    /// `epoch_week` (`None`: the first GPS week seen).
    pub fn with_base(format: InputFormat, base: TimeBase, epoch_week: Option<u32>) -> Decoder {
        let kind = match format {
            InputFormat::Csv => Kind::Csv(Box::default()),
            InputFormat::Binary => Kind::Binary,
            InputFormat::Mavlink => Kind::Mavlink,
        };
        Decoder {
            kind,
            base,
            epoch_week,
        }
    }

    /// True for CSV text (messages are lines).
    pub fn is_csv(&self) -> bool {
        matches!(self.kind, Kind::Csv(_))
    }

    /// The GPS week the states' times count from, once known (given, or the first GPS time
    /// tag's); `None` while the tags are simulation seconds.
    pub fn epoch_week(&self) -> Option<u32> {
        self.epoch_week
    }

    /// The state in one message (one CSV line, datagram or frame); `None` for a message that
    /// carries none (a CSV header, comment or blank line; another MAVLink message).
    pub fn decode(&mut self, msg: &[u8]) -> Result<Option<Decoded>, Malformed> {
        let (mut d, week) = match &mut self.kind {
            Kind::Csv(c) => match c.decode_tag(msg)? {
                Some(x) => x,
                None => return Ok(None),
            },
            Kind::Binary => binary::decode_tag(msg)?,
            Kind::Mavlink => match mavlink::decode(msg)? {
                Some(d) if self.base == TimeBase::Gps => {
                    return self.mavlink_gps(msg, d).map(Some);
                }
                Some(d) => (d, None),
                None => return Ok(None),
            },
        };
        match week {
            Some(w) => {
                let epoch = *self.epoch_week.get_or_insert(w);
                d.state.sample.t = since_week(w, epoch, d.state.sample.t);
            }
            None if self.base == TimeBase::Gps => {
                let (at, what) = match self.kind {
                    Kind::Csv(_) => (0, "CSV: gps_week,gps_sow instead of t"),
                    _ => (binary::WEEK, "binary: a GPS week, not 0xFFFF"),
                };
                return Err(Malformed::time_base(
                    at,
                    format!(
                        "the time tag {} is in simulation seconds: on the GPS time base (--time-base gps) the input's time tags must be GPS time ({what})",
                        d.state.sample.t
                    ),
                ));
            }
            None => {}
        }
        Ok(Some(d))
    }

    /// A MAVLink state on the GPS time base: its Unix `time_usec` in GPS time, from the start
    /// of the epoch week, counted in integer µs before the one rounding to seconds.
    fn mavlink_gps(&mut self, msg: &[u8], mut d: Decoded) -> Result<Decoded, Malformed> {
        let us = mavlink::time_usec(msg);
        if us < UNIX_USEC_MIN {
            return Err(Malformed::time_base(
                mavlink::HEADER,
                format!(
                    "time_usec {us} µs (sequence {}) is time since boot: on the GPS time base (--time-base gps) HIL_STATE_QUATERNION must carry Unix time (µs since 1970-01-01 UTC, above {UNIX_USEC_MIN}), which is converted to GPS time; or run on --time-base sim",
                    d.seq.unwrap_or(0)
                ),
            ));
        }
        static LEAP: OnceLock<LeapTable> = OnceLock::new();
        let (week, sow_us) = unix_us_to_gps(us, LEAP.get_or_init(LeapTable::builtin));
        let epoch = *self.epoch_week.get_or_insert(week);
        let us_since = (i64::from(week) - i64::from(epoch)) * WEEK_US + sow_us;
        d.state.sample.t = us_since as f64 / 1e6;
        Ok(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unix µs of 2026-12-02T06:00:00.123457 UTC: 1 796 191 200 s (20 789 days after
    /// 1970-01-01, by `calendar.timegm`) and 123 457 µs.
    const TODAY_US: u64 = 1_796_191_200_123_457;

    /// GPS time of three Unix instants, worked by hand. GPS − UTC is (TAI − UTC) − 19 s
    /// (IS-GPS-200 §3.3.4): 17 s until the leap second at the end of 2016, 18 s after it.
    /// * 2017-01-01T00:00:00 UTC (Unix 1 483 228 800): GPS seconds 1 483 228 800 − 315 964 800
    ///   + 18 = 1 167 264 018 = 1930·604 800 + 18 — week 1930 began that Sunday.
    /// * one Unix second before, 2016-12-31T23:59:59 (GPS − UTC still 17): 1 167 264 016, sow
    ///   16 (the leap second 23:59:60, sow 17, has no Unix time of its own).
    /// * 2026-12-02T06:00:00.123457 UTC, a Wednesday: 17 132 days after 1980-01-06 = 2447
    ///   weeks + 3 days, so sow = 3·86 400 + 6·3600 + 18 = 280 818 s and 123 457 µs.
    #[test]
    fn unix_time_converts_to_gps_week_and_seconds() {
        let leap = LeapTable::builtin();
        assert_eq!(
            unix_us_to_gps(1_483_228_800_000_000, &leap),
            (1930, 18_000_000)
        );
        assert_eq!(
            unix_us_to_gps(1_483_228_799_000_000, &leap),
            (1930, 16_000_000)
        );
        assert_eq!(unix_us_to_gps(TODAY_US, &leap), (2447, 280_818_123_457));
    }

    fn mavlink_at(seq: u8, time_usec: u64) -> Vec<u8> {
        let pos = [451_000_000, 75_000_000, 100_000];
        mavlink::encode(seq, time_usec, [1.0, 0.0, 0.0, 0.0], [0.0; 3], pos, [0; 3])
    }

    /// On the GPS time base a Unix `time_usec` becomes seconds since the start of the first
    /// GPS week seen, to the µs: 280 818.123 457 s, and a frame a week later 604 800 s more.
    /// Summing in f64 seconds (1.8e9 s: 2.4e-7 s apart) would miss the exact value. The sim
    /// base keeps the seconds as sent.
    #[test]
    fn mavlink_unix_time_on_the_gps_base() {
        let mut d = Decoder::with_base(InputFormat::Mavlink, TimeBase::Gps, None);
        let t = |d: &mut Decoder, seq, us| d.decode(&mavlink_at(seq, us)).unwrap().unwrap();
        assert_eq!(t(&mut d, 0, TODAY_US).state.sample.t, 280_818.123_457);
        assert_eq!(d.epoch_week(), Some(2447));
        let next_week = TODAY_US + 604_800_000_000 + 1;
        assert_eq!(
            t(&mut d, 1, next_week).state.sample.t,
            604_800.0 + 280_818.123_458
        );
        let mut given = Decoder::with_base(InputFormat::Mavlink, TimeBase::Gps, Some(2446));
        assert_eq!(
            t(&mut given, 0, TODAY_US).state.sample.t,
            604_800.0 + 280_818.123_457
        );
        let mut sim = Decoder::new(InputFormat::Mavlink);
        assert_eq!(
            t(&mut sim, 0, TODAY_US).state.sample.t,
            TODAY_US as f64 * 1e-6
        );
        assert_eq!(t(&mut sim, 0, 5_000_000).state.sample.t, 5.0);
        assert_eq!(sim.epoch_week(), None);
    }

    /// Time since boot on the GPS base, and simulation seconds in CSV or binary, are refused
    /// as fatal, naming the field's byte, the sequence number and what to send instead.
    #[test]
    fn gps_base_refuses_boot_time_and_simulation_seconds() {
        let mut d = Decoder::with_base(InputFormat::Mavlink, TimeBase::Gps, None);
        let e = d.decode(&mavlink_at(7, 5_000_000)).unwrap_err();
        assert!(e.fatal);
        assert_eq!(e.offset, mavlink::HEADER);
        assert!(
            e.message
                .contains("time_usec 5000000 µs (sequence 7) is time since boot")
        );
        assert!(e.message.contains("must carry Unix time"), "{e:?}");
        // Just above the threshold is Unix time (2001).
        assert!(d.decode(&mavlink_at(8, UNIX_USEC_MIN)).is_ok());

        let mut csv = Decoder::with_base(InputFormat::Csv, TimeBase::Gps, None);
        let e = csv.decode(b"1.5,45,7,1,1,2,3,0,0,90").unwrap_err();
        assert!(e.fatal && e.message.contains("must be GPS time (CSV: gps_week"));
        // A damaged line is not fatal.
        assert!(!csv.decode(b"1.5,45,x,1,1,2,3,0,0,90").unwrap_err().fatal);
        let mut w = binary::Datagram {
            seq: 0,
            week: binary::NO_WEEK,
            time: 1.5,
            flags: 0,
            pos: [45.0, 7.0, 1.0],
            vel: [0.0; 3],
            acc: [0.0; 3],
            quat: [1.0, 0.0, 0.0, 0.0],
            rate: [0.0; 3],
        };
        let mut bin = Decoder::with_base(InputFormat::Binary, TimeBase::Gps, None);
        let e = bin.decode(&binary::encode(&w)).unwrap_err();
        assert!(e.fatal && e.offset == binary::WEEK, "{e:?}");
        (w.week, w.time) = (2400, 0.25);
        assert_eq!(
            bin.decode(&binary::encode(&w))
                .unwrap()
                .unwrap()
                .state
                .sample
                .t,
            0.25
        );
    }

    /// Without a given week, GPS tags count from the first week seen, in any format; a later
    /// week adds whole weeks.
    #[test]
    fn gps_tags_count_from_the_first_week_seen() {
        let mut d = Decoder::new(InputFormat::Csv);
        assert_eq!(d.epoch_week(), None);
        d.decode(b"gps_week,gps_sow,lat,lon,h,vn,ve,vd,roll,pitch,yaw")
            .unwrap();
        let t = |d: &mut Decoder, line: &[u8]| d.decode(line).unwrap().unwrap().state.sample.t;
        assert_eq!(
            t(&mut d, b"2400,604799.000000125,45,7,1,1,2,3,0,0,90"),
            604_799.000_000_125
        );
        assert_eq!(d.epoch_week(), Some(2400));
        assert_eq!(
            t(&mut d, b"2401,0.000000125,45,7,1,1,2,3,0,0,90"),
            604_800.000_000_125
        );
    }
}
