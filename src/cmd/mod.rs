//! The subcommands, one module each; `setup` holds the simulation flags they share, `flow` the
//! running and printing of a run. What the flags mean is the library's (`imu_emu::run`).

pub mod analyze;
pub mod compare;
pub mod decode;
pub mod fit;
pub mod flow;
pub mod generate;
pub mod info;
pub mod input;
pub mod navigate;
pub mod plot_errors;
pub mod run;
pub mod setup;
pub mod stdout;
pub mod validate;
