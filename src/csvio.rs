//! The one text-table reader and the one file-error type shared by every CSV input (trajectory,
//! record contract, analysis input, temperature table): lines streamed from a file or stdin
//! with their numbers and byte offsets, `#` comments and blank lines skipped, a UTF-8
//! byte-order mark dropped, overlong lines refused, and field text echoed in errors cut to a
//! readable length.

use std::fmt;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// Longest line accepted (bytes). Real tables have lines of hundreds of bytes; a bound keeps
/// a file without line breaks from being read whole into memory.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Largest text file read whole (scene, template and motion-definition files, ADEV and
/// magnetic-field tables): real ones are kilobytes to a few megabytes; a bound keeps a wrong
/// path (a recording, a device) from being read into memory whole.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// Characters of a field's text quoted in an error; longer text is cut with its length given.
pub const ECHO_CHARS: usize = 40;

/// Where in a file a problem is.
#[derive(Clone, Debug, PartialEq)]
pub enum Place {
    /// The file as a whole (cannot open, too short, …).
    File,
    /// A 1-based text line.
    Line(u64),
    /// A fixed-size binary record: 1-based number and byte offset.
    Record(u64, u64),
}

/// A problem with an input file: which file, where, which column, and what.
#[derive(Debug, thiserror::Error)]
pub struct FileError {
    /// The file (`-` for stdin).
    pub path: PathBuf,
    /// Where in it.
    pub place: Place,
    /// 1-based column number and its name (empty when it has none).
    pub column: Option<(usize, String)>,
    /// What is wrong.
    pub message: String,
    /// The system's reason, for read failures (not repeated in the message, so an error chain
    /// printed with `{:#}` names it once).
    #[source]
    pub source: Option<std::io::Error>,
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        match self.place {
            Place::File => {}
            Place::Line(l) => write!(f, ":{l}")?,
            Place::Record(n, o) => write!(f, ": record {n} (byte {o})")?,
        }
        match &self.column {
            Some((i, n)) if n.is_empty() => write!(f, ": column {i}")?,
            Some((i, n)) => write!(f, ": column {i} (`{n}`)")?,
            None => {}
        }
        write!(f, ": {}", self.message)
    }
}

impl FileError {
    /// A problem with the whole file.
    pub fn file(path: &Path, message: impl Into<String>) -> FileError {
        FileError {
            path: path.to_path_buf(),
            place: Place::File,
            column: None,
            message: message.into(),
            source: None,
        }
    }
    /// The file cannot be opened or read.
    pub fn io(path: &Path, source: std::io::Error) -> FileError {
        FileError {
            source: Some(source),
            ..FileError::file(path, "cannot read")
        }
    }
    /// A problem on 1-based line `line`.
    pub fn line(path: &Path, line: u64, message: impl Into<String>) -> FileError {
        FileError {
            place: Place::Line(line),
            ..FileError::file(path, message)
        }
    }
    /// The same error, about 1-based column `index` named `name`.
    pub fn in_column(mut self, index: usize, name: &str) -> FileError {
        self.column = Some((index, name.to_string()));
        self
    }
}

/// `text` quoted for an error message: whole when short, else its first [`ECHO_CHARS`]
/// characters and its length.
pub fn clip(text: &str) -> String {
    match text.char_indices().nth(ECHO_CHARS) {
        None => format!("`{text}`"),
        Some((end, _)) => format!("`{}…` ({} bytes)", &text[..end], text.len()),
    }
}

/// A number for a message: the shortest text that reads back to it, in exponent form when
/// that is shorter (`1e160`, not 161 digits).
pub fn num(x: f64) -> String {
    let plain = x.to_string();
    let short = format!("{x:e}");
    if short.len() < plain.len() {
        short
    } else {
        plain
    }
}

/// [`num`] of `x` rounded to `digits` significant digits: for a value computed from others
/// (a difference of times), whose last digits are rounding.
pub fn num_sig(x: f64, digits: usize) -> String {
    let p = digits.max(1) - 1;
    num(format!("{x:.p$e}").parse().unwrap_or(x))
}

/// Parses a field as a finite number; the message (for a column error) quotes the clipped text.
pub fn parse_finite(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("{} is not finite", clip(text))),
        Err(_) => Err(format!("{} is not a number", clip(text))),
    }
}

/// `text` without a leading UTF-8 byte-order mark: spreadsheet exports and text written as
/// `utf-8-sig` start with one, and it is not part of the first field.
pub fn strip_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// The column of each of `known`'s names in the header `fields` (`None`: absent), as every
/// headed table reads its header: names in any order, an unknown name or one given twice
/// refused naming its 1-based column; `expected` (e.g. "(expected `t,lat`)") ends the message
/// of an unknown name. Which columns must be there is the caller's to check.
pub fn header_columns(
    fields: &[&str],
    known: &[&str],
    expected: &str,
) -> Result<Vec<Option<usize>>, String> {
    let mut at = vec![None; known.len()];
    for (c, name) in fields.iter().enumerate() {
        let Some(k) = known.iter().position(|n| n == name) else {
            let name = clip(name);
            return Err(format!(
                "header: column {}: unknown column {name} {expected}",
                c + 1
            ));
        };
        if at[k].is_some() {
            let name = clip(name);
            return Err(format!("header: column {}: {name} appears twice", c + 1));
        }
        at[k] = Some(c);
    }
    Ok(at)
}

/// Opens `path` for reading, or stdin for `-`.
pub fn open(path: &Path) -> Result<Box<dyn Read + Send>, FileError> {
    if path == Path::new("-") {
        return Ok(Box::new(std::io::stdin()));
    }
    let f = std::fs::File::open(path).map_err(|e| FileError::io(path, e))?;
    Ok(Box::new(f))
}

/// The whole text of `path`, refused (as [`std::io::ErrorKind::InvalidData`], naming the
/// limit) beyond [`MAX_TEXT_BYTES`]: a file from its length before a byte is read, a pipe once
/// that much has come.
pub fn read_text(path: &Path) -> std::io::Result<String> {
    let f = std::fs::File::open(path)?;
    let too_big = |size: String| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("{size} bytes: a file read whole has at most {MAX_TEXT_BYTES} bytes"),
        )
    };
    let len = f.metadata()?.len();
    if len > MAX_TEXT_BYTES {
        return Err(too_big(len.to_string()));
    }
    let mut text = String::new();
    f.take(MAX_TEXT_BYTES + 1).read_to_string(&mut text)?;
    if text.len() as u64 > MAX_TEXT_BYTES {
        return Err(too_big(format!("more than {MAX_TEXT_BYTES}")));
    }
    Ok(text)
}

/// A streaming reader of the data lines of a comma-separated table.
pub struct CsvLines<R> {
    input: R,
    path: PathBuf,
    line_no: u64,
    offset: u64,
    line_start: u64,
    buf: Vec<u8>,
    text: String,
}

impl CsvLines<BufReader<Box<dyn Read + Send>>> {
    /// Opens `path` (stdin for `-`).
    pub fn open(path: &Path) -> Result<Self, FileError> {
        Ok(CsvLines::new(
            BufReader::with_capacity(1 << 16, open(path)?),
            path,
        ))
    }
}

impl<R: BufRead> CsvLines<R> {
    /// Reads from `input`; `path` names it in messages.
    pub fn new(input: R, path: &Path) -> Self {
        CsvLines::resume(input, path, 0, 0)
    }

    /// Reads from `input`, which is positioned at byte `offset` of the file, just after line
    /// `line_no` (0 at the start).
    pub fn resume(input: R, path: &Path, offset: u64, line_no: u64) -> Self {
        CsvLines {
            input,
            path: path.to_path_buf(),
            line_no,
            offset,
            line_start: offset,
            buf: Vec::new(),
            text: String::new(),
        }
    }

    /// The file's name in messages.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// 1-based number of the last line read (0 before the first).
    pub fn line_no(&self) -> u64 {
        self.line_no
    }

    /// Byte offset of the start of the last line returned.
    pub fn line_offset(&self) -> u64 {
        self.line_start
    }

    /// An error on the last line read.
    pub fn error(&self, message: impl Into<String>) -> FileError {
        FileError::line(&self.path, self.line_no.max(1), message)
    }

    /// Moves to the next line that is neither blank nor a `#` comment; false at the end.
    pub fn advance(&mut self) -> Result<bool, FileError> {
        loop {
            if !self.read_raw()? {
                return Ok(false);
            }
            let t = self.text.trim();
            if !t.is_empty() && !t.starts_with('#') {
                return Ok(true);
            }
        }
    }

    /// Moves to the next line whatever it holds (comments and blank lines too, for formats
    /// whose comments carry settings); false at the end.
    pub fn advance_raw(&mut self) -> Result<bool, FileError> {
        self.read_raw()
    }

    /// The current line as read, its line end included.
    pub fn raw(&self) -> &str {
        &self.text
    }

    /// The current data line, trimmed.
    pub fn current(&self) -> &str {
        self.text.trim()
    }

    /// The current data line split at commas into trimmed fields.
    pub fn fields(&self) -> impl Iterator<Item = &str> {
        self.current().split(',').map(str::trim)
    }

    /// The next data line, trimmed; `None` at the end.
    pub fn next_line(&mut self) -> Result<Option<&str>, FileError> {
        Ok(if self.advance()? {
            Some(self.current())
        } else {
            None
        })
    }

    /// The next data line split at commas into trimmed fields.
    pub fn next_fields(&mut self) -> Result<Option<Vec<&str>>, FileError> {
        Ok(self
            .next_line()?
            .map(|l| l.split(',').map(str::trim).collect()))
    }

    /// One raw line into `self.text` (without its end of line); false at the end of input.
    fn read_raw(&mut self) -> Result<bool, FileError> {
        self.buf.clear();
        self.line_start = self.offset;
        loop {
            let avail = match self.input.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(FileError::io(&self.path, e)),
            };
            if avail.is_empty() {
                break;
            }
            let (take, done) = match avail.iter().position(|&b| b == b'\n') {
                Some(i) => (i + 1, true),
                None => (avail.len(), false),
            };
            self.buf.extend_from_slice(&avail[..take]);
            self.input.consume(take);
            self.offset += take as u64;
            if self.buf.len() > MAX_LINE_BYTES {
                self.line_no += 1;
                return Err(self.error(format!(
                    "line longer than {MAX_LINE_BYTES} bytes (is this a CSV table?)"
                )));
            }
            if done {
                break;
            }
        }
        if self.buf.is_empty() {
            return Ok(false);
        }
        self.line_no += 1;
        self.text.clear();
        match std::str::from_utf8(&self.buf) {
            Ok(s) => self.text.push_str(s),
            Err(e) => {
                let at = e.valid_up_to();
                return Err(self.error(format!("byte {} of the line is not UTF-8 text", at + 1)));
            }
        }
        if self.line_start == 0 {
            let mark = self.text.len() - strip_bom(&self.text).len();
            self.text.drain(..mark);
        }
        Ok(true)
    }
}

/// A TOML error of `text` on one line: `line L, column C: message`. The parser's own text
/// spans several lines (a code excerpt with a caret), which a one-line error cannot show.
pub fn toml_error_line(text: &str, e: &toml::de::Error) -> String {
    let message = e.message().trim().replace('\n', " ");
    match e.span() {
        Some(s) => {
            let (line, column) = line_col(text, s.start);
            format!("line {line}, column {column}: {message}")
        }
        None => message,
    }
}

/// 1-based line and column of a byte offset.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(text: &str) -> CsvLines<std::io::Cursor<Vec<u8>>> {
        CsvLines::new(
            std::io::Cursor::new(text.as_bytes().to_vec()),
            Path::new("x.csv"),
        )
    }

    #[test]
    fn skips_comments_blanks_and_bom_and_counts_lines() {
        let mut r = lines("\u{feff}a,b\n# c\n\n 1 , 2 \r\n3,4");
        assert_eq!(r.next_fields().unwrap(), Some(vec!["a", "b"]));
        assert_eq!(r.line_no(), 1);
        assert_eq!(r.next_fields().unwrap(), Some(vec!["1", "2"]));
        // Offset 12: the 3-byte mark, `a,b\n`, `# c\n` and the blank line precede it.
        assert_eq!((r.line_no(), r.line_offset()), (4, 12));
        assert_eq!(r.next_fields().unwrap(), Some(vec!["3", "4"]));
        assert_eq!(r.next_fields().unwrap(), None);
        assert_eq!(r.error("x").to_string(), "x.csv:5: x");
    }

    /// Names in any order; unknown and repeated names name their column.
    #[test]
    fn header_columns_in_any_order() {
        let known = ["t", "lat", "lon"];
        let at = header_columns(&["lon", "t", "lat"], &known, "(x)").unwrap();
        assert_eq!(at, vec![Some(1), Some(2), Some(0)]);
        assert_eq!(
            header_columns(&["t"], &known, "(x)").unwrap(),
            vec![Some(0), None, None]
        );
        let e = header_columns(&["t", "\u{feff}lat"], &known, "(x)").unwrap_err();
        assert_eq!(e, "header: column 2: unknown column `\u{feff}lat` (x)");
        let e = header_columns(&["t", "lat", "t"], &known, "(x)").unwrap_err();
        assert_eq!(e, "header: column 3: `t` appears twice");
        assert_eq!(strip_bom("\u{feff}t,lat"), "t,lat");
        assert_eq!(strip_bom("t,\u{feff}"), "t,\u{feff}");
    }

    #[test]
    fn long_lines_and_fields_are_cut() {
        let field = "z".repeat(5_000_000);
        let mut r = lines(&format!("a\n{field}\n"));
        r.next_line().unwrap();
        let e = r.next_line().unwrap_err().to_string();
        assert!(e.starts_with("x.csv:2: line longer than"), "{e}");
        let e = parse_finite(&field[..100_000]).unwrap_err();
        assert!(
            e.len() < 100 && e.contains("(100000 bytes) is not a number"),
            "{e}"
        );
        assert_eq!(parse_finite("-inf").unwrap_err(), "`-inf` is not finite");
    }

    #[test]
    fn a_file_read_whole_is_bounded_by_its_length() {
        let dir = tempfile::TempDir::new().unwrap();
        let p = dir.path().join("big.toml");
        // Sparse: its length is refused before a byte of it is read.
        std::fs::File::create(&p)
            .unwrap()
            .set_len(MAX_TEXT_BYTES + 1)
            .unwrap();
        let e = read_text(&p).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
        assert_eq!(
            e.to_string(),
            format!(
                "{} bytes: a file read whole has at most {MAX_TEXT_BYTES} bytes",
                MAX_TEXT_BYTES + 1
            )
        );
        std::fs::write(&p, "a = 1\n").unwrap();
        assert_eq!(read_text(&p).unwrap(), "a = 1\n");
    }

    #[test]
    fn messages_name_file_place_and_column() {
        let e = FileError::line(Path::new("a.csv"), 7, "bad").in_column(3, "h");
        assert_eq!(e.to_string(), "a.csv:7: column 3 (`h`): bad");
        let e = FileError {
            place: Place::Record(2, 104),
            ..FileError::file(Path::new("a.bin"), "truncated")
        };
        assert_eq!(e.to_string(), "a.bin: record 2 (byte 104): truncated");
        assert_eq!(num(1e160), "1e160");
        assert_eq!(num(0.25), "0.25");
        assert_eq!(num(-1.5e-9), "-1.5e-9");
    }
}
