//! Where states come from: `udp://HOST:PORT` (a datagram per message; a multicast HOST joins
//! its group), `tcp://HOST:PORT` (listens there and reads one connection after another), `-`
//! (stdin) or a path (a file or a FIFO). Streams are cut into messages by the format: lines
//! for CSV, the magic and fixed length for binary datagrams, the header's length for MAVLink.
//!
//! Nothing waits without looking at the run's stop flag ([`Receiver::open_until`]): a socket is
//! polled every [`POLL`], and a stream (stdin, a FIFO, a file, a TCP connection) is read — and a
//! FIFO opened — on a thread of its own whose chunks the receiver waits for [`POLL`] at a time,
//! so a signal before the first state (or during a silence) ends the run at once.
//!
//! A TCP input is not over when a connection closes: a readiness check that connects and
//! closes, a sender that reconnects are what real rigs do. One connection is read at a time
//! (the next waits in the listen queue); it goes on where the last one stopped, its lines
//! and bytes counted on from there, a line or frame the last one left unfinished cut off.
//! Like UDP, the input is over after the idle timeout without data, whatever connects.
//!
//! This file opens the endpoints and reads them; `cut` cuts what arrives into messages.

mod cut;

use std::collections::VecDeque;
use std::io::{ErrorKind, Read};
use std::net::{Ipv4Addr, Shutdown, SocketAddr, TcpListener, TcpStream, ToSocketAddrs, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver as ChunkRx, RecvTimeoutError, sync_channel};
use std::time::{Duration, Instant};

use super::InputFormat;

/// A source of states, as given on the command line.
#[derive(Clone, Debug, PartialEq)]
pub enum Endpoint {
    /// Datagrams received at this address.
    Udp(SocketAddr),
    /// Streams from the clients connecting to this address, one after another.
    Tcp(SocketAddr),
    /// A byte stream: stdin (`-`), a file or a FIFO.
    Stream(PathBuf),
}

impl Endpoint {
    /// Parses `udp://HOST:PORT`, `tcp://HOST:PORT`, `-` or a path.
    pub fn parse(s: &str) -> Result<Endpoint, String> {
        let addr = |rest: &str| {
            rest.to_socket_addrs()
                .map_err(|e| format!("`{s}`: {e} (expected HOST:PORT)"))?
                .next()
                .ok_or_else(|| format!("`{s}`: no address"))
        };
        if let Some(rest) = s.strip_prefix("udp://") {
            return Ok(Endpoint::Udp(addr(rest)?));
        }
        if let Some(rest) = s.strip_prefix("tcp://") {
            return Ok(Endpoint::Tcp(addr(rest)?));
        }
        if s.contains("://") {
            return Err(format!(
                "`{s}`: unknown scheme (expected udp://HOST:PORT, tcp://HOST:PORT, - or a path)"
            ));
        }
        Ok(Endpoint::Stream(PathBuf::from(s)))
    }
}

/// Where a message was in its input, for reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Place {
    /// Datagram n (1-based), line l within it (CSV; 0 for binary).
    Datagram(u64, u64),
    /// Line n of a stream (CSV).
    Line(u64),
    /// Byte offset of the frame's first byte in a stream.
    Byte(u64),
}

impl std::fmt::Display for Place {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Place::Datagram(n, 0) => write!(f, "datagram {n}"),
            Place::Datagram(n, l) => write!(f, "datagram {n} line {l}"),
            Place::Line(n) => write!(f, "line {n}"),
            Place::Byte(o) => write!(f, "byte {o}"),
        }
    }
}

impl Place {
    /// Where byte `offset` of the message is: inside a datagram or line, or the stream's own
    /// byte offset (a frame's place is already a byte: it is not named twice).
    pub fn at(&self, offset: usize) -> String {
        match self {
            Place::Byte(o) => format!("byte {}", o + offset as u64),
            _ => format!("{self}, byte {offset}"),
        }
    }
}

/// One message: its bytes, where it was and when it arrived.
#[derive(Clone, Debug)]
pub struct Message {
    /// The bytes (a line without its end, a datagram, a frame).
    pub bytes: Vec<u8>,
    /// Where it was.
    pub place: Place,
    /// When it was received.
    pub arrival: Instant,
    /// The TCP connection that brought it (1 for the first one); 0 for other inputs.
    pub connection: u64,
}

/// How long a receiver waits at a time before it looks at the stop flag again.
pub const POLL: Duration = Duration::from_millis(50);

/// Bytes a stream's reading thread hands over at a time.
const CHUNK: usize = 4096;

enum Kind {
    Udp(UdpSocket),
    /// A stream read on its own thread: chunks, an empty one at its end (or its idle timeout).
    Stream(ChunkRx<std::io::Result<Vec<u8>>>),
    /// A TCP listener (non-blocking) and the connection being read, as a stream, if any; the
    /// socket is kept to shut it down when the input ends while it is open.
    Tcp {
        listener: TcpListener,
        conn: Option<(TcpStream, ChunkRx<std::io::Result<Vec<u8>>>)>,
    },
}

/// Reads `r` on a thread of its own, chunk by chunk, into a bounded channel; an empty chunk
/// is the end of the stream (or a read timeout the stream was given).
fn pump(mut r: Box<dyn Read + Send>) -> ChunkRx<std::io::Result<Vec<u8>>> {
    let (tx, rx) = sync_channel(16);
    std::thread::spawn(move || {
        loop {
            let mut chunk = vec![0u8; CHUNK];
            let got = match r.read(&mut chunk) {
                Ok(n) => {
                    chunk.truncate(n);
                    Ok(chunk)
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    Ok(Vec::new())
                }
                Err(e) => Err(e),
            };
            let end = !matches!(&got, Ok(c) if !c.is_empty());
            if tx.send(got).is_err() || end {
                break;
            }
        }
    });
    rx
}

/// True once `stop` is set.
fn stopped(stop: &Option<Arc<AtomicBool>>) -> bool {
    stop.as_ref().is_some_and(|s| s.load(Ordering::Relaxed))
}

/// The error of an input opened too late: the run was stopped while it waited.
fn stopped_while(what: &str) -> std::io::Error {
    std::io::Error::new(ErrorKind::Interrupted, format!("stopped {what}"))
}

/// Receives messages from an [`Endpoint`].
pub struct Receiver {
    kind: Kind,
    format: InputFormat,
    name: String,
    /// Stream bytes not yet cut into messages, and the stream offset of `buf[0]`.
    buf: Vec<u8>,
    offset: u64,
    lines: u64,
    datagrams: u64,
    eof: bool,
    pending: VecDeque<Message>,
    skipped: u64,
    /// CSV: bytes at the front of `buf` already searched for a line end (each byte is searched
    /// once, however slowly a long line arrives).
    scanned: usize,
    /// CSV: the rest of an over-long line is being skipped, up to its end.
    discarding: bool,
    /// The UDP idle timeout, counted once the first datagram is in.
    idle: Option<Duration>,
    /// When the newest datagram came (UDP).
    last_data: Option<Instant>,
    /// The input ended by its idle timeout.
    idled: bool,
    /// The run's stop flag: a wait for data ends when it is set.
    stop: Option<Arc<AtomicBool>>,
    /// The UDP socket is polled (opened here); a caller's socket ends at its own timeout.
    polled: bool,
    rbuf: Vec<u8>,
    /// TCP connections accepted so far.
    connections: u64,
}

/// Largest datagram taken (bigger ones are cut, and then malformed).
const MAX_DATAGRAM: usize = 65_536;

impl Receiver {
    /// Opens `endpoint` for messages of `format`. A UDP or TCP receiver ends after `idle`
    /// without data once the first data arrived (a rig may start the emulator before the
    /// simulation; a TCP sender may reconnect meanwhile); never for `None`.
    pub fn open(
        endpoint: &Endpoint,
        format: InputFormat,
        idle: Option<Duration>,
    ) -> std::io::Result<Receiver> {
        Receiver::open_until(endpoint, format, idle, None)
    }

    /// [`Receiver::open`], giving up every wait once `stop` is set: opening (a FIFO before a
    /// writer opens it) then fails with `ErrorKind::Interrupted`, and
    /// [`Receiver::next_message`] (a TCP listener before a sender connects, or between
    /// connections) ends the input.
    pub fn open_until(
        endpoint: &Endpoint,
        format: InputFormat,
        idle: Option<Duration>,
        stop: Option<Arc<AtomicBool>>,
    ) -> std::io::Result<Receiver> {
        let (kind, name) = match endpoint {
            Endpoint::Udp(addr) => {
                let socket = match addr.ip() {
                    std::net::IpAddr::V4(group) if group.is_multicast() => {
                        let s = UdpSocket::bind((Ipv4Addr::UNSPECIFIED, addr.port()))?;
                        s.join_multicast_v4(&group, &Ipv4Addr::UNSPECIFIED)?;
                        s
                    }
                    _ => UdpSocket::bind(addr)?,
                };
                socket.set_read_timeout(Some(POLL))?;
                // A burst of states, or an input thread not scheduled for a while, must not
                // overflow the socket: the kernel would drop states without a word.
                #[cfg(feature = "realtime")]
                crate::realtime::udp::grow_receive_buffer(&socket);
                (Kind::Udp(socket), format!("udp://{addr}"))
            }
            Endpoint::Tcp(addr) => {
                // Connections are taken as messages are asked for ([`Receiver::fill`]).
                let listener = TcpListener::bind(addr)?;
                listener.set_nonblocking(true)?;
                let name = format!("tcp://{}", listener.local_addr()?);
                (
                    Kind::Tcp {
                        listener,
                        conn: None,
                    },
                    name,
                )
            }
            Endpoint::Stream(path) if path == Path::new("-") => (
                Kind::Stream(pump(Box::new(std::io::stdin()))),
                "stdin".into(),
            ),
            Endpoint::Stream(path) => {
                // Opening a FIFO waits for a writer: on a thread, so that a stop is heard.
                let (tx, rx) = sync_channel(1);
                let p = path.clone();
                std::thread::spawn(move || drop(tx.send(std::fs::File::open(p))));
                let f = loop {
                    match rx.recv_timeout(POLL) {
                        Ok(f) => break f?,
                        Err(RecvTimeoutError::Timeout) if stopped(&stop) => {
                            return Err(stopped_while("before a writer opened it"));
                        }
                        Err(RecvTimeoutError::Timeout) => {}
                        Err(RecvTimeoutError::Disconnected) => {
                            return Err(std::io::Error::other("opening failed"));
                        }
                    }
                };
                (Kind::Stream(pump(Box::new(f))), path.display().to_string())
            }
        };
        let mut r = Receiver::new(kind, format, name);
        r.idle = idle;
        r.stop = stop;
        r.polled = matches!(endpoint, Endpoint::Udp(_));
        Ok(r)
    }

    /// A receiver of the messages in a byte stream (e.g. a TCP stream a caller accepted).
    pub fn from_stream(r: Box<dyn Read + Send>, format: InputFormat, name: &str) -> Receiver {
        Receiver::new(Kind::Stream(pump(r)), format, name.into())
    }

    /// A receiver of datagrams on a bound socket.
    pub fn from_socket(s: UdpSocket, format: InputFormat, name: &str) -> Receiver {
        Receiver::new(Kind::Udp(s), format, name.into())
    }

    fn new(kind: Kind, format: InputFormat, name: String) -> Receiver {
        Receiver {
            kind,
            format,
            name,
            buf: Vec::new(),
            offset: 0,
            lines: 0,
            datagrams: 0,
            eof: false,
            pending: VecDeque::new(),
            skipped: 0,
            scanned: 0,
            discarding: false,
            idle: None,
            last_data: None,
            idled: false,
            stop: None,
            polled: false,
            rbuf: Vec::new(),
            connections: 0,
        }
    }

    /// The input's name for messages (`udp://…`, `stdin`, a path).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The local address of a UDP receiver (its port when bound to port 0).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        match &self.kind {
            Kind::Udp(s) => s.local_addr().ok(),
            Kind::Tcp { listener, .. } => listener.local_addr().ok(),
            Kind::Stream(_) => None,
        }
    }

    /// TCP connections accepted so far (0 for other inputs).
    pub fn connections(&self) -> u64 {
        self.connections
    }

    /// Stream bytes that were outside any frame so far.
    pub fn skipped_bytes(&self) -> u64 {
        self.skipped
    }

    /// When the silence that ended the input began to count as one (the newest datagram's
    /// arrival plus the idle timeout), if the input ended by its idle timeout; `None` for a
    /// stream's end or an input still going.
    pub fn silence_over_at(&self) -> Option<Instant> {
        match (self.idle, self.last_data) {
            (Some(i), Some(l)) if self.idled => Some(l + i),
            _ => None,
        }
    }

    /// The next message; `None` at the end of a stream or after the idle timeout.
    pub fn next_message(&mut self) -> std::io::Result<Option<Message>> {
        loop {
            if let Some(m) = self.pending.pop_front() {
                return Ok(Some(m));
            }
            let got = match &mut self.kind {
                Kind::Udp(s) => {
                    // One receive buffer for the run; each datagram is copied out at its size.
                    self.rbuf.resize(MAX_DATAGRAM, 0);
                    match s.recv(&mut self.rbuf) {
                        Ok(n) => {
                            self.last_data = Some(Instant::now());
                            let b = self.rbuf[..n].to_vec();
                            self.datagram(b);
                            true
                        }
                        Err(e)
                            if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) =>
                        {
                            // Silent for a poll: over once stopped, or idle since the newest.
                            let idle = match (self.idle, self.last_data) {
                                (Some(i), Some(l)) => l.elapsed() >= i,
                                _ => false,
                            };
                            if !self.polled || stopped(&self.stop) || idle {
                                self.idled = idle;
                                false
                            } else {
                                continue;
                            }
                        }
                        Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                        Err(e) => return Err(e),
                    }
                }
                Kind::Stream(_) | Kind::Tcp { .. } => self.fill()?,
            };
            if !got && self.pending.is_empty() {
                return Ok(None);
            }
        }
    }

    /// Reads more of the stream and cuts what is complete into messages; false at its end.
    fn fill(&mut self) -> std::io::Result<bool> {
        if self.eof {
            return Ok(false);
        }
        let chunk = match &mut self.kind {
            Kind::Stream(r) => loop {
                match r.recv_timeout(POLL) {
                    Ok(c) => break c?,
                    Err(RecvTimeoutError::Timeout) if stopped(&self.stop) => break Vec::new(),
                    Err(RecvTimeoutError::Timeout) => {}
                    Err(RecvTimeoutError::Disconnected) => break Vec::new(),
                }
            },
            Kind::Tcp { .. } => match self.tcp_chunk()? {
                // A connection ended: what it left unfinished is cut, the input goes on.
                Some(c) if c.is_empty() => return Ok(true),
                Some(c) => c,
                None => Vec::new(),
            },
            Kind::Udp(_) => unreachable!("a stream"),
        };
        let n = chunk.len();
        if n == 0 {
            self.eof = true;
        }
        self.buf.extend_from_slice(&chunk);
        self.cut();
        Ok(n > 0 || !self.pending.is_empty())
    }

    /// Cuts what the buffer holds into messages, by the format.
    fn cut(&mut self) {
        match self.format {
            InputFormat::Csv => self.cut_lines(),
            InputFormat::Binary | InputFormat::Mavlink => self.cut_frames(),
        }
    }

    /// True once the input is over while it waits for data: stopped, or idle since the
    /// newest data (which sets `idled`).
    fn waited_out(&mut self) -> bool {
        self.idled = matches!((self.idle, self.last_data), (Some(i), Some(l)) if l.elapsed() >= i);
        self.idled || stopped(&self.stop)
    }

    /// The next chunk of the TCP input, from the connection being read or, once it closes,
    /// from the next one to connect; empty when a connection's end left messages to take
    /// (what it left unfinished is cut as at a stream's end); `None` when the input is over.
    fn tcp_chunk(&mut self) -> std::io::Result<Option<Vec<u8>>> {
        loop {
            let Kind::Tcp { listener, conn } = &mut self.kind else {
                unreachable!("a TCP input")
            };
            let Some((_, r)) = conn else {
                match listener.accept() {
                    Ok((s, _)) => {
                        s.set_nonblocking(false)?;
                        *conn = Some((s.try_clone()?, pump(Box::new(s))));
                        self.connections += 1;
                    }
                    Err(e) if e.kind() == ErrorKind::WouldBlock => {
                        if self.waited_out() {
                            return Ok(None);
                        }
                        std::thread::sleep(POLL);
                    }
                    // A client gone before it was taken is no fault of the input.
                    Err(e)
                        if matches!(
                            e.kind(),
                            ErrorKind::Interrupted | ErrorKind::ConnectionAborted
                        ) => {}
                    Err(e) => return Err(e),
                }
                continue;
            };
            match r.recv_timeout(POLL) {
                Ok(Ok(c)) if !c.is_empty() => {
                    self.last_data = Some(Instant::now());
                    return Ok(Some(c));
                }
                // Its end, or a reset: the connection is over, not the input.
                Ok(_) | Err(RecvTimeoutError::Disconnected) => {
                    *conn = None;
                    self.eof = true;
                    self.cut();
                    self.eof = false;
                    self.discarding = false;
                    self.scanned = 0;
                    if !self.pending.is_empty() {
                        return Ok(Some(Vec::new()));
                    }
                }
                Err(RecvTimeoutError::Timeout) => {
                    if self.waited_out() {
                        if let Kind::Tcp {
                            conn: Some((s, _)), ..
                        } = &self.kind
                        {
                            // Its reading thread ends with it.
                            let _ = s.shutdown(Shutdown::Both);
                        }
                        return Ok(None);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
