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

/// Bytes of one binary record.
pub const BIN_RECORD_BYTES: usize = 104;

/// The 13 values (in the order of [`crate::record::COLUMNS`]) of one binary record.
pub fn decode_bin(bytes: &[u8; BIN_RECORD_BYTES]) -> [f64; 13] {
    std::array::from_fn(|i| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&bytes[8 * i..8 * i + 8]);
        f64::from_le_bytes(b)
    })
}

/// Appends the encoding of `records` to `buf`.
pub fn encode(format: Format, records: &[Record], buf: &mut Vec<u8>) {
    match format {
        Format::Bin => {
            buf.reserve(records.len() * BIN_RECORD_BYTES);
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
///
/// A destination that exists and is not a regular file (`/dev/null`, a FIFO, a tty) is
/// written directly: renaming over it would replace the device node.
pub struct AtomicFile {
    file: Option<File>,
    /// Temporary path, or `None` when writing straight into a special file.
    tmp: Option<PathBuf>,
    dest: PathBuf,
}

impl AtomicFile {
    /// Creates the temporary file next to `dest` (or opens `dest` if it is a special file).
    pub fn create(dest: &Path) -> io::Result<AtomicFile> {
        let special = std::fs::metadata(dest).is_ok_and(|m| !m.is_file() && !m.is_dir());
        if std::fs::metadata(dest).is_ok_and(|m| m.is_dir()) {
            // Refused now, not when the finished file cannot be renamed over it.
            return Err(io::Error::new(
                io::ErrorKind::IsADirectory,
                "is a directory",
            ));
        }
        if special {
            let file = std::fs::OpenOptions::new().write(true).open(dest)?;
            return Ok(AtomicFile {
                file: Some(file),
                tmp: None,
                dest: dest.to_path_buf(),
            });
        }
        let name = dest
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = dest.with_file_name(format!(".{name}.partial-{}", std::process::id()));
        let file = File::create(&tmp)?;
        Ok(AtomicFile {
            file: Some(file),
            tmp: Some(tmp),
            dest: dest.to_path_buf(),
        })
    }
    /// Flushes, closes and renames the file into place. On failure the temporary is removed.
    pub fn commit(mut self) -> io::Result<()> {
        let file = self.file.take();
        match self.tmp.take() {
            None => Ok(()),
            Some(tmp) => {
                let done = file
                    .map_or(Ok(()), |f| f.sync_data())
                    .and_then(|()| std::fs::rename(&tmp, &self.dest));
                if done.is_err() {
                    let _ = std::fs::remove_file(&tmp);
                }
                done
            }
        }
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
        if let (Some(_), Some(tmp)) = (self.file.take(), self.tmp.take()) {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Header of the injected-errors file: `t` then `KIND_SENSOR_AXIS` for every stage kind of
/// the error chain ([`crate::errors::StageKind::ALL`]), sensors gyro and accel, axes x, y, z.
pub fn components_header() -> String {
    let mut cols = vec!["t".to_string()];
    for k in crate::errors::StageKind::ALL {
        for s in crate::errors::Sensor::BOTH {
            for a in ["x", "y", "z"] {
                cols.push(format!("{}_{}_{a}", k.name(), s.name()));
            }
        }
    }
    cols.join(",") + "\n"
}

/// Appends the injected errors of `records` (CSV rows, or per record the time and then six
/// little-endian f64 per stage kind, in [`components_header`] order).
pub fn encode_components(
    format: Format,
    records: &[Record],
    comps: &[crate::errors::chain::Components],
    buf: &mut Vec<u8>,
) {
    let mut f = ryu::Buffer::new();
    for (r, c) in records.iter().zip(comps) {
        let mut vals = Vec::with_capacity(1 + 6 * c.0.len());
        vals.push(r.t);
        for g in &c.0 {
            for v in g {
                vals.extend_from_slice(v.as_slice());
            }
        }
        match format {
            Format::Bin => vals
                .iter()
                .for_each(|v| buf.extend_from_slice(&v.to_le_bytes())),
            Format::Csv => {
                for (i, v) in vals.iter().enumerate() {
                    if i > 0 {
                        buf.push(b',');
                    }
                    buf.extend_from_slice(f.format(*v).as_bytes());
                }
                buf.push(b'\n');
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_commit_leaves_nothing() {
        let dir = tempfile::TempDir::new().unwrap();
        let dest = dir.path().join("out.csv");
        let mut f = AtomicFile::create(&dest).unwrap();
        f.write_all(b"data").unwrap();
        // Something takes the name meanwhile: the rename fails, and the temporary goes.
        std::fs::create_dir(&dest).unwrap();
        std::fs::write(dest.join("keep"), b"").unwrap();
        assert!(f.commit().is_err());
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["out.csv"]);
    }

    #[test]
    fn directory_destination_is_refused_at_once() {
        let dir = tempfile::TempDir::new().unwrap();
        let e = AtomicFile::create(dir.path()).err().expect("refused");
        assert_eq!(e.kind(), io::ErrorKind::IsADirectory);
    }
}
