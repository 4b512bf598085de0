//! Size-effect stage: accelerometer i at r_i from the reference point senses
//! f + ω̇ × r_i + ω × (ω × r_i), whose interval mean is f̄ + (Δω/Δt) × r_i + (W − tr W·I) r_i
//! with W the mean of ω ωᵀ — exact, with no differentiation of ω. Needs the generator's
//! rotation terms; without them (`ErrorChain::apply`) the stage does nothing.

use super::{Block, Stage, any};
use crate::errors::model::StageKind;
use crate::math::Vec3;

/// The accelerometers' positions (row i: accelerometer i) in the case frame (m).
#[derive(Clone, Debug)]
pub(crate) struct SizeEffect {
    positions: [[f64; 3]; 3],
}

impl SizeEffect {
    /// The template's size effect; `None` when every offset is zero.
    pub(crate) fn build(positions: [[f64; 3]; 3]) -> Option<SizeEffect> {
        positions
            .iter()
            .any(|p| any(p))
            .then_some(SizeEffect { positions })
    }
    /// No offset yet (a lever arm is then added).
    pub(crate) fn zero() -> SizeEffect {
        SizeEffect {
            positions: [[0.0; 3]; 3],
        }
    }
    /// Moves every accelerometer by the lever arm `r` (case frame, m).
    pub(crate) fn add_lever_arm(&mut self, r: Vec3) {
        for row in self.positions.iter_mut() {
            for (c, v) in row.iter_mut().zip(r.iter()) {
                *c += v;
            }
        }
    }
}

impl Stage for SizeEffect {
    fn kind(&self) -> StageKind {
        StageKind::SizeEffect
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        let Some(rot) = b.rotation else { return };
        let inv_dt = 1.0 / b.dt;
        for (r, t) in b.records.iter_mut().zip(rot) {
            let (mut dw, mut w, mut g) = (t.d_omega, t.omega_outer, t.gravitation);
            if let Some(m) = b.mounting {
                dw = m * dw;
                w = m * w * m.transpose();
                g = m * g * m.transpose();
            }
            let tr = w[(0, 0)] + w[(1, 1)] + w[(2, 2)];
            for (i, p) in self.positions.iter().enumerate() {
                let p = Vec3::from(*p);
                // The gravitation's gradient across the offset as in rig::geometry::force_at.
                let add = (dw * inv_dt).cross(&p) + w * p - p * tr - g * p;
                r.accel[i] += add[i];
            }
        }
    }
}
