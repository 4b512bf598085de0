//! The frame sources of a run: the units' readings and their side streams, and the aiding
//! sensors', each a [`WindowSource`](crate::engine::frames::WindowSource).

pub mod aiding;
pub mod imu;
