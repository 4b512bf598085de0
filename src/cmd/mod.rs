//! The subcommands, one module each; `setup` holds the simulation flags they share, `routes`
//! the sink flags, `flow` the running and printing of a run.

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
pub mod routes;
pub mod run;
pub mod setup;
pub mod validate;
