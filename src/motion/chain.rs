//! The motion a real-time live run emits: a chain of quintic Hermite pieces that follows the
//! causal model's pieces while states arrive in time, extrapolates past the newest state when
//! they do not, and bridges back to the received motion when a late state arrives.
//!
//! Everything emitted is final: a piece is never changed over a span the generator has
//! already integrated (a correction starts at the end of the last record emitted), so every
//! Δθ/Δv is the exact integral of the motion this chain describes.
//!
//! * Extrapolation from a knot continues its jerk and its quaternion's second derivative for
//!   at most `max_extrapolation` seconds: r is a cubic, v a quadratic, the (unnormalised)
//!   quaternion a quadratic in time, which a quintic Hermite piece reproduces exactly. Past
//!   that bound the motion *holds*: constant acceleration and angular rate (jerk and angular
//!   acceleration drop to zero; acceleration and rate stay continuous).
//! * Correction: when a newer state arrives while the chain is not following, the chain is
//!   cut at the end of the last emitted record, t_e, and a bridge piece joins the cut — value,
//!   first and second derivative of position, velocity and quaternion taken from the emitted
//!   piece at t_e — to the received motion at t_e + horizon (value, first and second
//!   derivative again; sooner, at the newest state, when that is at least a tenth of the
//!   horizon ahead). Velocity, acceleration, attitude and angular rate are thus continuous
//!   across both ends: no step in velocity or attitude, no spike in the increments. The
//!   bridge is the quintic Hermite blend of the two motions: its basis weights are the C²
//!   smoothstep 10s³ − 15s⁴ + 6s⁵ and its companions (the standard quintic Hermite basis).

use std::collections::VecDeque;

use super::sampled::{Degree, Knot, hermite};
use crate::kinematics::{EcefState, Sensed, sense_ecef};
use crate::math::{Quat, Vec3};

/// Pieces kept behind the newest (the generator steps back at most one record interval).
const KEEP: usize = 4096;

/// How the chain extrapolates and corrects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainSettings {
    /// Duration of a correction bridge (s).
    pub horizon: f64,
    /// Longest extrapolation with the newest state's jerk and angular acceleration (s).
    pub max_extrapolation: f64,
}

/// What the end of the chain is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tail {
    /// Following the received motion (interpolating between states).
    Following,
    /// Extrapolating past the newest state (within `max_extrapolation`).
    Extrapolating,
    /// Past the extrapolation bound: constant acceleration and angular rate.
    Holding,
}

/// The largest correction applied so far, measured at the cut between the emitted motion and
/// the received one.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Corrections {
    /// Number of bridges made.
    pub count: u64,
    /// Largest position difference (m).
    pub position: f64,
    /// Largest velocity difference (m/s).
    pub velocity: f64,
    /// Largest attitude difference (rad).
    pub attitude: f64,
    /// The earliest time (s) the emitted motion left the received one: extrapolated or held
    /// past the newest state of the moment. Records up to it follow the received states
    /// exactly (a lockstep run of the same input makes the same ones).
    pub departed: Option<f64>,
    /// The longest span (s) the emitted motion ran past the newest state before a newer one
    /// brought it back (0 without a correction): the extrapolation a correction undoes.
    pub longest: f64,
    /// Where the latest correction's bridge rejoined the received motion (s): from there on
    /// the output follows the input again, until it next leaves it.
    pub rejoined: Option<f64>,
}

#[derive(Clone, Copy, Debug)]
pub(super) struct Piece {
    k0: Knot,
    k1: Knot,
    start: f64,
    end: f64,
}

/// The emitted chain (kept inside the causal model, under its lock).
#[derive(Clone, Debug)]
pub(super) struct Chain {
    settings: ChainSettings,
    pieces: VecDeque<Piece>,
    /// Global index of `pieces[0]`.
    base: usize,
    tail: Tail,
    /// End of the last piece: the chain is defined up to here.
    covered: f64,
    /// Global index of the next received pair (knots i, i + 1) to follow.
    next_pair: usize,
    /// Received knots when the tail last left them (a newer one triggers a correction).
    seen: usize,
    /// Where the tail last left the received motion (s), while it has not come back.
    left: Option<f64>,
    pub(super) corrections: Corrections,
}

impl Chain {
    pub(super) fn new(settings: ChainSettings) -> Chain {
        Chain {
            settings,
            pieces: VecDeque::new(),
            base: 0,
            tail: Tail::Following,
            covered: f64::NAN,
            next_pair: 0,
            seen: 0,
            left: None,
            corrections: Corrections::default(),
        }
    }

    pub(super) fn tail(&self) -> Tail {
        self.tail
    }

    /// Extends the chain to cover `upto`, having emitted up to `emitted`; `knots` (global
    /// index of the first: `kbase`) are the received knots. A received knot newer than the
    /// tail's first bridges the chain back to the received motion from `emitted` on.
    pub(super) fn prepare(
        &mut self,
        knots: &VecDeque<Knot>,
        kbase: usize,
        emitted: f64,
        upto: f64,
    ) {
        let n = kbase + knots.len();
        if knots.is_empty() {
            return;
        }
        if self.pieces.is_empty() && self.covered.is_nan() {
            self.covered = knots[0].t;
            self.next_pair = kbase;
        }
        if self.tail != Tail::Following && n > self.seen {
            self.bridge(knots, kbase, emitted);
        }
        while self.covered < upto {
            if self.tail == Tail::Following {
                let i = self.next_pair.max(kbase);
                if i + 1 < n {
                    let (k0, k1) = (knots[i - kbase], knots[i + 1 - kbase]);
                    self.push(k0, k1, self.covered, k1.t);
                    self.next_pair = i + 1;
                    continue;
                }
                let k = knots[n - 1 - kbase];
                let e = taylor(&k, self.settings.max_extrapolation);
                self.push(k, e, self.covered, e.t);
                self.tail = Tail::Extrapolating;
                self.left = Some(k.t);
                self.corrections.departed.get_or_insert(k.t);
                self.seen = n;
            } else {
                let last = self.pieces.back().expect("a tail piece").k1;
                let k0 = held(&last);
                let k1 = taylor(&k0, self.settings.max_extrapolation.max(0.1));
                self.push(k0, k1, self.covered, k1.t);
                self.tail = Tail::Holding;
            }
        }
    }

    /// Switches to holding at `emitted` (the input is stale and the policy says hold).
    pub(super) fn hold_from(&mut self, emitted: f64) {
        if self.tail == Tail::Holding
            || emitted.partial_cmp(&self.covered) != Some(std::cmp::Ordering::Less)
        {
            return;
        }
        let c = self.cut_at(emitted);
        let k0 = held(&c);
        let k1 = taylor(&k0, self.settings.max_extrapolation.max(0.1));
        self.push(k0, k1, emitted, k1.t);
        self.tail = Tail::Holding;
        self.left.get_or_insert(emitted);
        self.corrections.departed.get_or_insert(emitted);
    }

    /// Drops what lies after `t` (never emitted) and returns the chain's knot at `t`.
    fn cut_at(&mut self, t: f64) -> Knot {
        while self.pieces.len() > 1 && self.pieces.back().is_some_and(|p| p.start >= t) {
            self.pieces.pop_back();
        }
        let last = self.pieces.back_mut().expect("a piece");
        last.end = last.end.min(t);
        self.covered = t;
        cut(&last.k0, &last.k1, t)
    }

    fn bridge(&mut self, knots: &VecDeque<Knot>, kbase: usize, emitted: f64) {
        let n = kbase + knots.len();
        self.seen = n;
        let t_e = emitted.max(self.pieces.front().map_or(emitted, |p| p.start));
        let c = self.cut_at(t_e);
        let now = reference(knots, self.settings.max_extrapolation, t_e);
        let co = &mut self.corrections;
        co.count += 1;
        if let Some(left) = self.left {
            co.longest = co.longest.max(t_e - left);
        }
        co.position = co.position.max((now.knot.r - c.r).norm());
        co.velocity = co.velocity.max((now.knot.v - c.v).norm());
        let (qa, qb) = (now.knot.q.normalize(), c.q.normalize());
        co.attitude = co
            .attitude
            .max(2.0 * (qa.conjugate() * qb).imag().norm().min(1.0).asin());
        // A horizon longer than the received motion is ahead of the output would always
        // end on an extrapolation, and every state would start another bridge: end at the
        // newest state instead, once it is a tenth of the horizon ahead.
        let h = self.settings.horizon;
        let newest = knots[knots.len() - 1].t;
        let t_b = if t_e + h > newest && newest - t_e >= h / 10.0 {
            newest
        } else {
            t_e + h
        };
        let target = reference(knots, self.settings.max_extrapolation, t_b);
        self.push(c, target.knot, t_e, t_b);
        self.corrections.rejoined = Some(t_b);
        match target.after {
            After::Pair(i) => {
                let (k0, k1) = (knots[i], knots[i + 1]);
                if k1.t > t_b {
                    self.push(k0, k1, t_b, k1.t);
                }
                self.next_pair = kbase + i + 1;
                self.tail = Tail::Following;
                self.left = None;
            }
            After::Extrapolation(pair) => {
                let (k0, k1) = *pair;
                self.push(k0, k1, t_b, k1.t);
                self.tail = Tail::Extrapolating;
                self.left = Some(newest);
            }
            After::Hold => {
                self.tail = Tail::Holding;
                self.left = Some(newest);
            }
        }
    }

    fn push(&mut self, k0: Knot, k1: Knot, start: f64, end: f64) {
        self.pieces.push_back(Piece { k0, k1, start, end });
        self.covered = end;
        if self.pieces.len() > KEEP {
            self.pieces.pop_front();
            self.base += 1;
        }
    }

    /// Index of the piece that holds `t` (`hint`: a previous answer).
    pub(super) fn piece_at(&self, t: f64, hint: usize) -> usize {
        let n = self.pieces.len();
        if n == 0 {
            return self.base;
        }
        let h = hint.saturating_sub(self.base).min(n - 1);
        let inside = |i: usize| self.pieces[i].start <= t && (i + 1 == n || t < self.pieces[i].end);
        if inside(h) {
            return self.base + h;
        }
        if h + 1 < n && inside(h + 1) {
            return self.base + h + 1;
        }
        let idx = self.pieces.partition_point(|p| p.start <= t);
        self.base + idx.saturating_sub(1)
    }

    /// End of piece `piece`; infinite for the last, which may still grow.
    pub(super) fn piece_end(&self, piece: usize) -> f64 {
        match piece.checked_sub(self.base) {
            Some(i) if i + 1 < self.pieces.len() => self.pieces[i].end,
            _ => f64::INFINITY,
        }
    }

    /// The emitted kinematic state on `piece` at `t`; `None` for a piece no longer held.
    pub(super) fn state(&self, piece: usize, t: f64) -> Option<EcefState> {
        let p = self.pieces.get(piece.checked_sub(self.base)?)?;
        Some(hermite(Degree::Quintic, &p.k0, &p.k1, t).0)
    }

    /// Error-free sensed values on `piece` at `t`.
    pub(super) fn sense(&self, piece: usize, t: f64) -> Option<Sensed> {
        self.state(piece, t).map(|s| sense_ecef(&s))
    }
}

/// What follows a correction bridge.
enum After {
    /// The received pair (i, i + 1), indices into the knots given.
    Pair(usize),
    /// The extrapolation piece of the newest knot.
    Extrapolation(Box<(Knot, Knot)>),
    /// Past the extrapolation bound.
    Hold,
}

struct Reference {
    knot: Knot,
    after: After,
}

/// The received motion at `t` (with its continuation): the received pieces up to the newest
/// knot, its extrapolation for `max_ext` seconds past it, then the hold.
fn reference(knots: &VecDeque<Knot>, max_ext: f64, t: f64) -> Reference {
    let last = knots[knots.len() - 1];
    if t <= last.t && knots.len() >= 2 {
        let i = knots
            .partition_point(|k| k.t <= t)
            .clamp(1, knots.len() - 1)
            - 1;
        return Reference {
            knot: cut(&knots[i], &knots[i + 1], t),
            after: After::Pair(i),
        };
    }
    let e = taylor(&last, max_ext);
    if t <= e.t {
        return Reference {
            knot: cut(&last, &e, t),
            after: After::Extrapolation(Box::new((last, e))),
        };
    }
    let h0 = held(&e);
    let h1 = taylor(&h0, (t - e.t).max(1e-9));
    Reference {
        knot: cut(&h0, &h1, t),
        after: After::Hold,
    }
}

/// The knot `dt` seconds after `k` on its Taylor continuation: constant jerk (r cubic, v
/// quadratic) and constant quaternion second derivative.
pub(super) fn taylor(k: &Knot, dt: f64) -> Knot {
    let (d2, d3) = (dt * dt / 2.0, dt * dt * dt / 6.0);
    Knot {
        t: k.t + dt,
        r: k.r + k.v * dt + k.a * d2 + k.j * d3,
        v: k.v + k.a * dt + k.j * d2,
        a: k.a + k.j * dt,
        j: k.j,
        q: k.q + k.qd * dt + k.qdd * d2,
        qd: k.qd + k.qdd * dt,
        qdd: k.qdd,
    }
}

/// The knot of `k` with zero jerk and zero angular acceleration: the motion continues with
/// `k`'s acceleration and angular rate (attitude renormalised: q̈ = q ⊗ (−|ω|²/4, 0)).
fn held(k: &Knot) -> Knot {
    let n2 = k.q.norm_squared();
    let q = k.q * (1.0 / n2.sqrt());
    let omega = (k.q.conjugate() * k.qd).imag() * (2.0 / n2);
    Knot {
        j: Vec3::zeros(),
        q,
        qd: q * Quat::from_parts(0.0, omega * 0.5),
        qdd: q * Quat::from_parts(-0.25 * omega.dot(&omega), Vec3::zeros()),
        ..*k
    }
}

/// The knot of the piece (k0, k1) at `t`: position, velocity and quaternion polynomials'
/// value, first and second derivative there, so a piece started from it continues the
/// piece to second order (the quaternion unnormalised, as the piece carries it).
pub(super) fn cut(k0: &Knot, k1: &Knot, t: f64) -> Knot {
    let h = k1.t - k0.t;
    let b = Basis2::new((t - k0.t) / h);
    let (h2, hi, hi2) = (h * h, 1.0 / h, 1.0 / (h * h));
    let dr = k1.r - k0.r;
    let dv = k1.v - k0.v;
    let dq = k1.q - k0.q;
    let r = k0.r
        + dr * b.v[0]
        + (k0.v * b.v[1] + k1.v * b.v[2]) * h
        + (k0.a * b.v[3] + k1.a * b.v[4]) * h2;
    let v = k0.v
        + dv * b.v[0]
        + (k0.a * b.v[1] + k1.a * b.v[2]) * h
        + (k0.j * b.v[3] + k1.j * b.v[4]) * h2;
    let a =
        dv * (b.d[0] * hi) + k0.a * b.d[1] + k1.a * b.d[2] + (k0.j * b.d[3] + k1.j * b.d[4]) * h;
    let j = dv * (b.dd[0] * hi2)
        + (k0.a * b.dd[1] + k1.a * b.dd[2]) * hi
        + k0.j * b.dd[3]
        + k1.j * b.dd[4];
    let q = k0.q
        + dq * b.v[0]
        + (k0.qd * b.v[1] + k1.qd * b.v[2]) * h
        + (k0.qdd * b.v[3] + k1.qdd * b.v[4]) * h2;
    let qd = dq * (b.d[0] * hi)
        + k0.qd * b.d[1]
        + k1.qd * b.d[2]
        + (k0.qdd * b.d[3] + k1.qdd * b.d[4]) * h;
    let qdd = dq * (b.dd[0] * hi2)
        + (k0.qd * b.dd[1] + k1.qd * b.dd[2]) * hi
        + k0.qdd * b.dd[3]
        + k1.qdd * b.dd[4];
    Knot {
        t,
        r,
        v,
        a,
        j,
        q,
        qd,
        qdd,
    }
}

/// The quintic Hermite basis (h1, g0, g1, k0, k1 of [`super::sampled`]) on s ∈ [0, 1]: values,
/// first and second s-derivatives.
struct Basis2 {
    v: [f64; 5],
    d: [f64; 5],
    dd: [f64; 5],
}

impl Basis2 {
    fn new(s: f64) -> Basis2 {
        let (s2, s3) = (s * s, s * s * s);
        let (s4, s5) = (s3 * s, s3 * s2);
        Basis2 {
            v: [
                10.0 * s3 - 15.0 * s4 + 6.0 * s5,
                s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5,
                -4.0 * s3 + 7.0 * s4 - 3.0 * s5,
                0.5 * (s2 - 3.0 * s3 + 3.0 * s4 - s5),
                0.5 * (s3 - 2.0 * s4 + s5),
            ],
            d: [
                30.0 * s2 - 60.0 * s3 + 30.0 * s4,
                1.0 - 18.0 * s2 + 32.0 * s3 - 15.0 * s4,
                -12.0 * s2 + 28.0 * s3 - 15.0 * s4,
                0.5 * (2.0 * s - 9.0 * s2 + 12.0 * s3 - 5.0 * s4),
                0.5 * (3.0 * s2 - 8.0 * s3 + 5.0 * s4),
            ],
            dd: [
                60.0 * s - 180.0 * s2 + 120.0 * s3,
                -36.0 * s + 96.0 * s2 - 60.0 * s3,
                -24.0 * s + 84.0 * s2 - 60.0 * s3,
                0.5 * (2.0 - 18.0 * s + 36.0 * s2 - 20.0 * s3),
                0.5 * (6.0 * s - 24.0 * s2 + 20.0 * s3),
            ],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::sampled::{Conv, knot_at};
    use super::*;
    use crate::earth::Geodetic;
    use crate::math::QuatExt;

    /// A closed-form motion: ECEF position a cubic in time from `t0` (jerk `j`), attitude
    /// turning at the constant body rate `w`; `knot(t)` is its exact knot.
    #[derive(Clone, Copy)]
    struct Poly {
        t0: f64,
        r: Vec3,
        v: Vec3,
        a: Vec3,
        j: Vec3,
        q: Quat,
        w: Vec3,
    }

    impl Poly {
        fn a() -> Poly {
            Poly {
                t0: 0.0,
                r: Geodetic::from_radians(0.8, 0.12, 300.0).to_ecef(),
                v: Vec3::new(50.0, -30.0, 20.0),
                a: Vec3::new(1.0, -2.0, 0.5),
                j: Vec3::new(0.1, 0.05, -0.02),
                q: Quat::from_rotvec(Vec3::new(0.3, -1.2, 2.0)),
                w: Vec3::new(0.02, -0.05, 0.3),
            }
        }
        fn knot(&self, t: f64) -> Knot {
            let d = t - self.t0;
            let c = Conv {
                t,
                r: self.r + self.v * d + self.a * (d * d / 2.0) + self.j * (d * d * d / 6.0),
                v: self.v + self.a * d + self.j * (d * d / 2.0),
                q: self.q * Quat::from_rotvec(self.w * d),
            };
            knot_at(&c, self.a + self.j * d, self.j, self.w, Vec3::zeros())
        }
        /// The motion from `t` on with the jerk changed by `dj` and the rate by `dw`.
        fn turn(&self, t: f64, dj: Vec3, dw: Vec3) -> Poly {
            let k = self.knot(t);
            Poly {
                t0: t,
                r: k.r,
                v: k.v,
                a: k.a,
                j: self.j + dj,
                q: k.q,
                w: self.w + dw,
            }
        }
    }

    fn state(k0: &Knot, k1: &Knot, t: f64) -> (EcefState, Vec3) {
        hermite(Degree::Quintic, k0, k1, t)
    }

    /// Largest differences (position m, velocity m/s, acceleration m/s², attitude, rate rad/s).
    fn diff(x: &(EcefState, Vec3), y: &(EcefState, Vec3)) -> [f64; 5] {
        let dq = (x.0.q_b_e.conjugate() * y.0.q_b_e).imag().norm() * 2.0;
        [
            (x.1 - y.1).amax(),
            (x.0.v_e - y.0.v_e).amax(),
            (x.0.a_e - y.0.a_e).amax(),
            dq,
            (x.0.omega_eb_b - y.0.omega_eb_b).amax(),
        ]
    }

    /// Round-off bounds for ECEF positions of 6.4e6 m (ulp 1e-9 m), velocities of 60 m/s and
    /// pieces 10–250 ms long (the basis divides by h and h²).
    const TOL: [f64; 5] = [1e-7, 1e-10, 1e-7, 1e-13, 1e-11];

    fn assert_close(what: &str, d: [f64; 5]) {
        for (i, (x, tol)) in d.iter().zip(TOL).enumerate() {
            assert!(
                *x <= tol,
                "{what}: component {i} differs by {x:e} (tol {tol:e})"
            );
        }
    }

    /// A piece started from the cut knot continues the cut piece: same velocity,
    /// acceleration, attitude and rate to round-off, the same position at the cut (the cut carries the exact second
    /// derivatives; a wrong second-derivative basis misses by ~h²·j ≫ the tolerance).
    #[test]
    fn cut_continues_the_piece() {
        let p = Poly::a();
        let k0 = p.knot(0.0);
        let mut k1 = p.knot(0.01);
        // Not the cubic any more: the piece is a full quintic in every component.
        k1.a += Vec3::new(0.3, -0.2, 0.1);
        k1.j += Vec3::new(5.0, 2.0, -3.0);
        k1.qdd += Quat::new(0.01, -0.02, 0.03, 0.005);
        let c = cut(&k0, &k1, 0.0037);
        for t in [0.0037, 0.005, 0.008, 0.01] {
            let mut d = diff(&state(&k0, &k1, t), &state(&c, &k1, t));
            // Position and velocity are separate Hermite polynomials: the cut carries the
            // velocity polynomial's value as the position's slope, so past the cut the
            // position follows the emitted velocity, not the first piece's position
            // polynomial (they differ where the knots are not one polynomial motion, as here).
            if t > 0.0037 {
                d[0] = 0.0;
            }
            assert_close(&format!("t = {t}"), d);
        }
    }

    /// Extrapolation reproduces a cubic motion exactly (position, velocity, acceleration),
    /// and the quaternion's Taylor quadratic, normalised.
    #[test]
    fn extrapolation_is_the_taylor_continuation() {
        let p = Poly::a();
        let k = p.knot(1.0);
        let e = taylor(&k, 0.25);
        for t in [1.0, 1.05, 1.2, 1.25] {
            let got = state(&k, &e, t);
            let want = p.knot(t);
            assert!((got.1 - want.r).amax() < 1e-7, "r at {t}");
            assert!((got.0.v_e - want.v).amax() < 1e-10, "v at {t}");
            assert!((got.0.a_e - want.a).amax() < 1e-10, "a at {t}");
            let d = t - 1.0;
            let q = (k.q + k.qd * d + k.qdd * (d * d / 2.0)).normalize();
            assert!((got.0.q_b_e.coords - q.coords).amax() < 1e-14, "q at {t}");
        }
    }

    /// The late-state case: states up to 0.1 s, the chain extrapolates to 0.13 s; states
    /// then arrive from a motion whose jerk and rate changed at 0.1 s. The chain bridges from
    /// 0.13 s to the received motion at 0.13 s + horizon: continuous in position, velocity,
    /// acceleration, attitude and rate at both ends, the correction reported is the
    /// closed-form deviation, and the acceleration over the bridge stays within the bound of
    /// its Hermite weights.
    #[test]
    fn late_state_bridges_without_steps() {
        let (h, dt) = (0.05, 0.01);
        let a = Poly::a();
        let (dj, dw) = (Vec3::new(2.0, -1.0, 3.0), Vec3::new(0.0, 0.01, -0.02));
        let b = a.turn(0.1, dj, dw);
        let mut knots: VecDeque<Knot> = (0..=10).map(|i| a.knot(i as f64 * dt)).collect();
        let mut c = Chain::new(ChainSettings {
            horizon: h,
            max_extrapolation: 0.25,
        });
        c.prepare(&knots, 0, 0.0, 0.05);
        assert_eq!(c.tail(), Tail::Following);
        let i = c.piece_at(0.033, 0);
        let got = c.state(i, 0.033).unwrap();
        let want = state(&knots[3], &knots[4], 0.033).0;
        assert_eq!(
            (got.v_e, got.a_e, got.q_b_e),
            (want.v_e, want.a_e, want.q_b_e)
        );
        c.prepare(&knots, 0, 0.05, 0.13);
        assert_eq!(c.tail(), Tail::Extrapolating);
        // The late states arrive.
        knots.extend((11..=20).map(|i| b.knot(i as f64 * dt)));
        let (t_e, t_b) = (0.13, 0.13 + h);
        let before = c.piece_at(t_e - 1e-9, 0);
        c.prepare(&knots, 0, t_e, 0.2);
        assert_eq!(c.tail(), Tail::Following);
        let bridge = c.piece_at(t_e, before);
        assert_eq!(bridge, before + 1);
        let at = |p: usize, t: f64| {
            let pc = &c.pieces[p - c.base];
            state(&pc.k0, &pc.k1, t)
        };
        assert_close("at the cut", diff(&at(before, t_e), &at(bridge, t_e)));
        let after = c.piece_at(t_b, bridge);
        assert_eq!(after, bridge + 1);
        assert_close(
            "at the bridge's end",
            diff(&at(bridge, t_b), &at(after, t_b)),
        );
        let truth = |t: f64| {
            let k = b.knot(t);
            (k.r, k.v, k.a)
        };
        let (r_b, v_b, _) = truth(t_b);
        assert!((at(after, t_b).1 - r_b).amax() < 1e-7);
        assert!((at(after, t_b).0.v_e - v_b).amax() < 1e-10);
        // The correction: the extrapolation of a cubic is the cubic, so the deviation at the
        // cut is the changed jerk's: Δr = |dj|·0.03³/6, Δv = |dj|·0.03²/2.
        let co = c.corrections;
        assert_eq!(co.count, 1);
        let d = t_e - 0.1;
        // The output left the received motion at the newest knot then, 0.1 s, and ran 30 ms
        // past it before the bridge.
        assert_eq!(co.departed, Some(0.1));
        assert!((co.longest - d).abs() < 1e-15, "{}", co.longest);
        assert_eq!(co.rejoined, Some(t_b));
        // Positions are ECEF coordinates of 6.4e6 m (ulp 1e-9 m) against Δr ≈ 1.7e-5 m.
        assert!((co.position / (dj.norm() * d.powi(3) / 6.0) - 1.0).abs() < 1e-3);
        assert!((co.velocity / (dj.norm() * d * d / 2.0) - 1.0).abs() < 1e-8);
        // Attitude: the extrapolated quaternion (Taylor quadratic of knot 0.1 s, normalised)
        // against the received one.
        let k = knots[10];
        let q_x = (k.q + k.qd * d + k.qdd * (d * d / 2.0)).normalize();
        let q_r = b.knot(t_e).q;
        let want = 2.0 * (q_x.conjugate() * q_r).imag().norm().asin();
        assert!((co.attitude / want - 1.0).abs() < 1e-9, "{co:?} vs {want}");
        // Over the bridge the velocity difference is the quintic Hermite blend of its values
        // at the cut (Δv, Δa, Δj) down to zero, so its derivative is bounded by
        // max|h1'|·|Δv|/H + max|g0'|·|Δa| + max|k0'|·|Δj|·H = 1.875·|Δv|/H + |Δa| + 0.07·|Δj|·H.
        let (dv0, da0) = (dj * (d * d / 2.0), dj * d);
        let bound = 1.875 * dv0.amax() / h + da0.amax() + 0.07 * dj.amax() * h;
        let mut worst = 0.0f64;
        for m in 0..=100 {
            let t = t_e + h * m as f64 / 100.0;
            worst = worst.max((at(bridge, t).0.a_e - truth(t).2).amax());
        }
        eprintln!("bridge: worst acceleration difference {worst:e}, bound {bound:e}");
        assert!(worst <= bound * (1.0 + 1e-9), "{worst} > {bound}");
        assert!(
            worst > 0.3 * bound,
            "{worst} ≪ {bound}: the bridge does not correct"
        );
    }
}
