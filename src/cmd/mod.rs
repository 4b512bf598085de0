//! The subcommands, one module each; `setup` holds the simulation flags they share.

pub mod analyze;
pub mod compare;
pub mod decode;
pub mod generate;
pub mod info;
pub mod navigate;
pub mod rig;
pub mod run;
pub mod setup;
pub mod validate;
