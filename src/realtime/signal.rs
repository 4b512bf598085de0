//! Stopping a run: SIGINT (Ctrl-C) and SIGTERM end it after its summary, and the process then
//! exits with the shell convention 128 + signal number (130, 143), so a script can tell an
//! interrupted run from a complete one.

use std::io;

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
