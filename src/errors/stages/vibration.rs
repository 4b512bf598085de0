//! Vibration stage: the case's sinusoidal and random vibration (see `errors/vibration`), added
//! to the true signal after the mounting rotation, so every error stage acts on it.

use super::{Block, Stage};
use crate::errors::model::StageKind;
use crate::errors::vibration::Vibration;

impl Stage for Vibration {
    fn kind(&self) -> StageKind {
        StageKind::Vibration
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        for r in b.records.iter_mut() {
            let (g, a) = self.next();
            r.gyro += g;
            r.accel += a;
        }
    }
}
