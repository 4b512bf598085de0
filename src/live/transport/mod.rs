//! Where states come from: `udp://HOST:PORT` (a datagram per message; a multicast HOST joins
//! its group), `tcp://HOST:PORT` (listens there and takes the first connection), `-` (stdin)
//! or a path (a file or a FIFO). Streams are cut into messages by the format: lines for CSV,
//! the magic and fixed length for binary datagrams, the header's length for MAVLink.
//!
//! Nothing waits without looking at the run's stop flag ([`Receiver::open_until`]): a socket is
//! polled every [`POLL`], and a stream (stdin, a FIFO, a file, a TCP connection) is read — and a
//! FIFO opened — on a thread of its own whose chunks the receiver waits for [`POLL`] at a time,
//! so a signal before the first state (or during a silence) ends the run at once.

use std::collections::VecDeque;
use std::io::{ErrorKind, Read};
use std::net::{Ipv4Addr, SocketAddr, TcpListener, ToSocketAddrs, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver as ChunkRx, RecvTimeoutError, sync_channel};
use std::time::{Duration, Instant};

use super::csv::MAX_LINE_BYTES;
use super::{InputFormat, binary, mavlink};

/// A source of states, as given on the command line.
#[derive(Clone, Debug, PartialEq)]
pub enum Endpoint {
    /// Datagrams received at this address.
    Udp(SocketAddr),
    /// A stream from the first client connecting to this address.
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
}

/// How long a receiver waits at a time before it looks at the stop flag again.
pub const POLL: Duration = Duration::from_millis(50);

/// Bytes a stream's reading thread hands over at a time.
const CHUNK: usize = 4096;

enum Kind {
    Udp(UdpSocket),
    /// A stream read on its own thread: chunks, an empty one at its end (or its idle timeout).
    Stream(ChunkRx<std::io::Result<Vec<u8>>>),
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
    /// The run's stop flag: a wait for data ends when it is set.
    stop: Option<Arc<AtomicBool>>,
    /// The UDP socket is polled (opened here); a caller's socket ends at its own timeout.
    polled: bool,
    rbuf: Vec<u8>,
}

/// Largest datagram taken (bigger ones are cut, and then malformed).
const MAX_DATAGRAM: usize = 65_536;

impl Receiver {
    /// Opens `endpoint` for messages of `format`. A UDP receiver, and a TCP one once
    /// connected, end after `idle` without data once the first data arrived (a rig may start
    /// the emulator before the simulation); never for `None`.
    pub fn open(
        endpoint: &Endpoint,
        format: InputFormat,
        idle: Option<Duration>,
    ) -> std::io::Result<Receiver> {
        Receiver::open_until(endpoint, format, idle, None)
    }

    /// [`Receiver::open`], giving up every wait once `stop` is set: opening (a TCP listener
    /// before a sender connects, a FIFO before a writer opens it) then fails with
    /// `ErrorKind::Interrupted`, and [`Receiver::next_message`] ends the input.
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
                (Kind::Udp(socket), format!("udp://{addr}"))
            }
            Endpoint::Tcp(addr) => {
                let listener = TcpListener::bind(addr)?;
                listener.set_nonblocking(true)?;
                let stream = loop {
                    match listener.accept() {
                        Ok((s, _)) => break s,
                        Err(e) if e.kind() == ErrorKind::WouldBlock => {
                            if stopped(&stop) {
                                return Err(stopped_while("before a sender connected"));
                            }
                            std::thread::sleep(POLL);
                        }
                        Err(e) => return Err(e),
                    }
                };
                stream.set_nonblocking(false)?;
                stream.set_read_timeout(idle)?;
                (
                    Kind::Stream(pump(Box::new(stream))),
                    format!("tcp://{addr}"),
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
            stop: None,
            polled: false,
            rbuf: Vec::new(),
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
            Kind::Stream(_) => None,
        }
    }

    /// Stream bytes that were outside any frame so far.
    pub fn skipped_bytes(&self) -> u64 {
        self.skipped
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
                                false
                            } else {
                                continue;
                            }
                        }
                        Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                        Err(e) => return Err(e),
                    }
                }
                Kind::Stream(_) => self.fill()?,
            };
            if !got && self.pending.is_empty() {
                return Ok(None);
            }
        }
    }

    fn datagram(&mut self, b: Vec<u8>) {
        self.datagrams += 1;
        let n = self.datagrams;
        let arrival = Instant::now();
        if self.format != InputFormat::Csv {
            self.pending.push_back(Message {
                bytes: b,
                place: Place::Datagram(n, 0),
                arrival,
            });
            return;
        }
        for (l, line) in b.split(|&c| c == b'\n').enumerate() {
            if line.is_empty() {
                continue;
            }
            let kept = capped(line.len());
            self.skipped += (line.len() - kept) as u64;
            self.pending.push_back(Message {
                bytes: line[..kept].to_vec(),
                place: Place::Datagram(n, l as u64 + 1),
                arrival,
            });
        }
    }

    /// Reads more of the stream and cuts what is complete into messages; false at its end.
    fn fill(&mut self) -> std::io::Result<bool> {
        if self.eof {
            return Ok(false);
        }
        let Kind::Stream(r) = &mut self.kind else {
            unreachable!("a stream")
        };
        let chunk = loop {
            match r.recv_timeout(POLL) {
                Ok(c) => break c?,
                Err(RecvTimeoutError::Timeout) if stopped(&self.stop) => break Vec::new(),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break Vec::new(),
            }
        };
        let n = chunk.len();
        if n == 0 {
            self.eof = true;
        }
        self.buf.extend_from_slice(&chunk);
        match self.format {
            InputFormat::Csv => self.cut_lines(),
            InputFormat::Binary | InputFormat::Mavlink => self.cut_frames(),
        }
        Ok(n > 0 || !self.pending.is_empty())
    }

    /// Cuts complete lines off the front of the buffer (everything at the end of input). A
    /// line longer than [`MAX_LINE_BYTES`] becomes a message of its first `MAX_LINE_BYTES + 1`
    /// bytes, which the decoder refuses as too long, as soon as that many are in; the rest of
    /// it is skipped and counted as it arrives, so the buffer never holds more than one
    /// read beyond the limit and every byte is searched for the line end once.
    fn cut_lines(&mut self) {
        let arrival = Instant::now();
        let mut at = 0;
        loop {
            let rest = &self.buf[at..];
            if self.discarding {
                let (n, end) = match rest.iter().position(|&c| c == b'\n') {
                    Some(i) => (i + 1, true),
                    None => (rest.len(), false),
                };
                self.skipped += n as u64;
                at += n;
                self.discarding = !end;
                if !end {
                    break;
                }
                continue;
            }
            let from = self.scanned.min(rest.len());
            let len = match rest[from..].iter().position(|&c| c == b'\n') {
                Some(i) => from + i + 1,
                None if rest.len() > MAX_LINE_BYTES || (self.eof && !rest.is_empty()) => rest.len(),
                None => {
                    self.scanned = rest.len();
                    break;
                }
            };
            self.scanned = 0;
            let line = &rest[..len];
            let ended = line.last() == Some(&b'\n');
            let text = trim_line_end(line);
            let kept = capped(text.len());
            // A line beyond the limit is not one a simulation sends: its head goes to the
            // decoder, which refuses it, and the rest of it is skipped.
            self.skipped += (text.len() - kept) as u64;
            self.discarding = kept < text.len() && !ended && !self.eof;
            let bytes = text[..kept].to_vec();
            self.lines += 1;
            self.pending.push_back(Message {
                bytes,
                place: Place::Line(self.lines),
                arrival,
            });
            at += len;
        }
        self.buf.drain(..at);
        self.offset += at as u64;
    }

    /// Cuts complete binary datagrams or MAVLink frames off the front of the buffer
    /// (everything at the end of input).
    fn cut_frames(&mut self) {
        let arrival = Instant::now();
        let datagrams = self.format == InputFormat::Binary;
        let mut at = 0;
        loop {
            let rest = &self.buf[at..];
            let (start, len) = if datagrams {
                match find(rest, &binary::MAGIC) {
                    // A candidate that fails its CRC and holds another magic is a damaged or
                    // short frame: it ends where the next one starts.
                    Some(s) if rest.len() >= s + binary::LEN && !binary::crc_ok(&rest[s..]) => {
                        let inner = find(&rest[s + 1..s + binary::LEN], &binary::MAGIC);
                        (s, inner.map_or(binary::LEN, |j| j + 1))
                    }
                    Some(s) => (s, binary::LEN),
                    None => (rest.len().saturating_sub(3), 0),
                }
            } else {
                match rest.iter().position(|&c| c == mavlink::STX) {
                    Some(s) => match mavlink::frame_len(&rest[s..]) {
                        Some(l) => (s, l),
                        None => (s, usize::MAX),
                    },
                    None => (rest.len(), 0),
                }
            };
            // Bytes before a frame's start are garbage; keep a possible partial magic.
            let start = if self.eof {
                start.min(rest.len())
            } else {
                start
            };
            self.skipped += start as u64;
            at += start;
            let rest = &self.buf[at..];
            if len == 0 || len == usize::MAX || rest.len() < len {
                if self.eof {
                    self.skipped += rest.len() as u64;
                    at = self.buf.len();
                }
                break;
            }
            self.pending.push_back(Message {
                bytes: rest[..len].to_vec(),
                place: Place::Byte(self.offset + at as u64),
                arrival,
            });
            at += len;
        }
        self.buf.drain(..at);
        self.offset += at as u64;
    }
}

/// Bytes of a line of `len` bytes a message keeps: all of them, or one past the limit so the
/// decoder sees that it is too long.
fn capped(len: usize) -> usize {
    len.min(MAX_LINE_BYTES + 1)
}

fn trim_line_end(mut b: &[u8]) -> &[u8] {
    while let [rest @ .., b'\n' | b'\r'] = b {
        b = rest;
    }
    b
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn messages(format: InputFormat, bytes: Vec<u8>) -> (Vec<Message>, u64) {
        let mut r = Receiver::from_stream(Box::new(std::io::Cursor::new(bytes)), format, "x");
        let mut out = Vec::new();
        while let Some(m) = r.next_message().unwrap() {
            out.push(m);
        }
        (out, r.skipped_bytes())
    }

    #[test]
    fn parses_endpoints() {
        assert_eq!(
            Endpoint::parse("udp://127.0.0.1:5000").unwrap(),
            Endpoint::Udp("127.0.0.1:5000".parse().unwrap())
        );
        assert_eq!(
            Endpoint::parse("tcp://127.0.0.1:5001").unwrap(),
            Endpoint::Tcp("127.0.0.1:5001".parse().unwrap())
        );
        assert_eq!(
            Endpoint::parse("-").unwrap(),
            Endpoint::Stream(PathBuf::from("-"))
        );
        assert!(
            Endpoint::parse("udp://nohost")
                .unwrap_err()
                .contains("HOST:PORT")
        );
        assert!(
            Endpoint::parse("http://x")
                .unwrap_err()
                .contains("unknown scheme")
        );
    }

    /// Binary frames are found after garbage and across read boundaries; the garbage and a
    /// truncated last frame are counted, each frame named by its byte offset.
    #[test]
    fn binary_stream_framing() {
        let d = binary::Datagram {
            seq: 1,
            week: binary::NO_WEEK,
            time: 1.0,
            flags: 0,
            pos: [0.0; 3],
            vel: [0.0; 3],
            acc: [0.0; 3],
            quat: [1.0, 0.0, 0.0, 0.0],
            rate: [0.0; 3],
        };
        let f = binary::encode(&d);
        let mut s = b"junk!".to_vec();
        for _ in 0..40 {
            s.extend_from_slice(&f);
        }
        s.extend_from_slice(&f[..60]);
        let (m, skipped) = messages(InputFormat::Binary, s);
        assert_eq!(m.len(), 40);
        assert_eq!(m[0].place, Place::Byte(5));
        assert_eq!(m[39].place, Place::Byte(5 + 39 * 152));
        assert!(m.iter().all(|m| m.bytes == f));
        assert_eq!(skipped, 5 + 60);
    }

    #[test]
    fn csv_and_mavlink_stream_framing() {
        let (m, _) = messages(InputFormat::Csv, b"a,b\r\n\n1,2\n3,4".to_vec());
        let lines: Vec<&[u8]> = m.iter().map(|m| m.bytes.as_slice()).collect();
        assert_eq!(lines, vec![&b"a,b"[..], b"", b"1,2", b"3,4"]);
        assert_eq!(m[3].place, Place::Line(4));
        let f = mavlink::encode(1, 5, [1.0, 0.0, 0.0, 0.0], [0.0; 3], [1, 2, 3], [0; 3]);
        let mut s = vec![0u8, 1, 2];
        s.extend_from_slice(&f);
        s.extend_from_slice(&f);
        let (m, skipped) = messages(InputFormat::Mavlink, s);
        assert_eq!(m.len(), 2);
        assert_eq!(m[1].place, Place::Byte(3 + f.len() as u64));
        assert_eq!(skipped, 3);
    }

    /// A stream that yields `head`, then `n` bytes of `x` with no line end, then `tail`, a few
    /// bytes per read (as a slow sender's TCP segments).
    struct LongLine {
        head: Vec<u8>,
        n: usize,
        tail: Vec<u8>,
        at: usize,
    }

    impl Read for LongLine {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let total = self.head.len() + self.n + self.tail.len();
            let k = buf.len().min(1000).min(total - self.at);
            for b in &mut buf[..k] {
                let i = self.at;
                *b = if i < self.head.len() {
                    self.head[i]
                } else if i < self.head.len() + self.n {
                    b'x'
                } else {
                    self.tail[i - self.head.len() - self.n]
                };
                self.at += 1;
            }
            Ok(k)
        }
    }

    /// An 8 MB line without a line end (issue 23: once read whole and searched from its start
    /// on every read, quadratic in its length) becomes one message of the limit plus one byte,
    /// refused by the decoder as too long; the rest is skipped and counted; the buffer never
    /// holds more than the limit and a read; the lines after it come out with their numbers,
    /// and so does an over-long last line without an end.
    #[test]
    fn an_overlong_line_is_cut_and_counted() {
        let n = 8 << 20;
        for tail in [&b"\n1,2\n"[..], b""] {
            let stream = LongLine {
                head: b"a,b\n".to_vec(),
                n,
                tail: tail.to_vec(),
                at: 0,
            };
            let mut r = Receiver::from_stream(Box::new(stream), InputFormat::Csv, "x");
            let mut out = Vec::new();
            while let Some(m) = r.next_message().unwrap() {
                assert!(
                    r.buf.len() <= MAX_LINE_BYTES + 4096,
                    "{} buffered",
                    r.buf.len()
                );
                out.push(m);
            }
            let lines: Vec<usize> = out.iter().map(|m| m.bytes.len()).collect();
            let mut want = vec![3, MAX_LINE_BYTES + 1];
            if !tail.is_empty() {
                want.push(3);
            }
            assert_eq!(lines, want);
            assert_eq!(out[1].place, Place::Line(2));
            assert_eq!(out.last().unwrap().place, Place::Line(want.len() as u64));
            // The line's other bytes and its line end.
            let end = usize::from(!tail.is_empty());
            assert_eq!(r.skipped_bytes(), (n - MAX_LINE_BYTES - 1 + end) as u64);
            let e = crate::live::Decoder::new(InputFormat::Csv)
                .decode(&out[1].bytes)
                .unwrap_err();
            assert_eq!(e.offset, MAX_LINE_BYTES);
            assert!(e.message.contains("line longer than 65536 bytes"), "{e:?}");
        }
    }
}
