//! Running the `imu-emu` binary from the command-line test targets (`analysis`, `fit`,
//! `fit_table`).

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Output};

/// Runs `imu-emu` with `args`.
pub fn imu_emu<I: IntoIterator<Item = S>, S: AsRef<OsStr>>(args: I) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(args)
        .output()
        .expect("run imu-emu")
}

/// The stdout of a run that must succeed (its stderr in the failure message).
pub fn ok(out: Output) -> String {
    assert!(
        out.status.success(),
        "stderr:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// The stderr of a run that must fail.
pub fn err(out: Output) -> String {
    assert!(!out.status.success(), "expected failure");
    String::from_utf8(out.stderr).unwrap()
}

/// A path as the &str an argument list takes.
pub fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}
