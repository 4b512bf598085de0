//! The subcommands, one module each; `setup` resolves what the simulating commands share.

pub mod analyze;
pub mod decode;
pub mod generate;
pub mod info;
pub mod setup;
