//! Memory bounded by the work, not by the input's size (issue 38): each case runs the
//! command on a small and a large input and compares the two runs' own peak memory. A test
//! target of its own: a child's peak as `wait4` reports it includes the peak of the process
//! that spawned it, so this one never holds an input in memory (files are written in pieces).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "common/rusage.rs"]
mod rusage;

fn imu_emu() -> Command {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
}

/// `head`, then `n` bytes of `7` without a line end, written to `dir/name` in pieces.
fn long_line_file(dir: &Path, name: &str, head: &str, n: usize) -> PathBuf {
    let p = dir.join(name);
    let mut f = std::io::BufWriter::new(std::fs::File::create(&p).unwrap());
    f.write_all(head.as_bytes()).unwrap();
    std::io::copy(
        &mut std::io::Read::take(std::io::repeat(b'7'), n as u64),
        &mut f,
    )
    .unwrap();
    f.flush().unwrap();
    p
}

/// A line without an end costs `analyze` and `fit` what it costs `generate`, first in a
/// recording or on a row of an ADEV table: refused naming the file, the line and the limit,
/// the peak memory within 8 MB of a run refusing a line just over the limit (the first line
/// was read whole to see whether the file is a table: 2.1 GB for a 1 GiB line; a table was
/// read whole).
#[test]
fn a_long_line_costs_every_reader_what_it_costs_generate() {
    let dir = tempfile::TempDir::new().unwrap();
    let limit = imu_emu::csvio::MAX_LINE_BYTES;
    for (head, line) in [("", 1), ("tau_s,gx_deg_h\n", 2)] {
        let small = long_line_file(dir.path(), "small.csv", head, limit + 1);
        let big = long_line_file(dir.path(), "big.csv", head, 64 << 20);
        for args in [&["analyze"][..], &["fit", "-o", "/dev/null"][..]] {
            let run = |p: &Path| rusage::run_with_peak(imu_emu().args(args).arg(p));
            let (status, err, base) = run(&small);
            assert_eq!(status.code(), Some(1), "{args:?}: {err}");
            let (status, err, peak) = run(&big);
            assert_eq!(status.code(), Some(1), "{args:?}: {err}");
            let want = format!("{}:{line}: line longer than {limit} bytes", big.display());
            assert!(err.contains(&want), "{args:?} line {line}: {err}");
            println!("{args:?} line {line}: peak {peak} kB, {base} kB for a line at the limit");
            assert!(
                peak < base + 8 * 1024,
                "{args:?} line {line}: {peak} vs {base} kB"
            );
        }
    }
}

/// `plot-errors` streams: a `--truth-errors` file ten times longer (20 000 rows, 9.6 MB)
/// costs no more than 4 MB over the shorter one's peak (it read the file whole, then a row
/// vector each: 1.8 times the file).
#[test]
fn plot_errors_memory_does_not_grow_with_the_file() {
    let dir = tempfile::TempDir::new().unwrap();
    let errors = |seconds: &str| {
        let p = dir.path().join(format!("e{seconds}.csv"));
        let o = imu_emu()
            .args("generate --scene static --imu adis16405:typical --rate 1000".split(' '))
            .args(["--duration", seconds, "-o", "/dev/null", "--truth-errors"])
            .arg(&p)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        p
    };
    let peak = |p: &Path| {
        let png = dir.path().join("e.png");
        let (status, err, peak) = rusage::run_with_peak(
            imu_emu()
                .args(["plot-errors", "--points", "100", "-o"])
                .arg(&png)
                .arg(p),
        );
        assert!(status.success(), "{err}");
        (peak, std::fs::metadata(p).unwrap().len())
    };
    let (small, small_len) = peak(&errors("2"));
    let (big, big_len) = peak(&errors("20"));
    println!("peak {big} kB for {big_len} bytes, {small} kB for {small_len} bytes");
    assert!(big_len > 9 * small_len, "{big_len} vs {small_len} bytes");
    assert!(big < small + 4 * 1024, "{big} vs {small} kB");
}
