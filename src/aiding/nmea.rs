//! NMEA 0183 sentences of a GNSS epoch: GGA (fix), RMC (minimum data), VTG (course and
//! speed), ZDA (date and time), GST (error statistics), talker `GP`, each ended by its XOR
//! checksum and CR LF (NMEA 0183 v4.11; the field lists as in the public gpsd NMEA reference,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>).
//!
//! Resolution: time 0.01 s, latitude and longitude 10⁻⁷ minute (≈ 0.2 mm), heights and
//! σ's 1 mm, speeds 0.001 kn and 0.001 km/h, courses 0.01°. No geoid model: the altitude
//! field holds the ellipsoidal height and the geoid separation is 0.

use std::fmt::Write as _;

use super::gnss::{Fix, GnssEpoch};
use super::time::{GpsTime, Utc};

/// Metres per second in one knot (1852 m per hour, exact).
pub const M_S_PER_KNOT: f64 = 1852.0 / 3600.0;

/// The sentences of one epoch, in the order GGA, RMC, VTG, ZDA, GST, appended to `out`.
pub fn encode(e: &GnssEpoch, time: GpsTime, leap: i64, out: &mut Vec<u8>) {
    let u = Utc::from_units(time.utc_units(leap, 100), 100);
    let hms = format!("{:02}{:02}{:02}.{:02}", u.hour, u.minute, u.second, u.sub);
    let m = &e.measured;
    let fix = e.fix.is_valid();
    let (lat, lon) = if fix {
        (
            angle(m.lat.to_degrees(), 2, ['N', 'S']),
            angle(m.lon.to_degrees(), 3, ['E', 'W']),
        )
    } else {
        (",".to_string(), ",".to_string())
    };
    let (sog, cog) = course(m.v_n.x, m.v_n.y);
    let blank = |s: String| if fix { s } else { String::new() };

    sentence(
        out,
        &format!(
            "GPGGA,{hms},{lat},{lon},{},{:02},{},{},M,0.0,M,,",
            gga_quality(e.fix),
            e.satellites,
            blank(format!("{:.2}", e.hdop)),
            blank(format!("{:.3}", m.h)),
        ),
    );
    let date = format!("{:02}{:02}{:02}", u.day, u.month, u.year.rem_euclid(100));
    let (sog_kn, cog_deg) = (
        blank(format!("{:.3}", sog / M_S_PER_KNOT)),
        blank(course_text(cog)),
    );
    sentence(
        out,
        &format!(
            "GPRMC,{hms},{},{lat},{lon},{sog_kn},{cog_deg},{date},,,{}",
            if fix { 'A' } else { 'V' },
            mode(e.fix),
        ),
    );
    sentence(
        out,
        &format!(
            "GPVTG,{cog_deg},T,,M,{sog_kn},N,{},K,{}",
            blank(format!("{:.3}", sog * 3.6)),
            mode(e.fix),
        ),
    );
    sentence(
        out,
        &format!(
            "GPZDA,{hms},{:02},{:02},{:04},00,00",
            u.day, u.month, u.year
        ),
    );
    let s = e.sigma_pos;
    let (major, minor, orient) = if s.x >= s.y {
        (s.x, s.y, 0.0)
    } else {
        (s.y, s.x, 90.0)
    };
    sentence(
        out,
        &format!(
            "GPGST,{hms},{},{},{},{},{},{},{}",
            blank(format!("{:.3}", e.uere)),
            blank(format!("{major:.3}")),
            blank(format!("{minor:.3}")),
            blank(format!("{orient:.1}")),
            blank(format!("{:.3}", s.x)),
            blank(format!("{:.3}", s.y)),
            blank(format!("{:.3}", s.z)),
        ),
    );
}

/// Ground speed (m/s) and course over ground (deg from true north, in [0, 360)).
pub fn course(v_north: f64, v_east: f64) -> (f64, f64) {
    let c = v_east.atan2(v_north).to_degrees();
    (v_north.hypot(v_east), if c < 0.0 { c + 360.0 } else { c })
}

/// `deg` (in [0, 360)) as NMEA prints a course, to 0.01°: rounded first and wrapped after, so a
/// course a rounding below 360° prints `0.00`, not `360.00` (which gpsd reads as 0 and others
/// as 360).
pub fn course_text(deg: f64) -> String {
    let hundredths = (deg * 100.0).round() as i64;
    let h = hundredths.rem_euclid(36_000);
    format!("{}.{:02}", h / 100, h % 100)
}

/// GGA fix quality: 0 invalid, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float.
pub fn gga_quality(f: Fix) -> u8 {
    match f {
        Fix::None => 0,
        Fix::Autonomous => 1,
        Fix::Differential => 2,
        Fix::RtkFixed => 4,
        Fix::RtkFloat => 5,
    }
}

/// RMC/VTG mode indicator (NMEA 2.3+): N none, A autonomous, D differential, R RTK fixed,
/// F RTK float.
pub fn mode(f: Fix) -> char {
    match f {
        Fix::None => 'N',
        Fix::Autonomous => 'A',
        Fix::Differential => 'D',
        Fix::RtkFixed => 'R',
        Fix::RtkFloat => 'F',
    }
}

/// `deg` as `D…DMM.MMMMMMM,H`, with `width` degree digits and hemisphere letters `[+, −]`;
/// rounded once in whole 10⁻⁷ minutes so that minutes never print as 60.
fn angle(deg: f64, width: usize, hemi: [char; 2]) -> String {
    const PER_MIN: u64 = 10_000_000;
    let units = (deg.abs() * 60.0 * PER_MIN as f64).round() as u64;
    let (d, rem) = (units / (60 * PER_MIN), units % (60 * PER_MIN));
    format!(
        "{d:0width$}{:02}.{:07},{}",
        rem / PER_MIN,
        rem % PER_MIN,
        hemi[usize::from(deg < 0.0)]
    )
}

/// `$body*CS\r\n` with CS the XOR of the body's bytes in two hex digits.
fn sentence(out: &mut Vec<u8>, body: &str) {
    let cs = body.bytes().fold(0u8, |a, b| a ^ b);
    let mut s = String::with_capacity(body.len() + 6);
    let _ = write!(s, "${body}*{cs:02X}\r\n");
    out.extend_from_slice(s.as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The GGA example of the gpsd NMEA reference, checksum 47.
    #[test]
    fn checksum_of_a_published_sentence() {
        let mut out = Vec::new();
        sentence(
            &mut out,
            "GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
        );
        assert_eq!(
            out,
            b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
        );
    }

    #[test]
    fn angles_round_once_and_carry() {
        assert_eq!(angle(48.1173, 2, ['N', 'S']), "4807.0380000,N");
        assert_eq!(angle(-11.5, 3, ['E', 'W']), "01130.0000000,W");
        // 0.99999999999° rounds to 1°00', not 0°60'.
        assert_eq!(angle(0.999_999_999_99, 2, ['N', 'S']), "0100.0000000,N");
    }

    #[test]
    fn course_quadrants() {
        let (s, c) = course(-1.0, -1.0);
        assert!((s - 2f64.sqrt()).abs() < 1e-15);
        assert!((c - 225.0).abs() < 1e-12);
        assert_eq!(course(0.0, 3.0), (3.0, 90.0));
    }

    /// A course a rounding west of north is in [0, 360) but prints as 360.00 at two decimals.
    #[test]
    fn a_course_just_below_north_prints_as_zero() {
        let (_, c) = course(10.0, -1e-9);
        assert!(c < 360.0 && c > 359.99);
        assert_eq!(course_text(c), "0.00");
        assert_eq!(course_text(359.994), "359.99");
        assert_eq!(course_text(0.0), "0.00");
        assert_eq!(course_text(225.0), "225.00");
    }
}
