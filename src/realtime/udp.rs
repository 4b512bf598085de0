//! UDP sink: frames as datagrams (one each, or `batch` per datagram) to a unicast, broadcast
//! or multicast address. Nobody listening is normal: refused datagrams are ignored.

use std::io;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};

use super::sink::{Sink, SinkStats};

/// A UDP destination.
pub struct UdpSink {
    label: String,
    sock: UdpSocket,
    dest: SocketAddr,
    batch: usize,
    buf: Vec<u8>,
    in_buf: usize,
    stats: SinkStats,
}

impl UdpSink {
    /// A socket sending to `dest` (`HOST:PORT`), `batch` frames per datagram.
    pub fn open(dest: &str, batch: usize) -> io::Result<UdpSink> {
        let addr = dest
            .to_socket_addrs()?
            .next()
            .ok_or_else(|| io::Error::other(format!("{dest}: no address")))?;
        let sock = match addr {
            SocketAddr::V4(_) => UdpSocket::bind("0.0.0.0:0")?,
            SocketAddr::V6(_) => UdpSocket::bind("[::]:0")?,
        };
        if let SocketAddr::V4(a) = addr {
            // Broadcast needs the permission; multicast goes one hop and loops back locally.
            sock.set_broadcast(true)?;
            if a.ip().is_multicast() {
                sock.set_multicast_ttl_v4(1)?;
                sock.set_multicast_loop_v4(true)?;
            }
        }
        sock.set_nonblocking(true)?;
        Ok(UdpSink {
            label: format!("udp {dest}"),
            sock,
            dest: addr,
            batch: batch.max(1),
            buf: Vec::new(),
            in_buf: 0,
            stats: SinkStats::default(),
        })
    }

    fn send(&mut self) {
        if self.in_buf == 0 {
            return;
        }
        let n = self.in_buf as u64;
        let mut res = self.sock.send_to(&self.buf, self.dest);
        // A refusal reports an earlier datagram that found no listener: ignore it and send.
        if res
            .as_ref()
            .is_err_and(|e| e.kind() == io::ErrorKind::ConnectionRefused)
        {
            res = self.sock.send_to(&self.buf, self.dest);
        }
        match res {
            Ok(b) => {
                self.stats.sent += n;
                self.stats.bytes += b as u64;
            }
            Err(e) => {
                tracing::debug!("{}: {e}", self.label);
                self.stats.dropped += n;
            }
        }
        self.buf.clear();
        self.in_buf = 0;
    }
}

impl Sink for UdpSink {
    fn label(&self) -> &str {
        &self.label
    }

    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()> {
        let mut start = 0;
        for &end in ends {
            self.buf.extend_from_slice(&bytes[start..end]);
            self.in_buf += 1;
            start = end;
            if self.in_buf == self.batch {
                self.send();
            }
        }
        Ok(())
    }

    fn finish(&mut self) -> io::Result<()> {
        self.send();
        Ok(())
    }

    fn stats(&self) -> SinkStats {
        self.stats
    }
}

/// Asks for a 4 MiB receive buffer so a receiver descheduled for a while loses no datagram:
/// SO_RCVBUFFORCE where privileged, else SO_RCVBUF (capped by net.core.rmem_max).
pub fn grow_receive_buffer(sock: &UdpSocket) {
    use std::os::fd::AsRawFd;
    let size: libc::c_int = 4 << 20;
    for opt in [libc::SO_RCVBUFFORCE, libc::SO_RCVBUF] {
        // SAFETY: setsockopt reads one int through a valid pointer of the stated length.
        let rc = unsafe {
            libc::setsockopt(
                sock.as_raw_fd(),
                libc::SOL_SOCKET,
                opt,
                (&size as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        if rc == 0 {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Batches of 3 frames: 7 frames make datagrams of 3, 3 and (at the end) 1 frames; with
    /// no listener the sends still succeed or are counted, never fail the run.
    #[test]
    fn batching_and_no_listener() {
        let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut s = UdpSink::open(&rx.local_addr().unwrap().to_string(), 3).unwrap();
        let bytes: Vec<u8> = (0..14).collect();
        let ends: Vec<usize> = (1..=7).map(|i| 2 * i).collect();
        s.write(&bytes, &ends).unwrap();
        s.finish().unwrap();
        let mut buf = [0u8; 64];
        let sizes: Vec<usize> = (0..3).map(|_| rx.recv(&mut buf).unwrap()).collect();
        assert_eq!(sizes, [6, 6, 2]);
        assert_eq!(s.stats().sent, 7);
        let port = rx.local_addr().unwrap().port();
        drop(rx);
        let mut s = UdpSink::open(&format!("127.0.0.1:{port}"), 1).unwrap();
        for _ in 0..5 {
            s.write(&bytes, &ends).unwrap();
        }
        assert_eq!(s.stats().sent + s.stats().dropped, 35);
    }
}
