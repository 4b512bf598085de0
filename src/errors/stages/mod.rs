//! The stages of the error chain, one type per file. A stage corrupts a whole block of records
//! at a time (one dynamic call per stage and block, never per record); inside, it runs axis by
//! axis over the block, so each random process still steps once per record, in record order,
//! on its own named stream — the result does not depend on the block size.
//!
//! A stage is built only when one of its parameters is non-zero (`build` returns `None`
//! otherwise), so an ideal IMU has an empty chain.

mod bias;
mod misalignment;
mod noise;
mod quantization;
mod scale_factor;
mod size_effect;
mod temperature;
mod vibration;

pub(crate) use bias::Bias;
pub(crate) use misalignment::Misalignment;
pub(crate) use noise::Noise;
pub(crate) use quantization::Quantization;
pub use quantization::{FLAG_ACCEL_SATURATED, FLAG_GYRO_SATURATED};
pub(crate) use scale_factor::ScaleFactor;
pub(crate) use size_effect::SizeEffect;
pub(crate) use temperature::Temperature;

use std::any::Any;
use std::fmt::Debug;

use super::model::{Sensor, StageKind};
use crate::generator::RotationTerms;
use crate::math::{Mat3, Vec3};
use crate::record::Record;
use crate::rng::NormalStream;

/// Axis names in stream names.
const AXES: [&str; 3] = ["x", "y", "z"];

/// One stage of the chain.
pub(crate) trait Stage: StageBox + Debug + Send + Sync {
    /// Its kind: where it runs in the chain, and the group its injected error is counted in.
    fn kind(&self) -> StageKind;
    /// Its place among the stages of its kind (lower first; default 0): a temperature
    /// polynomial acts before the kind's own terms.
    fn rank(&self) -> i8 {
        0
    }
    /// True when it needs [`Block::f_true`], the error-free specific force.
    fn needs_true_force(&self) -> bool {
        false
    }
    /// Corrupts the records of `block` in place.
    fn apply(&mut self, block: &mut Block<'_>);
}

/// Cloning and downcasting of boxed stages (implemented for every `Stage + Clone`).
pub(crate) trait StageBox {
    /// A boxed copy.
    fn clone_box(&self) -> Box<dyn Stage>;
    /// For [`crate::errors::ErrorChain`]'s `with_…` methods that amend a built stage.
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<T: Stage + Clone + 'static> StageBox for T {
    fn clone_box(&self) -> Box<dyn Stage> {
        Box::new(self.clone())
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

impl Clone for Box<dyn Stage> {
    fn clone(&self) -> Box<dyn Stage> {
        self.clone_box()
    }
}

/// A block of records on its way through the chain, with what the stages share.
pub(crate) struct Block<'a> {
    /// The records, corrupted in place.
    pub records: &'a mut [Record],
    /// The generator's rotation terms of the same records, when given.
    pub rotation: Option<&'a [RotationTerms]>,
    /// C_b^c, when the case is not mounted along the body axes.
    pub mounting: Option<&'a Mat3>,
    /// The error-free specific force of each record (filled when a stage needs it).
    pub f_true: &'a [Vec3],
    /// T − T_ref of each record (filled when the chain has a temperature profile).
    pub dtemp: &'a [f64],
    /// Record step Δt (s).
    pub dt: f64,
    /// Per sensor: the quantization left the increments exactly on the LSB grid.
    pub exact: [bool; 2],
}

impl Sensor {
    /// The sensor's interval-mean rate in a record (gyro rad/s, accel m/s²).
    #[inline]
    pub(crate) fn rate(self, r: &mut Record) -> &mut Vec3 {
        match self {
            Sensor::Gyro => &mut r.gyro,
            Sensor::Accel => &mut r.accel,
        }
    }
    /// The sensor's increment in a record (Δθ, Δv).
    #[inline]
    pub(crate) fn increment(self, r: &mut Record) -> &mut Vec3 {
        match self {
            Sensor::Gyro => &mut r.dtheta,
            Sensor::Accel => &mut r.dv,
        }
    }
}

/// The stream of one term of one axis (or axis pair): `{sensor}/{axis}/{term}`. The names
/// are part of the output contract: a seed reproduces a run only while they stay.
fn stream(seed: u64, sensor: Sensor, axis: &str, term: &str) -> NormalStream {
    NormalStream::new(seed, &format!("{}/{axis}/{term}", sensor.name()))
}

/// A random constant: one draw of its own stream times σ (no stream when σ = 0).
fn turn_on(seed: u64, sensor: Sensor, axis: &str, term: &str, sigma: f64) -> f64 {
    if sigma == 0.0 {
        0.0
    } else {
        sigma * stream(seed, sensor, axis, term).draw()
    }
}

fn any(v: &[f64]) -> bool {
    v.iter().any(|x| *x != 0.0)
}
