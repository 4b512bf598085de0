//! UDP sink: frames as datagrams (one each, or `batch` per datagram) to a unicast, broadcast
//! or multicast address. Nobody listening is normal: refused datagrams are ignored.

use std::io;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};

use crate::protocol::{Plan, Transport};

use super::sink::{Sink, SinkStats};

/// Largest UDP payload over IPv4: 65 535 (IP total length) − 20 (IP header) − 8 (UDP header)
/// (RFC 791, RFC 768).
pub const MAX_DATAGRAM_V4: usize = 65_507;
/// Largest UDP payload over IPv6 without jumbograms: 65 535 (payload length, which excludes
/// the fixed header) − 8 (UDP header) (RFC 8200, RFC 768).
pub const MAX_DATAGRAM_V6: usize = 65_527;

/// Most bytes one frame of `plan` can take on the wire, transport included: stuffing can
/// double every byte of an HDLC payload and FCS, and adds one bit per five of SDLC's (plus
/// its flags, idle fill and the marks to a byte boundary).
pub fn max_wire_len(plan: &Plan) -> usize {
    let payload = plan.max_len();
    match &plan.transport {
        Transport::Plain => payload,
        Transport::Hdlc(o) => 2 + 2 * (payload + o.fcs.len()),
        Transport::Sdlc(o) => {
            let data_bits = 8 * (payload + o.fcs.len());
            let bits = 8 * (o.opening_flags.max(1) as usize + 1)
                + data_bits.div_ceil(5) * 6
                + o.idle_bits as usize;
            bits.div_ceil(8) + 1
        }
    }
}

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
    /// A socket sending to `dest` (`HOST:PORT`), `batch` frames per datagram. Port 0 is
    /// refused: no datagram can be sent there.
    pub fn open(dest: &str, batch: usize) -> io::Result<UdpSink> {
        let addr = dest
            .to_socket_addrs()?
            .next()
            .ok_or_else(|| io::Error::other(format!("{dest}: no address")))?;
        if addr.port() == 0 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "port 0 cannot be sent to: give the receiver's port",
            ));
        }
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

    /// Checks that `batch` frames of at most `frame_bytes` each fit one datagram to this
    /// destination: a larger one is refused by the kernel on every send (`EMSGSIZE`).
    pub fn check_datagram(&self, frame_bytes: usize) -> Result<(), String> {
        let max = match self.dest {
            SocketAddr::V4(_) => MAX_DATAGRAM_V4,
            SocketAddr::V6(_) => MAX_DATAGRAM_V6,
        };
        let need = frame_bytes.saturating_mul(self.batch);
        if need > max {
            return Err(format!(
                "{} frames of up to {frame_bytes} bytes make {need}-byte datagrams, more than the {max} bytes a UDP datagram can carry: lower --udp-batch to at most {}",
                self.batch,
                (max / frame_bytes.max(1)).max(1)
            ));
        }
        Ok(())
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
    fn live(&self) -> bool {
        true
    }

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
    use nix::sys::socket::{setsockopt, sockopt};
    let size = 4usize << 20;
    if setsockopt(sock, sockopt::RcvBufForce, &size).is_err() {
        // Unprivileged: the kernel caps the request at net.core.rmem_max; best effort.
        let _ = setsockopt(sock, sockopt::RcvBuf, &size);
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

    /// The datagram limit is the IPv4 one to the byte (1819 frames of 36 bytes fit 65 507,
    /// 1820 do not); port 0 is refused when the sink opens.
    #[test]
    fn datagram_limits() {
        let s = UdpSink::open("127.0.0.1:9", 1819).unwrap();
        assert!(s.check_datagram(36).is_ok());
        let s = UdpSink::open("127.0.0.1:9", 1820).unwrap();
        let e = s.check_datagram(36).unwrap_err();
        assert!(
            e.contains("65520-byte") && e.contains("at most 1819"),
            "{e}"
        );
        let e = UdpSink::open("127.0.0.1:0", 1).err().unwrap();
        assert!(e.to_string().contains("port 0"), "{e}");
        let (_, plan) = crate::protocol::load("kvh1750").unwrap();
        assert_eq!(max_wire_len(&plan), plan.len());
    }
}
