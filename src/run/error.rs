//! Why a run cannot be built or stopped early.

use crate::engine::EngineError;
use crate::sim::SimError;

/// Why a run cannot be built, or why it stopped before its end.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The signal (scene file, template, protocol, span) cannot be assembled.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Production stopped: a non-finite value, a sensor outside its table, a trigger edge.
    #[error(transparent)]
    Engine(#[from] EngineError),
    /// A part of the description is unusable, or cannot go with the rest of it: `what` names
    /// it (a flag or a scene-file key), `why` says what would make sense instead.
    #[error("{what}: {why}")]
    Spec {
        /// The flag, key or route at fault.
        what: String,
        /// Why, and what to do.
        why: String,
    },
    /// Opening, reading or writing failed.
    #[error("{what}")]
    Io {
        /// What was being done.
        what: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// An output could not be written: the error begins with its flag (or scene-file key) and
    /// names its file, then the system's reason.
    #[error(transparent)]
    Output(std::io::Error),
    /// Standard output was the run's only output and its reader left (`… | head`).
    #[error("{0}")]
    ReaderLeft(#[from] crate::output::failure::ReaderLeft),
    /// The live input ended before the motion model had its first piece.
    #[error(
        "{input}: the input ended after {states} usable states; the motion model needs {need} before the first record{why}"
    )]
    TooFewStates {
        /// The input's name.
        input: String,
        /// States taken.
        states: u64,
        /// States needed.
        need: usize,
        /// What became of the other messages ([`crate::live::stats::InputStats::why_unused`]).
        why: String,
    },
    /// The live input's time tags do not fit the time base chosen.
    #[error("{0}")]
    TimeBase(String),
}

impl RunError {
    /// A refusal of `what` (a flag, key or route), saying `why`.
    pub fn spec(what: &str, why: String) -> RunError {
        RunError::Spec {
            what: what.to_string(),
            why,
        }
    }

    /// An I/O error while doing `what`.
    pub fn io(what: impl Into<String>, source: std::io::Error) -> RunError {
        RunError::Io {
            what: what.into(),
            source,
        }
    }
}

/// A refusal of the flag (or key, or route) `what`, saying why.
pub(super) fn refuse(what: &str, why: impl Into<String>) -> RunError {
    RunError::spec(what, why.into())
}
