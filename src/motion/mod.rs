//! Continuous motion models: anything that can say, at any instant of its span, what an ideal
//! IMU senses there and where the vehicle is.
//!
//! A model is split into *pieces* inside which it is smooth (infinitely differentiable for the
//! analytic scenes; polynomial between two samples for a sampled trajectory). The increment
//! quadrature splits its intervals at piece boundaries, so its order is never lost to a kink.

pub mod causal;
pub mod chain;
pub mod fd;
pub mod knot;
pub mod limits;
pub mod sampled;
pub mod stream;

use crate::kinematics::Sensed;
use crate::math::{Quat, Vec3};

/// Position, velocity and attitude at one instant: a row of the trajectory contract.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Time (s).
    pub t: f64,
    /// Geodetic latitude (rad), in [−π/2, π/2].
    pub lat: f64,
    /// Longitude (rad).
    pub lon: f64,
    /// Ellipsoidal height (m).
    pub h: f64,
    /// Velocity relative to the Earth, NED (m/s).
    pub v_n: Vec3,
    /// Attitude C_b^n.
    pub q_b_n: Quat,
}

/// A continuous, piecewise-smooth motion with analytic derivatives.
pub trait Motion {
    /// First instant of the model (s).
    fn start(&self) -> f64;
    /// Last instant of the model (s); `f64::INFINITY` for an unbounded analytic scene.
    fn end(&self) -> f64;
    /// Index of the piece that contains `t` (pieces are half-open `[start, end)`, the last one
    /// closed). `hint` is a previous answer; monotone callers get O(1) lookups from it.
    fn piece_at(&self, t: f64, hint: usize) -> usize;
    /// End time of piece `piece` (the next breakpoint); `f64::INFINITY` for the last piece, so
    /// that round-off at the very end of the span never steps past it.
    fn piece_end(&self, piece: usize) -> f64;
    /// Error-free angular rate and specific force at `t`, evaluated on piece `piece`.
    fn sense(&self, piece: usize, t: f64) -> Sensed;
    /// Truth trajectory at `t`.
    fn pose(&self, t: f64) -> Pose;
    /// True when the sensed values never change (a static scene): evaluate once, repeat.
    fn is_stationary(&self) -> bool {
        false
    }
}
