//! Standard output that cannot be written (issue 23 item 5): a full disk (`/dev/full`) is an
//! error with exit status 1 and a message, never a panic (exit 101) and never success; a
//! reader that stopped early (`| head -1`) while standard output was the command's only
//! output ends the command quietly with 141, what a command killed by SIGPIPE gives (issue
//! 38: it was 0, which `set -o pipefail` took for a whole output). Beside other outputs it
//! is an error like any other (tests/sink_failures.rs).

use std::fs::File;
use std::process::{Command, Output, Stdio};

fn imu_emu() -> Command {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
}

/// Runs `args` with stdout on `/dev/full`.
fn to_full(args: &[&str]) -> Output {
    let full = File::options().write(true).open("/dev/full").unwrap();
    imu_emu()
        .args(args)
        .stdout(Stdio::from(full))
        .output()
        .unwrap()
}

/// Runs `args` with stdout on a pipe whose reader has already gone (what `| head -1` leaves
/// once head has its line: every write fails with EPIPE).
fn to_closed_pipe(args: &[&str]) -> Output {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    imu_emu()
        .args(args)
        .stdout(Stdio::from(writer))
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A full disk: exit 1, the system's reason on stderr, no panic.
fn assert_fails_cleanly(o: &Output, what: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{what}: {err}");
    assert!(err.contains("No space left on device"), "{what}: {err}");
    assert!(!err.contains("panicked"), "{what}: {err}");
}

#[test]
fn listings_to_a_full_disk_fail_with_a_message() {
    assert_fails_cleanly(&to_full(&["templates"]), "templates");
    assert_fails_cleanly(&to_full(&["scenes"]), "scenes");
}

#[test]
fn help_to_a_full_disk_is_no_success() {
    for args in [&["--help"][..], &["generate", "--help"], &["--version"]] {
        let o = to_full(args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("writing the help"), "{args:?}: {err}");
    }
    // A usage error still exits 2, its message on stderr.
    assert_eq!(to_full(&["--no-such-flag"]).status.code(), Some(2));
}

/// Exit 141 and nothing on stderr.
fn assert_reader_left(o: &Output, what: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(141), "{what}: {err}");
    assert!(err.is_empty(), "{what}: {err}");
}

#[test]
fn a_reader_that_stopped_early_ends_the_listing_quietly() {
    for args in [&["templates"][..], &["scenes"], &["--help"]] {
        assert_reader_left(&to_closed_pipe(args), &format!("{args:?}"));
    }
}

/// Every command whose only output is standard output: generate's records (offline, and
/// paced as `run` writes them), a trajectory, decoded frames, a run's description.
#[test]
fn a_reader_that_stopped_early_ends_every_command_quietly() {
    let dir = tempfile::TempDir::new().unwrap();
    let frames = dir.path().join("f.bin");
    let made = imu_emu()
        .args("generate --scene circle --duration 60 --imu ln200 --format ln200 -o".split(' '))
        .arg(&frames)
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", stderr(&made));
    let frames = frames.to_str().unwrap();
    let commands: [&[&str]; 5] = [
        &["generate", "--scene", "circle", "--duration", "100"],
        &[
            "run",
            "--scene",
            "circle",
            "--duration",
            "0.2",
            "--speed",
            "1",
            "--file",
            "-",
        ],
        &["trajectory", "--scene", "circle", "--duration", "100"],
        &["decode", "--protocol", "ln200", "--rate", "nominal", frames],
        &["run", "--scene", "circle", "--describe"],
    ];
    for args in commands {
        let o = to_closed_pipe(args);
        // The status line of a paced run is for a terminal: none here.
        assert_reader_left(&o, &format!("{args:?}"));
    }
}

#[test]
fn navigate_summary_to_a_full_disk_fails_with_a_message() {
    let dir = tempfile::TempDir::new().unwrap();
    let rec = dir.path().join("circle.bin");
    let made = imu_emu()
        .args([
            "generate",
            "--scene",
            "circle",
            "--rate",
            "100",
            "--duration",
            "1",
        ])
        .args(["--format", "bin", "-o"])
        .arg(&rec)
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", stderr(&made));
    let rec = rec.to_str().unwrap();
    assert_fails_cleanly(
        &to_full(&["navigate", rec, "--scene", "circle"]),
        "navigate",
    );
    let o = to_closed_pipe(&["navigate", rec, "--scene", "circle"]);
    assert_reader_left(&o, "navigate");
}
