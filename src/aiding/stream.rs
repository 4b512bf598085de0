//! A GNSS stream: epochs encoded in one wire format, and the truth rows of the same epochs.

use std::fmt::Write as _;

use super::gnss::{Fix, GnssEpoch};
use super::time::GpsTime;
use super::{mavlink, nmea, ubx};

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

impl GnssEncoder {
    /// Frames in `format` for a run whose record time 0 is GPS week `week0`, second `sow0`;
    /// UTC = GPS − `leap_seconds`.
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

    /// Appends epoch `e`'s frames to `out`.
    pub fn encode(&mut self, e: &GnssEpoch, out: &mut Vec<u8>) {
        let time = self.gps_time(e.t);
        match self.format {
            GnssFormat::Nmea => nmea::encode(e, time, self.leap, out),
            GnssFormat::Ubx => ubx::encode(e, time, self.leap, out),
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
