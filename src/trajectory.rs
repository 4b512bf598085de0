//! Reading a reference trajectory from CSV: `t,lat,lon,h,vn,ve,vd,roll,pitch,yaw`
//! (s, deg, deg, m ellipsoidal, m/s NED, deg ZYX Euler with yaw from north). Lines starting
//! with `#` are comments. Every problem is reported with file, line and column, including
//! values beyond the physical limits of [`crate::motion::limits`].

use std::io::{BufRead, BufReader, Read};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::csvio::{CsvLines, FileError, header_columns, num, parse_finite};
use crate::math::{Vec3, quat_from_euler};
use crate::motion::limits::{check_sample, check_step};
use crate::motion::sampled::{ModelError, ModelSettings, Sample, SampledMotion};
use crate::motion::stream::{IndexBuilder, Mark, SampleSource};

/// The required columns, in the order they are stored in a [`Sample`].
pub const COLUMNS: [&str; 10] = [
    "t", "lat", "lon", "h", "vn", "ve", "vd", "roll", "pitch", "yaw",
];

/// What is wrong with a trajectory file, and where (file, line, column).
pub type TrajectoryError = FileError;

/// The `expected …` hint of header errors.
const EXPECTED: &str = "(expected `t,lat,lon,h,vn,ve,vd,roll,pitch,yaw`)";

/// A streaming reader of trajectory samples: each one parsed, converted to SI and checked
/// (finite, latitude within ±90°, time increasing, the limits of [`crate::motion::limits`]).
pub struct TrajectoryReader<R> {
    lines: CsvLines<R>,
    /// order[c] = index into COLUMNS of file column c.
    order: Vec<usize>,
    prev: Option<Sample>,
}

impl<R: BufRead> TrajectoryReader<R> {
    /// Reads the header from `lines`.
    pub fn new(mut lines: CsvLines<R>) -> Result<Self, FileError> {
        let Some(header) = lines.next_fields()? else {
            return Err(lines.error(format!("no header line {EXPECTED}")));
        };
        let width = header.len();
        let at = header_columns(&header, &COLUMNS, EXPECTED).map_err(|p| lines.error(p))?;
        if let Some(k) = at.iter().position(Option::is_none) {
            let name = COLUMNS[k];
            return Err(lines.error(format!("header: missing column `{name}` {EXPECTED}")));
        }
        // order[c] = k for the file column c of COLUMNS[k].
        let mut order = vec![0; width];
        for (k, c) in at.iter().enumerate() {
            if let Some(c) = c {
                order[*c] = k;
            }
        }
        Ok(TrajectoryReader {
            lines,
            order,
            prev: None,
        })
    }

    /// A reader of the data lines of `lines` (positioned after the header of a file whose
    /// header gave `order`).
    fn resume(lines: CsvLines<R>, order: Vec<usize>) -> Self {
        TrajectoryReader {
            lines,
            order,
            prev: None,
        }
    }

    /// The line reader (for its position).
    pub fn lines(&self) -> &CsvLines<R> {
        &self.lines
    }

    /// The next sample; `None` at the end of the file.
    pub fn next_sample(&mut self) -> Result<Option<Sample>, FileError> {
        if !self.lines.advance()? {
            return Ok(None);
        }
        let width = self.order.len();
        let n = self.lines.fields().count();
        if n != width {
            let name = self.order.get(n).map(|&k| COLUMNS[k]);
            let what = match (name, n < width) {
                (Some(name), true) => format!(" (`{name}`) is missing"),
                (_, true) => " is missing".to_string(),
                (_, false) => " is extra".to_string(),
            };
            let index = n.min(width) + 1;
            let msg = format!("column {index}{what}: {n} fields, expected {width}");
            return Err(self.lines.error(msg));
        }
        let mut vals = [0.0; 10];
        for (c, field) in self.lines.fields().enumerate() {
            let k = self.order[c];
            let at = |m: String| self.lines.error(m).in_column(c + 1, COLUMNS[k]);
            let v = parse_finite(field).map_err(at)?;
            if k == 1 && v.abs() > 90.0 {
                return Err(at(format!("{} is outside [-90, 90] degrees", num(v))));
            }
            vals[k] = v;
        }
        let [t, lat, lon, h, vn, ve, vd, roll, pitch, yaw] = vals;
        let s = Sample {
            t,
            lat: lat.to_radians(),
            lon: lon.to_radians(),
            h,
            v_n: Vec3::new(vn, ve, vd),
            q_b_n: quat_from_euler(roll.to_radians(), pitch.to_radians(), yaw.to_radians()),
        };
        let col = |name: &str| {
            self.order
                .iter()
                .position(|&k| COLUMNS[k] == name)
                .unwrap_or(0)
                + 1
        };
        let at = |name: &'static str, m: String| match name {
            "" => self.lines.error(m),
            _ => self.lines.error(m).in_column(col(name), name),
        };
        if let Some(prev) = &self.prev
            && t <= prev.t
        {
            let m = format!(
                "{} does not increase (previous sample at {})",
                num(t),
                num(prev.t)
            );
            return Err(at("t", m));
        }
        // The sample's own limits first: they keep the step's differences finite.
        check_sample(&s).map_err(|v| at(v.column, v.message))?;
        if let Some(prev) = &self.prev {
            check_step(prev, &s).map_err(|v| at(v.column, v.message))?;
        }
        self.prev = Some(s);
        Ok(Some(s))
    }
}

/// Parses trajectory CSV text; `path` is used in error messages only.
pub fn parse(text: &str, path: &Path) -> Result<Vec<Sample>, TrajectoryError> {
    let mut r = TrajectoryReader::new(CsvLines::new(text.as_bytes(), path))?;
    let mut samples = Vec::new();
    while let Some(s) = r.next_sample()? {
        samples.push(s);
    }
    Ok(samples)
}

/// Reads and parses a whole trajectory file (`-`: stdin) into memory.
pub fn read(path: &Path) -> Result<Vec<Sample>, TrajectoryError> {
    let mut r = TrajectoryReader::new(CsvLines::open(path)?)?;
    let mut samples = Vec::new();
    while let Some(s) = r.next_sample()? {
        samples.push(s);
    }
    Ok(samples)
}

/// The motion model of a trajectory file (`-`: stdin), streaming: a first pass checks every
/// line and indexes the file; the model then re-reads it in a sliding window as it is
/// evaluated, so memory does not grow with the file. Stdin is copied to an unnamed temporary
/// file during the first pass, to be re-read from there.
pub fn open_motion(path: &Path, settings: ModelSettings) -> Result<SampledMotion, FileError> {
    let file = if path == Path::new("-") {
        spool_file().map_err(|e| FileError {
            message: "cannot create a temporary file to hold stdin".into(),
            ..FileError::io(path, e)
        })?
    } else {
        std::fs::File::open(path).map_err(|e| FileError::io(path, e))?
    };
    let file = Arc::new(file);
    let spool = (path == Path::new("-")).then(|| file.clone());
    let input: Box<dyn Read + Send> = match &spool {
        Some(f) => Box::new(Tee {
            input: std::io::stdin(),
            copy: f.clone(),
            at: 0,
        }),
        None => Box::new(At {
            file: file.clone(),
            pos: 0,
        }),
    };
    let mut reader = TrajectoryReader::new(CsvLines::new(
        BufReader::with_capacity(1 << 16, input),
        path,
    ))?;
    let mut index = IndexBuilder::new(settings);
    let t_col = 1 + reader
        .order
        .iter()
        .position(|&k| COLUMNS[k] == "t")
        .unwrap_or(0);
    while let Some(s) = reader.next_sample()? {
        let l = reader.lines();
        let mark = Mark(l.line_offset(), l.line_no() - 1);
        // The reader has checked everything the index checks, with line and column; what it
        // finds later (samples alone between gaps) it names by their marks.
        index
            .push(&s, mark)
            .map_err(|e| index_error(path, &index, t_col, e, || l.error("")))?;
    }
    let got = index.len();
    if got >= settings.min_samples() {
        let last = reader.lines().error("");
        index
            .finish_gaps()
            .map_err(|e| index_error(path, &index, t_col, e, || last))?;
    }
    let index = index.finish().map_err(|_| {
        let need = settings.min_samples();
        FileError::file(
            path,
            format!("{got} samples, but the motion model needs at least {need}"),
        )
    })?;
    let source = FileSamples {
        file,
        path: path.to_path_buf(),
        order: reader.order,
        reader: None,
    };
    Ok(SampledMotion::from_source(
        Box::new(source),
        index,
        settings,
    ))
}

/// A first-pass error as a file error: samples alone between gaps at their first line, in
/// the `t` column (the file's column `t_col`); anything else at the line `here` names.
fn index_error(
    path: &Path,
    index: &IndexBuilder,
    t_col: usize,
    e: ModelError,
    here: impl FnOnce() -> FileError,
) -> FileError {
    match &e {
        ModelError::Isolated(i) => match index.mark(i.first) {
            Some(m) => FileError::line(path, m.1 + 1, e.to_string()).in_column(t_col, "t"),
            None => FileError::file(path, e.to_string()),
        },
        _ => FileError {
            message: e.to_string(),
            ..here()
        },
    }
}

/// An unnamed temporary file (created and at once unlinked) for a copy of stdin.
fn spool_file() -> std::io::Result<std::fs::File> {
    let dir = std::env::temp_dir();
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let name = dir.join(format!(".imu-emu-stdin-{}-{nanos}", std::process::id()));
    let f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create_new(true)
        .open(&name)?;
    std::fs::remove_file(&name)?;
    Ok(f)
}

/// Reads `input`, appending everything read to `copy`.
struct Tee<R> {
    input: R,
    copy: Arc<std::fs::File>,
    at: u64,
}

impl<R: Read> Read for Tee<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.input.read(buf)?;
        self.copy.write_all_at(&buf[..n], self.at)?;
        self.at += n as u64;
        Ok(n)
    }
}

/// Reads a shared file from its own position (positional reads: copies do not interfere).
struct At {
    file: Arc<std::fs::File>,
    pos: u64,
}

impl Read for At {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.file.read_at(buf, self.pos)?;
        self.pos += n as u64;
        Ok(n)
    }
}

/// The samples of an indexed trajectory file, re-read on demand.
struct FileSamples {
    file: Arc<std::fs::File>,
    path: PathBuf,
    order: Vec<usize>,
    reader: Option<TrajectoryReader<BufReader<At>>>,
}

impl SampleSource for FileSamples {
    fn next_sample(&mut self) -> Result<Option<Sample>, String> {
        let r = self.reader.as_mut().ok_or("read before a rewind")?;
        r.next_sample()
            .map_err(|e| format!("{e} (the file changed while in use?)"))
    }
    fn rewind(&mut self, mark: Mark) -> Result<(), String> {
        let input = At {
            file: self.file.clone(),
            pos: mark.0,
        };
        let lines = CsvLines::resume(
            BufReader::with_capacity(1 << 16, input),
            &self.path,
            mark.0,
            mark.1,
        );
        self.reader = Some(TrajectoryReader::resume(lines, self.order.clone()));
        Ok(())
    }
    fn fork(&self) -> Box<dyn SampleSource> {
        Box::new(FileSamples {
            file: self.file.clone(),
            path: self.path.clone(),
            order: self.order.clone(),
            reader: None,
        })
    }
}

/// Formats samples as trajectory CSV (shortest round-trip numbers), e.g. to save a scene.
pub fn format_row(
    out: &mut String,
    t: f64,
    lat_deg: f64,
    lon_deg: f64,
    h: f64,
    v_n: Vec3,
    rpy_deg: (f64, f64, f64),
) {
    let vals = [
        t, lat_deg, lon_deg, h, v_n.x, v_n.y, v_n.z, rpy_deg.0, rpy_deg.1, rpy_deg.2,
    ];
    let mut buf = ryu::Buffer::new();
    for (i, v) in vals.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(buf.format(*v));
    }
    out.push('\n');
}

/// Trajectory CSV of `motion` sampled at t₀ + k/rate for k = 0..=count (degrees, shortest
/// round-trip decimals), preceded by `# comment` when given.
pub fn sample_motion(
    motion: &impl crate::motion::Motion,
    t0: f64,
    rate_hz: f64,
    count: u64,
    comment: Option<&str>,
) -> String {
    let mut text = String::new();
    if let Some(c) = comment {
        text.push_str("# ");
        text.push_str(c);
        text.push('\n');
    }
    text.push_str(&COLUMNS.join(","));
    text.push('\n');
    for k in 0..=count {
        pose_row(&mut text, &motion.pose(t0 + k as f64 / rate_hz));
    }
    text
}

/// Appends `p` as a row of [`COLUMNS`] (angles in degrees).
pub fn pose_row(text: &mut String, p: &crate::motion::Pose) {
    let (r, pi, y) = crate::math::euler_from_quat(p.q_b_n);
    format_row(
        text,
        p.t,
        p.lat.to_degrees(),
        p.lon.to_degrees(),
        p.h,
        p.v_n,
        (r.to_degrees(), pi.to_degrees(), y.to_degrees()),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::Motion;

    fn text(n: usize) -> String {
        let mut t = String::from("# a turn\nyaw,t,lat,lon,h,vn,ve,vd,roll,pitch\n");
        for i in 0..n {
            let s = i as f64 * 0.01;
            t += &format!(
                "{},{s},45,2,{},30,0,0,1,2\n",
                (170.0 + 40.0 * s) % 360.0 - 180.0,
                100.0 + s
            );
            if i % 500 == 0 {
                t += "\n# marks\n";
            }
        }
        t
    }

    /// The streaming model of a file (re-read from checkpoints, with comments and blank lines
    /// between samples) evaluates exactly as the model of the same samples held in memory.
    #[test]
    fn file_model_equals_memory_model() {
        let text = text(20_000);
        let dir = tempfile::TempDir::new().unwrap();
        let path = dir.path().join("t.csv");
        std::fs::write(&path, &text).unwrap();
        let settings = ModelSettings::default();
        let file = open_motion(&path, settings).unwrap();
        let mem = SampledMotion::new(&parse(&text, &path).unwrap(), settings).unwrap();
        assert_eq!((file.start(), file.end()), (mem.start(), mem.end()));
        for t in [150.0, 0.013, 199.98, 37.5, 36.0, 120.0, 0.0] {
            let (pf, pm) = (file.piece_at(t, 0), mem.piece_at(t, 0));
            assert_eq!(pf, pm);
            assert_eq!(file.sense(pf, t), mem.sense(pm, t), "t = {t}");
        }
        assert!(file.failure().is_none());
    }

    /// Overflowing and impossible values are refused at their line and column, with the
    /// limit; a long field is echoed cut.
    #[test]
    fn impossible_values_are_refused_where_they_are() {
        let p = Path::new("x.csv");
        let head = "t,lat,lon,h,vn,ve,vd,roll,pitch,yaw\n0,45,2,0,0,0,0,0,0,0\n";
        let e = |row: &str| parse(&format!("{head}{row}\n"), p).unwrap_err().to_string();
        let m = e("1,45,2,1e160,0,0,0,0,0,0");
        assert!(
            m.starts_with("x.csv:3: column 4 (`h`): height 1e160 m is outside [-1e5, 1e8] m"),
            "{m}"
        );
        let m = e("1,45,2,0,0,0,1e160,0,0,0");
        assert!(
            m.starts_with("x.csv:3: column 7 (`vd`): speed 1e160 m/s"),
            "{m}"
        );
        let m = e("1e-9,45,2,0,0,0,0,0,0,0");
        assert!(
            m.contains("column 1 (`t`)") && m.contains("at least 1e-6 s apart"),
            "{m}"
        );
        let m = e("0.25,45,2,0,30000,0,0,0,0,0");
        assert!(
            m.contains("implies 1.2e5 m/s², above the limit of 1e5 m/s²"),
            "{m}"
        );
        let m = e(&format!("1,45,2,{},0,0,0,0,0,0", "9".repeat(50_000)));
        assert!(m.len() < 200 && m.contains("(50000 bytes)"), "{m}");
    }
}
