//! Standard output of the commands that print a result: written, never printed (a full disk
//! is an error, not a panic). Its reader leaving (`… | head`) is [`ReaderLeft`] when it was
//! the command's only output — the binary then exits 141 without a word, as `yes | head`
//! does — and beside other outputs an error that names it, since those are then incomplete.

use std::io::{self, Write};

use anyhow::Result;

use imu_emu::output::failure::ReaderLeft;

/// Writes `bytes` (`what`: "the report", "the table" …) to standard output and flushes it;
/// `alone`: standard output is the command's only output.
pub fn write(bytes: &[u8], what: &str, alone: bool) -> Result<()> {
    let mut out = io::stdout().lock();
    (out.write_all(bytes).and_then(|()| out.flush())).map_err(|e| failed(e, what, alone))
}

/// The command's error for `e`, met writing `what` to standard output (`alone`: its only
/// output).
pub fn failed(e: io::Error, what: &str, alone: bool) -> anyhow::Error {
    if alone && e.kind() == io::ErrorKind::BrokenPipe {
        return ReaderLeft.into();
    }
    anyhow::Error::new(e).context(format!("writing {what} to standard output"))
}
