//! The host clock as a GPS-time source: CLOCK_TAI when the kernel knows the TAI offset (set by
//! a PTP or NTP daemon), else CLOCK_REALTIME plus the repository's leap-second table; and the
//! kernel's own estimate of the clock's error (`adjtimex`, read-only).

use nix::time::{ClockId, clock_gettime};

use super::clock::realtime_ns;
use crate::timebase::{GPS_EPOCH_UNIX_S, LeapTable, TAI_MINUS_GPS_S};

/// What the kernel says about its clock (`adjtimex(2)` with no modification).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KernelClock {
    /// Not `TIME_ERROR` and `STA_UNSYNC` clear: a daemon disciplines the clock.
    pub synchronised: bool,
    /// Estimated error (µs), as the disciplining daemon last set it.
    pub est_error_us: i64,
    /// Maximum error (µs).
    pub max_error_us: i64,
    /// TAI − UTC the kernel holds (s); 0 when no daemon set it.
    pub tai_offset_s: i64,
}

/// Reads the kernel clock status; `None` if the call fails.
pub fn kernel_clock() -> Option<KernelClock> {
    // Neither std nor nix wraps adjtimex. SAFETY: a zeroed `timex` is a valid value of this
    // plain C struct, `modes = 0` makes the call read-only, and the struct lives across it.
    let mut tx: libc::timex = unsafe { std::mem::zeroed() };
    // SAFETY: as above; the pointer is to our own struct.
    let rc = unsafe { libc::adjtimex(&mut tx) };
    if rc < 0 {
        return None;
    }
    Some(KernelClock {
        synchronised: rc != libc::TIME_ERROR && tx.status & libc::STA_UNSYNC == 0,
        est_error_us: tx.esterror as i64,
        max_error_us: tx.maxerror as i64,
        tai_offset_s: tx.tai as i64,
    })
}

/// GPS time from the host clock.
#[derive(Clone, Debug)]
pub struct GpsClock {
    leap: LeapTable,
    kernel: Option<KernelClock>,
}

impl GpsClock {
    /// The host's GPS clock with the leap-second table `leap`.
    pub fn new(leap: LeapTable) -> GpsClock {
        GpsClock {
            leap,
            kernel: kernel_clock(),
        }
    }

    /// True when the kernel's TAI offset is set, so CLOCK_TAI is used.
    pub fn uses_tai(&self) -> bool {
        self.kernel.is_some_and(|k| k.tai_offset_s > 0)
    }

    /// GPS − UTC (s) at the UTC instant `utc_ns`: from the kernel when it holds TAI − UTC,
    /// else from the table.
    pub fn gps_minus_utc(&self, utc_ns: i128) -> i64 {
        match self.kernel.filter(|k| k.tai_offset_s > 0) {
            Some(k) => k.tai_offset_s - TAI_MINUS_GPS_S,
            None => self
                .leap
                .gps_minus_utc(utc_ns.div_euclid(1_000_000_000) as i64),
        }
    }

    /// GPS time (ns since its epoch) of the UTC instant `utc_ns`.
    pub fn utc_to_gps_ns(&self, utc_ns: i128) -> i128 {
        utc_ns - GPS_EPOCH_UNIX_S as i128 * 1_000_000_000
            + self.gps_minus_utc(utc_ns) as i128 * 1_000_000_000
    }

    /// GPS time now (ns since its epoch).
    pub fn now_gps_ns(&self) -> i128 {
        if self.uses_tai()
            && let Ok(t) = clock_gettime(ClockId::CLOCK_TAI)
        {
            let tai = t.tv_sec() as i128 * 1_000_000_000 + t.tv_nsec() as i128;
            return tai - (GPS_EPOCH_UNIX_S + TAI_MINUS_GPS_S) as i128 * 1_000_000_000;
        }
        self.utc_to_gps_ns(realtime_ns())
    }

    /// A few words for the status line: the clock source and the kernel's error estimate.
    pub fn brief(&self) -> String {
        let source = if self.uses_tai() {
            "CLOCK_TAI"
        } else {
            "CLOCK_REALTIME"
        };
        match kernel_clock() {
            Some(k) if k.synchronised => format!(
                "{source} synchronised, estimated ±{} µs (bound {} µs)",
                k.est_error_us, k.max_error_us
            ),
            Some(k) => format!(
                "{source} not synchronised (uncertainty bound {} µs)",
                k.max_error_us
            ),
            None => format!("{source}, status unavailable"),
        }
    }

    /// One line for the user: the clock source, the leap seconds and the kernel's error
    /// estimate.
    pub fn describe(&self, utc_ns: i128) -> String {
        let leap = self.gps_minus_utc(utc_ns);
        let source = if self.uses_tai() {
            format!(
                "CLOCK_TAI (kernel TAI−UTC {} s), GPS−UTC {leap} s",
                leap + 19
            )
        } else {
            format!("CLOCK_REALTIME + leap-second table, GPS−UTC {leap} s")
        };
        let state = match self.kernel {
            Some(k) if k.synchronised => format!(
                "synchronised, estimated error {} µs (max {} µs)",
                k.est_error_us, k.max_error_us
            ),
            Some(_) => "NOT synchronised (kernel reports STA_UNSYNC): GPS time only as good as the free-running clock".into(),
            None => "kernel clock status unavailable".into(),
        };
        format!("{source}; {state}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The host's GPS time is its UTC plus 18 s (the table, or the kernel's TAI offset when a
    /// daemon set it) minus the epoch, within the microseconds between the two readings.
    #[test]
    fn gps_now_is_utc_plus_leap() {
        let c = GpsClock::new(LeapTable::builtin());
        let gps = |u: i128| u - GPS_EPOCH_UNIX_S as i128 * 1_000_000_000 + 18_000_000_000;
        // Between the UTC readings taken around it.
        let u0 = realtime_ns();
        let g = c.now_gps_ns();
        let u = realtime_ns();
        assert!(
            (gps(u0)..=gps(u)).contains(&g),
            "{g} not in [{}, {}]",
            gps(u0),
            gps(u)
        );
        assert!(c.describe(u).contains("GPS−UTC 18 s"), "{}", c.describe(u));
    }
}
