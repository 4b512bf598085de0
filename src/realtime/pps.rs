//! PPS input: sources of edges (CLOCK_MONOTONIC ns of each rising edge) that the pacer's phase
//! lock ([`super::lock`]) follows — the Linux PPS API (`/dev/ppsN`), a serial port's DCD or
//! CTS line, or UDP edge messages (a software PPS for tests and for rigs that publish their
//! second over the network).

use std::io;
use std::net::UdpSocket;
use std::os::fd::{AsRawFd, OwnedFd};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::time::Duration;

use super::clock::{monotonic_ns, utc_to_monotonic};

/// How long a source waits for an edge before checking whether the run stopped.
pub const POLL: Duration = Duration::from_millis(200);

/// Where edges come from.
pub trait EdgeSource: Send {
    /// Waits up to [`POLL`] for the next edge: its CLOCK_MONOTONIC instant (ns), or `None`
    /// when none came.
    fn next_edge(&mut self) -> io::Result<Option<i128>>;
}

/// Opens the source named on the command line: `/dev/ppsN` (or any path without a prefix),
/// `dcd:DEV`, `cts:DEV`, or `udp://HOST:PORT` (a socket bound there).
pub fn open(spec: &str) -> io::Result<Box<dyn EdgeSource>> {
    open_for("--pps-in", spec)
}

/// [`open`] for the command-line flag `flag`, which its errors name.
pub fn open_for(flag: &str, spec: &str) -> io::Result<Box<dyn EdgeSource>> {
    let named = |e: io::Error| io::Error::new(e.kind(), format!("{flag} {spec}: {e}"));
    Ok(if let Some(addr) = spec.strip_prefix("udp://") {
        Box::new(UdpEdges::bind(addr).map_err(named)?)
    } else if let Some(dev) = spec.strip_prefix("dcd:") {
        Box::new(ModemEdges::open(dev, libc::TIOCM_CD).map_err(named)?)
    } else if let Some(dev) = spec.strip_prefix("cts:") {
        Box::new(ModemEdges::open(dev, libc::TIOCM_CTS).map_err(named)?)
    } else {
        Box::new(PpsDevice::open(spec).map_err(named)?)
    })
}

/// Runs `source` on its own thread until `stop` is set or it fails, sending each edge; the
/// thread ends by itself when the receiver is dropped.
pub fn spawn(mut source: Box<dyn EdgeSource>, stop: Arc<AtomicBool>) -> io::Result<Receiver<i128>> {
    let (tx, rx) = channel();
    std::thread::Builder::new()
        .name("imu-pps".into())
        .spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                match source.next_edge() {
                    Ok(Some(e)) => {
                        if tx.send(e).is_err() {
                            return;
                        }
                    }
                    Ok(None) => {}
                    Err(e) => {
                        tracing::warn!("PPS input stopped: {e}");
                        eprintln!("imu-emu: warning: PPS input stopped ({e}); the schedule keeps its last rate");
                        return;
                    }
                }
            }
        })?;
    Ok(rx)
}

/// Edges as UDP datagrams: an 8-byte datagram carries the edge's CLOCK_REALTIME instant (ns
/// since the Unix epoch, little-endian i64) as its sender timed it; any other datagram is an
/// edge at its arrival.
pub struct UdpEdges {
    sock: UdpSocket,
    buf: [u8; 64],
}

impl UdpEdges {
    /// Binds `addr` (`HOST:PORT`).
    pub fn bind(addr: &str) -> io::Result<UdpEdges> {
        let sock = UdpSocket::bind(addr)?;
        sock.set_read_timeout(Some(POLL))?;
        Ok(UdpEdges { sock, buf: [0; 64] })
    }

    /// The bound address (for a port chosen by the system).
    pub fn local_addr(&self) -> io::Result<std::net::SocketAddr> {
        self.sock.local_addr()
    }
}

impl EdgeSource for UdpEdges {
    fn next_edge(&mut self) -> io::Result<Option<i128>> {
        match self.sock.recv(&mut self.buf) {
            Ok(8) => {
                let utc = i64::from_le_bytes(self.buf[..8].try_into().expect("8 bytes"));
                Ok(Some(utc_to_monotonic(utc as i128)))
            }
            Ok(_) => Ok(Some(monotonic_ns())),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }
}

/// `struct pps_ktime` of `<linux/pps.h>`.
#[repr(C)]
#[derive(Clone, Copy, Default)]
struct PpsKtime {
    sec: i64,
    nsec: i32,
    flags: u32,
}

/// `struct pps_kinfo` of `<linux/pps.h>`.
#[repr(C)]
#[derive(Clone, Copy, Default)]
struct PpsKinfo {
    assert_sequence: u32,
    clear_sequence: u32,
    assert_tu: PpsKtime,
    clear_tu: PpsKtime,
    current_mode: i32,
}

/// `struct pps_fdata` of `<linux/pps.h>`: PPS_FETCH's argument.
#[repr(C)]
#[derive(Clone, Copy, Default)]
struct PpsFdata {
    info: PpsKinfo,
    timeout: PpsKtime,
}

// `<linux/pps.h>`: `#define PPS_FETCH _IOWR('p', 0xa4, struct pps_fdata *)` — the size in the
// request number is a pointer's, as the header writes it.
nix::ioctl_readwrite_bad!(
    pps_fetch,
    nix::request_code_readwrite!(b'p', 0xa4, std::mem::size_of::<*mut PpsFdata>()),
    PpsFdata
);

/// A Linux PPS device (`/dev/ppsN`, Documentation/driver-api/pps.rst and RFC 2783): the
/// kernel timestamps each assert edge in CLOCK_REALTIME; PPS_FETCH waits for the next one.
pub struct PpsDevice {
    fd: OwnedFd,
    last_seq: Option<u32>,
}

impl PpsDevice {
    /// Opens `dev`.
    pub fn open(dev: &str) -> io::Result<PpsDevice> {
        use nix::fcntl::{OFlag, open};
        use nix::sys::stat::Mode;
        let fd = open(dev, OFlag::O_RDONLY | OFlag::O_CLOEXEC, Mode::empty())
            .map_err(|e| io::Error::other(format!("{dev}: {e}")))?;
        Ok(PpsDevice { fd, last_seq: None })
    }
}

impl EdgeSource for PpsDevice {
    fn next_edge(&mut self) -> io::Result<Option<i128>> {
        let mut d = PpsFdata {
            timeout: PpsKtime {
                sec: 0,
                nsec: POLL.as_nanos() as i32,
                flags: 0,
            },
            ..PpsFdata::default()
        };
        // SAFETY: `fd` is an open PPS device we own; PPS_FETCH reads and writes one
        // `pps_fdata`, which `d` is (same layout, `repr(C)`), alive across the call.
        match unsafe { pps_fetch(self.fd.as_raw_fd(), &mut d) } {
            Ok(_) => {}
            Err(nix::errno::Errno::ETIMEDOUT | nix::errno::Errno::EINTR) => return Ok(None),
            Err(e) => return Err(e.into()),
        }
        let seq = d.info.assert_sequence;
        if self.last_seq == Some(seq) {
            return Ok(None);
        }
        self.last_seq = Some(seq);
        let t = &d.info.assert_tu;
        let utc = t.sec as i128 * 1_000_000_000 + t.nsec as i128;
        Ok(Some(utc_to_monotonic(utc)))
    }
}

/// A serial port's DCD or CTS line: TIOCMIWAIT (tty_ioctl(4)) waits for it to change; the
/// edge is timed when the call returns, and only rising edges count.
pub struct ModemEdges {
    fd: OwnedFd,
    bit: libc::c_int,
}

impl ModemEdges {
    /// Opens `dev` to watch `bit` (`TIOCM_CD` or `TIOCM_CTS`).
    pub fn open(dev: &str, bit: libc::c_int) -> io::Result<ModemEdges> {
        use nix::fcntl::{OFlag, open};
        use nix::sys::stat::Mode;
        let fd = open(
            dev,
            OFlag::O_RDONLY | OFlag::O_NOCTTY | OFlag::O_NONBLOCK | OFlag::O_CLOEXEC,
            Mode::empty(),
        )
        .map_err(|e| io::Error::other(format!("{dev}: {e}")))?;
        Ok(ModemEdges { fd, bit })
    }
}

impl EdgeSource for ModemEdges {
    fn next_edge(&mut self) -> io::Result<Option<i128>> {
        // TIOCMIWAIT blocks until the line changes, with no timeout: a run that stops while
        // it waits ends with the process.
        // SAFETY: `fd` is an open tty we own; TIOCMIWAIT takes the mask by value.
        let rc = unsafe { libc::ioctl(self.fd.as_raw_fd(), libc::TIOCMIWAIT, self.bit) };
        let t = monotonic_ns();
        if rc < 0 {
            let e = io::Error::last_os_error();
            return match e.raw_os_error() {
                Some(libc::EINTR) => Ok(None),
                _ => Err(e),
            };
        }
        let mut state: libc::c_int = 0;
        // SAFETY: TIOCMGET writes one `int` through the pointer, which lives across the call.
        let rc = unsafe { libc::ioctl(self.fd.as_raw_fd(), libc::TIOCMGET, &mut state) };
        if rc < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok((state & self.bit != 0).then_some(t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::realtime::clock::realtime_ns;

    /// The ioctl structures have the sizes of `<linux/pps.h>` on 64-bit Linux, and PPS_FETCH
    /// the number the header gives (0xc00870a4: read-write, 8-byte argument, 'p', 0xa4).
    #[test]
    fn pps_abi() {
        assert_eq!(std::mem::size_of::<PpsKtime>(), 16);
        assert_eq!(std::mem::size_of::<PpsKinfo>(), 48);
        assert_eq!(std::mem::size_of::<PpsFdata>(), 64);
        assert_eq!(
            nix::request_code_readwrite!(b'p', 0xa4, std::mem::size_of::<*mut PpsFdata>()),
            0xc008_70a4
        );
    }

    /// A UDP edge carrying its own UTC instant maps to the monotonic clock at the current
    /// offset; an empty datagram is an edge at arrival; silence is no edge; a missing device
    /// is an error naming it.
    #[test]
    fn udp_edges() {
        let mut src = UdpEdges::bind("127.0.0.1:0").unwrap();
        let to = src.local_addr().unwrap();
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        // The edge's UTC instant, 5 ms before it was read, on the monotonic clock: between
        // the monotonic readings around the realtime one, ± the offset's reading.
        let w = super::super::clock::host_offset().within_ns;
        let m0 = monotonic_ns();
        let utc = realtime_ns() - 5_000_000;
        let m1 = monotonic_ns();
        tx.send_to(&(utc as i64).to_le_bytes(), to).unwrap();
        let e = src.next_edge().unwrap().unwrap();
        assert!(
            (m0 - 5_000_000 - w..=m1 - 5_000_000 + w).contains(&e),
            "{e} not in [{m0}, {m1}] − 5 ms ± {w} ns"
        );
        // An empty datagram: an edge when it came, between its sending and its reading.
        let sent = monotonic_ns();
        tx.send_to(b"x", to).unwrap();
        let e = src.next_edge().unwrap().unwrap();
        assert!((sent..=monotonic_ns()).contains(&e), "{e}");
        assert_eq!(src.next_edge().unwrap(), None);
        let err = open("/dev/pps-none").err().unwrap().to_string();
        assert!(err.contains("--pps-in /dev/pps-none"), "{err}");
    }
}
