//! Sinks: where frames go. Every sink takes whole frames and never blocks the pacer for long:
//! what it cannot take now is dropped and counted (a file is the exception: it is assumed to
//! keep up, and an unpaced run waits for it so that no frame is lost).

use std::io::{self, Write};
use std::os::fd::{AsFd, BorrowedFd};

/// What a sink delivered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SinkStats {
    /// Frames written whole.
    pub sent: u64,
    /// Frames dropped because the consumer could not take them (full buffer, slow link).
    pub dropped: u64,
    /// Frames dropped because nobody was reading (a pty with no reader).
    pub no_reader: u64,
    /// Bytes written.
    pub bytes: u64,
}

/// A destination for frames.
pub trait Sink: Send {
    /// What the user named (`pty /tmp/imu`, `udp 127.0.0.1:5000`, …).
    fn label(&self) -> &str;
    /// Writes frames `bytes`, frame `i` ending at `ends[i]` (offsets into `bytes`).
    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()>;
    /// Writes what is still buffered (end of run).
    fn finish(&mut self) -> io::Result<()> {
        Ok(())
    }
    /// Counts so far.
    fn stats(&self) -> SinkStats;
}

/// Non-blocking writes of whole frames to a file descriptor (pty master, serial device).
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
    /// `EIO`: nobody holds the other end (a pty with no reader). Frames counted as `no_reader`.
    NoReader,
}

impl FdWriter {
    /// Forgets a partly written frame (the consumer went away: a new one starts clean).
    pub fn reset(&mut self) {
        self.pending.clear();
    }

    /// Writes the frames to `fd` (opened `O_NONBLOCK`).
    pub fn write(&mut self, fd: BorrowedFd, bytes: &[u8], ends: &[usize]) -> io::Result<FdState> {
        if !self.pending.is_empty() {
            match raw_write(fd, &self.pending) {
                Ok(n) => {
                    self.stats.bytes += n as u64;
                    self.pending.drain(..n);
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {}
                Err(e) if e.raw_os_error() == Some(libc::EIO) => {
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
        match raw_write(fd, bytes) {
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
            Err(e) if e.raw_os_error() == Some(libc::EIO) => {
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

/// A file or stdout: every frame written, in order (a slow disk delays the run; paced runs
/// flush after every wake-up so a reader sees frames at their time).
pub struct FileSink {
    label: String,
    out: Box<dyn Write + Send>,
    flush_each: bool,
    stats: SinkStats,
}

impl FileSink {
    /// A sink writing to `out`; `flush_each` flushes after every write (paced runs).
    pub fn new(label: String, out: Box<dyn Write + Send>, flush_each: bool) -> FileSink {
        FileSink {
            label,
            out,
            flush_each,
            stats: SinkStats::default(),
        }
    }
}

impl Sink for FileSink {
    fn label(&self) -> &str {
        &self.label
    }

    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()> {
        self.out.write_all(bytes)?;
        if self.flush_each {
            self.out.flush()?;
        }
        self.stats.sent += ends.len() as u64;
        self.stats.bytes += bytes.len() as u64;
        Ok(())
    }

    fn finish(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    fn stats(&self) -> SinkStats {
        self.stats
    }
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
