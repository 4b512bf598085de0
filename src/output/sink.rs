//! Sinks: where a stream's frames go. A sink takes whole frames; the real-time ones (pty,
//! serial, UDP, TCP in `crate::realtime`) never block for long — what they cannot take now is
//! dropped and counted — while a file keeps every frame, in order.
//!
//! A file sink is all or nothing: unpaced runs write it under a temporary name renamed into
//! place when the run succeeds ([`AtomicFile`]); paced runs write the file itself, so a
//! reader can follow it, and remove it when the run fails. Either way a failed run leaves no
//! partial file behind.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::AtomicFile;

/// What a sink delivered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SinkStats {
    /// Frames written whole (a buffered file's once flushed).
    pub sent: u64,
    /// Frames dropped because the consumer could not take them (full buffer, slow link).
    pub dropped: u64,
    /// Frames dropped because nobody was reading (a pty with no reader, a TCP port with no
    /// client).
    pub no_reader: u64,
    /// Bytes written (a buffered file's once flushed).
    pub bytes: u64,
    /// Frames handed to the sink after it failed, never written: the run went on for its
    /// other sinks ([`crate::output::failure`]).
    pub lost: u64,
}

/// A destination for frames.
pub trait Sink: Send {
    /// What the user named (`pty /tmp/imu`, `udp 127.0.0.1:5000`, `file imu.bin`, …).
    fn label(&self) -> &str;
    /// Writes frames `bytes`, frame `i` ending at `ends[i]` (offsets into `bytes`).
    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()>;
    /// Writes a stream's preamble (a CSV header) ahead of its frames: a file is a document
    /// and starts with it; a stream to a device or a socket carries frames only (a reader
    /// joining later could not count on it anyway), so the others skip it.
    fn preamble(&mut self, _bytes: &[u8]) -> io::Result<()> {
        Ok(())
    }
    /// Writes what is still buffered (end of run).
    fn finish(&mut self) -> io::Result<()> {
        Ok(())
    }
    /// The run succeeded (or was stopped where stopping is its normal end): keep the output.
    fn commit(&mut self) -> io::Result<()> {
        Ok(())
    }
    /// The run failed: leave nothing behind.
    fn discard(&mut self) {}
    /// Counts so far.
    fn stats(&self) -> SinkStats;
    /// A link a consumer reads as the frames come (pty, serial, UDP, TCP): when another sink
    /// of the run fails, the run goes on for this one ([`crate::output::failure::absorb`]).
    fn live(&self) -> bool {
        false
    }
    /// Takes the sink out of a run that goes on without it, after the failure `why`: what it
    /// wrote is discarded, the frames it is handed from then on are counted as lost. False
    /// when the sink cannot be retired: the run ends instead.
    fn retire(&mut self, _why: &io::Error) -> bool {
        false
    }
    /// Why the sink was retired and what it lost; `None` while it works.
    fn failure(&self) -> Option<String> {
        None
    }
}

/// How a file sink writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileMode {
    /// Under a temporary name, renamed into place on commit (unpaced runs).
    Atomic,
    /// The file itself, flushed after every write so that a reader follows it (paced runs);
    /// removed if the run fails.
    Live,
}

/// The file behind a [`FileSink`].
enum Target {
    Atomic(Option<AtomicFile>),
    Live(Option<std::fs::File>, PathBuf),
    Stdout,
    Writer,
}

/// A file, stdout or any writer: every frame written, in order (a slow disk delays an
/// unpaced run; paced runs flush after every write so a reader sees frames at their time).
pub struct FileSink {
    label: String,
    target: Target,
    out: Box<dyn Write + Send>,
    flush_each: bool,
    stats: SinkStats,
    /// Frames and bytes in the buffer, counted once flushed: a sink that fails loses them.
    held: (u64, u64),
}

/// Buffer of a file sink (bytes).
const FILE_BUFFER: usize = 1 << 20;

impl FileSink {
    /// A sink writing to the file `path` (`-`: stdout) in `mode`; errors name the file.
    pub fn create(path: &Path, mode: FileMode) -> io::Result<FileSink> {
        if path == Path::new("-") {
            let out = io::BufWriter::with_capacity(FILE_BUFFER, io::stdout());
            return Ok(FileSink {
                label: "stdout".into(),
                target: Target::Stdout,
                out: Box::new(Labeled::new("stdout", out)),
                flush_each: mode == FileMode::Live,
                stats: SinkStats::default(),
                held: (0, 0),
            });
        }
        let label = format!("file {}", path.display());
        let named = |e: io::Error| labeled(&format!("creating {}", path.display()), e);
        let (target, out): (Target, Box<dyn Write + Send>) = match mode {
            FileMode::Atomic => {
                let f = AtomicFile::create(path).map_err(named)?;
                let w = f.try_clone_writer().map_err(named)?;
                (Target::Atomic(Some(f)), Box::new(w))
            }
            FileMode::Live => {
                // A FIFO's open waits for a reader.
                let f =
                    super::unfinished::blocking(|| std::fs::File::create(path)).map_err(named)?;
                super::unfinished::register(path);
                let w = f.try_clone().map_err(named)?;
                (Target::Live(Some(f), path.to_path_buf()), Box::new(w))
            }
        };
        let out = io::BufWriter::with_capacity(FILE_BUFFER, out);
        Ok(FileSink {
            target,
            out: Box::new(Labeled::new(&label, out)),
            label,
            flush_each: mode == FileMode::Live,
            stats: SinkStats::default(),
            held: (0, 0),
        })
    }

    /// A sink writing to `out`, named `label` in reports; `flush_each` flushes after every
    /// write. Nothing is removed when the run fails (the caller owns the writer).
    pub fn writer(label: String, out: Box<dyn Write + Send>, flush_each: bool) -> FileSink {
        FileSink {
            label,
            target: Target::Writer,
            out,
            flush_each,
            stats: SinkStats::default(),
            held: (0, 0),
        }
    }

    /// Flushes, and counts what was held as written.
    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()?;
        self.stats.sent += std::mem::take(&mut self.held.0);
        self.stats.bytes += std::mem::take(&mut self.held.1);
        Ok(())
    }
}

impl Sink for FileSink {
    fn label(&self) -> &str {
        &self.label
    }

    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()> {
        self.out.write_all(bytes)?;
        self.held.0 += ends.len() as u64;
        self.held.1 += bytes.len() as u64;
        if self.flush_each {
            self.flush()?;
        }
        Ok(())
    }

    fn preamble(&mut self, bytes: &[u8]) -> io::Result<()> {
        // Not a frame: only the bytes count.
        self.out.write_all(bytes)?;
        self.held.1 += bytes.len() as u64;
        Ok(())
    }

    fn finish(&mut self) -> io::Result<()> {
        self.flush()
    }

    fn commit(&mut self) -> io::Result<()> {
        self.flush()?;
        match &mut self.target {
            Target::Atomic(f) => match f.take() {
                Some(f) => f
                    .commit()
                    .map_err(|e| labeled(&format!("finishing {}", self.label), e)),
                None => Ok(()),
            },
            Target::Live(f, path) => {
                f.take();
                super::unfinished::forget(path);
                Ok(())
            }
            Target::Stdout | Target::Writer => Ok(()),
        }
    }

    fn discard(&mut self) {
        match &mut self.target {
            // Dropped uncommitted, the temporary is removed.
            Target::Atomic(f) => drop(f.take()),
            Target::Live(f, path) => {
                if f.take().is_some() {
                    super::remove_partial(path);
                }
            }
            Target::Stdout | Target::Writer => {}
        }
    }

    fn stats(&self) -> SinkStats {
        self.stats
    }
}

/// An I/O error that names what was being done, keeping the cause's kind (a broken pipe stays
/// one, so the binary can tell a reader that stopped early).
pub(crate) fn labeled(what: &str, e: io::Error) -> io::Error {
    io::Error::new(
        e.kind(),
        LabeledError {
            label: what.to_string(),
            source: e,
        },
    )
}

/// A write error of a labelled writer: the label, then the cause as its `source()`.
#[derive(Debug, thiserror::Error)]
#[error("{label}")]
struct LabeledError {
    label: String,
    source: io::Error,
}

/// A writer whose errors name what it writes to.
struct Labeled<W> {
    label: String,
    inner: W,
}

impl<W> Labeled<W> {
    fn new(label: &str, inner: W) -> Labeled<W> {
        Labeled {
            label: format!("writing {label}"),
            inner,
        }
    }
}

/// Counted as blocking calls: a pipe or FIFO whose reader stopped reading holds them.
impl<W: Write> Write for Labeled<W> {
    fn write(&mut self, b: &[u8]) -> io::Result<usize> {
        super::unfinished::blocking(|| self.inner.write(b)).map_err(|e| labeled(&self.label, e))
    }
    fn flush(&mut self) -> io::Result<()> {
        super::unfinished::blocking(|| self.inner.flush()).map_err(|e| labeled(&self.label, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An atomic file appears only on commit and a discarded one leaves nothing; a live file
    /// is there at once and removed on discard.
    #[test]
    fn files_are_all_or_nothing() {
        let dir = tempfile::tempdir().unwrap();
        for (n, mode) in [FileMode::Atomic, FileMode::Live].into_iter().enumerate() {
            let p = dir.path().join(format!("{mode:?}.bin"));
            let mut s = FileSink::create(&p, mode).unwrap();
            s.write(b"abcd", &[2, 4]).unwrap();
            s.finish().unwrap();
            assert_eq!(p.exists(), mode == FileMode::Live);
            s.commit().unwrap();
            assert_eq!(std::fs::read(&p).unwrap(), b"abcd");
            assert_eq!(s.stats().sent, 2);
            let q = dir.path().join(format!("{mode:?}-failed.bin"));
            let mut s = FileSink::create(&q, mode).unwrap();
            s.write(b"ab", &[2]).unwrap();
            s.discard();
            assert!(!q.exists(), "{mode:?}");
            let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
            assert_eq!(left.len(), n + 1, "no temporary left: {left:?}");
        }
    }
}
