//! A trajectory sample and the knots the motion models are built from: the sample in SI
//! units, its Earth-fixed form, the Hermite end conditions of a piece (a knot, from a
//! finite-difference stencil), the model's settings and why it cannot be built. Its own module
//! because the sampled model (`sampled`), its sliding window (`stream`), the live model
//! (`causal`) and the input limits (`limits`) all use them, and `sampled` uses `stream`.

use std::ops::Range;

use super::fd::fornberg;
use crate::csvio::{num, num_sig};
use crate::earth::Geodetic;
use crate::math::{Quat, QuatExt, Vec3};

/// Longest step a model bridges, as a multiple of the steps beside it: states lost in a row
/// on a lossy link (a hundred) pass; a tag off the time line — a clock in µs read as s, a
/// stray GPS time among simulation seconds — lands orders of magnitude further. A live model
/// (`CausalMotion::refuse_gaps`) refuses a longer step after the stencil before it; a
/// trajectory file's model (`stream::IndexBuilder`) splits the samples there and bridges the
/// gap with one Hermite piece between its two sides. Either way the bridge is an
/// interpolation, not the motion.
pub const GAP_FACTOR: f64 = 100.0;

/// One trajectory sample, in SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// Geodetic latitude (rad).
    pub lat: f64,
    /// Longitude (rad).
    pub lon: f64,
    /// Ellipsoidal height (m).
    pub h: f64,
    /// Velocity NED (m/s).
    pub v_n: Vec3,
    /// Attitude C_b^n.
    pub q_b_n: Quat,
}

/// Polynomial degree of the piecewise model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Degree {
    /// Cubic Hermite: value and first derivative continuous.
    Cubic,
    /// Quintic Hermite: value, first and second derivative continuous.
    Quintic,
}

/// How the model is built from the samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelSettings {
    /// Polynomial degree.
    pub degree: Degree,
    /// Number of samples in each finite-difference stencil for the knot derivatives.
    pub stencil: usize,
}

impl Default for ModelSettings {
    fn default() -> Self {
        ModelSettings {
            degree: Degree::Quintic,
            stencil: 9,
        }
    }
}

impl ModelSettings {
    /// Fewest samples the model can be built from.
    pub fn min_samples(&self) -> usize {
        self.stencil.max(3)
    }
}

/// The model between two samples is fixed by these values at each end.
#[derive(Clone, Copy, Debug)]
pub(super) struct Knot {
    pub(super) t: f64,
    pub(super) r: Vec3,
    pub(super) v: Vec3,
    pub(super) a: Vec3,
    pub(super) j: Vec3,
    pub(super) q: Quat,
    pub(super) qd: Quat,
    pub(super) qdd: Quat,
}

impl Knot {
    /// A knot whose every value is NaN: what a model that lost its input evaluates to.
    pub(super) const NAN: Knot = {
        let v = Vec3::new(f64::NAN, f64::NAN, f64::NAN);
        let q = Quat::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN);
        Knot {
            t: f64::NAN,
            r: v,
            v,
            a: v,
            j: v,
            q,
            qd: q,
            qdd: q,
        }
    };
}

/// A sample in Earth-fixed quantities: time, r^e, ṙ^e and C_b^e.
#[derive(Clone, Copy, Debug)]
pub(super) struct Conv {
    pub(super) t: f64,
    pub(super) r: Vec3,
    pub(super) v: Vec3,
    pub(super) q: Quat,
}

impl Conv {
    /// A sample that could not be read.
    pub(super) const NAN: Conv = {
        let v = Vec3::new(f64::NAN, f64::NAN, f64::NAN);
        Conv {
            t: f64::NAN,
            r: v,
            v,
            q: Quat::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN),
        }
    };
}

/// Converts a sample; `prev_q` is the previous sample's C_b^e, whose hemisphere it keeps so
/// that the R⁴ curve is continuous.
pub(super) fn convert(s: &Sample, prev_q: Option<Quat>) -> Conv {
    let g = Geodetic::from_radians(s.lat, s.lon, s.h);
    let mut q = g.q_n_e() * s.q_b_n;
    if let Some(prev) = prev_q
        && prev.dot(&q) < 0.0
    {
        q = -q;
    }
    Conv {
        t: s.t,
        r: g.to_ecef(),
        v: g.c_n_e() * s.v_n,
        q,
    }
}

/// Knot `i` from the converted samples of its stencil `st` (`at(k)` is sample k).
pub(super) fn make_knot<'a>(i: usize, st: Range<usize>, at: impl Fn(usize) -> &'a Conv) -> Knot {
    let t: Vec<f64> = st.clone().map(|k| at(k).t).collect();
    let c = at(i);
    let w = fornberg(c.t, &t, 2);
    let mut a = Vec3::zeros();
    let mut j = Vec3::zeros();
    let mut omega = Vec3::zeros();
    let mut omega_dot = Vec3::zeros();
    let phi: Vec<Vec3> = st
        .clone()
        .map(|k| (c.q.conjugate() * at(k).q).to_rotvec())
        .collect();
    for (m, k) in st.enumerate() {
        // Velocity differences relative to the centre keep the sums well scaled.
        let dv = at(k).v - c.v;
        a += dv * w[1][m];
        j += dv * w[2][m];
    }
    for (m, p) in phi.iter().enumerate() {
        omega += *p * w[1][m];
        omega_dot += *p * w[2][m];
    }
    knot_at(c, a, j, omega, omega_dot)
}

/// The knot at converted sample `c` with acceleration `a`, jerk `j`, body rate `omega` and
/// its derivative `omega_dot` (all in the rotation-vector chart centred on `c`).
pub(super) fn knot_at(c: &Conv, a: Vec3, j: Vec3, omega: Vec3, omega_dot: Vec3) -> Knot {
    // q̇ = ½ q ⊗ ω and q̈ = q ⊗ (−|ω|²/4, ω̇/2): consistent with |q| = 1 to second order.
    let qd = c.q * Quat::from_parts(0.0, omega * 0.5);
    let qdd = c.q * Quat::from_parts(-0.25 * omega.dot(&omega), omega_dot * 0.5);
    Knot {
        t: c.t,
        r: c.r,
        v: c.v,
        a,
        j,
        q: c.q,
        qd,
        qdd,
    }
}

/// Samples between two gaps (or a gap and an end) too few to fill a finite-difference
/// stencil, so the model cannot bridge the gap (see [`super::stream::IndexBuilder`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Isolated {
    /// Zero-based index of the first of them.
    pub first: usize,
    /// Zero-based index of the last of them.
    pub last: usize,
    /// Time of the first (s).
    pub t_first: f64,
    /// Time of the last (s).
    pub t_last: f64,
    /// The gap before them (s), if they do not start the series.
    pub before: Option<f64>,
    /// The gap after them (s), if they do not end the series.
    pub after: Option<f64>,
    /// Samples a stencil needs.
    pub need: usize,
}

/// Without the place: the caller names it.
impl std::fmt::Display for Isolated {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let count = self.last + 1 - self.first;
        let (t0, t1) = (num(self.t_first), num(self.t_last));
        let which = if count == 1 {
            format!("the sample at t = {t0} s lies")
        } else {
            format!("the {count} samples at t = {t0} … {t1} s lie")
        };
        let side = |gap: Option<f64>, end: &str| match gap {
            Some(g) => format!("a gap of {} s", num_sig(g, 4)),
            None => end.to_string(),
        };
        write!(
            f,
            "{which} between {} and {} (a gap is a step more than {} times the steps beside \
             it); the motion model needs {} samples on each side of a gap to bridge it: fill the \
             gap or cut the file there",
            side(self.before, "the start"),
            side(self.after, "the end"),
            num(GAP_FACTOR),
            self.need,
        )
    }
}

/// Why a motion model could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// Fewer samples than the finite-difference stencil needs.
    #[error("{got} samples, but the motion model needs at least {need}")]
    TooFewSamples {
        /// Samples given.
        got: usize,
        /// Samples needed.
        need: usize,
    },
    /// Time does not strictly increase.
    #[error("time does not increase at sample {index}")]
    NonIncreasingTime {
        /// Zero-based sample index.
        index: usize,
    },
    /// Samples alone between gaps.
    #[error("{0}")]
    Isolated(Isolated),
    /// A value beyond the physical limits of [`super::limits`].
    #[error("sample {index}: `{column}`: {message}")]
    Limit {
        /// Zero-based sample index.
        index: usize,
        /// The trajectory column concerned.
        column: &'static str,
        /// What is wrong.
        message: String,
    },
}
