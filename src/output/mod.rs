//! Writing records: CSV (header + shortest round-trip numbers) or binary (13 little-endian f64
//! per record, same order), into a file that appears under its name only when complete.

pub mod addr;
pub mod failure;
pub mod sink;
pub mod text;
pub mod unfinished;

pub use addr::SinkAddr;

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

/// Columns a truth file adds after the record's when the IMU has timing errors: the time of
/// validity of the gyros and of the accelerometers, and the emission time of the frame's first
/// byte (s, on the record's time axis).
pub const TIMING_COLUMNS: [&str; 3] = ["tov", "tov_accel", "emit"];

/// The CSV header line of a truth file with [`TIMING_COLUMNS`].
pub fn csv_header_timed() -> String {
    let mut s = COLUMNS.join(",");
    for c in TIMING_COLUMNS {
        s.push(',');
        s.push_str(c);
    }
    s.push('\n');
    s
}

/// Appends `records` with their [`TIMING_COLUMNS`] from `times`: in CSV three more columns,
/// in binary three more little-endian f64 (128 bytes per record).
pub fn encode_timed(
    format: Format,
    records: &[Record],
    times: &crate::timing::Times<'_>,
    buf: &mut Vec<u8>,
) {
    encode_truth(format, records, Some(times), None, buf);
}

/// Column a truth file adds last when the motion is a motion definition: whether GNSS is
/// visible at the record's time (1 or 0; in binary one more f64).
pub const GNSS_VISIBLE_COLUMN: &str = "gnss_visible";

/// The CSV header line of a truth file: the record's columns, [`TIMING_COLUMNS`] if `timed`,
/// [`GNSS_VISIBLE_COLUMN`] if `gnss`.
pub fn csv_header_truth(timed: bool, gnss: bool) -> String {
    let mut s = if timed {
        csv_header_timed()
    } else {
        csv_header()
    };
    if gnss {
        s.pop();
        s.push(',');
        s.push_str(GNSS_VISIBLE_COLUMN);
        s.push('\n');
    }
    s
}

/// Appends truth `records`: each with its [`TIMING_COLUMNS`] from `times` when given, then
/// `gnss(t)` at its time as [`GNSS_VISIBLE_COLUMN`] when given.
pub fn encode_truth(
    format: Format,
    records: &[Record],
    times: Option<&crate::timing::Times<'_>>,
    gnss: Option<&dyn Fn(f64) -> bool>,
    buf: &mut Vec<u8>,
) {
    if times.is_none() && gnss.is_none() {
        return encode(format, records, buf);
    }
    let mut f = ryu::Buffer::new();
    for (i, r) in records.iter().enumerate() {
        encode(format, std::slice::from_ref(r), buf);
        let csv = format == Format::Csv;
        if csv {
            buf.pop();
        }
        let push = |buf: &mut Vec<u8>, v: f64, text: &str| {
            if csv {
                buf.push(b',');
                buf.extend_from_slice(text.as_bytes());
            } else {
                buf.extend_from_slice(&v.to_le_bytes());
            }
        };
        if let Some(times) = times {
            for v in [times.tov[i], times.tov_accel[i], times.emit[i]].map(|x| times.t0 + x) {
                push(buf, v, f.format(v));
            }
        }
        if let Some(g) = gnss {
            let on = g(r.t);
            push(buf, f64::from(u8::from(on)), if on { "1" } else { "0" });
        }
        if csv {
            buf.push(b'\n');
        }
    }
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

/// Writes `bytes` to `dest` whole or not at all (an [`AtomicFile`]); an error names the file.
pub fn write_whole(dest: &Path, bytes: &[u8]) -> io::Result<()> {
    let named = |e: io::Error| io::Error::new(e.kind(), format!("{}: {e}", dest.display()));
    let mut f = AtomicFile::create(dest).map_err(named)?;
    f.write_all(bytes).map_err(named)?;
    f.commit().map_err(named)
}

/// Removes what a failed run wrote to `path`, when that is a regular file: a device or a FIFO
/// (`/dev/null`, `/dev/full`, a pipe to another program) written directly is no output of
/// ours to remove.
pub fn remove_partial(path: &Path) {
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file()) {
        let _ = std::fs::remove_file(path);
    }
    unfinished::forget(path);
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
            // A FIFO's open waits for a reader.
            let file = unfinished::blocking(|| std::fs::OpenOptions::new().write(true).open(dest))?;
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
        unfinished::register(&tmp);
        Ok(AtomicFile {
            file: Some(file),
            tmp: Some(tmp),
            dest: dest.to_path_buf(),
        })
    }
    /// A second handle on the file being written: what is written through it lands in the
    /// same file, committed or removed with it.
    pub fn try_clone_writer(&self) -> io::Result<File> {
        match &self.file {
            Some(f) => f.try_clone(),
            None => Err(io::Error::other("file already committed")),
        }
    }

    /// Flushes, closes and renames the file into place. On failure the temporary is removed.
    pub fn commit(mut self) -> io::Result<()> {
        let file = self.file.take();
        match self.tmp.take() {
            None => Ok(()),
            Some(tmp) => {
                let done = file
                    .map_or(Ok(()), |f| unfinished::blocking(|| f.sync_data()))
                    .and_then(|()| std::fs::rename(&tmp, &self.dest));
                if done.is_err() {
                    let _ = std::fs::remove_file(&tmp);
                }
                unfinished::forget(&tmp);
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
            let _ = std::fs::remove_file(&tmp);
            unfinished::forget(&tmp);
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
