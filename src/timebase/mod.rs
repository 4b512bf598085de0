//! Time bases: UTC instants (RFC 3339), GPS time (week and seconds of week) and the leap
//! seconds between them, from the table `src/timebase/leap-seconds.txt` embedded at build
//! time. Pure: the host clock is read in `realtime::hostclock`.
//!
//! GPS time started at 1980-01-06T00:00:00 UTC and has no leap seconds, so
//! GPS − UTC = (TAI − UTC) − 19 s (IS-GPS-200, §3.3.4; 18 s since 2017-01-01).

/// The leap-second table as shipped (see its header for how to update it).
pub const LEAP_SECONDS: &str = include_str!("leap-seconds.txt");

/// Unix time (s) of the GPS epoch, 1980-01-06T00:00:00 UTC.
pub const GPS_EPOCH_UNIX_S: i64 = 315_964_800;

/// Seconds in a GPS week.
pub const WEEK_S: i64 = 604_800;

/// TAI − GPS (s): constant by the definition of GPS time.
pub const TAI_MINUS_GPS_S: i64 = 19;

/// TAI − UTC from each UTC instant on, and until when the table is known to hold.
#[derive(Clone, Debug, PartialEq)]
pub struct LeapTable {
    /// (Unix time of the change (s), TAI − UTC from then on (s)), in order.
    pub steps: Vec<(i64, i64)>,
    /// Unix time (s) up to which no further leap second is announced.
    pub valid_until: i64,
}

impl LeapTable {
    /// The table embedded in the binary.
    pub fn builtin() -> LeapTable {
        LeapTable::parse(LEAP_SECONDS).expect("the shipped table parses (a test checks it)")
    }

    /// Parses a table: `YYYY-MM-DD  N` lines in order, one `valid-until YYYY-MM-DD`, `#`
    /// comments; errors name the line.
    pub fn parse(text: &str) -> Result<LeapTable, String> {
        let mut steps: Vec<(i64, i64)> = Vec::new();
        let mut valid_until = None;
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let bad = |what: &str| format!("leap-second table line {}: {what}: `{line}`", i + 1);
            let mut words = line.split_whitespace();
            let (a, b) = (words.next(), words.next());
            if words.next().is_some() {
                return Err(bad("expected two fields"));
            }
            let day = |d: &str| {
                parse_utc(&format!("{d}T00:00:00Z")).map(|ns| (ns / 1_000_000_000) as i64)
            };
            match (a, b) {
                (Some("valid-until"), Some(d)) => {
                    valid_until = Some(day(d).map_err(|_| bad("expected a date YYYY-MM-DD"))?)
                }
                (Some(d), Some(n)) => {
                    let t = day(d).map_err(|_| bad("expected a date YYYY-MM-DD"))?;
                    let n: i64 = n.parse().map_err(|_| bad("expected whole seconds"))?;
                    if steps.last().is_some_and(|l| l.0 >= t) {
                        return Err(bad("dates must increase"));
                    }
                    steps.push((t, n));
                }
                _ => return Err(bad("expected `YYYY-MM-DD N` or `valid-until YYYY-MM-DD`")),
            }
        }
        let valid_until = valid_until.ok_or("leap-second table: no `valid-until` line")?;
        if steps.is_empty() {
            return Err("leap-second table: no entry".into());
        }
        Ok(LeapTable { steps, valid_until })
    }

    /// TAI − UTC (s) at Unix time `unix_s` (the first entry's value before it).
    pub fn tai_minus_utc(&self, unix_s: i64) -> i64 {
        let i = self.steps.partition_point(|s| s.0 <= unix_s);
        self.steps[i.saturating_sub(1)].1
    }

    /// GPS − UTC (s) at Unix time `unix_s`.
    pub fn gps_minus_utc(&self, unix_s: i64) -> i64 {
        self.tai_minus_utc(unix_s) - TAI_MINUS_GPS_S
    }

    /// GPS time (ns since the GPS epoch) of the UTC instant `utc_ns` (ns since the Unix epoch).
    pub fn utc_to_gps_ns(&self, utc_ns: i128) -> i128 {
        let leap = self.gps_minus_utc(utc_ns.div_euclid(1_000_000_000) as i64) as i128;
        utc_ns - GPS_EPOCH_UNIX_S as i128 * 1_000_000_000 + leap * 1_000_000_000
    }

    /// The UTC instant (ns since the Unix epoch) of GPS time `gps_ns` (ns since its epoch).
    pub fn gps_to_utc_ns(&self, gps_ns: i128) -> i128 {
        let approx = gps_ns + GPS_EPOCH_UNIX_S as i128 * 1_000_000_000;
        // The offset at the UTC instant, found from the GPS one: equal except within the
        // leap seconds' own few seconds, where the second look settles it.
        let first = approx
            - self.gps_minus_utc(approx.div_euclid(1_000_000_000) as i64) as i128 * 1_000_000_000;
        approx - self.gps_minus_utc(first.div_euclid(1_000_000_000) as i64) as i128 * 1_000_000_000
    }
}

/// GPS week and seconds of week of GPS time `gps_ns` (ns since the GPS epoch).
pub fn week_sow(gps_ns: i128) -> (u32, f64) {
    let week_ns = WEEK_S as i128 * 1_000_000_000;
    let week = gps_ns.div_euclid(week_ns);
    (week as u32, gps_ns.rem_euclid(week_ns) as f64 / 1e9)
}

/// When to start: an instant (UTC ns since the Unix epoch) from `--start-at`: `next-second`
/// (the next whole second after `now_utc_ns`, the same instant in UTC and GPS time since the
/// offset is whole seconds), RFC 3339 with `Z` or a `±hh:mm` offset, or `gps:WEEK:SECONDS`.
pub fn parse_start(s: &str, now_utc_ns: i128, leap: &LeapTable) -> Result<i128, String> {
    if s == "next-second" {
        return Ok((now_utc_ns.div_euclid(1_000_000_000) + 1) * 1_000_000_000);
    }
    if let Some(rest) = s.strip_prefix("gps:") {
        let bad = || format!("`{s}`: expected gps:WEEK:SECONDS_OF_WEEK, e.g. gps:2395:345600");
        let (w, sow) = rest.split_once(':').ok_or_else(bad)?;
        let w: i128 = w.parse().map_err(|_| bad())?;
        let sow: f64 = sow.parse().map_err(|_| bad())?;
        if !(0.0..WEEK_S as f64).contains(&sow) {
            return Err(format!("`{s}`: seconds of week must be in [0, 604800)"));
        }
        let gps = w * WEEK_S as i128 * 1_000_000_000 + (sow * 1e9).round() as i128;
        return Ok(leap.gps_to_utc_ns(gps));
    }
    // A numeric offset `±hh:mm` at the end: the local time minus the offset is UTC.
    let n = s.len();
    if n > 6
        && s.is_char_boundary(n - 6)
        && matches!(&s[n - 6..n - 5], "+" | "-")
        && &s[n - 3..n - 2] == ":"
    {
        let (local, off) = s.split_at(n - 6);
        let bad = || format!("`{s}`: offset `{off}`: expected ±hh:mm");
        let (h, m) = (
            off[1..3].parse::<i128>().map_err(|_| bad())?,
            off[4..6].parse::<i128>().map_err(|_| bad())?,
        );
        if h > 23 || m > 59 {
            return Err(bad());
        }
        let sign = if off.starts_with('-') { -1 } else { 1 };
        let t = parse_utc(&format!("{local}Z"))?;
        return Ok(t - sign * (h * 3600 + m * 60) * 1_000_000_000);
    }
    parse_utc(s)
}

/// Parses an RFC 3339 UTC instant `YYYY-MM-DDTHH:MM:SS[.fff…]Z` to ns since the Unix epoch.
pub fn parse_utc(s: &str) -> Result<i128, String> {
    let bad = || format!("`{s}`: expected a UTC instant like 2026-11-24T15:00:00.000Z");
    let body = s
        .strip_suffix('Z')
        .or(s.strip_suffix('z'))
        .ok_or_else(bad)?;
    let (date, time) = body.split_once(['T', 't', ' ']).ok_or_else(bad)?;
    let num = |x: &str| -> Result<i64, String> {
        if x.is_empty() || !x.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        x.parse().map_err(|_| bad())
    };
    let d: Vec<&str> = date.split('-').collect();
    let t: Vec<&str> = time.split(':').collect();
    if d.len() != 3 || t.len() != 3 || d[0].len() != 4 {
        return Err(bad());
    }
    let (y, mo, day) = (num(d[0])?, num(d[1])?, num(d[2])?);
    let (sec, frac) = t[2].split_once('.').unwrap_or((t[2], ""));
    let (h, mi, sec) = (num(t[0])?, num(t[1])?, num(sec)?);
    let month_days = [
        31,
        28 + leap(y) as i64,
        31,
        30,
        31,
        30,
        31,
        31,
        30,
        31,
        30,
        31,
    ];
    if !(1..=12).contains(&mo) || day < 1 || day > month_days[mo as usize - 1] {
        return Err(format!("`{s}`: no such date"));
    }
    if h > 23 || mi > 59 || sec > 59 || frac.len() > 9 {
        return Err(format!("`{s}`: time of day out of range"));
    }
    let frac_ns = if frac.is_empty() {
        0
    } else {
        num(frac)? * 10i64.pow(9 - frac.len() as u32)
    };
    let days = days_from_civil(y, mo, day);
    Ok(((days * 86_400 + h * 3600 + mi * 60 + sec) as i128) * 1_000_000_000 + frac_ns as i128)
}

fn leap(y: i64) -> bool {
    (y % 4 == 0 && y % 100 != 0) || y % 400 == 0
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Parses a GPS time written `WEEK,SECONDS` (seconds of week in [0, 604800)), as the command
/// line's `--gps-time` takes it.
pub fn parse_week_seconds(s: &str) -> Result<(u32, f64), String> {
    let (w, sow) = s
        .split_once(',')
        .ok_or("expected WEEK,SECONDS_OF_WEEK, e.g. 2209,491674.0")?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("week `{w}` is not a whole number"))?;
    let sow: f64 = sow
        .trim()
        .parse()
        .map_err(|_| format!("seconds `{sow}` is not a number"))?;
    if !(0.0..604_800.0).contains(&sow) {
        return Err(format!("seconds of week {sow} outside [0, 604800)"));
    }
    Ok((w, sow))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn week_and_seconds_read_and_refuse_by_part() {
        assert_eq!(parse_week_seconds("2209, 491674.5"), Ok((2209, 491_674.5)));
        assert!(
            parse_week_seconds("2209")
                .unwrap_err()
                .contains("WEEK,SECONDS_OF_WEEK")
        );
        assert!(
            parse_week_seconds("-1,0")
                .unwrap_err()
                .contains("week `-1`")
        );
        assert!(
            parse_week_seconds("1,x")
                .unwrap_err()
                .contains("seconds `x`")
        );
        assert!(
            parse_week_seconds("1,604800")
                .unwrap_err()
                .contains("outside [0, 604800)")
        );
    }

    /// Known epoch offsets (`date -u -d … +%s`) and the fraction's digits.
    #[test]
    fn utc_instants() {
        assert_eq!(parse_utc("1970-01-01T00:00:00Z"), Ok(0));
        assert_eq!(
            parse_utc("1980-01-06T00:00:00Z"),
            Ok(GPS_EPOCH_UNIX_S as i128 * 1_000_000_000)
        );
        for bad in ["2026-11-24T15:00:00", "2026-02-29T00:00:00Z", "x"] {
            assert!(parse_utc(bad).is_err(), "{bad}");
        }
    }

    /// The shipped table: 18 s since 2017-01-01, 17 s the second before, 0 at the GPS epoch
    /// (TAI − UTC was 19 s then); bad tables are refused naming the line.
    #[test]
    fn leap_seconds() {
        let t = LeapTable::builtin();
        let jan2017 = 1_483_228_800;
        assert_eq!(t.gps_minus_utc(jan2017), 18);
        assert_eq!(t.gps_minus_utc(jan2017 - 1), 17);
        assert_eq!(t.gps_minus_utc(GPS_EPOCH_UNIX_S), 0);
        assert_eq!(t.valid_until, 1_798_416_000); // 2026-12-28 00:00 UTC
        let e =
            LeapTable::parse("2017-01-01 37\n2016-01-01 36\nvalid-until 2026-01-01\n").unwrap_err();
        assert!(e.contains("line 2") && e.contains("increase"), "{e}");
        let e = LeapTable::parse("2017-13-01 37\n").unwrap_err();
        assert!(e.contains("line 1"), "{e}");
        assert!(
            LeapTable::parse("2017-01-01 37\n")
                .unwrap_err()
                .contains("valid-until")
        );
    }

    /// GPS week and seconds of week of 2026-11-24T15:00:00Z: Unix 1 795 532 400 s, minus the
    /// GPS epoch 315 964 800 s, plus 18 s = 1 479 567 618 s = week 2446, 226 818 s (2446·604 800
    /// = 1 479 340 800). Round trip back to UTC, also across the 2016-12-31 leap second.
    #[test]
    fn gps_week_and_back() {
        let t = LeapTable::builtin();
        let utc = 1_795_532_400i128 * 1_000_000_000;
        let gps = t.utc_to_gps_ns(utc);
        assert_eq!(week_sow(gps), (2446, 226_818.0));
        assert_eq!(t.gps_to_utc_ns(gps), utc);
        for s in [1_483_228_799i128, 1_483_228_800, 1_483_228_801] {
            let u = s * 1_000_000_000;
            assert_eq!(t.gps_to_utc_ns(t.utc_to_gps_ns(u)), u, "{s}");
        }
    }

    /// `--start-at` forms: next-second, offsets, GPS week/seconds; bad ones refused.
    #[test]
    fn start_instants() {
        let t = LeapTable::builtin();
        let now = 1_795_532_400_250_000_000i128;
        assert_eq!(
            parse_start("next-second", now, &t),
            Ok(1_795_532_401_000_000_000)
        );
        let z = parse_start("2026-11-24T15:00:00Z", now, &t).unwrap();
        assert_eq!(parse_start("2026-11-24T16:30:00+01:30", now, &t), Ok(z));
        assert_eq!(parse_start("2026-11-24T10:00:00-05:00", now, &t), Ok(z));
        assert_eq!(parse_start("gps:2446:226818", now, &t), Ok(z));
        for bad in [
            "gps:2446",
            "gps:x:1",
            "gps:2446:700000",
            "2026-11-24T15:00:00+25:00",
            "soon",
        ] {
            assert!(parse_start(bad, now, &t).is_err(), "{bad}");
        }
    }
}
