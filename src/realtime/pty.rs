//! Pseudo-terminal sink: a raw pty pair whose slave is published at a stable path (a symlink,
//! like socat's `link=`). Readers may come and go; with none, frames are dropped and counted
//! and the emulator runs on unchanged (docs/realtime.md).

use std::io;
use std::os::fd::{AsFd, AsRawFd, OwnedFd};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
use nix::sys::termios::{self, FlushArg, SetArg};

use super::sink::{FdState, FdWriter, Sink, SinkStats, set_nonblocking};

/// A pty master with its slave published at `link`.
pub struct PtySink {
    label: String,
    master: OwnedFd,
    slave: PathBuf,
    link: Option<PathBuf>,
    attached: bool,
    writer: FdWriter,
}

impl PtySink {
    /// Opens a raw pty pair and, if `link` is given, publishes the slave there as a symlink.
    /// A link to a live pty (another run's) is refused unless `take_over`, in which case it is
    /// replaced atomically; a dangling link (a crashed run's) is replaced; anything that is not
    /// a symlink is never replaced.
    pub fn open(link: Option<&Path>, take_over: bool) -> io::Result<PtySink> {
        let pair = nix::pty::openpty(None, None)?;
        // Raw mode before any byte crosses: a cooked pty would swallow binary frames and echo
        // them back to the master. The slave fd is then closed; /dev/pts/N lives as long as the
        // master does.
        let mut t = termios::tcgetattr(&pair.slave)?;
        termios::cfmakeraw(&mut t);
        termios::tcsetattr(&pair.slave, SetArg::TCSANOW, &t)?;
        let slave = std::fs::read_link(format!("/proc/self/fd/{}", pair.slave.as_raw_fd()))?;
        drop(pair.slave);
        set_nonblocking(&pair.master)?;
        if let Some(link) = link {
            publish(&slave, link, take_over)?;
        }
        let shown = link.unwrap_or(&slave).display().to_string();
        Ok(PtySink {
            label: format!("pty {shown}"),
            master: pair.master,
            slave,
            link: link.map(Path::to_path_buf),
            attached: false,
            writer: FdWriter::default(),
        })
    }

    /// The slave device (`/dev/pts/N`).
    pub fn slave(&self) -> &Path {
        &self.slave
    }

    /// The published path: the link, or the slave itself.
    pub fn path(&self) -> &Path {
        self.link.as_deref().unwrap_or(&self.slave)
    }

    /// True when a reader holds the slave open (`POLLHUP` clear on the master).
    fn reader_present(&self) -> io::Result<bool> {
        let mut fds = [PollFd::new(self.master.as_fd(), PollFlags::POLLOUT)];
        poll(&mut fds, PollTimeout::ZERO)?;
        let ev = fds[0].revents().unwrap_or(PollFlags::empty());
        Ok(!ev.contains(PollFlags::POLLHUP))
    }
}

/// Points a symlink at `link` to `slave`. Creating it is atomic (`symlink` fails on an
/// existing name), so of two runs started together only one gets the link; replacing is an
/// atomic rename over it.
fn publish(slave: &Path, link: &Path, take_over: bool) -> io::Result<()> {
    match std::os::unix::fs::symlink(slave, link) {
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
        r => return r,
    }
    let meta = std::fs::symlink_metadata(link)?;
    if !meta.file_type().is_symlink() {
        return Err(io::Error::new(
            io::ErrorKind::AlreadyExists,
            format!(
                "{} exists and is not a symlink: not replacing it",
                link.display()
            ),
        ));
    }
    let target = std::fs::read_link(link)?;
    // A link whose pty still exists belongs to a live run (a pty disappears with its master).
    if target.exists() && !take_over {
        return Err(io::Error::new(
            io::ErrorKind::AddrInUse,
            format!(
                "{} is in use: it links to {}, the pty of another running emulator; stop that run, choose another path, or pass --take-over to replace the link",
                link.display(),
                target.display()
            ),
        ));
    }
    let tmp = link.with_file_name(format!(
        ".{}.tmp-{}",
        link.file_name()
            .map_or("pty".into(), |n| n.to_string_lossy()),
        std::process::id()
    ));
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(slave, &tmp)?;
    std::fs::rename(&tmp, link).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })?;
    if target.exists() {
        tracing::warn!(
            "{}: took the link over from {}",
            link.display(),
            target.display()
        );
    } else {
        tracing::info!(
            "{}: replaced a stale link to {}",
            link.display(),
            target.display()
        );
    }
    Ok(())
}

impl Sink for PtySink {
    fn live(&self) -> bool {
        true
    }

    fn label(&self) -> &str {
        &self.label
    }

    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()> {
        if !self.reader_present()? {
            if self.attached {
                // Discard what was written between the reader's close and now: the next
                // reader must not see it (it is flushed again when that reader attaches).
                termios::tcflush(&self.master, FlushArg::TCIOFLUSH)?;
                tracing::info!("{}: reader gone", self.label);
            }
            self.attached = false;
            self.writer.reset();
            self.writer.stats.no_reader += ends.len() as u64;
            return Ok(());
        }
        if !self.attached {
            // A new reader: discard whatever was queued before it came (stale frames).
            termios::tcflush(&self.master, FlushArg::TCIOFLUSH)?;
            self.writer.reset();
            self.attached = true;
            tracing::info!("{}: reader attached", self.label);
        }
        if self.writer.write(self.master.as_fd(), bytes, ends)? == FdState::NoReader {
            self.attached = false;
            self.writer.reset();
        }
        Ok(())
    }

    /// Gives an attached reader up to 200 ms to read the last frames: closing the master
    /// would discard what is still queued on the slave.
    fn finish(&mut self) -> io::Result<()> {
        if !self.attached {
            return Ok(());
        }
        let Ok(slave) = std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
            .open(&self.slave)
        else {
            return Ok(());
        };
        // The kernel moves written bytes to the slave's queue asynchronously: wait for the last
        // write to land before looking.
        std::thread::sleep(std::time::Duration::from_millis(5));
        for _ in 0..200 {
            let mut queued: libc::c_int = 0;
            // nix and std have no safe FIONREAD (nix only generates unsafe ioctl wrappers).
            // SAFETY: FIONREAD writes one int through a valid pointer.
            let rc = unsafe { libc::ioctl(slave.as_raw_fd(), libc::FIONREAD, &mut queued) };
            if rc != 0 || queued == 0 || !self.reader_present()? {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        Ok(())
    }

    fn stats(&self) -> SinkStats {
        self.writer.stats
    }
}

impl Drop for PtySink {
    fn drop(&mut self) {
        // Remove the link only if it still points at our slave (another run may own it now).
        if let Some(link) = &self.link
            && std::fs::read_link(link).is_ok_and(|t| t == self.slave)
        {
            let _ = std::fs::remove_file(link);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    /// Frames written with no reader are dropped as `no_reader`; a reader that opens the link
    /// gets only frames written after it came, byte for byte (raw mode: all 256 values).
    #[test]
    fn reader_attach_and_raw_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("imu");
        let mut s = PtySink::open(Some(&link), false).unwrap();
        assert_eq!(std::fs::read_link(&link).unwrap(), s.slave());
        let all: Vec<u8> = (0..=255).collect();
        s.write(&all, &[256]).unwrap();
        assert_eq!(s.stats().no_reader, 1);
        let mut r = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&link)
            .unwrap();
        let mut t = termios::tcgetattr(&r).unwrap();
        termios::cfmakeraw(&mut t);
        termios::tcsetattr(&r, SetArg::TCSANOW, &t).unwrap();
        s.write(&all, &[256]).unwrap();
        let mut got = vec![0u8; 256];
        r.read_exact(&mut got).unwrap();
        assert_eq!(got, all);
        assert_eq!(s.stats().sent, 1);
        drop(r);
        s.write(&all, &[256]).unwrap();
        assert_eq!(s.stats().no_reader, 2);
        drop(s);
        assert!(!link.exists() && link.symlink_metadata().is_err());
    }

    /// A link to a live pty is refused without `take_over` and replaced with it; the run that
    /// lost the link leaves it alone when it ends; a dangling link is replaced; a regular file
    /// is never replaced.
    #[test]
    fn link_ownership() {
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("imu");
        let first = PtySink::open(Some(&link), false).unwrap();
        let e = PtySink::open(Some(&link), false).err().unwrap();
        assert!(e.to_string().contains("--take-over"), "{e}");
        assert_eq!(std::fs::read_link(&link).unwrap(), first.slave());
        let second = PtySink::open(Some(&link), true).unwrap();
        assert_eq!(std::fs::read_link(&link).unwrap(), second.slave());
        drop(first);
        assert_eq!(std::fs::read_link(&link).unwrap(), second.slave());
        drop(second);
        assert!(link.symlink_metadata().is_err());
        std::os::unix::fs::symlink(dir.path().join("gone"), &link).unwrap();
        let third = PtySink::open(Some(&link), false).unwrap();
        assert_eq!(std::fs::read_link(&link).unwrap(), third.slave());
        drop(third);
        std::fs::write(&link, "data").unwrap();
        for take_over in [false, true] {
            let e = PtySink::open(Some(&link), take_over).err().unwrap();
            assert!(e.to_string().contains("not a symlink"), "{e}");
        }
        assert_eq!(std::fs::read_to_string(&link).unwrap(), "data");
    }
}
