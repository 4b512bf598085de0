//! The IMU error model (paper §3.3): random processes, IMU templates, and the chain of stages
//! that corrupts error-free records. (Sensor errors, not Rust error types.)
//!
//! `model` holds the data types (an IMU's figures in SI, the stage kinds), `template` loads
//! them from TOML with unit and range checks, `stages` holds one type per stage of the chain,
//! and `chain` assembles and applies the stage list.

pub mod chain;
pub mod filter_allan;
pub mod filtered;
pub mod headline;
pub mod model;
pub mod output_filter;
pub mod process;
mod stages;
pub mod temperature;
pub mod template;
pub mod vibration;

pub use chain::ErrorChain;
pub use model::{ImuModel, Sensor, StageKind, TriadModel};
pub use template::TemplateError;
