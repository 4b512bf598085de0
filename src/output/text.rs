//! A command's text output (a CSV, a report): a file that appears whole or not at all
//! ([`AtomicFile`]), or standard output for `-`; written in chunks of about a megabyte. A
//! file's errors name it and say what failed (`creating F: …`, `writing F: …`, `finishing F:
//! …`, with the system's error kind kept); standard output's are the system's own, so that a
//! reader that went away still reads as a broken pipe.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::AtomicFile;

/// Bytes held before they are written.
const CHUNK: usize = 1 << 20;

/// Where the text goes, and what is not written yet.
pub struct TextOut {
    to: To,
    buf: Vec<u8>,
}

enum To {
    Stdout,
    File(AtomicFile, PathBuf),
}

/// `e` with `what` and the path in front of its message, of the same kind.
fn named(what: &str, path: &Path, e: io::Error) -> io::Error {
    io::Error::new(e.kind(), format!("{what} {}: {e}", path.display()))
}

impl TextOut {
    /// Standard output for `-`, else the file at `path` (written under a temporary name).
    pub fn create(path: &Path) -> io::Result<TextOut> {
        let to = if path == Path::new("-") {
            To::Stdout
        } else {
            let f = AtomicFile::create(path).map_err(|e| named("creating", path, e))?;
            To::File(f, path.to_path_buf())
        };
        Ok(TextOut {
            to,
            buf: Vec::new(),
        })
    }

    /// Appends `text`; writes what is held once it passes a megabyte.
    pub fn write_all(&mut self, text: &[u8]) -> io::Result<()> {
        self.buf.extend_from_slice(text);
        if self.buf.len() > CHUNK {
            self.drain()?;
        }
        Ok(())
    }

    fn drain(&mut self) -> io::Result<()> {
        match &mut self.to {
            To::Stdout => io::stdout().lock().write_all(&self.buf)?,
            To::File(f, p) => f.write_all(&self.buf).map_err(|e| named("writing", p, e))?,
        }
        self.buf.clear();
        Ok(())
    }

    /// Writes the rest, and puts a file in place under its name.
    pub fn finish(mut self) -> io::Result<()> {
        self.drain()?;
        match self.to {
            To::Stdout => io::stdout().lock().flush(),
            To::File(f, p) => f.commit().map_err(|e| named("finishing", &p, e)),
        }
    }

    /// Whether this is standard output.
    pub fn is_stdout(&self) -> bool {
        matches!(self.to, To::Stdout)
    }
}
