//! Stopping a run: SIGINT (Ctrl-C) and SIGTERM end it after its summary, and the process then
//! exits with the shell convention 128 + signal number (130, 143), so a script can tell an
//! interrupted run from a complete one.

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicI32, Ordering};

use tokio::signal::unix::{Signal, SignalKind, signal};

/// The signals that stop a run, listened to from creation on: one that arrives between two
/// polls is kept, not lost.
pub struct StopSignals {
    int: Signal,
    term: Signal,
}

impl StopSignals {
    /// Installs the handlers (inside a tokio runtime with signals enabled).
    pub fn new() -> io::Result<StopSignals> {
        Ok(StopSignals {
            int: signal(SignalKind::interrupt())?,
            term: signal(SignalKind::terminate())?,
        })
    }

    /// Waits for the next stop signal; returns its number.
    pub async fn recv(&mut self) -> i32 {
        tokio::select! {
            _ = self.int.recv() => libc::SIGINT,
            _ = self.term.recv() => libc::SIGTERM,
        }
    }
}

/// Catches SIGINT and SIGTERM from now on, for commands that do not run inside tokio: the
/// returned flag holds the signal's number once one arrived (0 before), so a loop can stop
/// between two steps and clean up. tokio's handlers on a small thread of their own: no
/// signal-handler code of ours (a handler may only do async-signal-safe things).
pub fn watch() -> io::Result<Arc<AtomicI32>> {
    let caught = Arc::new(AtomicI32::new(0));
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    // Registered before returning, so no signal after this call kills the process.
    let mut signals = rt.block_on(async { StopSignals::new() })?;
    let flag = caught.clone();
    std::thread::Builder::new()
        .name("imu-signals".into())
        .spawn(move || {
            rt.block_on(async move { flag.store(signals.recv().await, Ordering::Relaxed) })
        })?;
    Ok(caught)
}

/// A run ended by a signal, after its summary: an error, so the process exits non-zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("interrupted by {}", signal_name(*.0))]
pub struct Interrupted(pub i32);

impl Interrupted {
    /// The exit status a shell gives a process killed by the signal: 128 + its number.
    pub fn exit_code(self) -> i32 {
        128 + self.0
    }
}

fn signal_name(sig: i32) -> &'static str {
    nix::sys::signal::Signal::try_from(sig).map_or("a signal", |s| s.as_str())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_codes_follow_the_shell() {
        assert_eq!(Interrupted(libc::SIGINT).exit_code(), 130);
        assert_eq!(Interrupted(libc::SIGTERM).exit_code(), 143);
        assert_eq!(
            Interrupted(libc::SIGTERM).to_string(),
            "interrupted by SIGTERM"
        );
    }
}
