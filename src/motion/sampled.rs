//! The motion model of a sampled trajectory (a CSV file): piecewise Hermite polynomials in the
//! Earth-fixed frame, with knot derivatives from high-order finite differences.
//!
//! Why this shape (docs/motion-model.md has the measurements):
//! * **Earth-fixed (ECEF) quantities** — position r^e, velocity ṙ^e and attitude C_b^e are
//!   smooth through the poles and across the ±180° heading wrap, where NED values jump.
//! * **Specific force from the velocity samples, never from positions.** A position in
//!   degrees carries ~1e-9 m of rounding; differentiating it twice over 10 ms amplifies that
//!   to ~1e-5 m/s². Velocities carry ~1e-14 m/s, so r̈^e = d/dt of the velocity model is clean.
//!   Positions feed only gravity and the Earth-rate terms, which are insensitive to nanometres.
//! * **Attitude in quaternion components**, a Hermite polynomial in R⁴ renormalised; the knot
//!   rates ω and ω̇ are estimated in the rotation-vector chart centred on each knot, where they
//!   are exactly φ̇ and φ̈, so the estimates keep full relative precision.
//! * **Quintic Hermite** (value, first and second derivative matched at both knots) gives a
//!   model whose ω and specific force are continuous with continuous derivatives across knots;
//!   the cubic variant (value and first derivative) is kept for the accuracy/cost table.

use std::ops::Range;
use std::sync::{Arc, Mutex};

use super::fd::fornberg;
use super::stream::{Index, IndexBuilder, Mark, MemorySamples, SampleSource, Window};
use super::{Motion, Pose};
use crate::earth::{Geodetic, ecef_to_geodetic};
use crate::kinematics::{EcefState, Sensed, sense_ecef};
use crate::math::{Quat, QuatExt, Vec3};

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

/// A sampled trajectory turned into a continuous, piecewise-polynomial motion. The knots are
/// computed on demand in a sliding window over the samples (see [`super::stream`]), so a
/// model of a file of any length holds a bounded number of them.
pub struct SampledMotion {
    degree: Degree,
    index: Arc<Index>,
    pub(super) window: Mutex<Window>,
}

impl Clone for SampledMotion {
    /// An independent model over the same samples (its own window and read position).
    fn clone(&self) -> Self {
        SampledMotion {
            degree: self.degree,
            index: self.index.clone(),
            window: Mutex::new(self.lock().fork()),
        }
    }
}

impl std::fmt::Debug for SampledMotion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SampledMotion")
            .field("degree", &self.degree)
            .field("samples", &self.index.len())
            .finish_non_exhaustive()
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

impl SampledMotion {
    /// Builds the model of samples held in memory. The samples must have strictly increasing
    /// time and respect the limits of [`super::limits`].
    pub fn new(samples: &[Sample], settings: ModelSettings) -> Result<SampledMotion, ModelError> {
        let mut b = IndexBuilder::new(settings);
        for (i, s) in samples.iter().enumerate() {
            b.push(s, Mark(i as u64, 0))?;
        }
        let source = Box::new(MemorySamples {
            samples: Arc::new(samples.to_vec()),
            next: 0,
        });
        Ok(SampledMotion::from_source(source, b.finish()?, settings))
    }

    /// The model of the samples `source` delivers, which `index` describes (built by an
    /// [`IndexBuilder`] over the same samples).
    pub fn from_source(
        source: Box<dyn SampleSource>,
        index: Index,
        settings: ModelSettings,
    ) -> SampledMotion {
        let index = Arc::new(index);
        SampledMotion {
            degree: settings.degree,
            window: Mutex::new(Window::new(source, index.clone())),
            index,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// Always false: a model has at least `min_samples` samples.
    pub fn is_empty(&self) -> bool {
        self.index.len() == 0
    }

    /// Why the samples could not be read again after the model was built (the file changed
    /// or vanished); the model then evaluates to NaN.
    pub fn failure(&self) -> Option<String> {
        self.lock().failure()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Window> {
        // A panic elsewhere cannot leave the window inconsistent: every update is complete.
        self.window.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Full ECEF state at t between knots `k0` and `k1`.
    #[inline]
    fn state(&self, k0: &Knot, k1: &Knot, t: f64) -> (EcefState, Vec3) {
        hermite(self.degree, k0, k1, t)
    }
}

/// Full ECEF state (and r^e) at t on the Hermite piece of `degree` between knots `k0` and
/// `k1`: the one evaluation the file model and the live model share.
#[inline]
pub(super) fn hermite(degree: Degree, k0: &Knot, k1: &Knot, t: f64) -> (EcefState, Vec3) {
    let h = k1.t - k0.t;
    let s = (t - k0.t) / h;
    let b = Basis::new(degree, s);
    let dr = k1.r - k0.r;
    let r_rel = dr * b.h1 + (k0.v * b.g0 + k1.v * b.g1) * h + (k0.a * b.k0 + k1.a * b.k1) * (h * h);
    let dv = k1.v - k0.v;
    let v =
        k0.v + dv * b.h1 + (k0.a * b.g0 + k1.a * b.g1) * h + (k0.j * b.k0 + k1.j * b.k1) * (h * h);
    let a = dv * (b.dh1 / h) + k0.a * b.dg0 + k1.a * b.dg1 + (k0.j * b.dk0 + k1.j * b.dk1) * h;
    let dq = k1.q - k0.q;
    let p = k0.q
        + dq * b.h1
        + (k0.qd * (b.g0 * h) + k1.qd * (b.g1 * h))
        + (k0.qdd * (b.k0 * h * h) + k1.qdd * (b.k1 * h * h));
    let pd = dq * (b.dh1 / h)
        + (k0.qd * b.dg0 + k1.qd * b.dg1)
        + (k0.qdd * (b.dk0 * h) + k1.qdd * (b.dk1 * h));
    let n2 = p.norm_squared();
    // For q = p/|p|: ω = 2 vec(q* ⊗ q̇) = 2 vec(p* ⊗ ṗ)/|p|².
    let omega_eb_b = (p.conjugate() * pd).imag() * (2.0 / n2);
    let q_b_e = p * (1.0 / n2.sqrt());
    let r = k0.r + r_rel;
    let pos = ecef_to_geodetic(r);
    (
        EcefState {
            pos,
            v_e: v,
            a_e: a,
            q_b_e,
            omega_eb_b,
        },
        r,
    )
}

/// Hermite basis functions on s ∈ [0, 1] and their s-derivatives.
struct Basis {
    h1: f64,
    g0: f64,
    g1: f64,
    k0: f64,
    k1: f64,
    dh1: f64,
    dg0: f64,
    dg1: f64,
    dk0: f64,
    dk1: f64,
}

impl Basis {
    #[inline]
    fn new(degree: Degree, s: f64) -> Basis {
        let s2 = s * s;
        let s3 = s2 * s;
        match degree {
            Degree::Cubic => Basis {
                h1: 3.0 * s2 - 2.0 * s3,
                g0: s - 2.0 * s2 + s3,
                g1: s3 - s2,
                k0: 0.0,
                k1: 0.0,
                dh1: 6.0 * s - 6.0 * s2,
                dg0: 1.0 - 4.0 * s + 3.0 * s2,
                dg1: 3.0 * s2 - 2.0 * s,
                dk0: 0.0,
                dk1: 0.0,
            },
            Degree::Quintic => {
                let s4 = s3 * s;
                let s5 = s4 * s;
                Basis {
                    h1: 10.0 * s3 - 15.0 * s4 + 6.0 * s5,
                    g0: s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5,
                    g1: -4.0 * s3 + 7.0 * s4 - 3.0 * s5,
                    k0: 0.5 * (s2 - 3.0 * s3 + 3.0 * s4 - s5),
                    k1: 0.5 * (s3 - 2.0 * s4 + s5),
                    dh1: 30.0 * s2 - 60.0 * s3 + 30.0 * s4,
                    dg0: 1.0 - 18.0 * s2 + 32.0 * s3 - 15.0 * s4,
                    dg1: -12.0 * s2 + 28.0 * s3 - 15.0 * s4,
                    dk0: 0.5 * (2.0 * s - 9.0 * s2 + 12.0 * s3 - 5.0 * s4),
                    dk1: 0.5 * (3.0 * s2 - 8.0 * s3 + 5.0 * s4),
                }
            }
        }
    }
}

impl Motion for SampledMotion {
    fn start(&self) -> f64 {
        self.index.first_time()
    }
    fn end(&self) -> f64 {
        self.index.last_time()
    }
    fn piece_at(&self, t: f64, hint: usize) -> usize {
        self.lock().piece_at(t, hint)
    }
    fn piece_end(&self, piece: usize) -> f64 {
        if piece + 2 >= self.index.len() {
            f64::INFINITY
        } else {
            self.lock().knot(piece + 1).t
        }
    }
    #[inline]
    fn sense(&self, piece: usize, t: f64) -> Sensed {
        let mut w = self.lock();
        let (k0, k1) = w.pair(piece);
        sense_ecef(&self.state(k0, k1, t).0)
    }
    fn pose(&self, t: f64) -> Pose {
        let mut w = self.lock();
        let i = w.piece_at(t, 0);
        let (k0, k1) = w.pair(i);
        let (s, _) = self.state(k0, k1, t);
        let q_n_e = s.pos.q_n_e();
        Pose {
            t,
            lat: s.pos.lat(),
            lon: s.pos.lon(),
            h: s.pos.h,
            v_n: s.pos.c_n_e().tr_mul(&s.v_e),
            q_b_n: q_n_e.conjugate() * s.q_b_e,
        }
    }
}
