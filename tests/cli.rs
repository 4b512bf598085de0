//! Black-box tests of the `imu-emu` binary: what a user typing commands can rely on.
//!
//! Every rejected input must exit non-zero, say on stderr which file, line and column is at
//! fault and what is wrong, and leave no output file behind (neither the `-o` path nor its
//! `.NAME.partial-*` temporary). Rates and durations are small so the whole file runs in a
//! fraction of a second.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use tempfile::TempDir;

const TRAJ_HEADER: &str = "t,lat,lon,h,vn,ve,vd,roll,pitch,yaw";
const IMU_HEADER: &str =
    "t,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z,dtheta_x,dtheta_y,dtheta_z,dv_x,dv_y,dv_z";

// ---------------------------------------------------------------------------------------------
// Helpers.

/// Runs the binary in directory `cwd` (`None`: the current one) with `args`.
fn imu_emu<'a>(cwd: Option<&Path>, args: impl IntoIterator<Item = &'a OsStr>) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_imu-emu"));
    if let Some(dir) = cwd {
        cmd.current_dir(dir);
    }
    cmd.args(args).output().expect("run imu-emu")
}

/// `run!("generate --rate 10 -o", out)`: runs the binary. The first argument is split at
/// spaces into words; the others (paths, values) are passed whole. `run!(in dir; …)` runs it
/// in directory `dir`.
macro_rules! run {
    (in $dir:expr; $words:expr $(, $arg:expr)* $(,)?) => {
        imu_emu(Some($dir), words($words).chain([$(OsStr::new(&$arg)),*]))
    };
    ($words:expr $(, $arg:expr)* $(,)?) => {
        imu_emu(None, words($words).chain([$(OsStr::new(&$arg)),*]))
    };
}

/// The space-separated words of `s` as arguments.
fn words(s: &str) -> impl Iterator<Item = &OsStr> {
    s.split_whitespace().map(OsStr::new)
}

/// Asserts success and returns stdout.
fn succeeded(out: Output) -> Vec<u8> {
    assert!(
        out.status.success(),
        "expected success, got {:?}; stderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// Asserts failure (exit code ≠ 0 and a message on stderr) and returns stderr.
fn failed(out: Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "expected failure, but it succeeded; stderr:\n{stderr}"
    );
    assert!(!stderr.trim().is_empty(), "failure without a message");
    stderr
}

/// Asserts that `msg` contains every one of `needles`.
fn assert_mentions(msg: &str, needles: &[&str]) {
    for n in needles {
        assert!(msg.contains(n), "message lacks `{n}`:\n{msg}");
    }
}

/// Asserts that neither `dir/name` nor a `.name.partial-*` temporary exists.
fn assert_no_output(dir: &Path, name: &str) {
    let partial = format!(".{name}.partial-");
    for entry in std::fs::read_dir(dir).expect("read dir") {
        let entry = entry.expect("dir entry").file_name();
        let entry = entry.to_string_lossy();
        assert!(
            entry != name && !entry.starts_with(&partial),
            "a failed run left `{entry}` in {}",
            dir.display()
        );
    }
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).expect("write test input");
}

fn path_str(p: &Path) -> String {
    p.display().to_string()
}

/// Parses IMU CSV output: the header line and rows of 13 numbers.
fn parse_imu_csv(bytes: &[u8]) -> (String, Vec<[f64; 13]>) {
    let text = std::str::from_utf8(bytes).expect("CSV output is UTF-8");
    let mut lines = text.lines();
    let header = lines.next().expect("CSV output has a header").to_string();
    let rows = lines
        .map(|l| {
            let v: Vec<f64> = (l.split(','))
                .map(|f| {
                    f.parse()
                        .unwrap_or_else(|_| panic!("bad number `{f}` in `{l}`"))
                })
                .collect();
            v.try_into()
                .unwrap_or_else(|_| panic!("record without 13 fields: `{l}`"))
        })
        .collect();
    (header, rows)
}

/// A valid trajectory data row: at rest at 45° N, 2° E, 100 m, level, heading 30°.
fn rest_row(t: f64) -> String {
    format!("{t},45,2,100,0,0,0,0,0,30\n")
}

/// `n` valid rows at t = 10, 10.1, 10.2, …
fn rest_rows(n: usize) -> String {
    (0..n).map(|i| rest_row(10.0 + i as f64 / 10.0)).collect()
}

/// A rejected trajectory file: its path as given on the command line, and the error text.
struct Rejected {
    path: String,
    stderr: String,
}

impl Rejected {
    /// Asserts the message has the form `PATH:LINE: …` and mentions every one of `needles`.
    fn at(&self, line: usize, needles: &[&str]) {
        assert_mentions(&self.stderr, &[&format!("{}:{line}: ", self.path)]);
        assert_mentions(&self.stderr, needles);
    }
}

/// Runs `generate --trajectory FILE --rate 10 -o OUT [extra]` on a file holding `text`;
/// asserts it fails, names the file and leaves no output behind.
fn reject_trajectory(text: &str, extra: &[&str]) -> Rejected {
    let dir = TempDir::new().expect("temp dir");
    let csv = dir.path().join("traj.csv");
    write(&csv, text);
    let out = dir.path().join("imu.csv");
    let args = [
        OsStr::new("generate"),
        "--trajectory".as_ref(),
        csv.as_ref(),
    ];
    let args = args
        .into_iter()
        .chain(["--rate", "10", "-o"].map(OsStr::new));
    let args = args
        .chain([out.as_os_str()])
        .chain(extra.iter().map(OsStr::new));
    let stderr = failed(imu_emu(None, args));
    let path = path_str(&csv);
    assert_mentions(&stderr, &[&path]);
    assert_no_output(dir.path(), "imu.csv");
    Rejected { path, stderr }
}

/// Runs `generate SCENE.toml -o OUT` on a scene file holding `text`; asserts it fails, names
/// the file and leaves no output. Returns the scene file's path and stderr.
fn reject_scene_file(text: &str) -> (String, String) {
    let dir = TempDir::new().unwrap();
    let scene = dir.path().join("bad.toml");
    write(&scene, text);
    let out = dir.path().join("imu.csv");
    let stderr = failed(run!("generate", scene, "-o", out));
    let path = path_str(&scene);
    assert_mentions(&stderr, &[&path]);
    assert_no_output(dir.path(), "imu.csv");
    (path, stderr)
}

// ---------------------------------------------------------------------------------------------
// Bad trajectory CSV: file, line, column and problem; no output.

// A header without a required column names the column and the header's line.
#[test]
fn trajectory_missing_column() {
    let text = "# made by hand\n\nt,lat,lon,h,vn,ve,vd,roll,yaw\n".to_string()
        + &"0,45,2,100,0,0,0,0,30\n".repeat(10);
    reject_trajectory(&text, &[]).at(3, &["header", "missing column `pitch`"]);
}

// A header with a column we do not know names its number and name.
#[test]
fn trajectory_unknown_column() {
    let text = format!("# c\n{TRAJ_HEADER},speed\n{}", rest_rows(10));
    reject_trajectory(&text, &[]).at(2, &["column 11", "unknown column `speed`"]);
}

// A header naming a column twice names the second occurrence.
#[test]
fn trajectory_duplicate_column() {
    let text = format!("t,lat,lon,h,vn,ve,lat,vd,roll,pitch,yaw\n{}", rest_rows(10));
    reject_trajectory(&text, &[]).at(1, &["column 7", "`lat` appears twice"]);
}

// A data line with too few fields says which column is missing; too many, which is extra.
#[test]
fn trajectory_wrong_field_count() {
    let text = format!(
        "{TRAJ_HEADER}\n{}# gap\n\n10.2,45,2,100,0,0,0,0,0\n",
        rest_rows(2)
    );
    let missing = ["column 10 (`yaw`) is missing", "9 fields, expected 10"];
    reject_trajectory(&text, &[]).at(6, &missing);

    let text = format!(
        "{TRAJ_HEADER}\n{}10.1,45,2,100,0,0,0,0,0,30,7\n",
        rest_rows(1)
    );
    reject_trajectory(&text, &[]).at(3, &["column 11 is extra", "11 fields, expected 10"]);
}

// A field that is not a number names the file column (number and name) and the text.
#[test]
fn trajectory_non_numeric_value() {
    // Columns in another order: `ve` is file column 3.
    let text = "t,vn,ve,vd,lat,lon,h,roll,pitch,yaw\n0,0,0,0,45,2,100,0,0,0\n\
                # next line is bad\n0.1,0,fast,0,45,2,100,0,0,0\n";
    reject_trajectory(text, &[]).at(4, &["column 3 (`ve`)", "`fast` is not a number"]);
}

// NaN is refused with its column.
#[test]
fn trajectory_nan_value() {
    let text = format!(
        "{TRAJ_HEADER}\n{}10.3,45,2,NaN,0,0,0,0,0,30\n",
        rest_rows(3)
    );
    reject_trajectory(&text, &[]).at(5, &["column 4 (`h`)", "`NaN` is not finite"]);
}

// Infinity is refused with its column.
#[test]
fn trajectory_infinite_value() {
    let text = format!(
        "{TRAJ_HEADER}\n\n{}10.3,45,2,100,0,0,0,0,0,-inf\n",
        rest_rows(3)
    );
    reject_trajectory(&text, &[]).at(6, &["column 10 (`yaw`)", "`-inf` is not finite"]);
}

// A time equal to the previous sample's is refused at its line.
#[test]
fn trajectory_repeated_time() {
    let text = format!("{TRAJ_HEADER}\n{}{}", rest_rows(4), rest_row(10.3));
    let problem = "10.3 does not increase (previous sample at 10.3)";
    reject_trajectory(&text, &[]).at(6, &["column 1 (`t`)", problem]);
}

// A time before the previous sample's is refused at its line, in whichever column `t` is.
#[test]
fn trajectory_decreasing_time() {
    let text = "# t last\nlat,lon,h,vn,ve,vd,roll,pitch,yaw,t\n\
                45,2,100,0,0,0,0,0,0,1\n45,2,100,0,0,0,0,0,0,2\n\n45,2,100,0,0,0,0,0,0,1.5\n";
    let problem = "1.5 does not increase (previous sample at 2)";
    reject_trajectory(text, &[]).at(6, &["column 10 (`t`)", problem]);
}

// A latitude beyond ±90° is refused with its value.
#[test]
fn trajectory_latitude_out_of_range() {
    let text = format!(
        "{TRAJ_HEADER}\n{}10.2,-90.5,2,100,0,0,0,0,0,30\n",
        rest_rows(2)
    );
    let problem = "-90.5 is outside [-90, 90] degrees";
    reject_trajectory(&text, &[]).at(4, &["column 2 (`lat`)", problem]);
}

// A sample alone after a gap (a step more than 100 times those beside it) is refused at its
// line: its finite differences would extrapolate from samples a hundred steps of theirs away
// (1e4 m/s² off across 10 s). With a stencil's samples past the gap, the gap is bridged.
#[test]
fn trajectory_sample_alone_beyond_a_gap() {
    let alone = format!("{TRAJ_HEADER}\n{}{}", rest_rows(20), rest_row(1000.0));
    let problem = "the sample at t = 1e3 s lies between a gap of 988.1 s and the end";
    reject_trajectory(&alone, &[]).at(22, &["column 1 (`t`)", problem, "9 samples on each side"]);
    let dir = TempDir::new().unwrap();
    let csv = dir.path().join("traj.csv");
    let far: String = (0..9).map(|i| rest_row(1000.0 + i as f64 / 10.0)).collect();
    write(&csv, &format!("{TRAJ_HEADER}\n{}{far}", rest_rows(20)));
    let o = run!(
        "generate --rate 10 --format bin -o /dev/null --trajectory",
        csv
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

// Fewer samples than the motion model needs (its stencil) is refused, saying how many there
// are and how many are needed; a smaller --stencil accepts the same file.
#[test]
fn trajectory_too_few_samples() {
    let need = imu_emu::motion::sampled::ModelSettings::default().stencil;
    let text = format!("{TRAJ_HEADER}\n{}", rest_rows(need - 1));
    let r = reject_trajectory(&text, &[]);
    let problem = format!(
        "{} samples, but the motion model needs at least {need}",
        need - 1
    );
    assert_mentions(&r.stderr, &[&problem]);
    let r = reject_trajectory(
        &format!("{TRAJ_HEADER}\n{}", rest_rows(5)),
        &["--stencil", "6"],
    );
    assert_mentions(&r.stderr, &["5 samples", "needs at least 6"]);
    let r = reject_trajectory(&format!("# header only\n{TRAJ_HEADER}\n"), &[]);
    assert_mentions(&r.stderr, &["0 samples", "needs at least"]);

    let dir = TempDir::new().unwrap();
    let csv = dir.path().join("five.csv");
    write(&csv, &format!("{TRAJ_HEADER}\n{}", rest_rows(5)));
    let out = run!("generate --rate 10 --stencil 5 --trajectory", csv);
    assert_eq!(parse_imu_csv(&succeeded(out)).1.len(), 4);
}

// --start before the first sample is refused, naming the file and both spans.
#[test]
fn trajectory_span_starts_before_first_sample() {
    let text = format!("{TRAJ_HEADER}\n{}", rest_rows(11)); // t = 10 … 11
    let r = reject_trajectory(&text, &["--start", "9.5", "--duration", "1"]);
    let span = "requested IMU span [9.5, 10.5] s is outside the trajectory [10, 11] s";
    assert_mentions(&r.stderr, &[&format!("{}: {span}", r.path)]);
    // A negative start is a number, not a flag.
    let r = reject_trajectory(&text, &["--start", "-1"]);
    assert_mentions(
        &r.stderr,
        &["span [-1, ", "outside the trajectory [10, 11] s"],
    );
}

// --duration past the last sample is refused; the span ending exactly on it is accepted.
#[test]
fn trajectory_span_ends_after_last_sample() {
    let text = format!("{TRAJ_HEADER}\n{}", rest_rows(11)); // t = 10 … 11
    let r = reject_trajectory(&text, &["--duration", "1.5"]);
    let span = "requested IMU span [10, 11.5] s is outside the trajectory [10, 11] s";
    assert_mentions(&r.stderr, &[&format!("{}: {span}", r.path)]);
    let r = reject_trajectory(&text, &["--start", "10.5", "--duration", "0.6"]);
    assert_mentions(&r.stderr, &["outside the trajectory [10, 11] s"]);

    let dir = TempDir::new().unwrap();
    let csv = dir.path().join("t.csv");
    write(&csv, &text);
    let out = run!(
        "generate --rate 10 --start 10 --duration 1 --trajectory",
        csv
    );
    let (_, rows) = parse_imu_csv(&succeeded(out));
    assert_eq!(rows.len(), 10);
    assert_eq!(rows[9][0], 11.0);
}

// An empty file, or one with only comments and blank lines, has no header; the line given
// is the file's last.
#[test]
fn trajectory_without_header() {
    reject_trajectory("", &[]).at(1, &["no header line", TRAJ_HEADER]);
    reject_trajectory("# nothing\n\n# here\n", &[]).at(3, &["no header line"]);
}

// A file that does not exist is reported with its path and the system's reason, once.
#[test]
fn trajectory_file_missing() {
    let dir = TempDir::new().unwrap();
    let csv = dir.path().join("nowhere.csv");
    let out = dir.path().join("imu.csv");
    let stderr = failed(run!("generate --trajectory", csv, "-o", out));
    assert_mentions(&stderr, &[&format!("{}: cannot read: ", csv.display())]);
    assert_eq!(stderr.matches("os error").count(), 1, "{stderr}");
    assert_no_output(dir.path(), "imu.csv");
}

// ---------------------------------------------------------------------------------------------
// Good trajectory CSV.

// A scene exported with `imu-emu trajectory` and fed back with --trajectory gives the CSV
// contract (header, duration×rate records at t = k/rate) and the scene's own IMU signal.
#[test]
fn exported_trajectory_round_trips() {
    let dir = TempDir::new().unwrap();
    let csv = dir.path().join("circle.csv");
    succeeded(run!(
        "trajectory --scene circle --rate 100 --duration 2 -o",
        csv
    ));
    let text = std::fs::read_to_string(&csv).unwrap();
    let data: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(data[0], TRAJ_HEADER);
    assert_eq!(data.len(), 1 + 201, "samples at t = 0, 0.01, …, 2");

    let out = dir.path().join("imu.csv");
    succeeded(run!("generate --rate 50 --trajectory", csv, "-o", out));
    let (header, replay) = parse_imu_csv(&std::fs::read(&out).unwrap());
    assert_eq!(header, IMU_HEADER);
    assert_eq!(replay.len(), 2 * 50);
    for (k, r) in (1..).zip(&replay) {
        assert_eq!(r[0], k as f64 / 50.0, "t of record {k}");
    }

    let scene = succeeded(run!("generate --scene circle --rate 50 --duration 2"));
    let (_, scene) = parse_imu_csv(&scene);
    assert_eq!(scene.len(), replay.len());
    for (a, b) in replay.iter().zip(&scene) {
        assert_eq!(a[0], b[0]);
        let gyro = (1..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max);
        let accel = (4..7).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max);
        // The sampled model's error on this 100 Hz circle, ends included: measured 2.5e-14
        // rad/s and 1.55e-12 m/s² (CSV written with shortest round-trip digits, so the file
        // loses nothing); bounds ×4 and ×3.2.
        assert!(
            gyro < 1e-13 && accel < 5e-12,
            "t = {}: {a:?} vs {b:?}",
            a[0]
        );
    }
}

// Comments, blank lines, another column order, uneven time steps and a yaw wrapping from
// +179° to −179° are all fine: finite output, and the yaw rate has no spike at the wrap.
#[test]
fn hand_written_trajectory_with_yaw_wrap() {
    // A turntable at 2°/s, sampled unevenly, yaw crossing ±180° between t = 3.6 and 4.5.
    let times = [
        0.0, 0.5, 1.2, 1.7, 2.5, 3.0, 3.6, 4.5, 5.0, 5.8, 6.5, 7.0, 7.4, 8.0,
    ];
    let mut text =
        String::from("# turntable, yaw 2 deg/s\n\nyaw,pitch,roll,t,vd,ve,vn,h,lon,lat\n");
    for (i, t) in times.iter().enumerate() {
        let mut yaw = 172.0 + 2.0 * t;
        if yaw > 180.0 {
            yaw -= 360.0;
        }
        text += &format!("{yaw},0,0,{t},0,0,0,100,2,45\n");
        if i == 6 {
            text += "# across the wrap\n\n";
        }
    }
    assert!(
        text.contains("\n179.2,") && text.contains("\n-179,"),
        "{text}"
    );
    let dir = TempDir::new().unwrap();
    let csv = dir.path().join("turntable.csv");
    write(&csv, &text);
    let (header, rows) = parse_imu_csv(&succeeded(run!("generate --rate 20 --trajectory", csv)));
    assert_eq!(header, IMU_HEADER);
    assert_eq!(rows.len(), 160);
    assert!(rows.iter().flatten().all(|v| v.is_finite()));
    // Body z is down: the turntable's 2°/s less the vertical part of the Earth rate.
    let expected = 2f64.to_radians() - 7.292115e-5 * 45f64.to_radians().sin();
    for r in &rows {
        assert!(
            (r[3] - expected).abs() < 1e-6,
            "gyro_z {} at t = {}",
            r[3],
            r[0]
        );
    }
    for w in rows.windows(2) {
        let jump = (w[1][3] - w[0][3]).abs();
        assert!(jump < 1e-7, "yaw-rate jump {jump} at t = {}", w[1][0]);
    }
}

// Windows line ends and a UTF-8 byte-order mark (spreadsheet exports) are accepted.
#[test]
fn trajectory_crlf_and_byte_order_mark() {
    let dir = TempDir::new().unwrap();
    let csv = dir.path().join("excel.csv");
    let text = format!("\u{feff}# exported\n{TRAJ_HEADER}\n{}", rest_rows(11));
    write(&csv, &text.replace('\n', "\r\n"));
    let (header, rows) = parse_imu_csv(&succeeded(run!("generate --rate 10 --trajectory", csv)));
    assert_eq!(header, IMU_HEADER);
    assert_eq!(rows.len(), 10);
}

// ---------------------------------------------------------------------------------------------
// Output formats and destinations.

// `--format bin` writes 104 bytes (13 little-endian f64) per record, bit-identical to the
// numbers of the CSV output (which uses shortest round-trip formatting).
#[test]
fn binary_output_matches_csv_bit_for_bit() {
    let dir = TempDir::new().unwrap();
    let (csv, bin) = (dir.path().join("imu.csv"), dir.path().join("imu.bin"));
    succeeded(run!(
        "generate --scene circle --rate 40 --duration 1 -o",
        csv
    ));
    succeeded(run!(
        "generate --scene circle --rate 40 --duration 1 --format bin -o",
        bin
    ));
    let (_, rows) = parse_imu_csv(&std::fs::read(&csv).unwrap());
    let bytes = std::fs::read(&bin).unwrap();
    assert_eq!(rows.len(), 40);
    assert_eq!(bytes.len(), 104 * rows.len());
    for (rec, row) in bytes.chunks_exact(104).zip(&rows) {
        for (field, v) in rec.chunks_exact(8).zip(row) {
            let b = f64::from_le_bytes(field.try_into().unwrap());
            assert_eq!(b.to_bits(), v.to_bits(), "bin {b:e} vs csv {v:e}");
        }
    }
}

// `-o -` and no `-o` both write the records to stdout, the same bytes as `-o FILE`.
#[test]
fn stdout_output() {
    let dir = TempDir::new().unwrap();
    let file = dir.path().join("imu.csv");
    let plain = succeeded(run!("generate --scene static --rate 10 --duration 1"));
    let dash = succeeded(run!("generate --scene static --rate 10 --duration 1 -o -"));
    let to_file = run!("generate --scene static --rate 10 --duration 1 -o", file);
    assert!(
        succeeded(to_file).is_empty(),
        "-o FILE writes nothing to stdout"
    );
    let written = std::fs::read(&file).unwrap();
    assert!(written.starts_with(format!("{IMU_HEADER}\n").as_bytes()));
    assert_eq!(written.iter().filter(|&&b| b == b'\n').count(), 1 + 10);
    assert_eq!(plain, written);
    assert_eq!(dash, written);
    let bin = succeeded(run!(
        "generate --scene static --rate 10 --duration 1 --format bin"
    ));
    assert_eq!(bin.len(), 10 * 104);
}

// An output path that is a directory is refused before any work, leaving no temporary.
#[test]
fn output_path_that_is_a_directory() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("imu.csv");
    std::fs::create_dir(&out).unwrap();
    let stderr = failed(run!(
        "generate --scene static --rate 10 --duration 1 -o",
        out
    ));
    assert_mentions(&stderr, &[&path_str(&out), "is a directory"]);
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 1, "only the directory itself: {names:?}");
}

// Out-of-range settings given as flags are refused, naming the setting, leaving no output.
#[test]
fn bad_setting_flags() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("imu.csv");
    for (flag, value, needle) in [
        ("--rate", "-5", "`rate` = -5"),
        ("--rate", "0", "`rate` = 0"),
        ("--duration", "0", "`duration` = 0"),
        ("--quadrature", "17", "quadrature 17"),
        ("--quadrature", "0", "quadrature 0"),
        ("--stencil", "2", "stencil 2"),
        ("--format", "xml", "output format `xml`"),
        ("--interp", "linear", "interpolation `linear`"),
    ] {
        let stderr = failed(run!("generate --scene static", flag, value, "-o", out));
        assert_mentions(&stderr, &[needle]);
        assert_no_output(dir.path(), "imu.csv");
    }
}

// ---------------------------------------------------------------------------------------------
// Scene files.

const CIRCLE_SCENE: &str = "\
[trajectory]
scene = \"circle\"

[trajectory.params]
radius_m = 300

[imu]
rate_hz = 50

[output]
duration_s = 1
";

// A scene file sets the scene, its parameters, the rate and the duration; flags override it.
#[test]
fn scene_file_runs_and_flags_override_it() {
    let dir = TempDir::new().unwrap();
    let scene = dir.path().join("circle.toml");
    write(&scene, CIRCLE_SCENE);
    let (header, rows) = parse_imu_csv(&succeeded(run!("generate", scene)));
    assert_eq!(header, IMU_HEADER);
    assert_eq!(rows.len(), 50);
    assert_eq!(rows.last().unwrap()[0], 1.0);
    // radius_m = 300 at the circle's 50 m/s: the body turns at 1/6 rad/s (plus Earth rate).
    for r in &rows {
        let rate = (r[1] * r[1] + r[2] * r[2] + r[3] * r[3]).sqrt();
        assert!((rate - 50.0 / 300.0).abs() < 1e-3, "turn rate {rate}");
    }

    let (_, rows) = parse_imu_csv(&succeeded(run!("generate --rate 10", scene)));
    assert_eq!(rows.len(), 10);
    assert_eq!(rows[0][0], 0.1);

    let bin = succeeded(run!("generate --duration 2 --format bin", scene));
    assert_eq!(bin.len(), 2 * 50 * 104);
}

// `file = "x.csv"` in a scene file is found next to the scene file, not in the current
// directory, and problems in it are reported with that resolved path.
#[test]
fn scene_file_trajectory_path_is_relative_to_the_scene_file() {
    let dir = TempDir::new().unwrap();
    let sub = dir.path().join("scenes");
    std::fs::create_dir(&sub).unwrap();
    let (csv, scene) = (sub.join("x.csv"), sub.join("replay.toml"));
    write(&csv, &format!("{TRAJ_HEADER}\n{}", rest_rows(11)));
    write(
        &scene,
        "[trajectory]\nfile = \"x.csv\"\n\n[imu]\nrate_hz = 10\n",
    );
    let elsewhere = TempDir::new().unwrap();
    let out = run!(in elsewhere.path(); "generate", scene);
    let (_, rows) = parse_imu_csv(&succeeded(out));
    assert_eq!(rows.len(), 10);
    assert_eq!(rows[0][0], 10.1);

    write(&csv, &format!("{TRAJ_HEADER}\n{}", rest_rows(3)));
    let stderr = failed(run!(in elsewhere.path(); "generate", scene));
    assert_mentions(&stderr, &[&format!("{}: 3 samples", csv.display())]);
}

// An unknown key is refused with file, line, column and the dotted key.
#[test]
fn scene_file_unknown_key() {
    let (p, e) = reject_scene_file("[trajectory]\nscene = \"circle\"\ncolour = \"red\"\n");
    assert_mentions(
        &e,
        &[&format!(
            "{p}:3:1: `trajectory.colour`: unknown field `colour`"
        )],
    );
    let (p, e) = reject_scene_file("[trajectory.params]\nradius = 5\n");
    let msg = format!("{p}:2:1: `trajectory.params.radius`: unknown field `radius`");
    assert_mentions(&e, &[&msg, "radius_m"]);
    let (p, e) = reject_scene_file("[imu]\nrate_hz = 5\n\n[outputs]\nformat = \"csv\"\n");
    assert_mentions(&e, &[&format!("{p}:4:"), "`outputs`: unknown field"]);
}

// A value of the wrong type is refused with file, line, column and the dotted key.
#[test]
fn scene_file_wrong_type() {
    let (p, e) = reject_scene_file("# rate\n[imu]\nrate_hz = \"fast\"\n");
    assert_mentions(&e, &[&format!("{p}:3:11: `imu.rate_hz`: invalid type")]);
    let (p, e) = reject_scene_file("[trajectory.params]\nlines = 2\nradius_m = \"big\"\n");
    assert_mentions(
        &e,
        &[&format!(
            "{p}:3:12: `trajectory.params.radius_m`: invalid type"
        )],
    );
}

// A TOML syntax error is refused with file, line and column.
#[test]
fn scene_file_syntax_error() {
    let (p, e) = reject_scene_file("\n[trajectory\nscene = \"circle\"\n");
    assert_mentions(&e, &[&format!("{p}:2:12: ")]);
}

// An unknown scene name is refused naming the file, the key and the built-in scenes.
#[test]
fn scene_file_unknown_scene() {
    let (p, e) = reject_scene_file("[trajectory]\nscene = \"spiral\"\n");
    let msg = format!("{p}: `trajectory.scene`: unknown scene `spiral`");
    assert_mentions(&e, &[&msg, "circle, survey"]);
}

// A parameter outside its range (a negative speed) is refused naming the file and the key.
#[test]
fn scene_file_negative_speed() {
    let text = "[trajectory]\nscene = \"circle\"\n[trajectory.params]\nspeed_m_s = -5\n";
    let (p, e) = reject_scene_file(text);
    let msg = format!("{p}: `trajectory.params.speed_m_s`: ");
    assert_mentions(&e, &[&msg, "-5", "a positive speed"]);
}

// Out-of-range settings in a scene file are refused naming the file and the key.
#[test]
fn scene_file_bad_settings() {
    for (text, key, needle) in [
        ("[imu]\nrate_hz = -5\n", "imu.rate_hz", "-5"),
        (
            "[imu]\nmodel = \"nosuchimu\"\n",
            "imu.model",
            "unknown IMU `nosuchimu`",
        ),
        (
            "[output]\nduration_s = 0\n",
            "output.duration_s",
            "positive duration",
        ),
        (
            "[output]\nstart_s = -10\n",
            "output.start_s",
            "outside the trajectory",
        ),
        ("[output]\nformat = \"xml\"\n", "output.format", "`xml`"),
        (
            "[engine]\nquadrature_nodes = 0\n",
            "engine.quadrature_nodes",
            "1 to 16",
        ),
        ("[engine]\nstencil = 16\n", "engine.stencil", "3 to 15"),
        (
            "[engine]\ninterpolation = \"linear\"\n",
            "engine.interpolation",
            "`linear`",
        ),
    ] {
        let (p, e) = reject_scene_file(text);
        assert_mentions(&e, &[&format!("{p}: `{key}`: "), needle]);
    }
}

// `scene` and `file` together are refused naming the file and the section.
#[test]
fn scene_file_scene_and_file_conflict() {
    let (p, e) = reject_scene_file("[trajectory]\nscene = \"circle\"\nfile = \"x.csv\"\n");
    assert_mentions(&e, &[&format!("{p}: `trajectory`: "), "not both"]);
}

// A live `--motion` is the run's motion source: a `--scene` or `--trajectory` beside it is
// refused by the parser, naming both flags, before anything is opened.
#[test]
fn live_motion_and_another_source_conflict() {
    for other in ["--scene circle", "--trajectory t.csv"] {
        let e = failed(run!(&format!("run --motion udp://127.0.0.1:1 {other}")));
        let flag = other.split(' ').next().unwrap();
        assert_mentions(&e, &["--motion", flag, "cannot be used with"]);
    }
}

// ---------------------------------------------------------------------------------------------
// IMU models and defaults.

// `--imu ideal` is accepted; a model that does not exist yet is refused clearly, leaving no
// output (from the scene file: see `scene_file_bad_settings`).
#[test]
fn imu_models() {
    let out = run!("generate --scene static --rate 10 --duration 1 --imu ideal");
    assert_eq!(parse_imu_csv(&succeeded(out)).1.len(), 10);

    let dir = TempDir::new().unwrap();
    let out = dir.path().join("imu.csv");
    let stderr = failed(run!("generate --scene static --imu nosuchimu -o", out));
    assert_mentions(&stderr, &["unknown IMU `nosuchimu`", "ideal"]);
    assert_no_output(dir.path(), "imu.csv");
}

// A template file with a bad value is refused naming the file and the key; nothing is written.
#[test]
fn bad_template_files() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("imu.csv");
    for (body, key, needle) in [
        (
            "[gyro]\nnoise = \"0.1 furlong\"\n",
            "gyro.noise",
            "unknown unit `furlong`",
        ),
        (
            "[gyro]\nbias_turn_on = \"-1 deg/h\"\n",
            "gyro.bias_turn_on",
            "negative",
        ),
        (
            "[accel]\nbias_gm = { sigma = \"1 mg\", tau = \"0 s\" }\n",
            "accel.bias_gm",
            "tau must be positive",
        ),
        (
            "[accel]\nbias_gm = { sigma = \"-1 mg\", tau = \"10 s\" }\n",
            "accel.bias_gm",
            "sigma must not be negative",
        ),
        (
            "[gyro]\nwobble = \"1 deg/h\"\n",
            "gyro.wobble",
            "unknown key",
        ),
        ("colour = \"red\"\n", "colour", "unknown key"),
        ("base = \"nosuch\"\n", "base", "unknown template"),
    ] {
        let t = dir.path().join("bad.toml");
        std::fs::write(&t, body).unwrap();
        let stderr = failed(run!(
            "generate --scene static --duration 1 --imu",
            t,
            "-o",
            out
        ));
        let p = t.display().to_string();
        assert_mentions(&stderr, &[&p, &format!("`{key}`"), needle]);
        assert_no_output(dir.path(), "imu.csv");
    }
}

// `--truth` writes the error-free records beside the corrupted ones, on the same grid.
#[test]
fn truth_file_beside_the_output() {
    let dir = TempDir::new().unwrap();
    let t = dir.path().join("noisy.toml");
    std::fs::write(&t, "name = \"noisy\"\n[gyro]\nnoise = \"1 deg/sqrt(h)\"\n[accel]\nnoise = \"0.1 m/s/sqrt(h)\"\n").unwrap();
    let (out, truth) = (dir.path().join("imu.csv"), dir.path().join("truth.csv"));
    succeeded(run!(
        "generate --scene static --rate 10 --duration 1 --imu",
        t,
        "-o",
        out,
        "--truth",
        truth
    ));
    let ideal = String::from_utf8(succeeded(run!(
        "generate --scene static --rate 10 --duration 1"
    )))
    .unwrap();
    assert_eq!(std::fs::read_to_string(&truth).unwrap(), ideal);
    let noisy = std::fs::read_to_string(&out).unwrap();
    assert_ne!(noisy, ideal);
    assert_eq!(noisy.lines().count(), ideal.lines().count());
}

// Unbounded scenes run 60 s when no duration is given.
#[test]
fn unbounded_scenes_default_to_60_s() {
    for scene in ["static", "circle"] {
        let (_, rows) = parse_imu_csv(&succeeded(run!("generate --rate 1 --scene", scene)));
        assert_eq!(rows.len(), 60, "{scene}");
        assert_eq!(rows.last().unwrap()[0], 60.0, "{scene}");
    }
}

// The survey runs to its end (about 601 s) by default: at 1 Hz the last record is t = 600.
// It is also the default scene.
#[test]
fn survey_runs_to_its_end() {
    let survey = succeeded(run!("generate --scene survey --rate 1"));
    let (_, rows) = parse_imu_csv(&survey);
    assert_eq!(rows.len(), 600);
    assert_eq!(rows.last().unwrap()[0], 600.0);
    assert_eq!(survey, succeeded(run!("generate --rate 1")));
}

// ---------------------------------------------------------------------------------------------
// The example scene file.

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/survey.toml")
}

// `imu-emu generate examples/survey.toml` runs (here for 1 s, into a temporary file).
#[test]
fn example_scene_file_runs() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("survey.csv");
    succeeded(run!("generate --duration 1", example(), "-o", out));
    let (header, rows) = parse_imu_csv(&std::fs::read(&out).unwrap());
    assert_eq!(header, IMU_HEADER);
    assert_eq!(rows.len(), 400);
}

// examples/survey.toml documents every scene parameter and setting with its current default
// (as `key = value` or `# key = value`), and reproduces the built-in survey.
#[test]
fn example_scene_file_documents_every_key() {
    use imu_emu::scenes::SceneParams;
    use toml::Value;
    let text = std::fs::read_to_string(example()).unwrap();
    let documented = |key: &str| -> Value {
        let line = (text.lines())
            .map(|l| l.trim_start_matches(['#', ' ']))
            .find(|l| l.split('=').next().map(str::trim) == Some(key))
            .unwrap_or_else(|| panic!("examples/survey.toml does not document `{key}`"));
        let value = line.split_once('=').unwrap().1;
        let value = value.split('#').next().unwrap().trim();
        let t: toml::Table = toml::from_str(&format!("v = {value}")).unwrap();
        t["v"].clone()
    };
    let same = |a: &Value, b: &Value| match (a, b) {
        (Value::Integer(x), Value::Float(y)) | (Value::Float(y), Value::Integer(x)) => {
            *x as f64 == *y
        }
        _ => a == b,
    };
    let stencil = imu_emu::motion::sampled::ModelSettings::default().stencil;
    let nodes = imu_emu::generator::DEFAULT_NODES;
    let settings = [
        ("model", Value::from("ideal")),
        ("rate_hz", Value::from(400.0)),
        ("format", Value::from("csv")),
        ("quadrature_nodes", Value::from(nodes as i64)),
        ("interpolation", Value::from("quintic")),
        ("stencil", Value::from(stencil as i64)),
    ];
    let survey = toml::Table::try_from(SceneParams::defaults_for("survey")).unwrap();
    let params = survey.iter().map(|(k, v)| (k.as_str(), v));
    for (key, default) in params.chain(settings.iter().map(|(k, v)| (*k, v))) {
        let doc = documented(key);
        assert!(
            same(&doc, default),
            "`{key}`: the example says {doc}, the default is {default}"
        );
    }
    for key in ["scene", "file", "path", "start_s", "duration_s"] {
        documented(key);
    }
    let file = imu_emu::config::SceneFile::read(&example()).unwrap();
    assert_eq!(file.trajectory.scene.as_deref(), Some("survey"));
    assert_eq!(
        file.scene_params("survey", &example()).unwrap(),
        SceneParams::defaults_for("survey")
    );
}

// Temperature: a template's bias and scale-factor polynomials of (T − T_ref) follow the
// scene file's profile; here a ramp from 25 °C at 1 °C/s with 0.1 mg/°C and 2e-4 (mg)/°C²
// of accelerometer bias gives exactly b(t) = 0.1·ΔT + 2e-4·ΔT² mg on each axis.
#[test]
fn temperature_profile_drives_the_bias() {
    let dir = TempDir::new().unwrap();
    let t = dir.path().join("warm.toml");
    std::fs::write(
        &t,
        "name = \"warm\"\ntemperature_ref = \"25 degC\"\n[accel]\nbias_temperature = [\"0.1 mg/degC\", \"2e-4 mg/degC^2\"]\n",
    )
    .unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[trajectory]\nscene = \"static\"\n[temperature]\nprofile = \"ramp\"\nstart_celsius = 25\nrate_celsius_per_s = 1\n",
    )
    .unwrap();
    let ideal = parse_imu_csv(&succeeded(run!("generate --rate 10 --duration 5", scene)));
    let warm = parse_imu_csv(&succeeded(run!(
        "generate --rate 10 --duration 5 --imu",
        t,
        scene
    )));
    for (a, b) in ideal.1.iter().zip(&warm.1) {
        let dt = a[0];
        let want = (0.1 * dt + 2e-4 * dt * dt) * 9.80665e-3;
        for c in 4..7 {
            assert!(
                (b[c] - a[c] - want).abs() < 1e-14,
                "t {dt}: {} vs {want}",
                b[c] - a[c]
            );
        }
    }
    // A profile with a missing key is refused naming the file and key.
    std::fs::write(
        &scene,
        "[temperature]\nprofile = \"warmup\"\nstart_celsius = 20\n",
    )
    .unwrap();
    let e = failed(run!("generate --duration 1 --imu", t, scene));
    assert_mentions(
        &e,
        &[
            "s.toml",
            "`temperature.tau_s`",
            "required by profile `warmup`",
        ],
    );
}

// Mounting: an IMU case yawed 90° in the body senses the body's x axis on its −y axis.
#[test]
fn mounting_rotation() {
    let dir = TempDir::new().unwrap();
    let scene = dir.path().join("m.toml");
    std::fs::write(&scene, "[trajectory]\nscene = \"static\"\n[trajectory.params]\npitch_deg = 30\n[imu]\nmounting_deg = [0, 0, 90]\n").unwrap();
    let body = dir.path().join("b.toml");
    std::fs::write(
        &body,
        "[trajectory]\nscene = \"static\"\n[trajectory.params]\npitch_deg = 30\n",
    )
    .unwrap();
    let (_, m) = parse_imu_csv(&succeeded(run!("generate --rate 10 --duration 1", scene)));
    let (_, b) = parse_imu_csv(&succeeded(run!("generate --rate 10 --duration 1", body)));
    for (m, b) in m.iter().zip(&b) {
        // C_b^c for a case yawed +90°: x_c = y_b, y_c = −x_b, z_c = z_b. The rotation's
        // entries carry ~1 ulp, so the bound is a few ulp of each vector's magnitude.
        let (gn, an) = (b[1].hypot(b[3]), b[4].hypot(b[6]));
        for (col, want, n) in [
            (1, b[2], gn),
            (2, -b[1], gn),
            (3, b[3], gn),
            (4, b[5], an),
            (5, -b[4], an),
            (6, b[6], an),
        ] {
            assert!(
                (m[col] - want).abs() <= 4.0 * f64::EPSILON * n,
                "col {col}: {} vs {want}",
                m[col]
            );
        }
    }
}

// A lever arm in the scene file moves every accelerometer: at rest at 41° N (level, heading
// north) an IMU 10 m along body y, east of the reference point, senses the gravity there,
// whose normal is turned by 10/(N + h) about north: f_y = γ·10/(N + h) ≈ 1.53e-5 m/s². The
// Earth's centripetal term ω(ω·r) − r|ω|² the rigid-body kinematics add is part of that
// gravity and cancels (the engine adds it through ω_ib and takes it out of the gravitation's
// gradient). Without the gradient the difference would be that term alone, −5.3e-8.
#[test]
fn lever_arm_from_the_scene_file() {
    let dir = TempDir::new().unwrap();
    let (arm, plain) = (dir.path().join("arm.toml"), dir.path().join("plain.toml"));
    std::fs::write(
        &arm,
        "[trajectory]\nscene = \"static\"\n[imu]\nlever_arm_m = [0, 10, 0]\n",
    )
    .unwrap();
    std::fs::write(&plain, "[trajectory]\nscene = \"static\"\n").unwrap();
    let (_, a) = parse_imu_csv(&succeeded(run!("generate --rate 10 --duration 1", arm)));
    let (_, p) = parse_imu_csv(&succeeded(run!("generate --rate 10 --duration 1", plain)));
    let s = 41f64.to_radians().sin();
    let want_y =
        10.0 * imu_emu::earth::normal_gravity(s, 0.0) / imu_emu::earth::radius_prime_vertical(s);
    for (a, p) in a.iter().zip(&p) {
        // Round-off of terms of 1.5e-5 and of the 5.3e-8 that cancels: a few 1e-21.
        assert!(
            (a[5] - p[5] - want_y).abs() < 1e-19,
            "{} vs {want_y}",
            a[5] - p[5]
        );
        assert_eq!(a[4], p[4]);
    }
}

// `--truth-errors` writes what each stage injected: the output equals the error-free record
// plus the sum of the groups (to a few ulp of the values), so a navigator can be scored.
#[test]
fn injected_errors_sum_to_the_output() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("imu.csv");
    let truth = dir.path().join("truth.csv");
    let errs = dir.path().join("errors.csv");
    succeeded(run!(
        "generate --scene circle --rate 50 --duration 2 --imu stim300 -o",
        out,
        "--truth",
        truth,
        "--truth-errors",
        errs
    ));
    let (_, o) = parse_imu_csv(&std::fs::read(&out).unwrap());
    let (_, t) = parse_imu_csv(&std::fs::read(&truth).unwrap());
    let text = std::fs::read_to_string(&errs).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.len(), 43);
    assert_eq!(header[1], "vibration_gyro_x");
    assert_eq!(header[7], "size_effect_gyro_x");
    assert_eq!(header[42], "quantization_accel_z");
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), o.len());
    for ((o, t), e) in o.iter().zip(&t).zip(&rows) {
        assert_eq!(o[0], e[0]);
        for sensor in 0..2 {
            for axis in 0..3 {
                let sum: f64 = (0..7).map(|g| e[1 + g * 6 + sensor * 3 + axis]).sum();
                let col = 1 + sensor * 3 + axis;
                // Stages mix axes (misalignment), so rounding scales with the whole vector.
                let mag: f64 = (1..4).map(|a| t[sensor * 3 + a].abs()).sum();
                let tol = 8.0 * f64::EPSILON * mag.max(1e-6);
                assert!(
                    (o[col] - t[col] - sum).abs() <= tol,
                    "col {col}: {} vs {sum}",
                    o[col] - t[col]
                );
            }
        }
    }
}

// Vibration from the scene file: a 0.5 g, 25 Hz sinusoid on accelerometer z is added to the
// true signal as its exact interval mean; bad entries are refused naming the file and entry.
#[test]
fn sinusoidal_vibration_from_the_scene_file() {
    let dir = TempDir::new().unwrap();
    let scene = dir.path().join("v.toml");
    std::fs::write(
        &scene,
        "[trajectory]\nscene = \"static\"\n[[vibration.sine]]\nsensor = \"accel\"\naxis = \"z\"\namplitude = \"0.5 g\"\nfrequency = \"25 Hz\"\n",
    )
    .unwrap();
    let out = dir.path().join("o.csv");
    let truth = dir.path().join("t.csv");
    succeeded(run!(
        "generate --rate 1000 --duration 0.2 -o",
        out,
        "--truth",
        truth,
        scene
    ));
    let (_, o) = parse_imu_csv(&std::fs::read(&out).unwrap());
    let (_, t) = parse_imu_csv(&std::fs::read(&truth).unwrap());
    let (a, w, dt) = (0.5 * 9.80665, 2.0 * std::f64::consts::PI * 25.0, 1e-3);
    for (k, (o, t)) in o.iter().zip(&t).enumerate() {
        let (t0, t1) = (k as f64 * dt, (k + 1) as f64 * dt);
        let mean = a * ((w * t0).cos() - (w * t1).cos()) / (w * dt);
        assert!(
            (o[6] - t[6] - mean).abs() < 1e-12,
            "k {k}: {} vs {mean}",
            o[6] - t[6]
        );
        assert_eq!(o[4], t[4]);
    }
    std::fs::write(&scene, "[trajectory]\nscene = \"static\"\n[[vibration.sine]]\nsensor = \"accel\"\naxis = \"w\"\namplitude = \"0.5 g\"\nfrequency = \"25 Hz\"\n").unwrap();
    let e = failed(run!("generate --duration 1 -o", out, scene));
    assert_mentions(&e, &["v.toml", "`vibration.sine[0].axis`", "`w`"]);
}

// Non-finite numbers in a scene file never reach the signal: NaN and inf are refused naming
// the file and key, and nothing is written.
#[test]
fn non_finite_scene_values_are_refused() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("o.csv");
    for (body, key) in [
        (
            "[trajectory]\nscene = \"static\"\n[trajectory.params]\nroll_deg = nan\n",
            "`trajectory.params.roll_deg`",
        ),
        (
            "[trajectory]\nscene = \"circle\"\n[trajectory.params]\nroll_osc_hz = inf\n",
            "`trajectory.params.roll_osc_hz`",
        ),
        ("[imu]\nmounting_deg = [0, nan, 0]\n", "`imu.mounting_deg`"),
        ("[imu]\nlever_arm_m = [inf, 0, 0]\n", "`imu.lever_arm_m`"),
    ] {
        let f = dir.path().join("n.toml");
        std::fs::write(&f, body).unwrap();
        let e = failed(run!("generate --duration 1 -o", out, f));
        assert_mentions(&e, &["n.toml", key]);
        assert_no_output(dir.path(), "o.csv");
    }
}

/// A reader that stops early (`imu-emu generate | head`) ends the run quietly, with the status
/// of a command killed by SIGPIPE (141; it was 0 until issue 38): its records were the run's
/// only output.
#[test]
fn closed_stdout_is_not_an_error() {
    use std::io::Read;
    let mut child = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(["generate", "--scene", "circle", "--duration", "600"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut head = [0u8; 100];
    child.stdout.take().unwrap().read_exact(&mut head).unwrap();
    // The pipe's read end is dropped here.
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(141));
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

// ---------------------------------------------------------------------------------------------
// Input limits, streaming trajectories, survey setup, time resolution (issue 10, input side).

// Values that would make the kinematics overflow are refused at their line and column with the
// limit, before any output: height and speed of a sample, and the acceleration and angular
// rate implied between two samples.
#[test]
fn trajectory_beyond_physical_limits() {
    let row = |t: &str, h: &str, vn: &str, yaw: &str| format!("{t},45,2,{h},{vn},0,0,0,0,{yaw}\n");
    let ok = row("10", "100", "0", "30");
    for (bad, line_col, needles) in [
        (
            row("10.1", "1e160", "0", "30"),
            "column 4 (`h`)",
            ["height 1e160 m", "outside [-1e5, 1e8] m"],
        ),
        (
            row("10.1", "100", "1e160", "30"),
            "column 5 (`vn`)",
            ["speed 1e160 m/s", "limit of 3e4 m/s"],
        ),
        (
            row("10.25", "100", "30000", "30"),
            "column 5 (`vn`)",
            ["implies 1.2e5 m/s²", "limit of 1e5 m/s²"],
        ),
        (
            row("10.0001", "100", "0", "120"),
            "attitude change (roll, pitch, yaw)",
            ["rad/s", "limit of 1e4 rad/s"],
        ),
        (
            row("10.0000001", "100", "0", "30"),
            "column 1 (`t`)",
            ["at least 1e-6 s apart", ""],
        ),
    ] {
        let text = format!("{TRAJ_HEADER}\n{ok}{bad}");
        let r = reject_trajectory(&text, &[]);
        r.at(3, &[line_col, needles[0], needles[1]]);
    }
}

// A scene-file parameter that would overflow the kinematics is refused with its key and range.
#[test]
fn scene_parameters_beyond_limits() {
    for (params, key, range) in [
        (
            "scene = \"straight\"\n[trajectory.params]\nh_m = 1e160",
            "h_m",
            "[−1e5, 1e8] m",
        ),
        (
            "scene = \"circle\"\n[trajectory.params]\nspeed_m_s = 1e160",
            "speed_m_s",
            "3e4",
        ),
        (
            "scene = \"circle\"\n[trajectory.params]\nradius_m = 1e-300",
            "radius_m",
            "1e5 m/s²",
        ),
        (
            "scene = \"survey\"\n[trajectory.params]\nlines = 100001",
            "lines",
            "at most 100000",
        ),
        (
            "scene = \"coning\"\n[trajectory.params]\ncone_hz = 1e9",
            "cone_hz",
            "1592 Hz",
        ),
    ] {
        let (p, e) = reject_scene_file(&format!("[trajectory]\n{params}\n"));
        let msg = format!("{p}: `trajectory.params.{key}`: ");
        assert_mentions(&e, &[&msg, range]);
    }
}

// A field of 100 000 characters is echoed cut, with its length: the message stays short.
#[test]
fn trajectory_long_field_is_echoed_cut() {
    let long = "x".repeat(100_000);
    let text = format!("{TRAJ_HEADER}\n10,45,2,{long},0,0,0,0,0,0\n");
    let r = reject_trajectory(&text, &[]);
    r.at(2, &["column 4 (`h`)", "(100000 bytes) is not a number"]);
    assert!(r.stderr.len() < 400, "{} bytes of message", r.stderr.len());
}

// `--trajectory -` reads the trajectory from stdin (streamed through a temporary copy) and
// gives the same bytes as the file, including a start in the middle (a rewind).
#[test]
fn trajectory_from_stdin() {
    use std::io::Write;
    let dir = TempDir::new().unwrap();
    let csv = dir.path().join("survey.csv");
    succeeded(run!(
        "trajectory --scene survey --duration 60 --rate 50 -o",
        csv
    ));
    let args = "generate --rate 200 --format bin --start 20 --duration 30 --trajectory";
    let from_file = succeeded(run!(args, csv));
    let mut child = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(args.split_whitespace().chain(["-"]))
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let text = std::fs::read(&csv).unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || stdin.write_all(&text));
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap().unwrap();
    assert_eq!(succeeded(out), from_file);
    assert_eq!(from_file.len(), 30 * 200 * 104);
}

// A survey of 100 000 lines is set up and runs (its setup was quadratic and took minutes;
// how long it takes now is a timing figure: printed here, measured in benches/throughput.rs).
#[test]
fn survey_with_many_lines_sets_up() {
    let dir = TempDir::new().unwrap();
    let scene = dir.path().join("s.toml");
    write(
        &scene,
        "[trajectory]\nscene = \"survey\"\n[trajectory.params]\nlines = 100000\n",
    );
    let started = std::time::Instant::now();
    let out = succeeded(run!("generate --rate 10 --duration 1 --format bin", scene));
    assert_eq!(out.len(), 10 * 104);
    eprintln!("100 000 lines: {:.2} s", started.elapsed().as_secs_f64());
}

// Time tags that cannot hold the record interval are refused (t₀ = 1.4e9 s is held to
// 2.4e-7 s, more than 1/1000 of 1e-7 s), naming the spacing and the remedy; a rate the
// tags can resolve at the same start is accepted.
#[test]
fn unresolvable_time_tags_are_refused() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("imu.bin");
    let e = failed(run!(
        "generate --scene static --start 1.4e9 --rate 1e7 --duration 0.001 --format bin -o",
        out
    ));
    assert_mentions(
        &e,
        &[
            "held to 2.384185791015625e-7 s",
            "1/1000 of the record interval 1e-7 s",
            "--start",
        ],
    );
    assert_no_output(dir.path(), "imu.bin");
    succeeded(run!(
        "generate --scene static --start 1.4e9 --rate 1000 --duration 1 --format bin -o",
        out
    ));
}

// ---------------------------------------------------------------------------------------------
// The library core behind the commands: non-finite values, interruption, messages, shared
// flags and scene files everywhere.

// A record that comes out non-finite (here a temperature ramp of 1e308 °C/s through a bias
// temperature coefficient, infinite from the first record on) stops the run with the record's
// time and quantity; nothing is written, no file left behind, exit status non-zero.
#[test]
fn non_finite_record_stops_the_run() {
    let dir = TempDir::new().unwrap();
    let t = dir.path().join("warm.toml");
    write(
        &t,
        "name = \"warm\"\ntemperature_ref = \"25 degC\"\n[accel]\nbias_temperature = [\"0.1 mg/degC\", \"2e-4 mg/degC^2\"]\n",
    );
    let scene = dir.path().join("s.toml");
    write(
        &scene,
        "[trajectory]\nscene = \"static\"\n[temperature]\nprofile = \"ramp\"\nstart_celsius = 25\nrate_celsius_per_s = 1e308\n",
    );
    let out = dir.path().join("imu.csv");
    let truth = dir.path().join("truth.csv");
    let e = failed(run!(
        "generate --rate 10 --duration 5 --imu",
        t,
        scene,
        "-o",
        out,
        "--truth",
        truth
    ));
    assert_mentions(
        &e,
        &[
            "record at t = 0.1 s",
            "accel_x",
            "inf",
            "after the error chain",
        ],
    );
    assert_no_output(dir.path(), "imu.csv");
    assert_no_output(dir.path(), "truth.csv");
}

// SIGINT or SIGTERM during `generate` removes the unfinished hidden file, says the run was
// interrupted and exits 130 or 143 as a shell reports the signal.
#[test]
fn interrupted_generate_leaves_no_partial_file() {
    for (signal, code) in [("-INT", 130), ("-TERM", 143)] {
        let dir = TempDir::new().unwrap();
        let out = dir.path().join("imu.bin");
        // Far more records than the test waits for.
        let child = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
            .args(["generate", "--scene", "static", "--rate", "1000"])
            .args(["--duration", "1e6", "--format", "bin", "-o"])
            .arg(&out)
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let partial = dir.path().join(format!(".imu.bin.partial-{}", child.id()));
        let t0 = std::time::Instant::now();
        while std::fs::metadata(&partial).map_or(true, |m| m.len() == 0) {
            assert!(t0.elapsed().as_secs() < 60, "no partial file after 60 s");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let kill = Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        let done = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&done.stderr);
        assert_eq!(done.status.code(), Some(code), "{signal}: {stderr}");
        assert_mentions(&stderr, &["interrupted"]);
        assert_no_output(dir.path(), "imu.bin");
    }
}

// A duration shorter than one sample says so, instead of a span "outside the trajectory".
#[test]
fn duration_shorter_than_one_sample() {
    let e = failed(run!("generate --rate 1 --duration 0.5"));
    assert_mentions(
        &e,
        &["`duration` = 0.5 s", "shorter than one sample at 1 Hz"],
    );
    assert!(!e.contains("outside the trajectory"), "{e}");
}

// Messages: numbers in exponent form rather than 300 digits; a missing file's cause once;
// a TOML syntax error in a template on one line with its line and column; the file a `run`
// file sink failed to write named; `run --help` without the stale protocol default.
#[test]
fn messages_are_short_and_say_it_once() {
    let e = failed(run!("generate --duration 1 --rate 1e300"));
    assert_mentions(&e, &["`rate` = 1e300"]);
    assert!(e.len() < 200, "{e}");

    let dir = TempDir::new().unwrap();
    let missing = dir.path().join("missing.csv");
    for args in [
        vec![OsStr::new("analyze"), missing.as_os_str()],
        vec![
            OsStr::new("generate"),
            OsStr::new("--trajectory"),
            missing.as_os_str(),
        ],
    ] {
        let e = failed(imu_emu(None, args));
        assert_mentions(&e, &[&path_str(&missing)]);
        assert_eq!(e.matches("os error 2").count(), 1, "{e}");
    }

    let t = dir.path().join("t.toml");
    write(&t, "name = \"x\"\n[gyro\n");
    let e = failed(run!("generate --duration 1 --imu", t));
    assert_mentions(&e, &[&path_str(&t), "line 2, column 6", "unclosed table"]);
    assert_eq!(e.trim_end().lines().count(), 1, "{e}");

    // /proc/version opens for writing but refuses the bytes.
    if Path::new("/proc/version").exists() {
        let e = failed(run!("run --duration 0.1 --file /proc/version"));
        assert_mentions(&e, &["/proc/version"]);
    }

    let help = String::from_utf8(succeeded(run!("run --help"))).unwrap();
    assert!(!help.contains("until ln200 is built in"), "{help}");
    assert_mentions(&help, &["--format", "ln200 frames in `run`"]);
}

// `generate` and `run` share their simulation flags: the same `--format`, `--imu`, `--rate`,
// `--seed` give the same frames from both (run unpaced into a file).
#[test]
fn generate_and_run_share_flags_and_frames() {
    let dir = TempDir::new().unwrap();
    let g = dir.path().join("g.kvh");
    let r = dir.path().join("r.kvh");
    let flags = "--scene circle --imu ln200 --format kvh1750 --rate 200 --duration 2 --seed 5";
    succeeded(run!(&format!("generate {flags} -o"), g));
    succeeded(run!(&format!("run {flags} --file"), r));
    let (a, b) = (std::fs::read(&g).unwrap(), std::fs::read(&r).unwrap());
    assert!(!a.is_empty() && a.len() % 400 == 0, "{} bytes", a.len());
    assert!(a == b, "generate and run wrote different frames");
}

// `navigate` takes the scene file the records came from: a circle of 300 m (not the built-in
// 500 m) navigates to within metres with `--scene-file`; the built-in scene's defaults are
// a different reference, kilometres off.
#[test]
fn navigate_takes_a_scene_file() {
    let dir = TempDir::new().unwrap();
    let scene = dir.path().join("c.toml");
    write(
        &scene,
        "[trajectory]\nscene = \"circle\"\n[trajectory.params]\nradius_m = 300\n[output]\nduration_s = 20\n",
    );
    let rec = dir.path().join("c.bin");
    succeeded(run!("generate --rate 200 --format bin -o", rec, scene));
    let final_error = |reference: &[&OsStr]| {
        let args = [OsStr::new("navigate"), rec.as_os_str()];
        let out = succeeded(imu_emu(
            None,
            args.into_iter().chain(reference.iter().copied()),
        ));
        let text = String::from_utf8(out).unwrap();
        let line = text.lines().find(|l| l.starts_with("max error")).unwrap();
        let m: f64 = line.split_whitespace().nth(3).unwrap().parse().unwrap();
        m
    };
    let own = final_error(&[OsStr::new("--scene-file"), scene.as_os_str()]);
    assert!(own < 1.0, "navigated against its own scene file: {own} m");
    let other = final_error(&[OsStr::new("--scene"), OsStr::new("circle")]);
    assert!(other > 100.0, "against the default circle: {other} m");
}

// `trajectory` takes a scene file: its parameters shape the exported trajectory.
#[test]
fn trajectory_takes_a_scene_file() {
    let dir = TempDir::new().unwrap();
    let scene = dir.path().join("c.toml");
    write(
        &scene,
        "[trajectory]\nscene = \"circle\"\n[trajectory.params]\nradius_m = 300\n",
    );
    let own = succeeded(run!("trajectory --rate 10 --duration 5", scene));
    let builtin = succeeded(run!("trajectory --rate 10 --duration 5 --scene circle"));
    let last = |b: &[u8]| {
        String::from_utf8(b.to_vec())
            .unwrap()
            .lines()
            .last()
            .unwrap()
            .to_string()
    };
    assert_ne!(last(&own), last(&builtin));
    let lines = String::from_utf8(own).unwrap();
    assert_eq!(
        lines.lines().filter(|l| !l.starts_with('#')).count(),
        1 + 51
    );
}

// A reader that stops early (`imu-emu analyze … | head`) ends the command quietly with status
// 141, as one killed by SIGPIPE (it panicked in println! before, then exited 0): the report is
// its only output.
#[test]
fn analyze_into_a_closed_pipe_ends_quietly() {
    let dir = TempDir::new().unwrap();
    let rec = dir.path().join("imu.bin");
    succeeded(run!(
        "generate --scene static --imu stim300 --rate 200 --duration 20 --format bin -o",
        rec
    ));
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .arg("analyze")
        .arg(&rec)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader is gone before anything was written
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(141), "{err}");
    assert!(err.is_empty(), "{err}");
}

/// `plot-errors` draws a `--truth-errors` file (PNG written); a malformed row is refused
/// with the file and line, and no plot is left behind.
#[test]
fn plot_errors_draws_and_refuses_bad_rows() {
    let dir = tempfile::tempdir().unwrap();
    let errors = dir.path().join("errors.csv");
    let out = dir.path().join("errors.png");
    succeeded(run!(
        "generate --scene static --imu adis16405:typical --duration 5 --rate 100 -o /dev/null --truth-errors",
        errors
    ));
    succeeded(run!("plot-errors -o", out, errors));
    let png = std::fs::read(&out).unwrap();
    assert_eq!(&png[..4], b"\x89PNG");
    let bad = dir.path().join("bad.csv");
    let text = std::fs::read_to_string(&errors).unwrap();
    let mut lines: Vec<&str> = text.lines().take(5).collect();
    lines[3] = "0.03,oops";
    write(&bad, &lines.join("\n"));
    let msg = failed(run!(in dir.path(); "plot-errors -o bad.png bad.csv"));
    assert_mentions(&msg, &["bad.csv", "line 4"]);
    assert_no_output(dir.path(), "bad.png");
}
