//! A GNSS stream: epochs encoded in one wire format, and the truth rows of the same epochs.

use std::fmt::Write as _;
use std::sync::OnceLock;

use super::gnss::{Fix, GnssEpoch};
use super::time::GpsTime;
use super::{mavlink, nmea, ubx};
use crate::timebase::{GPS_EPOCH_UNIX_S, LeapTable, TAI_MINUS_GPS_S};

/// A GNSS wire format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GnssFormat {
    /// NMEA 0183 GGA, RMC, VTG, ZDA and GST sentences per epoch.
    Nmea,
    /// u-blox UBX NAV-PVT, one frame per epoch.
    Ubx,
    /// MAVLink 2 HIL_GPS, one packet per epoch.
    Mavlink,
}

impl GnssFormat {
    /// Every format's name, as [`GnssFormat::from_name`] takes it.
    pub const NAMES: [&str; 3] = ["nmea", "ubx", "mavlink"];

    /// The format called `name` (`nmea`, `ubx`, `mavlink`).
    pub fn from_name(name: &str) -> Option<GnssFormat> {
        match name {
            "nmea" => Some(GnssFormat::Nmea),
            "ubx" => Some(GnssFormat::Ubx),
            "mavlink" => Some(GnssFormat::Mavlink),
            _ => None,
        }
    }
}

/// Encodes epochs of one run: its GPS time reference, leap seconds and packet sequence.
#[derive(Clone, Debug)]
pub struct GnssEncoder {
    format: GnssFormat,
    week0: u32,
    sow0: f64,
    leap: i64,
    seq: u8,
}

/// The built-in leap-second table, read once.
fn leap_table() -> &'static LeapTable {
    static TABLE: OnceLock<LeapTable> = OnceLock::new();
    TABLE.get_or_init(LeapTable::builtin)
}

/// GPS time (whole seconds since the GPS epoch) of the table's last leap second: from then on
/// GPS − UTC is what a receiver is told now, before it the table's value.
fn last_leap_gps_s(table: &LeapTable) -> i64 {
    let &(unix_s, tai_minus_utc) = table.steps.last().expect("the table has an entry");
    unix_s - GPS_EPOCH_UNIX_S + tai_minus_utc - TAI_MINUS_GPS_S
}

impl GnssEncoder {
    /// Frames in `format` for a run whose record time 0 is GPS week `week0`, second `sow0`;
    /// UTC = GPS − `leap_seconds` from the last leap second of the built-in table on (18 s since
    /// 2017-01-01), and before it GPS − UTC as the table has it: a run on week 0 (a run
    /// without a GPS time) is dated 1980-01-06 00:00:00 UTC, the GPS epoch, as its records'
    /// GPS time fields are, not 18 s before it.
    pub fn new(format: GnssFormat, week0: u32, sow0: f64, leap_seconds: i64) -> GnssEncoder {
        GnssEncoder {
            format,
            week0,
            sow0,
            leap: leap_seconds,
            seq: 0,
        }
    }

    /// The GPS time of record time `t`.
    pub fn gps_time(&self, t: f64) -> GpsTime {
        GpsTime::from_record(self.week0, self.sow0, t)
    }

    /// GPS − UTC (s) at GPS time `time` (see [`GnssEncoder::new`]).
    pub fn leap_at(&self, time: GpsTime) -> i64 {
        let table = leap_table();
        if time.secs >= last_leap_gps_s(table) {
            return self.leap;
        }
        let utc_ns = table.gps_to_utc_ns(i128::from(time.secs) * 1_000_000_000);
        table.gps_minus_utc(utc_ns.div_euclid(1_000_000_000) as i64)
    }

    /// Appends epoch `e`'s frames to `out`.
    pub fn encode(&mut self, e: &GnssEpoch, out: &mut Vec<u8>) {
        let time = self.gps_time(e.t);
        let leap = self.leap_at(time);
        match self.format {
            GnssFormat::Nmea => nmea::encode(e, time, leap, out),
            GnssFormat::Ubx => ubx::encode(e, time, leap, out),
            GnssFormat::Mavlink => {
                mavlink::encode(e, self.seq, out);
                self.seq = self.seq.wrapping_add(1);
            }
        }
    }
}

/// Header of the GNSS truth CSV: per epoch, the times, the fix, the true antenna state, the
/// reported one and the injected errors (NED), angles in degrees.
pub const TRUTH_HEADER: &str = "k,t,t_emit,fix,satellites,lat,lon,h,vn,ve,vd,\
meas_lat,meas_lon,meas_h,meas_vn,meas_ve,meas_vd,err_n,err_e,err_d,err_vn,err_ve,err_vd\n";

/// The truth CSV row of epoch `e` (shortest round-trip decimals), appended to `out`.
pub fn truth_row(e: &GnssEpoch, out: &mut String) {
    let (tr, m) = (&e.truth, &e.measured);
    let _ = write!(
        out,
        "{},{},{},{},{}",
        e.k,
        e.t,
        e.t_emit,
        fix_name(e.fix),
        e.satellites
    );
    for s in [tr, m] {
        let _ = write!(
            out,
            ",{},{},{}",
            s.lat.to_degrees(),
            s.lon.to_degrees(),
            s.h
        );
        for v in &s.v_n {
            let _ = write!(out, ",{v}");
        }
    }
    for v in e.pos_err_n.iter().chain(e.vel_err_n.iter()) {
        let _ = write!(out, ",{v}");
    }
    out.push('\n');
}

/// The truth file's name of a fix kind.
pub fn fix_name(f: Fix) -> &'static str {
    match f {
        Fix::None => "none",
        Fix::Autonomous => "autonomous",
        Fix::Differential => "differential",
        Fix::RtkFloat => "rtk-float",
        Fix::RtkFixed => "rtk-fixed",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aiding::gnss::AntennaState;
    use crate::math::Vec3;

    fn epoch(t: f64) -> GnssEpoch {
        let a = AntennaState {
            lat: 0.7,
            lon: 0.1,
            h: 100.0,
            v_n: Vec3::zeros(),
        };
        GnssEpoch {
            k: 0,
            t,
            t_emit: t,
            fix: Fix::Autonomous,
            satellites: 10,
            measured: a,
            truth: a,
            pos_err_n: Vec3::zeros(),
            vel_err_n: Vec3::zeros(),
            sigma_pos: Vec3::new(1.0, 1.0, 2.0),
            sigma_vel: Vec3::zeros(),
            hdop: 1.0,
            vdop: 1.5,
            uere: 2.0,
        }
    }

    /// The fields of the ZDA sentence of epoch `t` of a run at GPS week `week`, second `sow`.
    fn zda(week: u32, sow: f64, leap: i64, t: f64) -> String {
        let mut out = Vec::new();
        GnssEncoder::new(GnssFormat::Nmea, week, sow, leap).encode(&epoch(t), &mut out);
        let text = String::from_utf8(out).unwrap();
        let line = text.lines().find(|l| l.starts_with("$GPZDA")).unwrap();
        line.split(',')
            .skip(1)
            .take(4)
            .collect::<Vec<_>>()
            .join(",")
    }

    /// A run without a GPS time starts at week 0, the GPS epoch 1980-01-06 00:00:00, when GPS
    /// and UTC agreed: its NMEA date is that day (issue 23 item 8: 18 s before it,
    /// 1980-01-05 23:59:42, a date before GPS existed). Around the leap second at the end of
    /// 2016 (IERS Bulletin C 52) GPS − UTC is 17 s before and 18 s after; a receiver told of a
    /// leap second beyond the table (19 s) keeps it after the table's last one.
    #[test]
    fn utc_follows_the_leap_seconds_in_force() {
        assert_eq!(zda(0, 0.0, 18, 0.0), "000000.00,06,01,1980");
        assert_eq!(zda(0, 0.0, 18, 86_400.5), "000000.50,07,01,1980");
        // GPS week 1930, second 18 is 2017-01-01 00:00:00 UTC and second 16 is 2016-12-31
        // 23:59:59 UTC (worked in live::tests::unix_time_converts_to_gps_week_and_seconds).
        assert_eq!(zda(1930, 16.0, 18, 0.0), "235959.00,31,12,2016");
        assert_eq!(zda(1930, 18.0, 18, 0.0), "000000.00,01,01,2017");
        assert_eq!(zda(2447, 0.0, 19, 1.0), zda(2447, 0.0, 18, 0.0));
    }
}
