//! GPS time of an epoch and the UTC calendar date and time receivers print.

/// Seconds in a GPS week.
pub const WEEK_S: i64 = 604_800;

/// Days from 1970-01-01 to the GPS epoch 1980-01-06.
const GPS_EPOCH_UNIX_DAYS: i64 = 3657;

/// A GPS time held as whole seconds since 1980-01-06 00:00:00 and a fraction in [0, 1), so
/// that sub-microsecond parts survive at any week number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpsTime {
    /// Whole seconds since the GPS epoch.
    pub secs: i64,
    /// Fraction of a second, in [0, 1).
    pub frac: f64,
}

impl GpsTime {
    /// Record time `t` (s) of a run whose time 0 is GPS week `week0`, second `sow0`.
    pub fn from_record(week0: u32, sow0: f64, t: f64) -> GpsTime {
        let x = sow0 + t;
        let w = x.floor();
        GpsTime {
            secs: week0 as i64 * WEEK_S + w as i64,
            frac: x - w,
        }
    }

    /// Time of week in milliseconds, rounded, in [0, 604 800 000).
    pub fn tow_ms(&self) -> u32 {
        let ms = self.secs.rem_euclid(WEEK_S) * 1000 + (self.frac * 1000.0).round() as i64;
        ms.rem_euclid(WEEK_S * 1000) as u32
    }

    /// UTC (GPS − `leap` s) as whole units of `1/per_s` seconds since the GPS epoch, rounded.
    pub fn utc_units(&self, leap: i64, per_s: i64) -> i64 {
        (self.secs - leap) * per_s + (self.frac * per_s as f64).round() as i64
    }
}

/// A UTC calendar instant with its sub-second part in units of `1/per_s` seconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Utc {
    /// Year.
    pub year: i64,
    /// Month, 1–12.
    pub month: u32,
    /// Day of the month, 1–31.
    pub day: u32,
    /// Hour, 0–23.
    pub hour: u32,
    /// Minute, 0–59.
    pub minute: u32,
    /// Second, 0–59.
    pub second: u32,
    /// Sub-second units, in [0, per_s).
    pub sub: i64,
}

impl Utc {
    /// From whole units of `1/per_s` s since the GPS epoch (as [`GpsTime::utc_units`] gives).
    pub fn from_units(units: i64, per_s: i64) -> Utc {
        let secs = units.div_euclid(per_s);
        let sub = units.rem_euclid(per_s);
        let days = secs.div_euclid(86_400);
        let sod = secs.rem_euclid(86_400) as u32;
        let (year, month, day) = civil_from_days(days + GPS_EPOCH_UNIX_DAYS);
        Utc {
            year,
            month,
            day,
            hour: sod / 3600,
            minute: sod / 60 % 60,
            second: sod % 60,
            sub,
        }
    }
}

/// Proleptic Gregorian (year, month, day) of day `z` since 1970-01-01: H. Hinnant's
/// `civil_from_days` ("chrono-Compatible Low-Level Date Algorithms", public domain).
pub fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calendar_anchors() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(GPS_EPOCH_UNIX_DAYS), (1980, 1, 6));
        // 2000-02-29 (a leap day of a century divisible by 400) is day 11 016.
        assert_eq!(civil_from_days(11_016), (2000, 2, 29));
        assert_eq!(civil_from_days(11_017), (2000, 3, 1));
    }

    /// The second GPS week-number rollover began 2019-04-07 00:00:00 GPS, which with 18 leap
    /// seconds is 2019-04-06 23:59:42 UTC (IS-GPS-200; IERS Bulletin C).
    #[test]
    fn week_2048_rollover_in_utc() {
        let g = GpsTime::from_record(2048, 0.0, 0.25);
        assert_eq!(g.tow_ms(), 250);
        let u = Utc::from_units(g.utc_units(18, 100), 100);
        assert_eq!(
            u,
            Utc {
                year: 2019,
                month: 4,
                day: 6,
                hour: 23,
                minute: 59,
                second: 42,
                sub: 25
            }
        );
    }

    /// A time that rounds up to the next whole second carries into the minute, hour and day
    /// instead of printing second 60.
    #[test]
    fn rounding_carries() {
        let g = GpsTime::from_record(2048, 18.0 - 0.001, 0.0);
        let u = Utc::from_units(g.utc_units(18, 100), 100);
        assert_eq!((u.day, u.hour, u.minute, u.second, u.sub), (7, 0, 0, 0, 0));
        assert_eq!(
            GpsTime::from_record(0, WEEK_S as f64 - 0.0001, 0.0).tow_ms(),
            0
        );
    }
}
