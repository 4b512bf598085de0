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

use std::sync::{Arc, Mutex};

pub(super) use super::knot::{Conv, Knot, convert, knot_at};
pub use super::knot::{Degree, ModelError, ModelSettings, Sample};
use super::stream::{Index, IndexBuilder, Mark, MemorySamples, SampleSource, Window};
use super::{Motion, Pose};
use crate::earth::ecef_to_geodetic;
use crate::kinematics::{EcefState, Sensed, sense_ecef};
use crate::math::Vec3;

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
