//! Temperature stages: the bias or scale-factor polynomial of T − T_ref, per triad (the same
//! offset on all three axes), ahead of the kind's own terms.

use super::{Block, Stage, any};
use crate::errors::model::{Sensor, StageKind};
use crate::math::Vec3;

/// c₁d + c₂d² + c₃d³ with d = T − T_ref, as a bias or a scale-factor error.
#[derive(Clone, Debug)]
pub(crate) struct Temperature {
    sensor: Sensor,
    /// [`StageKind::Bias`] or [`StageKind::ScaleFactor`].
    kind: StageKind,
    c: [f64; 3],
}

impl Temperature {
    /// The polynomial `c` of `sensor` acting as `kind`; `None` when every coefficient is zero.
    pub(crate) fn build(sensor: Sensor, kind: StageKind, c: [f64; 3]) -> Option<Temperature> {
        debug_assert!(matches!(kind, StageKind::Bias | StageKind::ScaleFactor));
        any(&c).then_some(Temperature { sensor, kind, c })
    }
}

impl Stage for Temperature {
    fn kind(&self) -> StageKind {
        self.kind
    }
    fn rank(&self) -> i8 {
        -1
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        let (c, s) = (self.c, self.sensor);
        let poly = |d: f64| d * (c[0] + d * (c[1] + d * c[2]));
        if self.kind == StageKind::Bias {
            for (r, d) in b.records.iter_mut().zip(b.dtemp) {
                let v = poly(*d);
                *s.rate(r) += Vec3::new(v, v, v);
            }
        } else {
            for (r, d) in b.records.iter_mut().zip(b.dtemp) {
                let k = poly(*d);
                *s.rate(r) = *s.rate(r) * (1.0 + k);
            }
        }
    }
}
