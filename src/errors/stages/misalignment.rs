//! Misalignment stage (paper eq. 7–8): y = M x with M = I + the constant and turn-on angles.

use super::{Block, Stage, any, turn_on};
use crate::errors::model::{Sensor, StageKind, TriadModel};
use crate::math::Mat3;

/// Angle names in stream names, in the template's order.
const PAIRS: [&str; 6] = ["xy", "xz", "yx", "yz", "zx", "zy"];

/// The misalignment matrix of one triad.
#[derive(Clone, Debug)]
pub(crate) struct Misalignment {
    sensor: Sensor,
    m: Mat3,
}

impl Misalignment {
    /// The triad's misalignment, drawing the turn-on angles from `seed`; `None` when the
    /// template sets none.
    pub(crate) fn build(m: &TriadModel, sensor: Sensor, seed: u64) -> Option<Misalignment> {
        if !(any(&m.misalignment) || any(&m.misalignment_turn_on)) {
            return None;
        }
        let ang: [f64; 6] = std::array::from_fn(|j| {
            let term = "misalignment_turn_on";
            m.misalignment[j] + turn_on(seed, sensor, PAIRS[j], term, m.misalignment_turn_on[j])
        });
        // Paper eq. 7–8: [[1, −y_z, z_y], [x_z, 1, −z_x], [−x_y, y_x, 1]] with angles
        // ordered [xy, xz, yx, yz, zx, zy].
        let [xy, xz, yx, yz, zx, zy] = ang;
        Some(Misalignment {
            sensor,
            m: Mat3::new(1.0, -yz, zy, xz, 1.0, -zx, -xy, yx, 1.0),
        })
    }
}

impl Stage for Misalignment {
    fn kind(&self) -> StageKind {
        StageKind::Misalignment
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        let (m, s) = (&self.m, self.sensor);
        for r in b.records.iter_mut() {
            let x = *s.rate(r);
            *s.rate(r) = m * x;
        }
    }
}
