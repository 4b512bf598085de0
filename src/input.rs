//! Reading the record contract back: CSV with the header of `record::COLUMNS` (columns in any
//! order, extra columns ignored) or the 104-byte little-endian binary records, streamed one
//! record at a time. Every problem names the file, the line (CSV) or record (binary) and the
//! column.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use crate::output::{BIN_RECORD_BYTES, Format, decode_bin};
use crate::record::{COLUMNS, Record};

/// What is wrong with a record file, and where.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The file could not be opened or read (the cause is the error's source).
    #[error("{path}: cannot read")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// A problem on a CSV line.
    #[error("{path}:{line}: {problem}")]
    Line {
        /// File.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        problem: String,
    },
    /// A problem in a binary record.
    #[error("{path}: record {record} (byte {offset}): {problem}")]
    Binary {
        /// File.
        path: PathBuf,
        /// 1-based record number.
        record: u64,
        /// Byte offset of the record.
        offset: u64,
        /// What is wrong.
        problem: String,
    },
}

/// A streaming reader of records.
pub struct RecordReader {
    input: Box<dyn BufRead>,
    path: PathBuf,
    format: Format,
    /// CSV: file column of each `COLUMNS` entry, and the number of header columns.
    columns: [usize; 13],
    width: usize,
    line_no: usize,
    records: u64,
    line: String,
}

impl RecordReader {
    /// Opens `path` (or stdin for `-`).
    pub fn open(path: &Path, format: Format) -> Result<RecordReader, InputError> {
        let input: Box<dyn Read> = if path == Path::new("-") {
            Box::new(std::io::stdin())
        } else {
            Box::new(std::fs::File::open(path).map_err(|source| InputError::Io {
                path: path.to_path_buf(),
                source,
            })?)
        };
        RecordReader::new(BufReader::with_capacity(1 << 20, input), path, format)
    }

    /// Reads from any buffered reader; `path` names it in messages.
    pub fn new(
        input: impl BufRead + 'static,
        path: &Path,
        format: Format,
    ) -> Result<RecordReader, InputError> {
        let mut r = RecordReader {
            input: Box::new(input),
            path: path.to_path_buf(),
            format,
            columns: std::array::from_fn(|i| i),
            width: 13,
            line_no: 0,
            records: 0,
            line: String::new(),
        };
        if format == Format::Csv {
            r.read_header()?;
        }
        Ok(r)
    }

    fn at(&self, problem: String) -> InputError {
        InputError::Line {
            path: self.path.clone(),
            line: self.line_no,
            problem,
        }
    }

    /// Next non-empty, non-comment line into `self.line`; false at the end.
    fn next_line(&mut self) -> Result<bool, InputError> {
        loop {
            self.line.clear();
            let n = self
                .input
                .read_line(&mut self.line)
                .map_err(|source| InputError::Io {
                    path: self.path.clone(),
                    source,
                })?;
            if n == 0 {
                return Ok(false);
            }
            self.line_no += 1;
            let t = self.line.trim();
            if !t.is_empty() && !t.starts_with('#') {
                return Ok(true);
            }
        }
    }

    fn read_header(&mut self) -> Result<(), InputError> {
        if !self.next_line()? {
            return Err(self.at(format!("no header line (expected `{}`)", COLUMNS.join(","))));
        }
        let header: Vec<String> = self
            .line
            .trim()
            .trim_start_matches('\u{feff}')
            .split(',')
            .map(|s| s.trim().to_string())
            .collect();
        for (i, name) in COLUMNS.iter().enumerate() {
            match header.iter().position(|h| h == name) {
                Some(c) => self.columns[i] = c,
                None => {
                    return Err(self.at(format!(
                        "header: missing column `{name}` (expected `{}`)",
                        COLUMNS.join(",")
                    )));
                }
            }
        }
        self.width = header.len();
        Ok(())
    }

    fn csv_record(&mut self) -> Result<Option<Record>, InputError> {
        if !self.next_line()? {
            return Ok(None);
        }
        let fields: Vec<&str> = self.line.trim().split(',').map(str::trim).collect();
        if fields.len() != self.width {
            let problem = format!("{} fields, expected {}", fields.len(), self.width);
            return Err(self.at(problem));
        }
        let mut v = [0.0; 13];
        for (i, name) in COLUMNS.iter().enumerate() {
            let c = self.columns[i];
            let text = fields[c];
            match text.parse::<f64>() {
                Ok(x) if x.is_finite() => v[i] = x,
                Ok(_) => {
                    let p = format!("column {} (`{name}`): `{text}` is not finite", c + 1);
                    return Err(self.at(p));
                }
                Err(_) => {
                    let p = format!("column {} (`{name}`): `{text}` is not a number", c + 1);
                    return Err(self.at(p));
                }
            }
        }
        Ok(Some(Record::from_values(&v)))
    }

    fn bin_record(&mut self) -> Result<Option<Record>, InputError> {
        let mut buf = [0u8; BIN_RECORD_BYTES];
        let mut got = 0;
        while got < buf.len() {
            let n = self
                .input
                .read(&mut buf[got..])
                .map_err(|source| InputError::Io {
                    path: self.path.clone(),
                    source,
                })?;
            if n == 0 {
                break;
            }
            got += n;
        }
        let offset = self.records * BIN_RECORD_BYTES as u64;
        let err = |problem: String| InputError::Binary {
            path: self.path.clone(),
            record: self.records + 1,
            offset,
            problem,
        };
        if got == 0 {
            return Ok(None);
        }
        if got < buf.len() {
            return Err(err(format!(
                "truncated: {got} of 104 bytes (is the file CSV? use --format csv)"
            )));
        }
        let v = decode_bin(&buf);
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(err(format!("`{}` is not finite", COLUMNS[i])));
        }
        Ok(Some(Record::from_values(&v)))
    }

    /// Where the last record came from, for messages: `file:line` or `file: record N`.
    pub fn position(&self) -> String {
        match self.format {
            Format::Csv => format!("{}:{}", self.path.display(), self.line_no),
            Format::Bin => format!("{}: record {}", self.path.display(), self.records),
        }
    }
}

impl Iterator for RecordReader {
    type Item = Result<Record, InputError>;
    fn next(&mut self) -> Option<Self::Item> {
        let r = match self.format {
            Format::Csv => self.csv_record(),
            Format::Bin => self.bin_record(),
        };
        if let Ok(Some(_)) = r {
            self.records += 1;
        }
        r.transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    fn read(text: &str) -> Result<Vec<Record>, InputError> {
        let r = RecordReader::new(
            std::io::Cursor::new(text.as_bytes().to_vec()),
            Path::new("x.csv"),
            Format::Csv,
        )?;
        r.collect()
    }

    #[test]
    fn csv_round_trip_any_column_order() {
        let rec = Record {
            t: 0.0025,
            gyro: Vec3::new(1.0, 2.0, 3.0),
            accel: Vec3::new(4.0, 5.0, 6.0),
            dtheta: Vec3::new(7.0, 8.0, 9.0),
            dv: Vec3::new(10.0, 11.0, 12.0),
            flags: 0,
        };
        let mut buf = crate::output::csv_header().into_bytes();
        crate::output::encode(Format::Csv, &[rec, rec], &mut buf);
        let got = read(std::str::from_utf8(&buf).unwrap()).unwrap();
        assert_eq!(got, vec![rec, rec]);
        let mut bin = Vec::new();
        crate::output::encode(Format::Bin, &[rec], &mut bin);
        let r =
            RecordReader::new(std::io::Cursor::new(bin), Path::new("x.bin"), Format::Bin).unwrap();
        assert_eq!(r.collect::<Result<Vec<_>, _>>().unwrap(), vec![rec]);
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let e = read("t,gyro_x\n1,2\n").unwrap_err().to_string();
        assert!(
            e.contains("x.csv:1") && e.contains("missing column `gyro_y`"),
            "{e}"
        );
        let head = COLUMNS.join(",");
        let e = read(&format!("{head}\n0,1,2,3,4,5,6,7,8,9,10,11,zz\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("x.csv:2") && e.contains("`dv_z`") && e.contains("`zz`"),
            "{e}"
        );
        let e = read(&format!("{head}\n0,1\n")).unwrap_err().to_string();
        assert!(e.contains("x.csv:2: 2 fields, expected 13"), "{e}");
        let r = RecordReader::new(
            std::io::Cursor::new(vec![0u8; 150]),
            Path::new("x.bin"),
            Format::Bin,
        )
        .unwrap();
        let e = r.collect::<Result<Vec<_>, _>>().unwrap_err().to_string();
        assert!(e.contains("x.bin: record 2 (byte 104): truncated"), "{e}");
    }
}
