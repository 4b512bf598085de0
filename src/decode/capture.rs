//! Reading a frame stream into a [`Session`]: from a file or stdin to its end, or live from a
//! pty or serial device (opened shared, its input flushed first) or UDP datagrams (a
//! multicast group is joined), until a number of frames, a duration or a stop signal, with
//! the tally told once a second while live.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicI32, Ordering};
use std::time::{Duration, Instant};

use super::{Session, tally};
use crate::protocol::StreamStats;
use crate::realtime::clock::monotonic_ns;
use crate::realtime::stats::Lateness;

/// Where the bytes come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    /// Standard input.
    Stdin,
    /// A file (`-`: standard input).
    File(PathBuf),
    /// A pty or serial device at a baud rate.
    Serial(String, u32),
    /// Datagrams sent to HOST:PORT.
    Udp(String),
}

impl Source {
    /// Live input: it has no end of its own.
    pub fn is_live(&self) -> bool {
        matches!(self, Source::Serial(..) | Source::Udp(_))
    }
}

/// Why a capture could not start or go on.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// The device, socket or file cannot be opened: `what` names it.
    #[error("{what}")]
    Open {
        /// What was being opened.
        what: String,
        /// The cause.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The address names no socket address.
    #[error("--udp-listen {0}: no address")]
    NoAddress(String),
    /// Reading the input or writing the rows failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// Setting up the serial device failed.
    #[error(transparent)]
    Serial(#[from] serialport::Error),
}

/// `what` could not be opened, because of `e`.
fn open_error(
    what: String,
    e: impl Into<Box<dyn std::error::Error + Send + Sync>>,
) -> CaptureError {
    CaptureError::Open {
        what,
        source: e.into(),
    }
}

/// An opened source.
pub enum Input {
    /// Bytes in order (file, stdin, serial device).
    Stream(Box<dyn Read>),
    /// Datagrams.
    Udp(UdpSocket),
}

impl Input {
    /// Opens `source`.
    pub fn open(source: &Source) -> Result<Input, CaptureError> {
        Ok(match source {
            Source::Serial(dev, baud) => {
                let mut port = serialport::new(dev, *baud)
                    .timeout(Duration::from_millis(100))
                    .open_native()
                    .map_err(|e| open_error(format!("opening {dev}"), e))?;
                port.set_exclusive(false)?;
                serialport::SerialPort::clear(&port, serialport::ClearBuffer::Input)?;
                Input::Stream(Box::new(port))
            }
            Source::Udp(addr) => Input::Udp(open_udp(addr)?),
            Source::Stdin => Input::Stream(Box::new(std::io::stdin().lock())),
            Source::File(p) if p == Path::new("-") => {
                Input::Stream(Box::new(std::io::stdin().lock()))
            }
            Source::File(p) => Input::Stream(Box::new(
                std::fs::File::open(p)
                    .map_err(|e| open_error(format!("opening {}", p.display()), e))?,
            )),
        })
    }

    /// Reads some bytes: `Ok(None)` at the end of the input, `Ok(Some(0))` on a timeout.
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<Option<usize>> {
        let r = match self {
            Input::Stream(r) => r.read(buf),
            Input::Udp(s) => s.recv(buf),
        };
        match r {
            Ok(0) if matches!(self, Input::Stream(_)) => Ok(None),
            Ok(n) => Ok(Some(n)),
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) =>
            {
                Ok(Some(0))
            }
            // A pty whose emulator went away (EIO, or a hang-up that serialport reports as a
            // broken pipe).
            Err(e) if e.raw_os_error() == Some(libc::EIO) || e.kind() == ErrorKind::BrokenPipe => {
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }
}

fn open_udp(addr: &str) -> Result<UdpSocket, CaptureError> {
    let flag = |e: std::io::Error| open_error(format!("--udp-listen {addr}"), e);
    let a: SocketAddr = addr
        .to_socket_addrs()
        .map_err(flag)?
        .next()
        .ok_or_else(|| CaptureError::NoAddress(addr.to_string()))?;
    let sock = match a {
        SocketAddr::V4(v4) if v4.ip().is_multicast() => {
            let s = UdpSocket::bind(("0.0.0.0", v4.port()))?;
            s.join_multicast_v4(v4.ip(), &std::net::Ipv4Addr::UNSPECIFIED)?;
            s
        }
        _ => UdpSocket::bind(a).map_err(flag)?,
    };
    sock.set_read_timeout(Some(Duration::from_millis(100)))?;
    crate::realtime::udp::grow_receive_buffer(&sock);
    Ok(sock)
}

/// When a capture ends, besides the end of a file.
#[derive(Debug, Default)]
pub struct Until {
    /// After this many good frames.
    pub frames: Option<u64>,
    /// After this many seconds.
    pub duration_s: Option<f64>,
    /// Once this flag is non-zero (a stop signal's number, [`crate::realtime::signal::watch`]).
    pub stop: Option<std::sync::Arc<AtomicI32>>,
}

/// Feeds `input` to `session`, its rows to `out`, until the input ends or `until` says; a
/// live input's tally goes to `tell` once a second when it changed. Returns the final counts
/// and their tally (with the time between frame arrivals for live input).
pub fn run(
    input: &mut Input,
    live: bool,
    session: &mut Session,
    until: &Until,
    out: &mut impl Write,
    mut tell: impl FnMut(&str),
) -> Result<(StreamStats, String), CaptureError> {
    let mut buf = vec![0u8; 1 << 16];
    let mut gaps = Lateness::default();
    let mut last_arrival: Option<i128> = None;
    let started = Instant::now();
    let mut last_tally = Instant::now();
    let mut tallied = StreamStats::default();
    let deadline = until
        .duration_s
        .map(|d| started + Duration::from_secs_f64(d.max(0.0)));
    let limit = until.frames.unwrap_or(u64::MAX);
    let gap_text = |gaps: &Lateness| (live && gaps.count() > 0).then(|| gaps.summary());
    let stopped = || (until.stop.as_ref()).is_some_and(|s| s.load(Ordering::Relaxed) != 0);
    while !stopped() && session.stats().frames < limit {
        if deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        let read = input.read(&mut buf)?;
        let now = monotonic_ns();
        // Every frame of a read (or confirmed by the input's end) arrived at `now`: the first
        // one `now − last` after the previous frame, the others at once.
        let frames = match read {
            Some(n) => session.feed(&buf[..n], out)?,
            None => session.finish(out)?,
        };
        for _ in 0..frames {
            if let Some(t) = last_arrival {
                gaps.add(now - t);
            }
            last_arrival = Some(now);
        }
        if read.is_none() {
            break;
        }
        if live && last_tally.elapsed() >= Duration::from_secs(1) {
            out.flush()?;
            last_tally = Instant::now();
            if session.stats() == tallied {
                continue;
            }
            tallied = session.stats();
            tell(&tally(&tallied, gap_text(&gaps).as_deref()));
        }
    }
    out.flush()?;
    let stats = session.stats();
    Ok((stats, tally(&stats, gap_text(&gaps).as_deref())))
}
