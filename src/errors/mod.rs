//! The IMU error model (paper §3.3, DESIGN §3): random processes, IMU templates, and the chain
//! of stages that corrupts error-free records. (Sensor errors, not Rust error types.)

pub mod chain;
pub mod process;
pub mod temperature;
pub mod template;
pub mod vibration;

pub use chain::ErrorChain;
pub use template::{ImuModel, TemplateError};
