//! The error-free IMU: increments Δθ_k = ∫ω_ib^b dt and Δv_k = ∫f^b dt over (t_{k−1}, t_k],
//! integrated on the continuous motion model by Gauss–Legendre quadrature split at the model's
//! breakpoints, and their interval means. Raw integrals: no coning or sculling compensation.

use crate::kinematics::Sensed;
use crate::math::{Mat3, Vec3};
use crate::motion::Motion;
use crate::quadrature::GaussLegendre;
use crate::record::Record;

/// Default number of Gauss–Legendre nodes per interval (order 2n); chosen from the
/// run-time-against-error table of `cargo bench --bench accuracy` (docs/motion-model.md).
pub const DEFAULT_NODES: usize = 3;

/// What a sensor away from the IMU's reference point adds needs over each interval: the change
/// of ω_ib^b (so the mean of ω̇ is Δω/Δt exactly) and the mean of ω ωᵀ (for ω × (ω × r)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RotationTerms {
    /// ω_ib^b(t_k) − ω_ib^b(t_{k−1}) (rad/s).
    pub d_omega: Vec3,
    /// Interval mean of ω ωᵀ (rad²/s²).
    pub omega_outer: Mat3,
}

/// Generates error-free records k = 1, 2, … at t_k = t₀ + k/rate.
pub struct IdealImu<M: Motion> {
    motion: M,
    rate_hz: f64,
    t0: f64,
    count: u64,
    rule: GaussLegendre,
    hint: usize,
    stationary: Option<(Vec3, Vec3)>,
}

impl<M: Motion> IdealImu<M> {
    /// A generator of `count` records at `rate_hz` starting after `t0`, with an `nodes`-point
    /// Gauss–Legendre rule. The caller has checked that the span lies within the motion.
    ///
    /// # Panics
    /// If `nodes` is not in 1..=[`crate::quadrature::MAX_NODES`] (`job::run` checks it first).
    pub fn new(motion: M, rate_hz: f64, t0: f64, count: u64, nodes: usize) -> Self {
        let rule = GaussLegendre::new(nodes).expect("node count validated by the caller");
        IdealImu {
            motion,
            rate_hz,
            t0,
            count,
            rule,
            hint: 0,
            stationary: None,
        }
    }

    /// Number of records.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// The motion model.
    pub fn motion(&self) -> &M {
        &self.motion
    }

    /// Time tag of record k: t₀ + k/rate from the integer k.
    #[inline]
    pub fn time_of(&self, k: u64) -> f64 {
        self.t0 + k as f64 / self.rate_hz
    }

    /// Fills `out` with records k_first, k_first+1, … (k ≥ 1).
    pub fn fill(&mut self, k_first: u64, out: &mut [Record]) {
        let dt = 1.0 / self.rate_hz;
        if self.motion.is_stationary() {
            let (g, a) = *self.stationary.get_or_insert_with(|| {
                let s = self.motion.sense(0, self.motion.start());
                (s.omega_ib_b, s.f_b)
            });
            for (i, r) in out.iter_mut().enumerate() {
                let k = k_first + i as u64;
                *r = Record {
                    t: self.time_of(k),
                    gyro: g,
                    accel: a,
                    dtheta: g * dt,
                    dv: a * dt,
                    flags: 0,
                };
            }
            return;
        }
        for (i, r) in out.iter_mut().enumerate() {
            let k = k_first + i as u64;
            let (g, a) = self.interval_mean(k);
            *r = Record {
                t: self.time_of(k),
                gyro: g,
                accel: a,
                dtheta: g * dt,
                dv: a * dt,
                flags: 0,
            };
        }
    }

    /// Fills `out` with the rotation terms of records k_first, k_first+1, … (for sensors
    /// offset from the reference point; costs about one more evaluation per node).
    pub fn rotation_terms(&mut self, k_first: u64, out: &mut [RotationTerms]) {
        let omega_at =
            |s: &Self, t: f64| s.motion.sense(s.motion.piece_at(t, s.hint), t).omega_ib_b;
        let mut w_prev = omega_at(self, self.time_of(k_first - 1));
        for (i, o) in out.iter_mut().enumerate() {
            let k = k_first + i as u64;
            let (lo, hi) = (self.time_of(k - 1), self.time_of(k));
            let w_end = omega_at(self, hi);
            let mut outer = Mat3::zeros();
            // Same splitting at breakpoints as the increments.
            let mut piece = self.motion.piece_at(lo, self.hint);
            let mut a = lo;
            loop {
                let b = self.motion.piece_end(piece).min(hi);
                let len = b - a;
                if len > 0.0 {
                    for (x, wt) in self.rule.nodes.iter().zip(&self.rule.weights) {
                        let w = self.motion.sense(piece, a + x * len).omega_ib_b;
                        let f = wt * len / (hi - lo);
                        outer += Mat3::from_fn(|i, j| f * w[i] * w[j]);
                    }
                }
                if b >= hi {
                    break;
                }
                piece += 1;
                a = b;
            }
            self.hint = piece;
            *o = RotationTerms {
                d_omega: w_end - w_prev,
                omega_outer: outer,
            };
            w_prev = w_end;
        }
    }

    /// Mean of ω_ib^b and f^b over (t_{k−1}, t_k].
    #[inline]
    fn interval_mean(&mut self, k: u64) -> (Vec3, Vec3) {
        let lo = self.time_of(k - 1);
        let hi = self.time_of(k);
        let mut piece = self.motion.piece_at(lo, self.hint);
        self.hint = piece;
        let mut end = self.motion.piece_end(piece);
        if end >= hi {
            // The common case: one smooth piece; node times from the integer k.
            let base = (k - 1) as f64;
            let (mut sg, mut sa) = (Vec3::zeros(), Vec3::zeros());
            for (x, w) in self.rule.nodes.iter().zip(&self.rule.weights) {
                let t = self.t0 + (base + x) / self.rate_hz;
                let Sensed { omega_ib_b, f_b } = self.motion.sense(piece, t);
                sg += omega_ib_b * *w;
                sa += f_b * *w;
            }
            return (sg, sa);
        }
        // Split at every breakpoint inside the interval; weight each part by its length.
        let inv_width = 1.0 / (hi - lo);
        let (mut sg, mut sa) = (Vec3::zeros(), Vec3::zeros());
        let mut a = lo;
        loop {
            let b = end.min(hi);
            let len = b - a;
            if len > 0.0 {
                for (x, w) in self.rule.nodes.iter().zip(&self.rule.weights) {
                    let s = self.motion.sense(piece, a + x * len);
                    let wl = w * len * inv_width;
                    sg += s.omega_ib_b * wl;
                    sa += s.f_b * wl;
                }
            }
            if b >= hi {
                break;
            }
            piece += 1;
            a = b;
            end = self.motion.piece_end(piece);
        }
        (sg, sa)
    }
}
