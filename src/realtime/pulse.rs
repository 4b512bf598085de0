//! Pulse output: a time-of-validity or PPS pulse on a serial port's RTS or DTR modem line, as
//! real IMUs drive a receiver's event input (the KVH 1750/1775 technical manuals specify a
//! time-of-validity pulse per sample; NovAtel's SETIMUEVENT command takes such a pulse on an
//! event input). The edges run on their own thread, sleeping to absolute instants like the
//! pacer; the line is behind the [`Line`] trait so tests record the edges a real port would
//! carry.

use std::io;
use std::os::fd::{AsRawFd, OwnedFd};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;

use super::clock::{monotonic_ns, sleep_until};
use super::hook::{FrameHook, FrameTime};
use super::lock::Schedule;

/// A modem control line that can be raised and lowered.
pub trait Line: Send {
    /// Raises (`true`) or lowers the line.
    fn set(&mut self, high: bool) -> io::Result<()>;
}

/// Which modem line carries the pulse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pin {
    /// Request To Send.
    Rts,
    /// Data Terminal Ready.
    Dtr,
}

/// When the pulse rises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    /// At every sample's time of validity.
    Tov,
    /// At the time of validity of the first sample at or after each whole second of the
    /// records' time axis (with `--time-base gps`, whole GPS seconds).
    Pps,
}

/// A parsed `--pulse rts|dtr:tov|pps[:OFFSET][:WIDTH]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PulseSpec {
    /// The line.
    pub pin: Pin,
    /// What the pulse marks.
    pub mark: Mark,
    /// Rising edge after the marked instant (ns, may be negative).
    pub offset_ns: i64,
    /// High time (ns).
    pub width_ns: i64,
}

/// Default pulse width: 10 % of a 200 Hz sample interval, the duty cycle KVH's manuals give
/// for their time-of-validity pulse.
pub const DEFAULT_WIDTH_NS: i64 = 500_000;

impl std::str::FromStr for PulseSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<PulseSpec, String> {
        let usage = "expected LINE:MARK[:OFFSET][:WIDTH] with LINE rts or dtr, MARK tov or pps, times like 0, 250us, -1ms";
        let mut it = s.split(':');
        let pin = match it.next() {
            Some("rts") => Pin::Rts,
            Some("dtr") => Pin::Dtr,
            other => return Err(format!("line `{}`: {usage}", other.unwrap_or(""))),
        };
        let mark = match it.next() {
            Some("tov") => Mark::Tov,
            Some("pps") => Mark::Pps,
            other => return Err(format!("mark `{}`: {usage}", other.unwrap_or(""))),
        };
        let time = |name: &str, v: Option<&str>, default: i64| -> Result<i64, String> {
            match v {
                None => Ok(default),
                Some(v) => parse_time_ns(v).ok_or_else(|| format!("{name} `{v}`: {usage}")),
            }
        };
        let offset_ns = time("offset", it.next(), 0)?;
        let width_ns = time("width", it.next(), DEFAULT_WIDTH_NS)?;
        if let Some(extra) = it.next() {
            return Err(format!("`{extra}` after the width: {usage}"));
        }
        if width_ns <= 0 {
            return Err(format!("width `{width_ns} ns`: expected a positive time"));
        }
        Ok(PulseSpec {
            pin,
            mark,
            offset_ns,
            width_ns,
        })
    }
}

/// A time like `250us`, `-1ms`, `0.5 s` or `0` (a unit of [`crate::units::Kind::Time`]
/// required unless zero) to whole ns; `None` if malformed.
pub fn parse_time_ns(v: &str) -> Option<i64> {
    let split = v.find(|c: char| c.is_alphabetic()).unwrap_or(v.len());
    let (num, unit) = v.split_at(split);
    if unit.is_empty() {
        return (num.trim().parse::<f64>().ok()? == 0.0).then_some(0);
    }
    let s = crate::units::parse(&format!("{} {unit}", num.trim()), crate::units::Kind::Time)
        .ok()?
        .0;
    (s.abs() < 1e6).then(|| (s * 1e9).round() as i64)
}

impl PulseSpec {
    /// Checks the pulse fits the frames: a rising edge every `interval_ns` at most, so the
    /// width must leave the line low between pulses.
    pub fn check(&self, interval_ns: f64) -> Result<(), String> {
        let period = match self.mark {
            Mark::Tov => interval_ns,
            Mark::Pps => 1e9,
        };
        if self.width_ns as f64 >= period {
            return Err(format!(
                "width {} µs is not shorter than the {} µs between pulses",
                self.width_ns as f64 / 1e3,
                period / 1e3
            ));
        }
        Ok(())
    }

    /// The rising edge (CLOCK_MONOTONIC ns) for frame `f`, if it carries a pulse; `prev_tov`
    /// is the previous frame's time of validity on the records' axis.
    pub fn edge(&self, f: &FrameTime, prev_tov_sim_ns: Option<i64>) -> Option<i128> {
        let marked = match self.mark {
            Mark::Tov => true,
            // A whole second in (previous ToV, this ToV]; the first frame marks t₀'s second
            // only when it falls on it.
            Mark::Pps => {
                let sec = |t: i64| t.div_euclid(1_000_000_000);
                match prev_tov_sim_ns {
                    Some(p) => sec(p) != sec(f.tov_sim_ns),
                    None => f.tov_sim_ns.rem_euclid(1_000_000_000) == 0,
                }
            }
        };
        marked.then_some(f.tov_ns + self.offset_ns as i128)
    }
}

/// RTS or DTR of a serial device, through the TIOCMBIS/TIOCMBIC ioctls (tty_ioctl(4)).
pub struct ModemLine {
    fd: OwnedFd,
    bits: libc::c_int,
}

impl ModemLine {
    /// Opens `dev` (without becoming its controlling terminal) and lowers `pin`.
    pub fn open(dev: &str, pin: Pin) -> io::Result<ModemLine> {
        use nix::fcntl::{OFlag, open};
        use nix::sys::stat::Mode;
        let fd = open(
            dev,
            OFlag::O_RDWR | OFlag::O_NOCTTY | OFlag::O_NONBLOCK | OFlag::O_CLOEXEC,
            Mode::empty(),
        )
        .map_err(|e| io::Error::other(format!("{dev}: {e}")))?;
        let bits = match pin {
            Pin::Rts => libc::TIOCM_RTS,
            Pin::Dtr => libc::TIOCM_DTR,
        };
        let mut line = ModemLine { fd, bits };
        line.set(false)
            .map_err(|e| io::Error::new(e.kind(), format!("{dev}: modem line: {e}")))?;
        Ok(line)
    }
}

impl Line for ModemLine {
    fn set(&mut self, high: bool) -> io::Result<()> {
        let req = if high { libc::TIOCMBIS } else { libc::TIOCMBIC };
        // Neither std nor nix wraps the modem-line ioctls. SAFETY: `fd` is an open descriptor we
        // own, and TIOCMBIS/TIOCMBIC read one `int` through the pointer, which lives across the
        // call.
        let rc = unsafe { libc::ioctl(self.fd.as_raw_fd(), req, &self.bits) };
        if rc < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(())
    }
}

/// Rising edges waiting for the pulse thread; frames beyond it are not pulsed (counted).
const QUEUE: usize = 1 << 14;

/// How long before a rising edge the pulse thread stops waiting for a new schedule and sleeps
/// to the edge itself: the edge can then be off by the rate change times this at most (≤ 10 µs
/// at the lock's 1 % slew limit).
const FINAL_APPROACH_NS: i128 = 1_000_000;

/// The pacer's latest schedule after a phase lock slewed it (`None`: never), and the signal
/// that it changed.
type Shared = Arc<(Mutex<Option<Schedule>>, Condvar)>;

/// The pulse hook: computes each frame's rising edge as its block arrives and hands it to a
/// thread that sleeps to it, raises the line, and lowers it `width` later.
pub struct Pulse {
    spec: PulseSpec,
    prev_tov: Option<i64>,
    /// (rising edge as the schedule gave it when the block came, the ToV's nominal offset).
    tx: Option<SyncSender<(i128, i128)>>,
    sched: Shared,
    thread: Option<JoinHandle<io::Result<u64>>>,
    /// Edges not queued because the thread was behind.
    pub missed: u64,
}

impl Pulse {
    /// Pulses per `spec` on `line`.
    pub fn new(spec: PulseSpec, line: Box<dyn Line>) -> io::Result<Pulse> {
        let (tx, rx) = sync_channel(QUEUE);
        let sched: Shared = Arc::new((Mutex::new(None), Condvar::new()));
        let shared = sched.clone();
        let thread = std::thread::Builder::new()
            .name("imu-pulse".into())
            .spawn(move || drive(rx, line, spec, &shared))?;
        Ok(Pulse {
            spec,
            prev_tov: None,
            tx: Some(tx),
            sched,
            thread: Some(thread),
            missed: 0,
        })
    }
}

/// The pulse thread: each rising edge at its instant (at once when already past), the
/// falling edge `width` after it really rose; returns the pulses sent. The width is checked
/// shorter than the interval between pulses, so a pulse ends before the next one is due.
///
/// An edge is queued up to a block ahead; when a phase lock slews the schedule meanwhile, the
/// edge moves with it: the thread maps the ToV's nominal offset through the latest schedule,
/// waiting for changes until [`FINAL_APPROACH_NS`] before the edge.
fn drive(
    rx: Receiver<(i128, i128)>,
    mut line: Box<dyn Line>,
    spec: PulseSpec,
    shared: &Shared,
) -> io::Result<u64> {
    let (width, offset) = (spec.width_ns as i128, spec.offset_ns as i128);
    let (lock, changed) = &**shared;
    let mut sent = 0;
    while let Ok((queued, tov_nominal)) = rx.recv() {
        let mut guard = lock.lock().unwrap_or_else(|e| e.into_inner());
        let rise = loop {
            let rise = guard.map_or(queued, |s| s.at(tov_nominal) + offset);
            let ahead = rise - FINAL_APPROACH_NS - monotonic_ns();
            if ahead <= 0 {
                break rise;
            }
            let wait = std::time::Duration::from_nanos(ahead as u64);
            guard = changed
                .wait_timeout(guard, wait)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        };
        drop(guard);
        sleep_until(rise);
        line.set(true)?;
        sent += 1;
        sleep_until(rise.max(monotonic_ns()) + width);
        line.set(false)?;
    }
    Ok(sent)
}

impl FrameHook for Pulse {
    fn ahead(&mut self, frames: &[FrameTime]) {
        for f in frames {
            let edge = self.spec.edge(f, self.prev_tov);
            self.prev_tov = Some(f.tov_sim_ns);
            if let (Some(e), Some(tx)) = (edge, &self.tx) {
                match tx.try_send((e, f.tov_nominal_ns)) {
                    Ok(()) => {}
                    Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => self.missed += 1,
                }
            }
        }
    }

    fn rescheduled(&mut self, sched: &Schedule) {
        let (lock, changed) = &*self.sched;
        *lock.lock().unwrap_or_else(|e| e.into_inner()) = Some(*sched);
        changed.notify_all();
    }

    fn written(&mut self, _f: &FrameTime) -> io::Result<()> {
        Ok(())
    }

    fn finish(&mut self) -> io::Result<()> {
        self.tx = None;
        match self.thread.take().map(|t| t.join()) {
            Some(Ok(r)) => r.map(|_| ()),
            Some(Err(_)) => Err(io::Error::other("the pulse thread panicked")),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spec_parsing() {
        let p: PulseSpec = "dtr:pps:-1ms:100us".parse().unwrap();
        assert_eq!(
            p,
            PulseSpec {
                pin: Pin::Dtr,
                mark: Mark::Pps,
                offset_ns: -1_000_000,
                width_ns: 100_000
            }
        );
        let p: PulseSpec = "rts:tov".parse().unwrap();
        assert_eq!((p.offset_ns, p.width_ns), (0, DEFAULT_WIDTH_NS));
        assert_eq!(
            "rts:tov:0:2 ms".parse::<PulseSpec>().unwrap().width_ns,
            2_000_000
        );
        for bad in [
            "cts:tov",
            "rts",
            "rts:edge",
            "rts:tov:5",
            "rts:tov:1ms:0",
            "rts:tov:1ms:1ms:1",
        ] {
            assert!(bad.parse::<PulseSpec>().is_err(), "{bad}");
        }
        assert!(p.check(5e6).is_ok());
        assert!(
            "rts:tov:0:5ms"
                .parse::<PulseSpec>()
                .unwrap()
                .check(5e6)
                .is_err()
        );
    }

    fn frame(tov_sim_ns: i64) -> FrameTime {
        FrameTime {
            stream: 0,
            index: 0,
            tov_sim_ns,
            tov_ns: 1_000 + tov_sim_ns as i128,
            tov_nominal_ns: tov_sim_ns as i128,
            due_ns: 0,
            written_ns: 0,
        }
    }

    /// ToV pulses mark every frame at ToV + offset; PPS ones only the first frame at or after
    /// each whole second (a sensor clock a little slow or fast included).
    #[test]
    fn edges() {
        let tov: PulseSpec = "rts:tov:-200us".parse().unwrap();
        assert_eq!(tov.edge(&frame(5_000_000), None), Some(1_000 + 4_800_000));
        let pps: PulseSpec = "rts:pps:1ms".parse().unwrap();
        assert_eq!(pps.edge(&frame(0), None), Some(1_000 + 1_000_000));
        assert_eq!(pps.edge(&frame(5_000_000), None), None);
        assert_eq!(
            pps.edge(&frame(1_000_000_000), Some(995_000_000)),
            Some(1_000 + 1_001_000_000)
        );
        assert_eq!(
            pps.edge(&frame(1_004_000_000), Some(999_000_000)),
            Some(1_000 + 1_005_000_000)
        );
        assert_eq!(pps.edge(&frame(1_005_000_000), Some(1_000_000_000)), None);
    }
}
