//! Writing records: CSV (header + shortest round-trip numbers) or binary (13 little-endian f64
//! per record, same order), into a file that appears under its name only when complete.

use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use crate::record::{COLUMNS, Record};

/// Output encoding of records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Text with a header row.
    Csv,
    /// 104 bytes per record: t and the 12 sensor values as little-endian f64.
    Bin,
}

impl Format {
    /// Parses `csv` or `bin`.
    pub fn from_name(s: &str) -> Option<Format> {
        match s {
            "csv" => Some(Format::Csv),
            "bin" => Some(Format::Bin),
            _ => None,
        }
    }
}

/// The CSV header line.
pub fn csv_header() -> String {
    let mut s = COLUMNS.join(",");
    s.push('\n');
    s
}

/// Appends the encoding of `records` to `buf`.
pub fn encode(format: Format, records: &[Record], buf: &mut Vec<u8>) {
    match format {
        Format::Bin => {
            buf.reserve(records.len() * 104);
            for r in records {
                for v in r.values() {
                    buf.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        Format::Csv => {
            let mut f = ryu::Buffer::new();
            for r in records {
                for (i, v) in r.values().iter().enumerate() {
                    if i > 0 {
                        buf.push(b',');
                    }
                    // ryu prints the shortest string that parses back to the same f64.
                    buf.extend_from_slice(f.format(*v).as_bytes());
                }
                buf.push(b'\n');
            }
        }
    }
}

/// A file written under a temporary name and renamed into place by [`AtomicFile::commit`];
/// dropped without commit, the temporary is removed, so a failed run leaves nothing behind.
pub struct AtomicFile {
    file: Option<File>,
    tmp: PathBuf,
    dest: PathBuf,
}

impl AtomicFile {
    /// Creates the temporary file next to `dest`.
    pub fn create(dest: &Path) -> io::Result<AtomicFile> {
        let name = dest
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = dest.with_file_name(format!(".{name}.partial-{}", std::process::id()));
        let file = File::create(&tmp)?;
        Ok(AtomicFile {
            file: Some(file),
            tmp,
            dest: dest.to_path_buf(),
        })
    }
    /// Flushes, closes and renames the file into place.
    pub fn commit(mut self) -> io::Result<()> {
        if let Some(f) = self.file.take() {
            f.sync_data().or_else(|e| {
                if e.kind() == io::ErrorKind::InvalidInput {
                    Ok(())
                } else {
                    Err(e)
                }
            })?;
        }
        std::fs::rename(&self.tmp, &self.dest)
    }
}

impl Write for AtomicFile {
    fn write(&mut self, b: &[u8]) -> io::Result<usize> {
        match self.file.as_mut() {
            Some(f) => f.write(b),
            None => Err(io::Error::other("file already committed")),
        }
    }
    fn flush(&mut self) -> io::Result<()> {
        self.file.as_mut().map_or(Ok(()), |f| f.flush())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}
