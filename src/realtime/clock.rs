//! Clocks: monotonic nanoseconds for deadlines, UTC instants for `--start-at`.

use nix::sys::time::TimeSpec;
use nix::time::{ClockId, ClockNanosleepFlags, clock_gettime, clock_nanosleep};

/// CLOCK_MONOTONIC now (ns).
pub fn monotonic_ns() -> i128 {
    ns(clock_gettime(ClockId::CLOCK_MONOTONIC).expect("CLOCK_MONOTONIC is always available"))
}

/// CLOCK_REALTIME now (ns since the Unix epoch).
pub fn realtime_ns() -> i128 {
    ns(clock_gettime(ClockId::CLOCK_REALTIME).expect("CLOCK_REALTIME is always available"))
}

fn ns(t: TimeSpec) -> i128 {
    t.tv_sec() as i128 * 1_000_000_000 + t.tv_nsec() as i128
}

/// Sleeps until CLOCK_MONOTONIC reaches `deadline` (ns): an absolute deadline, so time spent
/// between wake-ups never accumulates. Returns at once if the deadline has passed.
pub fn sleep_until(deadline: i128) {
    let t = TimeSpec::new(
        (deadline.div_euclid(1_000_000_000)) as _,
        (deadline.rem_euclid(1_000_000_000)) as _,
    );
    // EINTR (a signal) just means "check the clock and sleep again".
    while clock_nanosleep(
        ClockId::CLOCK_MONOTONIC,
        ClockNanosleepFlags::TIMER_ABSTIME,
        &t,
    )
    .is_err()
    {
        if monotonic_ns() >= deadline {
            break;
        }
    }
}

/// Converts a UTC instant (ns since the Unix epoch) to CLOCK_MONOTONIC, through the current
/// offset between the two clocks.
pub fn utc_to_monotonic(utc_ns: i128) -> i128 {
    let (r, m) = (realtime_ns(), monotonic_ns());
    m + (utc_ns - r)
}

/// The CLOCK_MONOTONIC instant of `--start-at` `utc_ns`, which must still be ahead: frames
/// due before the run began cannot be sent at their time, and skipping them would leave a
/// receiver aligned on the instant with nothing it can use.
pub fn start_at(utc_ns: i128) -> Result<i128, String> {
    let ahead = utc_ns - realtime_ns();
    if ahead <= 0 {
        return Err(format!(
            "the instant is {:.3} s in the past: give one in the future (a few seconds ahead leaves time to start every emulator)",
            -ahead as f64 / 1e9
        ));
    }
    Ok(utc_to_monotonic(utc_ns))
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Known epoch offsets (`date -u -d … +%s`) and the fraction's digits.
    #[test]
    fn utc_instants() {
        assert_eq!(parse_utc("1970-01-01T00:00:00Z"), Ok(0));
        assert_eq!(
            parse_utc("2026-11-24T15:00:00Z"),
            Ok(1_795_532_400 * 1_000_000_000)
        );
        assert_eq!(
            parse_utc("2000-02-29T23:59:59.25Z"),
            Ok(951_868_799 * 1_000_000_000 + 250_000_000)
        );
        for bad in [
            "2026-11-24T15:00:00",
            "2026-02-29T00:00:00Z",
            "2026-11-24T24:00:00Z",
            "x",
            "2026-11-24T15:00:00.1234567890Z",
        ] {
            assert!(parse_utc(bad).is_err(), "{bad}");
        }
    }

    /// An instant ahead maps to the monotonic clock at the current offset; one behind is
    /// refused, saying how far behind.
    #[test]
    fn start_at_future_only() {
        let ahead = realtime_ns() + 2_000_000_000;
        let m = start_at(ahead).unwrap() - monotonic_ns();
        assert!((1_000_000_000..=2_000_000_000).contains(&m), "{m}");
        let e = start_at(realtime_ns() - 5_000_000_000).unwrap_err();
        assert!(e.contains("5.0") && e.contains("in the past"), "{e}");
    }
}
