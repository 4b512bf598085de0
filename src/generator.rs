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
        let piece = self.motion.piece_at(lo, self.hint);
        self.hint = piece;
        let end = self.motion.piece_end(piece);
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
        self.weighted(lo, hi, piece, end, 1.0 / (hi - lo))
    }

    /// ∫ω_ib^b dt and ∫f^b dt over (lo, hi], split at the breakpoints, times `factor`.
    fn weighted(
        &mut self,
        lo: f64,
        hi: f64,
        mut piece: usize,
        mut end: f64,
        factor: f64,
    ) -> (Vec3, Vec3) {
        let (mut sg, mut sa) = (Vec3::zeros(), Vec3::zeros());
        let mut a = lo;
        loop {
            let b = end.min(hi);
            let len = b - a;
            if len > 0.0 {
                for (x, w) in self.rule.nodes.iter().zip(&self.rule.weights) {
                    let s = self.motion.sense(piece, a + x * len);
                    let wl = w * len * factor;
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
        self.hint = piece;
        (sg, sa)
    }

    /// ∫ω_ib^b dt and ∫f^b dt over (t₀ + lo, t₀ + hi].
    fn integral(&mut self, lo: f64, hi: f64) -> (Vec3, Vec3) {
        let (lo, hi) = (self.t0 + lo, self.t0 + hi);
        if self.motion.is_stationary() {
            let s = self.motion.sense(0, self.motion.start());
            return (s.omega_ib_b * (hi - lo), s.f_b * (hi - lo));
        }
        let piece = self.motion.piece_at(lo, self.hint);
        let end = self.motion.piece_end(piece);
        self.weighted(lo, hi, piece, end, 1.0)
    }

    /// Fills `out` with records k_first, k_first+1, … whose increments integrate over the
    /// sensor's true intervals `timed` (relative to t₀; [`crate::timing::SensorTiming`]): the
    /// gyro's over `timed.gyro`, the accelerometers' over `timed.accel`. The record's time tag
    /// stays t₀ + k/rate (the sensor clock's reading) and its rates are the increments over
    /// the nominal Δt, as a unit that divides by the interval its own clock measured reports
    /// them.
    pub fn fill_timed(
        &mut self,
        k_first: u64,
        timed: &crate::timing::TimedBlock,
        out: &mut [Record],
    ) {
        let same = timed.gyro == timed.accel;
        for (i, r) in out.iter_mut().enumerate() {
            let (dtheta, dv_g) = self.integral(timed.gyro[i], timed.gyro[i + 1]);
            let dv = if same {
                dv_g
            } else {
                self.integral(timed.accel[i], timed.accel[i + 1]).1
            };
            *r = Record {
                t: self.time_of(k_first + i as u64),
                gyro: dtheta * self.rate_hz,
                accel: dv * self.rate_hz,
                dtheta,
                dv,
                flags: 0,
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::Pose;
    use crate::timing::{SensorTiming, TimedBlock, TimingModel};

    /// ω = (t², t³, 1), f = (5t⁴, t, 1) on two pieces split at 0.5 s: polynomials of degree
    /// ≤ 5, which the 3-node Gauss–Legendre rule integrates exactly.
    struct Poly;

    impl Motion for Poly {
        fn start(&self) -> f64 {
            0.0
        }
        fn end(&self) -> f64 {
            2.0
        }
        fn piece_at(&self, t: f64, _: usize) -> usize {
            usize::from(t >= 0.5)
        }
        fn piece_end(&self, piece: usize) -> f64 {
            if piece == 0 { 0.5 } else { f64::INFINITY }
        }
        fn sense(&self, _: usize, t: f64) -> Sensed {
            Sensed {
                omega_ib_b: Vec3::new(t * t, t * t * t, 1.0),
                f_b: Vec3::new(5.0 * t.powi(4), t, 1.0),
            }
        }
        fn pose(&self, _: f64) -> Pose {
            unreachable!("not used by the generator")
        }
    }

    /// The increments integrate over the sensor's true intervals (a clock 300 ppm fast, 20 µs
    /// jitter, accelerometers 150 µs late), in closed form: ∫t² = (b³−a³)/3, ∫t³ = (b⁴−a⁴)/4,
    /// ∫5t⁴ = b⁵−a⁵, ∫t = (b²−a²)/2, to a few ulps of the larger power. Integrating over the nominal
    /// intervals instead misses by about 3e-4 relative, over the gyro's intervals for the
    /// accelerometers by 1.5e-4 of Δt; the rates are the increments over the nominal Δt.
    #[test]
    fn increments_over_the_true_intervals() {
        let rate = 100.0;
        let model = TimingModel {
            clock_offset: 300e-6,
            jitter: 20e-6,
            skew: 150e-6,
            ..Default::default()
        };
        let mut timing = SensorTiming::new(model, rate, 1.5, 3, (0.0, 2.0)).unwrap();
        let mut imu = IdealImu::new(Poly, rate, 0.0, 150, 3);
        let mut timed = TimedBlock::default();
        let mut out = vec![Record::default(); 150];
        timing.fill(1, 150, &mut timed);
        imu.fill_timed(1, &timed, &mut out);
        for (i, r) in out.iter().enumerate() {
            let (a, b) = (timed.gyro[i], timed.gyro[i + 1]);
            let (c, d) = (timed.accel[i], timed.accel[i + 1]);
            // hⁿ − lⁿ and its round-off scale (the subtraction cancels): 1e-15·hⁿ, about 5 ulps of hⁿ.
            let p = |n: i32, lo: f64, hi: f64| (hi.powi(n) - lo.powi(n), 1e-15 * hi.powi(n));
            let div = |(x, e): (f64, f64), k: f64| (x / k, e / k);
            let want_g = [div(p(3, a, b), 3.0), div(p(4, a, b), 4.0), p(1, a, b)];
            let want_a = [p(5, c, d), div(p(2, c, d), 2.0), p(1, c, d)];
            for j in 0..3 {
                let (g, eg) = want_g[j];
                let (f, ef) = want_a[j];
                assert!((r.dtheta[j] - g).abs() <= eg + 1e-18, "{i} gyro {j}");
                assert!(
                    (r.dv[j] - f).abs() <= ef + 1e-18,
                    "{i} accel {j}: {} vs {f} ({c}, {d})",
                    r.dv[j]
                );
                assert_eq!(r.gyro[j], r.dtheta[j] * rate);
                assert_eq!(r.accel[j], r.dv[j] * rate);
            }
            assert_eq!(r.t, (i + 1) as f64 / rate);
        }
        // The last gyro bound is the clock's 150th tick, 1.5 s/(1 + 300 ppm), give or take
        // the jitter (6σ).
        assert!((timed.gyro[150] - 1.5 / (1.0 + 300e-6)).abs() < 120e-6);
    }
}
