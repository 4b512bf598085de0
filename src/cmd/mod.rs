//! The subcommands, one module each; `setup` holds the simulation flags they share.

pub mod aiding_run;
pub mod analyze;
pub mod compare;
pub mod decode;
pub mod fit;
pub mod generate;
pub mod info;
pub mod input;
pub mod live;
pub mod live_rt;
pub mod navigate;
pub mod plot_errors;
pub mod rig;
pub mod rigrun;
pub mod run;
pub mod setup;
pub mod validate;
