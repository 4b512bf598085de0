//! Non-blocking whole-frame writes to a file descriptor or a socket, which the pty, serial and
//! TCP sinks share; the [`Sink`] trait and the file sink are `crate::output::sink`'s.

use std::io;
use std::os::fd::{AsFd, BorrowedFd};

pub use crate::output::sink::{FileSink, Sink, SinkStats};

/// Non-blocking writes of whole frames to a file descriptor (pty master, serial device) or a
/// socket (a TCP connection).
///
/// A write the kernel takes only partly leaves the rest of that frame in `pending`, sent
/// before anything else next time, so the byte stream never carries a torn frame; the frames
/// after it are dropped and counted.
#[derive(Debug, Default)]
pub struct FdWriter {
    pending: Vec<u8>,
    /// Counts so far.
    pub stats: SinkStats,
}

/// What a non-blocking write found.
#[derive(Debug, PartialEq, Eq)]
pub enum FdState {
    /// Written, or dropped because the consumer is slow (counted).
    Ok,
    /// Nobody holds the other end (`EIO` on a pty with no reader, a TCP peer that closed).
    /// Frames counted as `no_reader`.
    NoReader,
}

impl FdWriter {
    /// Forgets a partly written frame (the consumer went away: a new one starts clean).
    pub fn reset(&mut self) {
        self.pending.clear();
    }

    /// What is left of a cut frame, taken out to be finished another way (at the end of a
    /// run, with a bounded wait); counted as written.
    pub fn take_pending(&mut self) -> Vec<u8> {
        self.stats.bytes += self.pending.len() as u64;
        std::mem::take(&mut self.pending)
    }

    /// Writes the frames to `fd` (opened `O_NONBLOCK`); `EIO` says nobody holds the other end.
    pub fn write(&mut self, fd: BorrowedFd, bytes: &[u8], ends: &[usize]) -> io::Result<FdState> {
        let eio = |e: &io::Error| e.raw_os_error() == Some(libc::EIO);
        self.write_via(|b| raw_write(fd, b), eio, bytes, ends)
    }

    /// Writes the frames with `raw` (one non-blocking write, returning the bytes taken);
    /// an error `gone` accepts means the consumer went away (counted as `no_reader`, what is
    /// left of a cut frame forgotten), any other but `WouldBlock` is returned.
    pub fn write_via(
        &mut self,
        mut raw: impl FnMut(&[u8]) -> io::Result<usize>,
        gone: impl Fn(&io::Error) -> bool,
        bytes: &[u8],
        ends: &[usize],
    ) -> io::Result<FdState> {
        if !self.pending.is_empty() {
            match raw(&self.pending) {
                Ok(n) => {
                    self.stats.bytes += n as u64;
                    self.pending.drain(..n);
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {}
                Err(e) if gone(&e) => {
                    self.pending.clear();
                }
                Err(e) => return Err(e),
            }
            if !self.pending.is_empty() {
                self.stats.dropped += ends.len() as u64;
                return Ok(FdState::Ok);
            }
        }
        if bytes.is_empty() {
            return Ok(FdState::Ok);
        }
        match raw(bytes) {
            Ok(n) => {
                self.stats.bytes += n as u64;
                let whole = ends.partition_point(|&e| e <= n);
                self.stats.sent += whole as u64;
                if whole < ends.len() {
                    let start = if whole == 0 { 0 } else { ends[whole - 1] };
                    if n > start {
                        // Part of frame `whole` went out: finish it next time, count it sent.
                        self.pending.extend_from_slice(&bytes[n..ends[whole]]);
                        self.stats.sent += 1;
                        self.stats.dropped += (ends.len() - whole - 1) as u64;
                    } else {
                        self.stats.dropped += (ends.len() - whole) as u64;
                    }
                }
                Ok(FdState::Ok)
            }
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                self.stats.dropped += ends.len() as u64;
                Ok(FdState::Ok)
            }
            Err(e) if gone(&e) => {
                self.stats.no_reader += ends.len() as u64;
                Ok(FdState::NoReader)
            }
            Err(e) => Err(e),
        }
    }
}

fn raw_write(fd: BorrowedFd, bytes: &[u8]) -> io::Result<usize> {
    Ok(nix::unistd::write(fd, bytes)?)
}

/// Sets `O_NONBLOCK` on a descriptor.
pub fn set_nonblocking(fd: impl AsFd) -> io::Result<()> {
    use nix::fcntl::{FcntlArg, OFlag, fcntl};
    let fd = fd.as_fd();
    let flags = OFlag::from_bits_truncate(fcntl(fd, FcntlArg::F_GETFL)?);
    fcntl(fd, FcntlArg::F_SETFL(flags | OFlag::O_NONBLOCK))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::os::fd::OwnedFd;

    fn pipe() -> (OwnedFd, OwnedFd) {
        let (r, w) = nix::unistd::pipe().unwrap();
        set_nonblocking(&w).unwrap();
        (r, w)
    }

    /// A full pipe: the frame cut by the kernel is completed first on the next write, the
    /// frames after it are dropped and counted, and the reader sees only whole frames.
    #[test]
    fn partial_writes_keep_frames_whole() {
        let (r, w) = pipe();
        let frame = |i: u8| vec![i; 1000];
        let mut fw = FdWriter::default();
        let mut total = 0u64;
        // Fill the pipe (64 KiB) with 1000-byte frames, 10 per write.
        for round in 0..10u8 {
            let mut bytes = Vec::new();
            let mut ends = Vec::new();
            for i in 0..10u8 {
                bytes.extend(frame(round * 10 + i));
                ends.push(bytes.len());
            }
            total += 10;
            fw.write(w.as_fd(), &bytes, &ends).unwrap();
        }
        assert_eq!(fw.stats.sent + fw.stats.dropped, total);
        assert!(fw.stats.dropped > 0, "a 64 KiB pipe cannot take 100 kB");
        // Drain, then one more write completes the cut frame before the new one.
        let mut reader = std::fs::File::from(r);
        let mut got = vec![0u8; 1 << 17];
        let n = reader.read(&mut got).unwrap();
        fw.write(w.as_fd(), &frame(200), &[1000]).unwrap();
        let m = reader.read(&mut got[n..]).unwrap();
        let got = &got[..n + m];
        assert_eq!(got.len() % 1000, 0, "only whole frames on the wire");
        for f in got.chunks(1000) {
            assert!(f.iter().all(|&b| b == f[0]), "a frame mixes two frames");
        }
        assert_eq!(*got.last().unwrap(), 200);
        assert_eq!(fw.stats.bytes as usize, got.len());
    }
}
