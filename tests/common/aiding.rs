//! Helpers of the aiding test targets (`aiding_cli`, `rig_aiding`): the binary run in a
//! directory, and how it ended.
// Each test target uses only some of these.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// `imu-emu ARGS` run in `dir`.
pub fn imu_emu(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run imu-emu")
}

/// The run succeeded (else the assertion shows its stderr).
pub fn ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The run failed: its stderr.
pub fn failed(out: Output) -> String {
    assert!(!out.status.success());
    String::from_utf8_lossy(&out.stderr).into_owned()
}
