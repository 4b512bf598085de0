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

/// Converts a UTC instant (ns since the Unix epoch) to CLOCK_MONOTONIC, through the
/// process's one reading of the offset between the two clocks ([`host_offset`]).
pub fn utc_to_monotonic(utc_ns: i128) -> i128 {
    utc_ns - host_offset().utc_minus_mono
}

/// The offset between the host's UTC and monotonic clocks as this process uses it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HostOffset {
    /// CLOCK_REALTIME − CLOCK_MONOTONIC (ns).
    pub utc_minus_mono: i128,
    /// Half the width of the bracket it was read in (ns): the true offset at that reading is
    /// within this of `utc_minus_mono`.
    pub within_ns: i128,
}

/// CLOCK_REALTIME − CLOCK_MONOTONIC, read once per process ([`read_offset`]): every UTC or GPS
/// instant a run converts (a `--start-at`, a GPS time base, time marks) uses the same reading,
/// so they agree with each other to the nanosecond, and each is within
/// [`HostOffset::within_ns`] of the clocks' true offset. The offset moves only when the realtime
/// clock is stepped: the kernel slews both clocks alike.
pub fn host_offset() -> HostOffset {
    static OFFSET: std::sync::OnceLock<HostOffset> = std::sync::OnceLock::new();
    *OFFSET.get_or_init(read_offset)
}

/// A few words for logs: how well the run's UTC and GPS instants sit on the host clocks.
pub fn describe_offset() -> String {
    format!(
        "host clocks: UTC − monotonic read to ±{} ns",
        host_offset().within_ns
    )
}

/// CLOCK_REALTIME − CLOCK_MONOTONIC now (ns). One CLOCK_MONOTONIC read is bracketed by two
/// CLOCK_REALTIME reads, a few times, and the tightest bracket's midpoint is kept: a process
/// preempted between two plain reads (milliseconds on a loaded host) would otherwise carry the
/// preemption into every instant it converts, so that two emulators started on the same
/// `--start-at` second would disagree by it.
pub fn utc_minus_monotonic() -> i128 {
    read_offset().utc_minus_mono
}

/// A fresh reading of [`HostOffset`]: the tightest of a few brackets (see
/// [`utc_minus_monotonic`]); its half-width is the reading's uncertainty.
pub fn read_offset() -> HostOffset {
    let mut best: Option<(i128, i128)> = None;
    for _ in 0..5 {
        let r0 = realtime_ns();
        let m = monotonic_ns();
        let r1 = realtime_ns();
        let width = r1 - r0;
        // A negative width is a step of the realtime clock between the reads: not a bracket.
        if width >= 0 && best.is_none_or(|b| width < b.0) {
            best = Some((width, r0 + width / 2 - m));
        }
    }
    match best {
        Some((width, off)) => HostOffset {
            utc_minus_mono: off,
            within_ns: (width + 1) / 2,
        },
        // Every reading saw a step: read again, plainly, and say nothing of its bounds.
        None => HostOffset {
            utc_minus_mono: realtime_ns() - monotonic_ns(),
            within_ns: i128::MAX,
        },
    }
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

/// Parses an RFC 3339 UTC instant `YYYY-MM-DDTHH:MM:SS[.fff…]Z` to ns since the Unix epoch
/// ([`crate::timebase::parse_utc`]).
pub fn parse_utc(s: &str) -> Result<i128, String> {
    crate::timebase::parse_utc(s)
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

    /// An instant ahead maps to the monotonic clock at the process's offset, within the
    /// reading's bracket of where the clocks stood when it was given; one behind is refused,
    /// saying how far behind.
    #[test]
    fn start_at_future_only() {
        let w = host_offset().within_ns;
        let m0 = monotonic_ns();
        let ahead = realtime_ns() + 2_000_000_000;
        let m = start_at(ahead).unwrap();
        let m1 = monotonic_ns();
        assert!(
            (m0 + 2_000_000_000 - w..=m1 + 2_000_000_000 + w).contains(&m),
            "{m} not in [{m0}, {m1}] + 2 s ± {w} ns"
        );
        let e = start_at(realtime_ns() - 5_000_000_000).unwrap_err();
        assert!(e.contains("5.0") && e.contains("in the past"), "{e}");
    }

    /// The offset is the two clocks' difference to within its bracket: two readings agree to
    /// the sum of their half-widths (the offset moves only when the realtime clock is
    /// stepped), and an instant converted lies between the monotonic readings taken around
    /// it, ± the process's reading's half-width.
    #[test]
    fn offset_between_the_clocks() {
        let (a, b) = (read_offset(), read_offset());
        assert!(
            (a.utc_minus_mono - b.utc_minus_mono).abs() <= a.within_ns + b.within_ns,
            "{a:?} then {b:?}"
        );
        let w = host_offset().within_ns;
        let m0 = monotonic_ns();
        let m = utc_to_monotonic(realtime_ns());
        let m1 = monotonic_ns();
        assert!(
            (m0 - w..=m1 + w).contains(&m),
            "{m} not in [{m0}, {m1}] ± {w}"
        );
    }
}
