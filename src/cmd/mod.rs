//! The subcommands, one module each; `setup` holds the simulation flags they share.

pub mod analyze;
pub mod compare;
pub mod decode;
pub mod generate;
pub mod info;
pub mod navigate;
pub mod run;
pub mod setup;
pub mod validate;

/// A command stopped by a signal: `main` prints it and exits with 128 + the signal number
/// (130 for SIGINT, 143 for SIGTERM), as a shell reports a process killed by it.
#[derive(Debug, thiserror::Error)]
#[error("interrupted by {name}: stopped before the end, unfinished output files removed")]
pub struct Interrupted {
    /// Signal name.
    pub name: &'static str,
    /// Exit status.
    pub code: i32,
}

impl Interrupted {
    /// The interruption by signal `number` (0: none).
    pub fn from_signal(number: i32) -> Option<Interrupted> {
        match number {
            0 => None,
            2 => Some(Interrupted {
                name: "SIGINT",
                code: 130,
            }),
            15 => Some(Interrupted {
                name: "SIGTERM",
                code: 143,
            }),
            n => Some(Interrupted {
                name: "a signal",
                code: 128 + n,
            }),
        }
    }
}
