//! The error-free IMU: increments Δθ_k = ∫ω_ib^b dt and Δv_k = ∫f^b dt over (t_{k−1}, t_k],
//! integrated on the continuous motion model by Gauss–Legendre quadrature split at the model's
//! breakpoints, and their interval means. Raw integrals: no coning or sculling compensation.

use crate::kinematics::Sensed;
use crate::math::{Mat3, QuatExt, Vec3};
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
    /// The gravitational gradient Γ^b in body axes (s⁻²) over the interval, normalised as
    /// `omega_outer` is: a point at r reads −Γ r more specific force
    /// ([`crate::earth::gravitation_gradient_ned`]).
    pub gravitation: Mat3,
}

/// The gravitation's gradient in the body axes of `pose`, Γ^b = C_n^b Γ^n C_b^n (s⁻²,
/// [`crate::earth::gravitation_gradient_ned`]).
pub fn gravitation_gradient_b(pose: &crate::motion::Pose) -> Mat3 {
    let (s, c) = pose.lat.sin_cos();
    let c_b_n = pose.q_b_n.to_mat();
    c_b_n.transpose() * crate::earth::gravitation_gradient_ned(s, c, pose.h) * c_b_n
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
    /// If `nodes` is not in 1..=[`crate::quadrature::MAX_NODES`] (`engine::run` checks it first).
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
        let mut w_prev = self.omega_at(self.time_of(k_first - 1));
        for (i, o) in out.iter_mut().enumerate() {
            let k = k_first + i as u64;
            let (lo, hi) = (self.time_of(k - 1), self.time_of(k));
            *o = self.rotation_over(lo, hi, hi - lo, &mut w_prev);
        }
    }

    /// Fills `out` with the rotation terms over the sensor's true intervals `bounds` (relative
    /// to t₀; sample i covers (bounds[i], bounds[i+1]]), the mean of ω ωᵀ taken over the
    /// *nominal* Δt — the same convention as [`IdealImu::fill_timed`]'s rates, so that the
    /// lever-arm force [`crate::rig::geometry::force_at`] with 1/Δt gives the increment over
    /// the true interval divided by the nominal Δt.
    pub fn rotation_terms_timed(&mut self, bounds: &[f64], out: &mut [RotationTerms]) {
        let dt = 1.0 / self.rate_hz;
        let mut w_prev = self.omega_at(self.t0 + bounds[0]);
        for (i, o) in out.iter_mut().enumerate() {
            let (lo, hi) = (self.t0 + bounds[i], self.t0 + bounds[i + 1]);
            *o = self.rotation_over(lo, hi, dt, &mut w_prev);
        }
    }

    /// The gravitational gradient in body axes at `t`, Γ^b = C_n^b Γ^n C_b^n, taken at each
    /// interval's middle (one pose per interval: a pose costs what a node's evaluation does,
    /// and three of them added 13 % to the rig example's instructions). Γ^b turns with the
    /// attitude; its interval mean differs from the middle value by (Δt²/24)·Γ̈^b, and
    /// |Γ̈^b| ≤ 4ω²|Γ|, so by at most (ωΔt)²/6·|Γ|: with |Γ| ≈ 3.1e-6 s⁻², 1.5e-11 s⁻² at
    /// 0.55 rad/s and 100 Hz, 1.3e-15 s⁻² at 0.1 rad/s and 400 Hz.
    fn gravitation_at(&self, t: f64) -> Mat3 {
        gravitation_gradient_b(&self.motion.pose(t))
    }

    /// ω_ib^b at `t` as the end of an interval: on the piece that holds the instants just
    /// before `t` (a state's time tag a rounding before `t` counts as `t`, see
    /// [`Self::reaches`]), so that it does not depend on whether a later piece is known yet.
    fn omega_at(&self, t: f64) -> Vec3 {
        let before = t - crate::math::tag_slack(t, t);
        self.motion
            .sense(self.motion.piece_at(before, self.hint), t)
            .omega_ib_b
    }

    /// The rotation terms over (lo, hi]: Δω from `w_prev` (ω at `lo`, updated to ω at `hi`)
    /// and ∫ω ωᵀ dt / `norm`, split at the breakpoints as the increments are.
    fn rotation_over(&mut self, lo: f64, hi: f64, norm: f64, w_prev: &mut Vec3) -> RotationTerms {
        let w_end = self.omega_at(hi);
        let mut outer = Mat3::zeros();
        let mut piece = self.motion.piece_at(lo, self.hint);
        let mut a = lo;
        loop {
            let end = self.motion.piece_end(piece);
            let b = if Self::reaches(end, hi) { hi } else { end };
            let len = b - a;
            if len > 0.0 {
                for (x, wt) in self.rule.nodes.iter().zip(&self.rule.weights) {
                    let w = self.motion.sense(piece, a + x * len).omega_ib_b;
                    let f = wt * len / norm;
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
        let d_omega = w_end - *w_prev;
        *w_prev = w_end;
        RotationTerms {
            d_omega,
            omega_outer: outer,
            gravitation: self.gravitation_at(0.5 * (lo + hi)) * ((hi - lo) / norm),
        }
    }

    /// True when a piece ending at `end` covers an interval ending at `hi`: also when `end` is
    /// an ulp or two short of it. A piece end is a state's time tag and `hi` is t₀ + k/rate,
    /// computed: the same instant can come out a rounding apart, and a split there would
    /// evaluate a sliver of 1e-17 s on the next piece when it is known (a live run ahead of
    /// its clock) and not when it is not yet (lockstep at the newest state), so the same
    /// input would give records that differ in their last bits.
    #[inline]
    fn reaches(end: f64, hi: f64) -> bool {
        end >= hi || hi - end <= crate::math::tag_slack(hi, hi)
    }

    /// Mean of ω_ib^b and f^b over (t_{k−1}, t_k].
    #[inline]
    fn interval_mean(&mut self, k: u64) -> (Vec3, Vec3) {
        let lo = self.time_of(k - 1);
        let hi = self.time_of(k);
        let piece = self.motion.piece_at(lo, self.hint);
        self.hint = piece;
        let end = self.motion.piece_end(piece);
        if Self::reaches(end, hi) {
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
            let b = if Self::reaches(end, hi) { hi } else { end };
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

    /// Fills `out` with records over the variable intervals `bounds` (relative to t₀; record
    /// i covers (bounds[i], bounds[i+1]]), as an externally triggered unit samples: the time
    /// tag is the interval's end; the rates are the means over the interval itself (the
    /// error chain's [`crate::errors::ErrorChain::apply_over`] turns them back into
    /// increments with the same interval).
    pub fn fill_between(&mut self, bounds: &[f64], out: &mut [Record]) {
        for (i, r) in out.iter_mut().enumerate() {
            let (lo, hi) = (bounds[i], bounds[i + 1]);
            let (dtheta, dv) = self.integral(lo, hi);
            let inv = 1.0 / (hi - lo);
            *r = Record {
                t: self.t0 + hi,
                gyro: dtheta * inv,
                accel: dv * inv,
                dtheta,
                dv,
                flags: 0,
            };
        }
    }

    /// Fills `out` with records k_first, k_first+1, … whose increments integrate over the
    /// sensor's true intervals (relative to t₀; the timing model's `SensorTiming`): the
    /// gyro's over (gyro[i], gyro[i+1]], the accelerometers' over (accel[i], accel[i+1]]. The record's time tag
    /// stays t₀ + k/rate (the sensor clock's reading) and its rates are the increments over
    /// the nominal Δt, as a unit that divides by the interval its own clock measured reports
    /// them.
    pub fn fill_timed(
        &mut self,
        k_first: u64,
        (gyro, accel): (&[f64], &[f64]),
        out: &mut [Record],
    ) {
        let same = gyro == accel;
        for (i, r) in out.iter_mut().enumerate() {
            let (dtheta, dv_g) = self.integral(gyro[i], gyro[i + 1]);
            let dv = if same {
                dv_g
            } else {
                self.integral(accel[i], accel[i + 1]).1
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
        /// Only the rotation terms' gravitation gradient reads it: level at the equator.
        fn pose(&self, t: f64) -> Pose {
            Pose {
                t,
                lat: 0.0,
                lon: 0.0,
                h: 0.0,
                v_n: Vec3::zeros(),
                q_b_n: crate::math::Quat::identity(),
            }
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
        imu.fill_timed(1, (&timed.gyro, &timed.accel), &mut out);
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

    /// The lever-arm terms over the accelerometers' true intervals: Δω = ω(b) − ω(a) and
    /// ∫ω ωᵀ dt over (a, b] divided by the nominal Δt, in closed form (∫tⁿ = (bⁿ⁺¹ − aⁿ⁺¹)/(n+1);
    /// ω ωᵀ has degree 6, exact for the 4-node rule). Over the nominal intervals instead they
    /// would miss by the clock's 300 ppm and the 150 µs skew, far above the tolerance.
    #[test]
    fn rotation_terms_over_the_true_intervals() {
        let rate = 100.0;
        let model = TimingModel {
            clock_offset: 300e-6,
            jitter: 20e-6,
            skew: 150e-6,
            ..Default::default()
        };
        let mut timing = SensorTiming::new(model, rate, 1.5, 3, (0.0, 2.0)).unwrap();
        let mut imu = IdealImu::new(Poly, rate, 0.0, 150, 4);
        let mut timed = TimedBlock::default();
        timing.fill(1, 150, &mut timed);
        let mut rot = vec![RotationTerms::default(); 150];
        imu.rotation_terms_timed(&timed.accel, &mut rot);
        let w = |t: f64| [t * t, t * t * t, 1.0];
        // ω_i ω_j = t^(p_i + p_j) with powers p = (2, 3, 0).
        let pw = [2, 3, 0];
        for (i, r) in rot.iter().enumerate() {
            let (a, b) = (timed.accel[i], timed.accel[i + 1]);
            for j in 0..3 {
                let want = w(b)[j] - w(a)[j];
                assert!(
                    (r.d_omega[j] - want).abs() <= 1e-15 * w(b)[j].abs() + 1e-18,
                    "{i} {j}"
                );
                for l in 0..3 {
                    let n = pw[j] + pw[l] + 1;
                    let want = (b.powi(n) - a.powi(n)) / n as f64 * rate;
                    let tol = 1e-14 * b.powi(n) * rate + 1e-18;
                    let got = r.omega_outer[(j, l)];
                    assert!((got - want).abs() <= tol, "{i} ({j},{l}): {got} vs {want}");
                }
            }
        }
    }

    /// Triggered samples at irregular instants (one crossing the 0.5 s breakpoint): each
    /// record's increments are the closed-form integrals over its own interval, its time tag
    /// the interval's end and its rates the means over that interval. Sampling on the
    /// nominal grid instead misses by whole intervals.
    #[test]
    fn triggered_intervals() {
        let t0 = 0.25;
        let mut imu = IdealImu::new(Poly, 100.0, t0, 0, 3);
        let bounds = [0.0, 0.0031, 0.0197, 0.2804, 0.281, 0.9];
        let mut out = vec![Record::default(); bounds.len() - 1];
        imu.fill_between(&bounds, &mut out);
        for (i, r) in out.iter().enumerate() {
            let (a, b) = (t0 + bounds[i], t0 + bounds[i + 1]);
            let p = |n: i32| (b.powi(n) - a.powi(n), 1e-15 * b.powi(n) + 1e-18);
            let div = |(x, e): (f64, f64), k: f64| (x / k, e / k);
            let want_g = [div(p(3), 3.0), div(p(4), 4.0), p(1)];
            let want_a = [p(5), div(p(2), 2.0), p(1)];
            for j in 0..3 {
                assert!(
                    (r.dtheta[j] - want_g[j].0).abs() <= want_g[j].1,
                    "{i} gyro {j}"
                );
                assert!(
                    (r.dv[j] - want_a[j].0).abs() <= want_a[j].1,
                    "{i} accel {j}"
                );
                let inv = 1.0 / (bounds[i + 1] - bounds[i]);
                assert_eq!((r.gyro[j], r.accel[j]), (r.dtheta[j] * inv, r.dv[j] * inv));
            }
            assert_eq!(r.t, t0 + bounds[i + 1]);
        }
    }

    /// The gravitation's gradient in the rotation terms is Γ^b at each interval's middle, and
    /// that differs from its interval mean (16-point Gauss–Legendre here) by at most the
    /// documented (ωΔt)²/6·|Γ|: a coning body (half-cone 20°, 3 rad/s: |ω| ≈ 1 rad/s) at
    /// 100 Hz, where the bound is 5e-11 s⁻². The bound is not slack by more than a factor
    /// of 50 either (the difference is that large), and the middle value is Γ^b of the pose
    /// there to round-off.
    #[test]
    fn gravitation_is_the_middle_value_within_its_bound() {
        use crate::scenes::fixed::FixedScene;
        let q = crate::math::Quat::identity();
        let scene = FixedScene::new(0.7, 0.1, 300.0, q, Some((0.35, 3.0)));
        let rate = 100.0;
        let mut imu = IdealImu::new(scene.clone(), rate, 0.0, 200, 3);
        let mut rot = vec![RotationTerms::default(); 200];
        imu.rotation_terms(1, &mut rot);
        let gl = GaussLegendre::new(16).unwrap();
        let mut worst = 0.0f64;
        let mut bound = 0.0f64;
        for (k, r) in rot.iter().enumerate() {
            let (lo, hi) = (k as f64 / rate, (k + 1) as f64 / rate);
            let mid = gravitation_gradient_b(&scene.pose(0.5 * (lo + hi)));
            assert!((r.gravitation - mid).amax() < 1e-20, "{k}");
            let mut mean = Mat3::zeros();
            for (x, w) in gl.nodes.iter().zip(&gl.weights) {
                mean += gravitation_gradient_b(&scene.pose(lo + x * (hi - lo))) * *w;
            }
            let omega = scene.sense(0, 0.5 * (lo + hi)).omega_ib_b.norm();
            let b = (omega / rate).powi(2) / 6.0 * mid.norm();
            worst = worst.max((mean - mid).amax() / b);
            bound = bound.max(b);
        }
        assert!(
            worst <= 1.0 && worst > 0.02,
            "{worst} of the bound {bound:e}"
        );
    }

    /// A motion of two pieces meeting at a state's tag, 0.15 s, the second 10⁶ rad/s and m/s²
    /// off (so a sliver evaluated on it would show); `known`: whether the second piece is
    /// known yet (else the first runs on, as a live model's newest piece does).
    struct Knot15 {
        known: bool,
    }

    impl Motion for Knot15 {
        fn start(&self) -> f64 {
            0.0
        }
        fn end(&self) -> f64 {
            1.0
        }
        fn piece_at(&self, t: f64, _: usize) -> usize {
            usize::from(self.known && t >= 0.15)
        }
        fn piece_end(&self, piece: usize) -> f64 {
            if piece == 0 && self.known {
                0.15
            } else {
                f64::INFINITY
            }
        }
        fn sense(&self, piece: usize, t: f64) -> Sensed {
            let v = t + 1e6 * piece as f64;
            Sensed {
                omega_ib_b: Vec3::new(v, 0.0, 0.0),
                f_b: Vec3::new(0.0, v, 0.0),
            }
        }
        fn pose(&self, t: f64) -> Pose {
            Poly.pose(t)
        }
    }

    /// The record ending on a state's tag comes out the same whether the next piece is known:
    /// t₀ = 0.08 s at 400 Hz puts record 28's end at 0.08 + 28/400 = 0.15000000000000002, an
    /// ulp past the tag 0.15; split there, the known motion would add a 2.8e-17 s sliver of
    /// the second piece (10⁶ · 2.8e-17/0.0025 = 1.1e-8 rad/s). Its interval mean is then the
    /// first piece's, t at the middle (the rule is exact for a line), and the same for the
    /// rotation terms' ω at its end.
    #[test]
    fn a_record_on_a_tag_does_not_split_a_rounding_off() {
        let hi = 0.08 + 28.0 / 400.0;
        assert!(hi > 0.15, "the case this test is for");
        let rec = |known: bool| {
            let mut imu = IdealImu::new(Knot15 { known }, 400.0, 0.08, 40, 3);
            let mut out = vec![Record::default(); 1];
            imu.fill(28, &mut out);
            let mut rot = vec![RotationTerms::default(); 1];
            imu.rotation_terms(28, &mut rot);
            (out[0], rot[0].d_omega)
        };
        let (a, da) = rec(true);
        let (b, db) = rec(false);
        assert_eq!((a.gyro, a.accel, da), (b.gyro, b.accel, db));
        let mid = 0.08 + 27.5 / 400.0;
        assert!((a.gyro.x - mid).abs() < 1e-16, "{}", a.gyro.x);
    }
}
