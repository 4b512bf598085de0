//! A loopback UDP receiver for the wall-clock tests that neither loses datagrams nor misdates
//! them when the machine is loaded: the kernel stamps each datagram on CLOCK_REALTIME as it
//! reaches the socket (`SO_TIMESTAMPNS`), so the receiving thread's own scheduling delay is not
//! in the arrival time; the socket's buffer is grown to 4 MiB (`SO_RCVBUFFORCE` as root, else up
//! to the system's limit) so a receiver thread that is not scheduled for a while does not drop
//! what arrives meanwhile; and it stops on an event — [`UdpRx::stop`], called once the sender
//! has exited — after reading everything queued, never after a fixed time or a silence.
#![allow(dead_code)]

use std::net::UdpSocket;
use std::os::fd::AsRawFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use nix::sys::socket::{self, ControlMessageOwned, MsgFlags, sockopt};

/// A datagram: the kernel's CLOCK_REALTIME stamp of its arrival (ns since the Unix epoch), and
/// its bytes.
pub type Stamped = (i128, Vec<u8>);

/// A receiver on its own thread.
pub struct UdpRx {
    /// Its address (`127.0.0.1:PORT`).
    pub dest: String,
    done: Arc<AtomicBool>,
    count: Arc<AtomicUsize>,
    thread: JoinHandle<Vec<Stamped>>,
}

impl UdpRx {
    /// Binds a loopback port and starts receiving.
    pub fn start() -> UdpRx {
        UdpRx::bind("127.0.0.1:0")
    }

    /// Binds `addr` (a group's port, say) and starts receiving.
    pub fn bind(addr: &str) -> UdpRx {
        let sock = UdpSocket::bind(addr).unwrap();
        grow(&sock);
        socket::setsockopt(&sock, sockopt::ReceiveTimestampns, &true).unwrap();
        sock.set_read_timeout(Some(Duration::from_millis(20)))
            .unwrap();
        let dest = sock.local_addr().unwrap().to_string();
        let done = Arc::new(AtomicBool::new(false));
        let count = Arc::new(AtomicUsize::new(0));
        let (stop, counted) = (done.clone(), count.clone());
        let thread = std::thread::spawn(move || {
            let mut got = Vec::new();
            loop {
                // Read after the flag: once it is set, whatever was queued before is drained
                // by reads that time out only when the queue is empty.
                let last = stop.load(Ordering::Acquire);
                while let Some(d) = recv(&sock) {
                    got.push(d);
                    counted.fetch_add(1, Ordering::Relaxed);
                }
                if last {
                    break;
                }
            }
            got
        });
        UdpRx {
            dest,
            done,
            count,
            thread,
        }
    }

    /// Waits until `n` datagrams have come (a hang guard of 60 s: the sender is started by the
    /// caller, however loaded the machine).
    pub fn wait_for(&self, n: usize) {
        let t = std::time::Instant::now();
        while self.count.load(Ordering::Relaxed) < n {
            assert!(t.elapsed() < Duration::from_secs(60), "no frames came");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// The port.
    pub fn port(&self) -> u16 {
        self.dest.rsplit(':').next().unwrap().parse().unwrap()
    }

    /// Everything received, in order: call once the sender has exited (its datagrams are then
    /// all in the socket's queue, loopback delivering within the send call).
    pub fn stop(self) -> Vec<Stamped> {
        self.done.store(true, Ordering::Release);
        self.thread.join().unwrap()
    }
}

/// Grows the socket's receive buffer to 4 MiB: forced as root, else as far as
/// `net.core.rmem_max` allows.
fn grow(sock: &UdpSocket) {
    const WANT: usize = 4 << 20;
    if socket::setsockopt(sock, sockopt::RcvBufForce, &WANT).is_err() {
        let _ = socket::setsockopt(sock, sockopt::RcvBuf, &WANT);
    }
}

/// One datagram with its kernel stamp; `None` when none came within the read timeout.
fn recv(sock: &UdpSocket) -> Option<Stamped> {
    let mut buf = vec![0u8; 65536];
    let mut cmsg = nix::cmsg_space!(nix::sys::time::TimeSpec);
    let (n, stamp) = {
        let mut iov = [std::io::IoSliceMut::new(&mut buf)];
        let msg = socket::recvmsg::<()>(
            sock.as_raw_fd(),
            &mut iov,
            Some(&mut cmsg),
            MsgFlags::empty(),
        )
        .ok()?;
        let stamp = msg.cmsgs().ok()?.find_map(|c| match c {
            ControlMessageOwned::ScmTimestampns(t) => {
                Some(t.tv_sec() as i128 * 1_000_000_000 + t.tv_nsec() as i128)
            }
            _ => None,
        });
        (msg.bytes, stamp)
    };
    buf.truncate(n);
    Some((
        stamp.expect("SO_TIMESTAMPNS gives every datagram a stamp"),
        buf,
    ))
}

/// The datagrams' bytes back to back.
pub fn joined(d: &[Stamped]) -> Vec<u8> {
    d.iter().flat_map(|x| x.1.iter().copied()).collect()
}
