//! Saturation and quantization stage (paper eq. 9–10): clamp at ±range (flagging the record),
//! then quantize. With an increment LSB the quantized increments are the output, exactly.

use super::{Block, Stage};
use crate::errors::model::{Sensor, StageKind, TriadModel};
use crate::errors::process::{QuantMode, Quantizer};
use crate::units::Lsb;

/// The record owns its status flags; saturation sets these.
pub use crate::record::{FLAG_ACCEL_SATURATED, FLAG_GYRO_SATURATED};

/// The output interface of one triad.
#[derive(Clone, Debug)]
pub(crate) struct Quantization {
    sensor: Sensor,
    range: Option<f64>,
    quant: Option<(Lsb, [Quantizer; 3])>,
}

impl Quantization {
    /// The triad's range and LSB; `None` when it has neither.
    pub(crate) fn build(m: &TriadModel, sensor: Sensor, mode: QuantMode) -> Option<Self> {
        let quant = m.quantization.map(|lsb| {
            let q = match lsb {
                Lsb::Increment(q) | Lsb::Rate(q) => q,
            };
            (lsb, std::array::from_fn(|_| Quantizer::new(q, mode)))
        });
        (quant.is_some() || m.range.is_some()).then_some(Quantization {
            sensor,
            range: m.range,
            quant,
        })
    }
}

impl Stage for Quantization {
    fn kind(&self) -> StageKind {
        StageKind::Quantization
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        let s = self.sensor;
        if let Some(lim) = self.range {
            let flag = match s {
                Sensor::Gyro => FLAG_GYRO_SATURATED,
                Sensor::Accel => FLAG_ACCEL_SATURATED,
            };
            for r in b.records.iter_mut() {
                let mut hit = false;
                // A plain slice: its loop of three is unrolled wherever codegen units put
                // this function (nalgebra's strided iterator was not, in some builds).
                for v in s.rate(r).as_mut_slice() {
                    if v.abs() > lim {
                        *v = v.clamp(-lim, lim);
                        hit = true;
                    }
                }
                if hit {
                    r.flags |= flag;
                }
            }
        }
        let Some((lsb, q)) = self.quant.as_mut() else {
            return;
        };
        let dt = b.dt;
        match lsb {
            Lsb::Increment(_) => {
                for (i, q) in q.iter_mut().enumerate() {
                    for r in b.records.iter_mut() {
                        let d = q.apply(s.rate(r)[i] * dt);
                        s.increment(r)[i] = d;
                        s.rate(r)[i] = d / dt;
                    }
                }
                b.exact[s as usize] = true;
            }
            Lsb::Rate(_) => {
                for (i, q) in q.iter_mut().enumerate() {
                    for r in b.records.iter_mut() {
                        let v = &mut s.rate(r)[i];
                        *v = q.apply(*v);
                    }
                }
            }
        }
    }
}
