//! What a failing output does to a run. A sink that cannot be written (the reader of a pipe or
//! a FIFO left, the disk is full) fails the run, its error naming the flag that asked for it —
//! unless a live link of the same run (pty, serial, UDP, TCP) still works: a rig's consumer
//! reads that one as the frames come, so the run goes on, the failed sink retired with its
//! partial file removed and the frames it loses counted, and the run reports the failure at
//! its end. Standard output that was a command's only output ends it quietly
//! ([`ReaderLeft`]).

use std::io;

use super::sink::{Sink, SinkStats, labeled};

/// Standard output was the command's only output and its reader left (`… | head`): nobody
/// reads what is missing, so nothing is said; the command exits 141 (128 + SIGPIPE) as one
/// killed by SIGPIPE does, so that `set -o pipefail` still sees an incomplete output.
#[derive(Debug, thiserror::Error)]
#[error("standard output: the reader left")]
pub struct ReaderLeft;

/// `e` and its causes on one line, `: ` between them (an error of [`Named`] reads
/// `--truth: writing file t.csv: Broken pipe (os error 32)`).
pub fn describe(e: &io::Error) -> String {
    let mut text = e.to_string();
    let mut cause = std::error::Error::source(e);
    while let Some(c) = cause {
        text += &format!(": {c}");
        cause = c.source();
    }
    text
}

/// A run's answer to sink `k` of `sinks` failing with `e`: while another of them is a live
/// link still working, sink `k` is retired and the run goes on (`Ok`, with the warning to
/// give); otherwise `Err(e)`, which ends the run.
pub fn absorb(
    sinks: &mut [&mut (dyn Sink + 'static)],
    k: usize,
    e: io::Error,
) -> io::Result<String> {
    let others =
        (sinks.iter().enumerate()).any(|(j, s)| j != k && s.live() && s.failure().is_none());
    if others && sinks[k].retire(&e) {
        Ok(format!(
            "{}: the run goes on for its other sinks; this one's frames are counted as lost",
            describe(&e)
        ))
    } else {
        Err(e)
    }
}

/// A sink under the name of the flag (or scene-file key) that asked for it: its errors begin
/// with that name, and a run may retire it after a failure ([`absorb`]).
pub struct Named {
    origin: String,
    inner: Box<dyn Sink>,
    /// Frames handed to it while it worked.
    handed: u64,
    /// Why it was retired.
    failed: Option<String>,
    lost: u64,
}

impl Named {
    /// `inner`, asked for by `origin` (`--truth`, `--file -`, a unit's `sink` key …).
    pub fn new(origin: impl Into<String>, inner: Box<dyn Sink>) -> Named {
        Named {
            origin: origin.into(),
            inner,
            handed: 0,
            failed: None,
            lost: 0,
        }
    }

    fn named(&self, e: io::Error) -> io::Error {
        labeled(&self.origin, e)
    }
}

impl Sink for Named {
    fn label(&self) -> &str {
        self.inner.label()
    }

    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()> {
        if self.failed.is_some() {
            self.lost += ends.len() as u64;
            return Ok(());
        }
        self.handed += ends.len() as u64;
        self.inner.write(bytes, ends).map_err(|e| self.named(e))
    }

    fn preamble(&mut self, bytes: &[u8]) -> io::Result<()> {
        if self.failed.is_some() {
            return Ok(());
        }
        self.inner.preamble(bytes).map_err(|e| self.named(e))
    }

    fn finish(&mut self) -> io::Result<()> {
        if self.failed.is_some() {
            return Ok(());
        }
        self.inner.finish().map_err(|e| self.named(e))
    }

    fn commit(&mut self) -> io::Result<()> {
        if self.failed.is_some() {
            return Ok(());
        }
        self.inner.commit().map_err(|e| self.named(e))
    }

    fn discard(&mut self) {
        self.inner.discard();
    }

    fn stats(&self) -> SinkStats {
        SinkStats {
            lost: self.inner.stats().lost + self.lost,
            ..self.inner.stats()
        }
    }

    fn live(&self) -> bool {
        self.inner.live()
    }

    fn retire(&mut self, why: &io::Error) -> bool {
        if self.failed.is_none() {
            self.failed = Some(describe(why));
            // What it took and never wrote (the failed write, a buffer it could not flush) is
            // lost with what comes after.
            let s = self.inner.stats();
            self.lost = (self.handed).saturating_sub(s.sent + s.dropped + s.no_reader);
            self.inner.discard();
        }
        true
    }

    fn failure(&self) -> Option<String> {
        (self.failed.as_ref()).map(|w| format!("{w}; {} frames lost", self.lost))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::sink::{FileMode, FileSink};

    /// A sink that fails every write, live or not.
    struct Failing(bool);

    impl Sink for Failing {
        fn label(&self) -> &str {
            "failing"
        }
        fn write(&mut self, _: &[u8], _: &[usize]) -> io::Result<()> {
            Err(io::Error::new(io::ErrorKind::BrokenPipe, "gone"))
        }
        fn stats(&self) -> SinkStats {
            SinkStats::default()
        }
        fn live(&self) -> bool {
            self.0
        }
    }

    /// Beside files only, a failure ends the run, named by its flag; beside a live link still
    /// working, the failed sink is retired, its file removed and its frames counted.
    #[test]
    fn a_failed_sink_is_retired_only_beside_a_live_link() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        let file = FileSink::create(&path, FileMode::Live).unwrap();
        let mut file = Named::new("--file out.bin", Box::new(file));
        let mut bad = Named::new("--file -", Box::new(Failing(false)));
        file.write(b"ab", &[2]).unwrap();
        let e = bad.write(b"ab", &[2]).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::BrokenPipe);
        assert_eq!(describe(&e), "--file -: gone");
        assert!(absorb(&mut [&mut file, &mut bad], 1, e).is_err());
        assert!(bad.failure().is_none() && path.exists());

        let mut link = Named::new("--udp x", Box::new(Failing(true)));
        let e = io::Error::other("full");
        let warn = absorb(&mut [&mut link, &mut file], 1, e).unwrap();
        assert!(warn.starts_with("full: the run goes on"), "{warn}");
        assert!(!path.exists(), "the retired sink's file is removed");
        file.write(b"abcd", &[2, 4]).unwrap();
        file.commit().unwrap();
        assert!(!path.exists(), "a retired sink keeps nothing");
        assert_eq!(file.stats().lost, 2);
        assert_eq!(file.failure().unwrap(), "full; 2 frames lost");
        // A retired link carries the run no more.
        let mut other = Named::new("--udp y", Box::new(Failing(true)));
        let e = link.write(b"", &[]).unwrap_err();
        assert!(absorb(&mut [&mut link, &mut other], 0, e).is_ok());
        let e = bad.write(b"", &[]).unwrap_err();
        assert!(absorb(&mut [&mut link, &mut bad], 1, e).is_err());
    }
}
