//! The command line's answers to hostile or unlucky input (issue 23 items 6–8): exit statuses
//! that say what happened and messages that name the place and the cause, never a
//! library's debug output.

use std::path::Path;
use std::process::{Command, Output};

use rand::{RngExt, SeedableRng};

fn imu_emu() -> Command {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `n` random bytes (fixed seed) in `dir/name`.
fn noise_file(dir: &Path, name: &str, n: usize) -> std::path::PathBuf {
    let mut r = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(2323);
    let bytes: Vec<u8> = (0..n).map(|_| r.random::<u8>()).collect();
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// 4 MB of random bytes hold no frame of any built-in protocol: `decode` exits 1 saying so
/// (issue 23 item 6: `ln200`, without a sync word and with a 16-bit sum, found 313 "frames"
/// in 20 MB and exited 0).
#[test]
fn decode_of_noise_finds_no_frame_of_any_protocol() {
    let dir = tempfile::TempDir::new().unwrap();
    let noise = noise_file(dir.path(), "noise.bin", 4 << 20);
    for name in imu_emu::protocol::builtin_names() {
        let o = imu_emu()
            .args(["decode", "--protocol", name, "--tally-only"])
            .arg(&noise)
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(err.contains(" 0 frames,"), "{name}: {err}");
        assert!(
            err.contains(&format!("no valid `{name}` frame in the input")),
            "{name}: {err}"
        );
    }
}

/// A spec whose frames have neither a constant field nor a check decodes noise as frames,
/// and `decode` says so.
#[test]
fn decode_warns_when_frames_cannot_be_told_from_noise() {
    let dir = tempfile::TempDir::new().unwrap();
    let spec = dir.path().join("bare.toml");
    std::fs::write(
        &spec,
        "name = \"bare\"\ndescription = \"one word, no sync, no check\"\nrate_hz = 100\n\
         byte_order = \"little\"\n\n[[field]]\nname = \"gyro_x\"\ntype = \"i16\"\n\
         source = \"gyro.x\"\nlsb = 0.001\n",
    )
    .unwrap();
    let noise = noise_file(dir.path(), "noise.bin", 1000);
    let o = imu_emu()
        .arg("decode")
        .arg("--protocol-file")
        .arg(&spec)
        .arg("--tally-only")
        .arg(&noise)
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("`bare` frames have neither constant fields nor a check"),
        "{err}"
    );
    assert!(err.contains("500 frames"), "{err}");
}

/// `generate`s a CSV record file of `scene` (1 s at 100 Hz) into `dir/name`.
fn records_csv(dir: &Path, scene: &str, name: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    let o = imu_emu()
        .args([
            "generate",
            "--scene",
            scene,
            "--rate",
            "100",
            "--duration",
            "1",
            "-o",
        ])
        .arg(&p)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    p
}

/// The stderr of `imu-emu navigate RECORDS --scene circle`, which must exit 1.
fn navigate_fails(records: &Path) -> String {
    let o = imu_emu()
        .arg("navigate")
        .arg(records)
        .args(["--scene", "circle"])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    err
}

/// A record whose increment no IMU measures (Δθ_x = 1e300 rad) is named with its values
/// (issue 23 item 7: a free-inertial run blamed "the GNSS-aided filter", which it did not
/// use); numbers in `navigate`'s messages are short (a random file's t₀ was printed with
/// 190 digits).
#[test]
fn navigate_names_the_record_not_a_filter_it_did_not_use() {
    let dir = tempfile::TempDir::new().unwrap();
    let rec = records_csv(dir.path(), "circle", "c.csv");
    let text = std::fs::read_to_string(&rec).unwrap();
    let bad: String = text
        .lines()
        .map(|l| match l.strip_prefix("0.5,") {
            Some(rest) => {
                let mut f: Vec<&str> = rest.split(',').collect();
                f[6] = "1e300";
                format!("0.5,{}\n", f.join(","))
            }
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(&rec, bad).unwrap();
    let err = navigate_fails(&rec);
    assert!(
        err.contains("c.csv: record 50 at t = 0.5 s: increments dtheta [1e300, "),
        "{err}"
    );
    assert!(!err.contains("GNSS"), "{err}");

    let err = navigate_fails(&noise_file(dir.path(), "noise.bin", 20_000));
    assert!(!err.contains("GNSS"), "{err}");
    let longest_number = err
        .split(|c: char| !c.is_ascii_digit())
        .map(str::len)
        .max()
        .unwrap_or(0);
    assert!(longest_number <= 17, "{err}");
}

/// A plot that cannot be written names the file and the system's reason (issue 23 item 7:
/// `ImageError(IoError(Os { code: 2, … }))`), for PNG and SVG alike, and leaves no file.
#[test]
fn analyze_plot_that_cannot_be_written_says_why() {
    let dir = tempfile::TempDir::new().unwrap();
    let rec = records_csv(dir.path(), "static", "s.csv");
    // A disk that fills up while the plot is written.
    std::os::unix::fs::symlink("/dev/full", dir.path().join("full.png")).unwrap();
    let d = dir.path().display();
    for (plot, why) in [
        (
            format!("{d}/none/adev.png"),
            "none/adev.png: cannot write the plot: No such file or directory",
        ),
        (
            format!("{d}/s.csv/adev.svg"),
            "adev.svg: cannot write the plot: Not a directory",
        ),
        (
            format!("{d}/full.png"),
            "full.png: cannot write the plot: No space left on device",
        ),
    ] {
        let o = imu_emu()
            .arg("analyze")
            .arg(&rec)
            .args(["--plot", &plot])
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(why), "{err}");
        assert!(!err.contains("Os {") && !err.contains("Error("), "{err}");
    }
    assert!(!dir.path().join("none").exists());
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(left.len(), 2, "only the records and the link: {left:?}");
}

/// Frames of `protocol` from the static scene (1 s, `generate_args` added) decoded with
/// `decode_args`: the CSV rows as columns by name, and stderr.
fn decode_rows(
    protocol: &str,
    generate_args: &[&str],
    decode_args: &[&str],
) -> (Vec<Vec<(String, String)>>, String) {
    let dir = tempfile::TempDir::new().unwrap();
    let frames = dir.path().join("f.bin");
    let o = imu_emu()
        .args([
            "generate",
            "--scene",
            "static",
            "--imu",
            "stim300",
            "--duration",
            "1",
        ])
        .args(["--format", protocol])
        .args(generate_args)
        .arg("-o")
        .arg(&frames)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let o = imu_emu()
        .args(["decode", "--protocol", protocol])
        .args(decode_args)
        .arg(&frames)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout.clone()).unwrap();
    let mut lines = text.lines();
    let head: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| {
            head.iter()
                .cloned()
                .zip(l.split(',').map(String::from))
                .collect()
        })
        .collect();
    (rows, stderr(&o))
}

fn cell(row: &[(String, String)], name: &str) -> Option<f64> {
    let v = &row.iter().find(|c| c.0 == name).unwrap().1;
    (!v.is_empty()).then(|| v.parse().unwrap())
}

/// iMAR iXCOM frames carry GPS whole seconds and microseconds (issue 23 item 7: `decode`
/// said they carry no time tag and left `t` and the increments empty): `t` is their time and
/// the increments are the rates over the interval of the tags (1/rate).
#[test]
fn decode_reads_ixcom_time_tags() {
    let rate = 400.0;
    let (rows, err) = decode_rows("imar-ixcom", &["--rate", "400"], &[]);
    assert!(!err.contains("no time tag"), "{err}");
    assert!(
        err.contains("derived over the interval of their time tags"),
        "{err}"
    );
    assert_eq!(rows.len() as f64, rate);
    for (k, r) in rows.iter().enumerate() {
        let t = cell(r, "t").unwrap();
        let want = cell(r, "tow_seconds").unwrap() + cell(r, "tow_micros").unwrap() * 1e-6;
        assert_eq!(t, want);
        // The tags are whole microseconds.
        assert!((t - (k + 1) as f64 / rate).abs() < 1e-6, "row {k}: t = {t}");
        if k > 0 {
            let (w, dth) = (cell(r, "gyro_x").unwrap(), cell(r, "dtheta_x").unwrap());
            assert!(
                (dth - w / rate).abs() <= 1e-12 * w.abs(),
                "row {k}: {dth} vs {w}"
            );
        }
    }
}

/// KVH 1750 frames carry increments and no time tag: `--rate nominal` derives the rates over
/// the protocol's 1000 Hz, the rate `generate` wrote them at (issue 23 item 7: the README
/// tour's decode left them empty); a spec without a nominal rate is refused.
#[test]
fn decode_takes_the_nominal_rate_when_asked() {
    let (rows, err) = decode_rows("kvh1750", &[], &["--rate", "nominal"]);
    assert!(!err.contains("left empty"), "{err}");
    assert_eq!(rows.len(), 1000);
    for r in &rows {
        assert_eq!(cell(r, "t"), None);
        let (w, dth) = (cell(r, "gyro_x").unwrap(), cell(r, "dtheta_x").unwrap());
        assert!((w - dth * 1000.0).abs() <= 1e-12 * w.abs(), "{w} vs {dth}");
    }
    let dir = tempfile::TempDir::new().unwrap();
    let spec = dir.path().join("norate.toml");
    std::fs::write(
        &spec,
        "name = \"norate\"\ndescription = \"no rate\"\nbyte_order = \"little\"\n\n\
         [[field]]\nname = \"sync\"\ntype = \"u16\"\nvalue = 0x5AA5\n\n\
         [[field]]\nname = \"gyro_x\"\ntype = \"i16\"\nsource = \"gyro.x\"\nlsb = 0.001\n",
    )
    .unwrap();
    let o = imu_emu()
        .arg("decode")
        .arg("--protocol-file")
        .arg(&spec)
        .args(["--rate", "nominal", "-"])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--rate nominal: the `norate` spec gives no nominal rate"),
        "{err}"
    );
}

/// `imu-emu templates` shows the turn-on bias (issue 23 item 8: `mpu6000`'s 20°/s 1σ turn-on
/// bias, which dominates the tour's `compare`, was in no column): 72 000 deg/h, and its
/// accelerometers' largest, 80 mg, as the template gives them.
#[test]
fn templates_show_the_turn_on_bias() {
    let o = imu_emu().arg("templates").output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    let head: Vec<&str> = text
        .lines()
        .next()
        .unwrap()
        .split("  ")
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    assert!(
        head.contains(&"gyro TO") && head.contains(&"accel TO"),
        "{head:?}"
    );
    let row: Vec<&str> = text
        .lines()
        .find(|l| l.starts_with("mpu6000 "))
        .unwrap()
        .split_whitespace()
        .collect();
    let m = imu_emu::errors::template::load("mpu6000").unwrap();
    let deg_h = m.gyro.bias_turn_on[0].to_degrees() * 3600.0;
    let ug = m.accel.bias_turn_on[2] / imu_emu::units::G0 * 1e6;
    assert_eq!(row[3], format!("{deg_h:.1}"), "{row:?}");
    assert_eq!(row[6], format!("{ug:.0}"), "{row:?}");
    assert_eq!((row[3], row[6]), ("72000.0", "80000"));
}

/// Issue 23 item 7: `generate --start 1e300` printed the span as a 301-digit number; numbers in
/// the message are now the shortest text that reads back (`1e300`), and nothing is written.
#[test]
fn a_huge_start_is_named_in_short_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.csv");
    let o = imu_emu()
        .args(["generate", "--start", "1e300", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains("1e300"), "{err}");
    assert!(!err.contains("0000000000"), "{err}");
    assert!(err.len() < 400, "{err}");
    assert!(!out.exists());
}

/// Two outputs on one file (issue 38: `generate -o X --truth X` interleaved both streams in X,
/// `run --file X --record-input X` lost the input record), both on stdout, or an output on
/// the file the live input reads: refused naming both flags before anything is written — no
/// file is created, the input is left as it was.
#[test]
fn two_outputs_on_one_file_are_refused_before_anything_is_written() {
    let dir = tempfile::TempDir::new().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("sub")).unwrap();
    let input = "t,lat,lon,h,vn,ve,vd,roll,pitch,yaw\n";
    std::fs::write(d.join("in.csv"), input).unwrap();
    let cases: [(&[&str], &str); 5] = [
        (
            &[
                "generate",
                "--duration",
                "1",
                "-o",
                "x.csv",
                "--truth",
                "x.csv",
            ],
            "--truth: writes to x.csv, as --output does",
        ),
        // The same file under another name.
        (
            &[
                "generate",
                "--duration",
                "1",
                "-o",
                "x.csv",
                "--truth",
                "sub/../x.csv",
            ],
            "--truth: writes to sub/../x.csv, as --output does",
        ),
        (
            &["generate", "--duration", "1", "--truth", "-"],
            "--truth: writes to stdout, as --output does",
        ),
        (
            &[
                "run",
                "--motion",
                "in.csv",
                "--time-mode",
                "lockstep",
                "--file",
                "x.csv",
                "--record-input",
                "./x.csv",
            ],
            "--record-input: writes to ./x.csv, as --file x.csv does",
        ),
        (
            &[
                "run",
                "--motion",
                "in.csv",
                "--time-mode",
                "lockstep",
                "--file",
                "./in.csv",
            ],
            "--file ./in.csv: writes to in.csv, the file --motion reads",
        ),
    ];
    for (args, want) in cases {
        let o = imu_emu().current_dir(d).args(args).output().unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!d.join("x.csv").exists(), "{args:?}: x.csv written");
        assert_eq!(std::fs::read_to_string(d.join("in.csv")).unwrap(), input);
    }
}

/// A Welch segment that costs more than the analysis can use, or that is not a power of two
/// (issue 38: `analyze --segment 268435456` on a 6 000-sample file asked for 20 GB and met
/// the kernel's OOM killer; 1000 was rounded down to 512 without a word): refused before
/// the file is read, naming the limit; 2^20 itself is taken.
#[test]
fn a_segment_beyond_its_limit_is_refused() {
    let dir = tempfile::TempDir::new().unwrap();
    let rec = dir.path().join("static.csv");
    let o = imu_emu()
        .args(["generate", "--scene", "static", "--duration", "6", "-o"])
        .arg(&rec)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    for (segment, ok) in [
        ("268435456", false),
        ("1000", false),
        ("4", false),
        ("1048576", true),
    ] {
        for command in ["analyze", "fit"] {
            let o = imu_emu()
                .args([command, "--segment", segment])
                .arg(&rec)
                .args(if command == "fit" {
                    &["-o", "/dev/null"][..]
                } else {
                    &[][..]
                })
                .output()
                .unwrap();
            let err = stderr(&o);
            if ok {
                assert!(!err.contains("--segment"), "{command} {segment}: {err}");
            } else {
                assert_eq!(o.status.code(), Some(1), "{command} {segment}: {err}");
                assert!(
                    err.contains(&format!(
                        "--segment: {segment} samples; expected a power of two from 8 to 1048576"
                    )),
                    "{command} {segment}: {err}"
                );
            }
        }
    }
}

/// A binary record file whose length is not a whole number of records is refused from its
/// length, before a record is read (issue 38: `analyze` read a whole 1 GiB file before its
/// last record came up short). The first record holds a NaN, which a reader that started
/// reading would have named instead.
#[test]
fn a_binary_record_file_of_the_wrong_size_is_refused_before_it_is_read() {
    let dir = tempfile::TempDir::new().unwrap();
    let bin = dir.path().join("cut.bin");
    let mut bytes = Vec::new();
    for k in 0..20 {
        let mut v = [0.0; 13];
        v[0] = f64::from(k + 1) * 0.01;
        v[1] = if k == 0 { f64::NAN } else { 0.0 };
        let r = imu_emu::record::Record::from_values(&v);
        imu_emu::output::encode(imu_emu::output::Format::Bin, &[r], &mut bytes);
    }
    bytes.extend_from_slice(&[0; 50]);
    std::fs::write(&bin, bytes).unwrap();
    let want = format!(
        "{}: 2130 bytes is not a whole number of 104-byte records (20 records and 50 bytes",
        bin.display()
    );
    for args in [
        &["analyze"][..],
        &["fit", "-o", "/dev/null"][..],
        &["navigate", "--scene", "circle"][..],
    ] {
        let o = imu_emu().args(args).arg(&bin).output().unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(&want), "{args:?}: {err}");
    }
}

/// Numeric arguments are checked against what they cost and refused naming the limit (issue
/// 38): a sampling rate beyond 1e7 Hz (`analyze --rate 1e300` analysed at Δt = 1e-300 s),
/// Monte Carlo runs beyond 100 000 (10^9 took 5 GB in 8 s before the first run), plot points
/// beyond 100 000 per line.
#[test]
fn numeric_arguments_beyond_what_they_cost_are_refused() {
    let dir = tempfile::TempDir::new().unwrap();
    let d = dir.path();
    let rec = records_csv(d, "static", "s.csv");
    let cases: [(&[&str], &str); 5] = [
        (
            &["analyze", "s.csv", "--rate", "1e300"],
            "--rate: 1e300 Hz; expected a sampling rate in (0, 1e7] Hz",
        ),
        (
            &["fit", "s.csv", "--rate=-5", "-o", "/dev/null"],
            "--rate: -5 Hz; expected a sampling rate in (0, 1e7] Hz",
        ),
        (
            &["compare", "--imu", "adis16405", "--runs", "1000000000"],
            "runs 1000000000: expected 1 to 100000 runs",
        ),
        (
            &["compare", "--imu", "adis16405", "--runs", "0"],
            "runs 0: expected 1 to 100000 runs",
        ),
        (
            &[
                "plot-errors",
                "s.csv",
                "-o",
                "x.png",
                "--points",
                "1000000000000",
            ],
            "--points 1000000000000: at most 100000 points per line",
        ),
    ];
    assert!(rec.exists());
    for (args, want) in cases {
        let o = imu_emu().current_dir(d).args(args).output().unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
    assert!(!d.join("x.png").exists());
}

/// Frames with valid checks carrying a rate no gyro measures (KVH 1750 Δθ of 1e30 rad) are
/// refused by the frame that carries it, by `analyze` and `fit` alike (issue 38: `fit` wrote
/// a template beyond every bound and said "the fitted template does not load (a bug: please
/// report it)"); the same in a CSV names the line and column.
#[test]
fn a_rate_no_sensor_measures_is_refused_by_its_frame() {
    let dir = tempfile::TempDir::new().unwrap();
    let (_, plan) = imu_emu::protocol::load("kvh1750").unwrap();
    let mut state = imu_emu::protocol::EncoderState::default();
    let mut frames = Vec::new();
    for k in 0..2000 {
        let mut v = [0.0; 13];
        v[0] = f64::from(k + 1) * 1e-3;
        v[6] = -9.8;
        v[12] = -9.8e-3;
        if k == 700 {
            v[7] = 1e30;
        }
        let r = imu_emu::record::Record::from_values(&v);
        plan.encode(&r, 25.0, &mut state, &mut frames);
    }
    let bin = dir.path().join("kvh.bin");
    std::fs::write(&bin, frames).unwrap();
    for args in [&["analyze"][..], &["fit", "-o", "/dev/null"][..]] {
        let o = imu_emu()
            .args(args)
            .arg(&bin)
            .args(["--format", "kvh1750"])
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("frame 700: gyro x is 1."), "{args:?}: {err}");
        assert!(
            err.contains("e33 rad/s, beyond the 1e4 rad/s no gyro measures"),
            "{args:?}: {err}"
        );
    }
    let csv = dir.path().join("big.csv");
    std::fs::write(
        &csv,
        "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,-9.8\n0.01,0,2e4,0,0,0,-9.8\n",
    )
    .unwrap();
    let o = imu_emu().arg("analyze").arg(&csv).output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains(":3: column 3 (`gy`): gyro y is 2e4 rad/s, beyond the 1e4 rad/s"),
        "{err}"
    );
}
