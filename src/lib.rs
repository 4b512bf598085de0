//! # imu-emu
//!
//! An IMU simulator: from a georeferenced reference trajectory it computes what an ideal
//! inertial measurement unit senses (equations 1 and 2 of Parés, Rosales & Colomina, "Yet
//! another IMU simulator"), as raw increments Δθ, Δv over each sample interval and their
//! interval means.
//!
//! The signal chain, one module per stage:
//! [`trajectory`] (CSV input) and [`scenes`] (analytic trajectories) → [`motion`] (continuous
//! models with analytic derivatives) → [`kinematics`] (ω_ib^b, f^b on the WGS-84 [`earth`]) →
//! [`generator`] (increments by [`quadrature`]) → [`output`] (CSV / binary records).
//!
//! Conventions: NED local level, body x forward / y right / z down, C_b^n = Rz(ψ)Ry(θ)Rx(φ),
//! SI units inside; see docs/signals.md.

pub mod aiding;
pub mod analysis;
pub mod config;
pub mod csvio;
pub mod decode;
pub mod earth;
pub mod engine;
pub mod errors;
pub mod fit;
pub mod generator;
pub mod input;
pub mod kinematics;
pub mod live;
pub mod math;
pub mod motion;
pub mod motiondef;
pub mod nav;
pub mod output;
pub mod plot;
pub mod protocol;
pub mod quadrature;
#[cfg(feature = "realtime")]
pub mod realtime;
pub mod record;
pub mod rig;
pub mod rng;
pub mod run;
pub mod scenes;
pub mod sim;
pub mod source;
pub mod timebase;
pub mod timing;
pub mod trajectory;
pub mod truth;
pub mod units;
pub mod validation;
