//! Public data sets other projects published (docs/testing.md, "Public data sets"), read from
//! outside the repository: the folder `IMU_EMU_TEST_DATA` names, by default `../shared/data`
//! beside the clone. A test that needs one and cannot find it says so in one line and passes;
//! under CI (`CI` set and not empty) it fails, so that a missing copy is never a silent pass.
// Each test target uses only some of these.
#![allow(dead_code)]

use std::io::Write;
use std::path::{Path, PathBuf};

/// The folder that holds the data sets.
pub fn root() -> PathBuf {
    match std::env::var_os("IMU_EMU_TEST_DATA") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"),
    }
}

/// The folder of data set `name`, or `None` (with one line on stderr naming `test`, the folder
/// and how to point at a copy) when it is absent outside CI; absent under CI, a panic.
pub fn set(name: &str, test: &str) -> Option<PathBuf> {
    let dir = root().join(name);
    if dir.is_dir() {
        return Some(dir);
    }
    let why = format!(
        "public data set `{name}` not found at {} (set IMU_EMU_TEST_DATA to the folder holding \
         it; docs/testing.md)",
        dir.display()
    );
    if std::env::var_os("CI").is_some_and(|v| !v.is_empty()) {
        panic!("{test}: {why}; under CI the data sets must be present");
    }
    // Written past the test harness's capture, so a plain `cargo test` shows it.
    let _ = writeln!(std::io::stderr(), "{test}: skipped: {why}");
    None
}
