//! TCP sinks: `tcp:HOST:PORT` connects to a consumer listening there (a receiver's TCP port),
//! `tcp-listen:ADDR:PORT` listens and sends every frame to every client connected (a
//! serial-over-TCP server). Like the other real-time sinks they never hold the pacer up: whole
//! frames, written non-blocking ([`FdWriter`]); what a consumer cannot take now is dropped and
//! counted, frames with no consumer connected count as "no reader", and a consumer that joins
//! (or rejoins) starts on a frame boundary.
//!
//! Reconnect policy of `tcp:`: the first connection is made when the sink opens (waiting at
//! most [`CONNECT_TIMEOUT`]); a refused or unanswered one is not an error, the consumer may
//! start later. While not connected — from the start, or after the consumer closed or reset
//! the connection — a helper thread tries again every [`RETRY`], so the pacer never waits for
//! a connection; the frames meanwhile count as "no reader".

use std::io::{self, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::{Duration, Instant};

use super::sink::{FdState, FdWriter, Sink, SinkStats};

/// Interval between connection attempts of a `tcp:` sink that is not connected.
pub const RETRY: Duration = Duration::from_secs(1);
/// Longest wait for one connection attempt.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(1);

/// Any write error ends a TCP connection (reset, broken pipe, timed out, unreachable): the
/// consumer has gone, which never stops the run.
fn gone(_: &io::Error) -> bool {
    true
}

/// The longest a closing connection waits to finish a cut frame.
const CLOSE_WAIT: Duration = Duration::from_secs(2);

/// Adds the counts of `b` to `a`.
fn add(a: &mut SinkStats, b: SinkStats) {
    a.sent += b.sent;
    a.dropped += b.dropped;
    a.no_reader += b.no_reader;
    a.bytes += b.bytes;
}

/// One connection and its whole-frame writer.
struct Conn {
    stream: TcpStream,
    writer: FdWriter,
}

impl Conn {
    fn new(stream: TcpStream) -> io::Result<Conn> {
        stream.set_nonblocking(true)?;
        // A frame leaves at once rather than waiting to fill a segment.
        stream.set_nodelay(true)?;
        Ok(Conn {
            stream,
            writer: FdWriter::default(),
        })
    }

    /// Writes the frames; false once the consumer has gone. (std's TCP writes pass
    /// `MSG_NOSIGNAL`: a closed peer is an error here, never a SIGPIPE.)
    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> bool {
        let Conn { stream, writer } = self;
        let state = writer.write_via(|b| (&*stream).write(b), gone, bytes, ends);
        matches!(state, Ok(FdState::Ok))
    }

    /// Finishes a frame cut by a full buffer and closes the sending side, so the consumer
    /// reads to the end of what was sent, whole frames only. The run is over, so waiting
    /// (at most [`CLOSE_WAIT`]) delays nothing; a consumer that takes nothing in that time
    /// gets a reset instead of a clean end after a torn frame.
    fn close(&mut self) {
        self.write(&[], &[]);
        let rest = self.writer.take_pending();
        if !rest.is_empty() {
            let s = &self.stream;
            let done = (s.set_nonblocking(false))
                .and_then(|()| s.set_write_timeout(Some(CLOSE_WAIT)))
                .and_then(|()| (&*s).write_all(&rest));
            if done.is_err() {
                // SO_LINGER 0: the close that follows (on drop) sends RST.
                let off = nix::sys::socket::sockopt::Linger;
                let zero = libc::linger {
                    l_onoff: 1,
                    l_linger: 0,
                };
                let _ = nix::sys::socket::setsockopt(s, off, &zero);
                return;
            }
        }
        let _ = self.stream.shutdown(Shutdown::Write);
    }
}

/// The one address of `dest` (`HOST:PORT`); port 0 is refused.
fn resolve(dest: &str) -> io::Result<SocketAddr> {
    let addr = (dest.to_socket_addrs()?.next())
        .ok_or_else(|| io::Error::other(format!("{dest}: no address")))?;
    if addr.port() == 0 {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "port 0 cannot be connected to: give the consumer's port",
        ));
    }
    Ok(addr)
}

/// A consumer's TCP port, connected to and reconnected as the module says.
pub struct TcpSink {
    label: String,
    conn: Option<Conn>,
    /// Connections the helper thread made.
    made: mpsc::Receiver<TcpStream>,
    /// Asks the helper for a connection; dropped with the sink, it ends the helper.
    want: mpsc::Sender<()>,
    /// Counts of the closed connections, and frames written with none.
    stats: SinkStats,
}

impl TcpSink {
    /// A sink connected (or connecting) to `dest` (`HOST:PORT`); a name that does not resolve
    /// and port 0 are errors, a consumer not listening yet is not.
    pub fn open(dest: &str) -> io::Result<TcpSink> {
        let addr = resolve(dest)?;
        let (made_tx, made) = mpsc::channel();
        let (want, want_rx) = mpsc::channel();
        let conn = match TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT) {
            Ok(s) => Some(Conn::new(s)?),
            Err(e) => {
                tracing::debug!("tcp {dest}: {e}; retrying every {RETRY:?}");
                let _ = want.send(());
                None
            }
        };
        std::thread::Builder::new()
            .name("imu-tcp-connect".into())
            .spawn(move || connector(addr, want_rx, made_tx))?;
        Ok(TcpSink {
            label: format!("tcp {dest}"),
            conn,
            made,
            want,
            stats: SinkStats::default(),
        })
    }

    /// Whether a consumer is connected now.
    pub fn connected(&self) -> bool {
        self.conn.is_some()
    }
}

/// The helper of a [`TcpSink`]: for each request, connects (every [`RETRY`] until it
/// succeeds) and hands the connection over; ends when the sink is dropped.
fn connector(addr: SocketAddr, want: mpsc::Receiver<()>, made: mpsc::Sender<TcpStream>) {
    while want.recv().is_ok() {
        loop {
            let tried = Instant::now();
            match TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT) {
                Ok(s) => {
                    if made.send(s).is_err() {
                        return;
                    }
                    break;
                }
                Err(e) => tracing::debug!("tcp {addr}: {e}"),
            }
            let left = RETRY.saturating_sub(tried.elapsed());
            if let Err(RecvTimeoutError::Disconnected) = want.recv_timeout(left) {
                return;
            }
        }
    }
}

impl Sink for TcpSink {
    fn live(&self) -> bool {
        true
    }

    fn label(&self) -> &str {
        &self.label
    }

    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()> {
        if self.conn.is_none()
            && let Ok(s) = self.made.try_recv()
        {
            match Conn::new(s) {
                Ok(c) => self.conn = Some(c),
                Err(_) => {
                    let _ = self.want.send(());
                }
            }
        }
        match &mut self.conn {
            None => self.stats.no_reader += ends.len() as u64,
            Some(c) => {
                if !c.write(bytes, ends) {
                    let c = self.conn.take().expect("connected");
                    add(&mut self.stats, c.writer.stats);
                    let _ = self.want.send(());
                }
            }
        }
        Ok(())
    }

    fn finish(&mut self) -> io::Result<()> {
        if let Some(c) = &mut self.conn {
            c.close();
        }
        Ok(())
    }

    fn stats(&self) -> SinkStats {
        let mut s = self.stats;
        if let Some(c) = &self.conn {
            add(&mut s, c.writer.stats);
        }
        s
    }
}

/// A listening port: every frame to every client connected. The counts are per delivery:
/// a frame two clients took counts as sent twice; one no client was connected for counts
/// once as "no reader".
pub struct TcpListenSink {
    label: String,
    listener: TcpListener,
    clients: Vec<Conn>,
    /// Counts of the clients gone, and frames written with none.
    stats: SinkStats,
}

impl TcpListenSink {
    /// Listens on `addr` (`ADDR:PORT`; port 0: one the system picks, see
    /// [`TcpListenSink::local_addr`]).
    pub fn open(addr: &str) -> io::Result<TcpListenSink> {
        let listener = TcpListener::bind(addr)?;
        listener.set_nonblocking(true)?;
        // The port the system gave, when asked for port 0.
        let bound = listener.local_addr()?;
        Ok(TcpListenSink {
            label: format!("tcp-listen {bound}"),
            listener,
            clients: Vec::new(),
            stats: SinkStats::default(),
        })
    }

    /// The address it listens on.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.clients.len()
    }

    /// Takes the clients waiting to be accepted.
    fn accept(&mut self) {
        loop {
            match self.listener.accept() {
                Ok((s, peer)) => match Conn::new(s) {
                    Ok(c) => {
                        tracing::info!("{}: client {peer} connected", self.label);
                        self.clients.push(c);
                    }
                    Err(e) => tracing::debug!("{}: client {peer}: {e}", self.label),
                },
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                // A client that reset before being accepted, or no descriptor left: the
                // next write tries again.
                Err(e) => {
                    tracing::debug!("{}: accept: {e}", self.label);
                    return;
                }
            }
        }
    }
}

impl Sink for TcpListenSink {
    fn live(&self) -> bool {
        true
    }

    fn label(&self) -> &str {
        &self.label
    }

    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()> {
        self.accept();
        if self.clients.is_empty() {
            self.stats.no_reader += ends.len() as u64;
            return Ok(());
        }
        let stats = &mut self.stats;
        self.clients.retain_mut(|c| {
            let alive = c.write(bytes, ends);
            if !alive {
                add(stats, c.writer.stats);
            }
            alive
        });
        Ok(())
    }

    fn finish(&mut self) -> io::Result<()> {
        self.clients.iter_mut().for_each(Conn::close);
        Ok(())
    }

    fn stats(&self) -> SinkStats {
        let mut s = self.stats;
        for c in &self.clients {
            add(&mut s, c.writer.stats);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    /// Frames `0..n` of 10 bytes each (byte value = frame number), and their ends.
    fn frames(first: u8, n: u8) -> (Vec<u8>, Vec<usize>) {
        let bytes: Vec<u8> = (first..first + n).flat_map(|i| [i; 10]).collect();
        let ends = (1..=n as usize).map(|i| 10 * i).collect();
        (bytes, ends)
    }

    /// Reads `stream` to its end.
    fn read_all(mut s: TcpStream) -> Vec<u8> {
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut v = Vec::new();
        s.read_to_end(&mut v).unwrap();
        v
    }

    /// A consumer listening at the start gets every frame in order; one that closes is
    /// replaced by the next connection (within the retry interval), which starts on a frame
    /// boundary; frames with no consumer count as "no reader".
    #[test]
    fn client_connects_and_reconnects() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let mut sink = TcpSink::open(&l.local_addr().unwrap().to_string()).unwrap();
        assert!(sink.connected());
        let (first, _) = l.accept().unwrap();
        let (b, e) = frames(0, 5);
        sink.write(&b, &e).unwrap();
        drop(first);
        // Writes into a closed connection fail (reset, broken pipe) within a few tries.
        let mut n = 5u8;
        while sink.connected() {
            let (b, e) = frames(n, 1);
            sink.write(&b, &e).unwrap();
            n += 1;
            std::thread::sleep(Duration::from_millis(10));
        }
        let (second, _) = l.accept().unwrap();
        let t = Instant::now();
        // The write that takes up the new connection sends its frame on it.
        let mut expected = Vec::new();
        while !sink.connected() {
            assert!(t.elapsed() < RETRY * 3, "reconnected");
            let (b, e) = frames(n, 1);
            sink.write(&b, &e).unwrap();
            if sink.connected() {
                expected = b;
            }
            n += 1;
            std::thread::sleep(Duration::from_millis(20));
        }
        let (b, e) = frames(200, 3);
        sink.write(&b, &e).unwrap();
        expected.extend(b);
        sink.finish().unwrap();
        let got = read_all(second);
        assert_eq!(got, expected, "the new connection starts at a frame");
        let s = sink.stats();
        assert!(s.no_reader >= 1, "{s:?}");
        assert_eq!(s.sent + s.no_reader, u64::from(n) + 3, "{s:?}");
    }

    /// Nobody listening at the start: not an error; frames count as "no reader" until a
    /// consumer appears, then reach it. Port 0 and unresolvable names are refused.
    #[test]
    fn client_waits_for_a_consumer() {
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let mut sink = TcpSink::open(&format!("127.0.0.1:{port}")).unwrap();
        assert!(!sink.connected());
        let (b, e) = frames(0, 2);
        sink.write(&b, &e).unwrap();
        assert_eq!(sink.stats().no_reader, 2);
        let l = TcpListener::bind(("127.0.0.1", port)).unwrap();
        let t = Instant::now();
        while !sink.connected() {
            assert!(t.elapsed() < RETRY * 3, "connected");
            std::thread::sleep(Duration::from_millis(20));
            sink.write(&[], &[]).unwrap();
        }
        let (c, _) = l.accept().unwrap();
        let (b, e) = frames(7, 2);
        sink.write(&b, &e).unwrap();
        sink.finish().unwrap();
        assert_eq!(read_all(c), b);
        let e = TcpSink::open("127.0.0.1:0").err().unwrap();
        assert!(e.to_string().contains("port 0"), "{e}");
        assert!(TcpSink::open("no-such-host.invalid:5").is_err());
    }

    /// Two clients get every frame; one that reads nothing fills its buffers and then
    /// loses frames (whole ones: what it reads later is frames back to back, each intact,
    /// to the end) while the other still gets all; a client that leaves is dropped.
    #[test]
    fn listener_serves_every_client() {
        let mut sink = TcpListenSink::open("127.0.0.1:0").unwrap();
        let addr = sink.local_addr().unwrap();
        let (b, e) = frames(0, 3);
        sink.write(&b, &e).unwrap();
        assert_eq!(sink.stats().no_reader, 3);
        let fast = TcpStream::connect(addr).unwrap();
        let slow = TcpStream::connect(addr).unwrap();
        let gone = TcpStream::connect(addr).unwrap();
        let reader = std::thread::spawn(move || read_all(fast));
        // Frames of 1000 bytes: the slow client's socket buffers fill after a few MB.
        let frame = |i: u32| vec![(i % 251) as u8; 1000];
        let mut sent = 0u32;
        while sink.clients() < 3 {
            sink.write(&frame(sent), &[1000]).unwrap();
            sent += 1;
        }
        drop(gone);
        for _ in 0..20_000 {
            sink.write(&frame(sent), &[1000]).unwrap();
            sent += 1;
        }
        assert_eq!(sink.clients(), 2, "the client that left is dropped");
        // The slow client reads from now on: the frame its full buffer cut is finished when
        // the sink closes, so it too ends on a frame boundary.
        let slow_reader = std::thread::spawn(move || read_all(slow));
        sink.finish().unwrap();
        let fast_got = reader.join().unwrap();
        let slow_got = slow_reader.join().unwrap();
        let s = sink.stats();
        assert!(s.dropped > 0, "the slow client lost frames: {s:?}");
        for got in [&fast_got, &slow_got] {
            assert_eq!(got.len() % 1000, 0);
            for f in got.chunks(1000) {
                assert!(f.iter().all(|&x| x == f[0]), "a torn frame");
            }
        }
        assert!(fast_got.len() >= slow_got.len());
    }
}
