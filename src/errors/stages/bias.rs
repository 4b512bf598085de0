//! Bias stage (paper eq. 5–6): constant, turn-on, Gauss–Markov, random walk, bias
//! instability (flicker) and rate ramp per axis, then the gyro's g-sensitivity to the error-free specific
//! force.

use super::{AXES, Block, Stage, any, stream, turn_on};
use crate::errors::model::{Sensor, StageKind, TriadModel};
use crate::errors::process::{Flicker, GaussMarkov, RandomWalk};
use crate::math::Mat3;

/// Bias of one axis.
#[derive(Clone, Debug)]
struct Axis {
    fixed: f64,
    gm: Option<GaussMarkov>,
    rw: Option<RandomWalk>,
    flicker: Option<Flicker>,
    /// Rate ramp R: the bias grows by R per second from the run's start.
    ramp: f64,
}

/// The bias of one triad.
#[derive(Clone, Debug)]
pub(crate) struct Bias {
    sensor: Sensor,
    axes: Option<[Axis; 3]>,
    /// Gyro g-sensitivity, (rad/s)/(m/s²), row-major.
    g_sens: Option<Mat3>,
    /// Record interval (s) and records done at it, plus the time of the records done at
    /// other intervals (an externally triggered unit): the ramp's clock.
    dt: f64,
    done: u64,
    off_grid: f64,
}

impl Bias {
    /// The triad's bias terms, drawing the turn-on constants and seeding the processes from
    /// `seed`; `None` when the template sets none.
    pub(crate) fn build(m: &TriadModel, sensor: Sensor, dt: f64, seed: u64) -> Option<Bias> {
        let needed = any(&m.bias)
            || any(&m.bias_turn_on)
            || any(&m.bias_instability)
            || m.bias_gm.is_some()
            || any(&m.random_walk)
            || any(&m.ramp);
        let axis = |i: usize| Axis {
            fixed: m.bias[i] + turn_on(seed, sensor, AXES[i], "bias_turn_on", m.bias_turn_on[i]),
            gm: m.bias_gm.and_then(|(s, t)| {
                (s[i] > 0.0).then(|| {
                    GaussMarkov::new(s[i], t[i], dt, stream(seed, sensor, AXES[i], "bias_gm"))
                })
            }),
            rw: (m.random_walk[i] > 0.0).then(|| {
                RandomWalk::new(
                    m.random_walk[i],
                    dt,
                    stream(seed, sensor, AXES[i], "random_walk"),
                )
            }),
            flicker: (m.bias_instability[i] > 0.0).then(|| {
                Flicker::new(m.bias_instability[i], m.bias_instability_band, dt, |j| {
                    stream(seed, sensor, AXES[i], &format!("bias_instability/{j}"))
                })
            }),
            ramp: m.ramp[i],
        };
        let s = &m.g_sensitivity;
        let g_sens = (sensor == Sensor::Gyro && any(s)).then_some(Mat3::from_row_slice(s));
        let axes = needed.then(|| std::array::from_fn(axis));
        (axes.is_some() || g_sens.is_some()).then_some(Bias {
            sensor,
            axes,
            g_sens,
            dt,
            done: 0,
            off_grid: 0.0,
        })
    }
}

impl Stage for Bias {
    fn kind(&self) -> StageKind {
        StageKind::Bias
    }
    fn needs_true_force(&self) -> bool {
        self.g_sens.is_some()
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        let (s, dt) = (self.sensor, b.dt);
        let nominal = dt == self.dt;
        for (i, a) in self.axes.iter_mut().flatten().enumerate() {
            if a.ramp != 0.0 {
                // Record k covers ((k−1)Δt, kΔt] from the start: the ramp's exact mean there
                // is R·(k − ½)Δt; a record of another interval T starting at s, R·(s + T/2).
                // A loop of its own, so a template without a ramp pays nothing per record.
                let start = self.done as f64 * self.dt + self.off_grid;
                for (j, r) in b.records.iter_mut().enumerate() {
                    s.rate(r)[i] += if self.off_grid == 0.0 && nominal {
                        a.ramp * ((self.done + j as u64) as f64 + 0.5) * self.dt
                    } else {
                        a.ramp * (start + (j as f64 + 0.5) * dt)
                    };
                }
            }
            for r in b.records.iter_mut() {
                let v = &mut s.rate(r)[i];
                *v += a.fixed;
                if let Some(gm) = a.gm.as_mut() {
                    *v += gm.step_over(dt);
                }
                if let Some(rw) = a.rw.as_mut() {
                    *v += rw.step_over(dt);
                }
                if let Some(f) = a.flicker.as_mut() {
                    *v += f.step_over(dt);
                }
            }
        }
        if nominal {
            self.done += b.records.len() as u64;
        } else {
            self.off_grid += b.records.len() as f64 * dt;
        }
        if let Some(m) = &self.g_sens {
            for (r, f) in b.records.iter_mut().zip(b.f_true) {
                *s.rate(r) += m * f;
            }
        }
    }
}
