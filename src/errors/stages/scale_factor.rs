//! Scale-factor stage (paper eq. 3–4): y = x(1 + k) + q x², with k the constant, turn-on,
//! Gauss–Markov and random-walk errors plus half the asymmetry with the sign of the input.

use super::{AXES, Block, Stage, any, stream, turn_on};
use crate::errors::model::{Sensor, StageKind, TriadModel};
use crate::errors::process::{GaussMarkov, RandomWalk};

/// Scale-factor error of one axis.
#[derive(Clone, Debug)]
struct Axis {
    fixed: f64,
    gm: Option<GaussMarkov>,
    rw: Option<RandomWalk>,
    asym_half: f64,
    quad: f64,
}

/// The scale-factor errors of one triad.
#[derive(Clone, Debug)]
pub(crate) struct ScaleFactor {
    sensor: Sensor,
    axes: [Axis; 3],
}

impl ScaleFactor {
    /// The triad's scale-factor errors, drawing the turn-on constants and seeding the
    /// processes from `seed`; `None` when the template sets none.
    pub(crate) fn build(m: &TriadModel, sensor: Sensor, dt: f64, seed: u64) -> Option<Self> {
        let needed = any(&m.scale_factor)
            || any(&m.scale_factor_turn_on)
            || m.scale_factor_gm.is_some()
            || any(&m.scale_factor_random_walk)
            || any(&m.scale_factor_asymmetry)
            || any(&m.scale_factor_quadratic);
        let axis = |i: usize| Axis {
            fixed: m.scale_factor[i]
                + turn_on(
                    seed,
                    sensor,
                    AXES[i],
                    "scale_factor_turn_on",
                    m.scale_factor_turn_on[i],
                ),
            gm: m.scale_factor_gm.and_then(|(s, t)| {
                (s[i] > 0.0).then(|| {
                    GaussMarkov::new(
                        s[i],
                        t[i],
                        dt,
                        stream(seed, sensor, AXES[i], "scale_factor_gm"),
                    )
                })
            }),
            rw: (m.scale_factor_random_walk[i] > 0.0).then(|| {
                RandomWalk::new(
                    m.scale_factor_random_walk[i],
                    dt,
                    stream(seed, sensor, AXES[i], "scale_factor_random_walk"),
                )
            }),
            asym_half: 0.5 * m.scale_factor_asymmetry[i],
            quad: m.scale_factor_quadratic[i],
        };
        needed.then(|| ScaleFactor {
            sensor,
            axes: std::array::from_fn(axis),
        })
    }
}

impl Stage for ScaleFactor {
    fn kind(&self) -> StageKind {
        StageKind::ScaleFactor
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        let (s, dt) = (self.sensor, b.dt);
        for (i, a) in self.axes.iter_mut().enumerate() {
            for r in b.records.iter_mut() {
                let v = &mut s.rate(r)[i];
                let mut k = a.fixed + if *v >= 0.0 { a.asym_half } else { -a.asym_half };
                if let Some(gm) = a.gm.as_mut() {
                    k += gm.step_over(dt);
                }
                if let Some(rw) = a.rw.as_mut() {
                    k += rw.step_over(dt);
                }
                *v = *v * (1.0 + k) + a.quad * *v * *v;
            }
        }
    }
}
