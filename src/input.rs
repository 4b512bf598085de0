//! Reading the record contract back: CSV with the header of `record::COLUMNS` (columns in any
//! order, extra columns ignored) or the 104-byte little-endian binary records, streamed one
//! record at a time. Every problem names the file, the line (CSV) or record (binary) and the
//! column.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use crate::csvio::{CsvLines, FileError, Place, parse_finite};

use crate::output::{BIN_RECORD_BYTES, Format, decode_bin};
use crate::record::{COLUMNS, Record};

/// What is wrong with a record file, and where (line and column, or binary record).
pub type InputError = FileError;

/// A streaming reader of records.
pub struct RecordReader {
    input: Input,
    path: PathBuf,
    /// CSV: file column of each `COLUMNS` entry, and the number of header columns.
    columns: [usize; 13],
    width: usize,
    records: u64,
}

/// The text or binary stream records come from.
enum Input {
    Csv(CsvLines<Box<dyn BufRead>>),
    Bin(Box<dyn BufRead>),
}

impl RecordReader {
    /// Opens `path` (or stdin for `-`).
    pub fn open(path: &Path, format: Format) -> Result<RecordReader, InputError> {
        if format == Format::Bin {
            check_whole_records(path)?;
        }
        let input = BufReader::with_capacity(1 << 20, crate::csvio::open(path)?);
        RecordReader::new(input, path, format)
    }

    /// Reads from any buffered reader; `path` names it in messages.
    pub fn new(
        input: impl BufRead + 'static,
        path: &Path,
        format: Format,
    ) -> Result<RecordReader, InputError> {
        let input: Box<dyn BufRead> = Box::new(input);
        let mut r = RecordReader {
            input: match format {
                Format::Csv => Input::Csv(CsvLines::new(input, path)),
                Format::Bin => Input::Bin(input),
            },
            path: path.to_path_buf(),
            columns: std::array::from_fn(|i| i),
            width: 13,
            records: 0,
        };
        if let Input::Csv(lines) = &mut r.input {
            (r.columns, r.width) = read_header(lines)?;
        }
        Ok(r)
    }

    fn csv_record(&mut self) -> Result<Option<Record>, InputError> {
        let Input::Csv(lines) = &mut self.input else {
            unreachable!("CSV input");
        };
        if !lines.advance()? {
            return Ok(None);
        }
        let fields: Vec<&str> = lines.fields().collect();
        if fields.len() != self.width {
            let problem = format!("{} fields, expected {}", fields.len(), self.width);
            return Err(lines.error(problem));
        }
        let mut v = [0.0; 13];
        for (i, name) in COLUMNS.iter().enumerate() {
            let c = self.columns[i];
            v[i] = parse_finite(fields[c]).map_err(|m| lines.error(m).in_column(c + 1, name))?;
        }
        Ok(Some(Record::from_values(&v)))
    }

    fn bin_record(&mut self) -> Result<Option<Record>, InputError> {
        let Input::Bin(input) = &mut self.input else {
            unreachable!("binary input");
        };
        let mut buf = [0u8; BIN_RECORD_BYTES];
        let mut got = 0;
        while got < buf.len() {
            let n = input
                .read(&mut buf[got..])
                .map_err(|e| FileError::io(&self.path, e))?;
            if n == 0 {
                break;
            }
            got += n;
        }
        let offset = self.records * BIN_RECORD_BYTES as u64;
        let err = |message: String| FileError {
            place: Place::Record(self.records + 1, offset),
            ..FileError::file(&self.path, message)
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
        match &self.input {
            Input::Csv(l) => format!("{}:{}", self.path.display(), l.line_no()),
            Input::Bin(_) => format!("{}: record {}", self.path.display(), self.records),
        }
    }
}

/// Refuses a regular file whose length is not a whole number of binary records, before a
/// byte of it is read: a cut or foreign file would otherwise be read to its end (a whole
/// gigabyte) before its last record came up short. Pipes are checked record by record.
pub fn check_whole_records(path: &Path) -> Result<(), InputError> {
    let Ok(meta) = std::fs::metadata(path) else {
        // The open that follows names the reason.
        return Ok(());
    };
    let (len, rec) = (meta.len(), BIN_RECORD_BYTES as u64);
    if !meta.is_file() || len % rec == 0 {
        return Ok(());
    }
    Err(FileError::file(
        path,
        format!(
            "{len} bytes is not a whole number of {rec}-byte records ({} records and {} bytes; is the file CSV? use --format csv)",
            len / rec,
            len % rec
        ),
    ))
}

/// Reads the header: the file column of each of `COLUMNS`, and the number of columns.
fn read_header<R: BufRead>(lines: &mut CsvLines<R>) -> Result<([usize; 13], usize), InputError> {
    let expected = COLUMNS.join(",");
    if !lines.advance()? {
        return Err(lines.error(format!("no header line (expected `{expected}`)")));
    }
    let header: Vec<&str> = lines.fields().collect();
    let mut columns = [0; 13];
    for (i, name) in COLUMNS.iter().enumerate() {
        match header.iter().position(|h| h == name) {
            Some(c) => columns[i] = c,
            None => {
                return Err(lines.error(format!(
                    "header: missing column `{name}` (expected `{expected}`)"
                )));
            }
        }
    }
    Ok((columns, header.len()))
}

impl Iterator for RecordReader {
    type Item = Result<Record, InputError>;
    fn next(&mut self) -> Option<Self::Item> {
        let r = match self.input {
            Input::Csv(_) => self.csv_record(),
            Input::Bin(_) => self.bin_record(),
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
