//! The motion model of a sampled trajectory (a CSV file): piecewise Hermite polynomials in the
//! Earth-fixed frame, with knot derivatives from high-order finite differences.
//!
//! Why this shape (README "Motion model" has the measurements):
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

use super::fd::{fornberg, stencil};
use super::{Motion, Pose};
use crate::earth::{Geodetic, ecef_to_geodetic};
use crate::kinematics::{EcefState, Sensed, sense_ecef};
use crate::math::{Quat, Vec3};

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

#[derive(Clone, Copy, Debug)]
struct Knot {
    t: f64,
    r: Vec3,
    v: Vec3,
    a: Vec3,
    j: Vec3,
    q: Quat,
    qd: Quat,
    qdd: Quat,
}

/// A sampled trajectory turned into a continuous, piecewise-polynomial motion.
#[derive(Clone, Debug)]
pub struct SampledMotion {
    knots: Vec<Knot>,
    degree: Degree,
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
}

impl SampledMotion {
    /// Builds the model. The samples must have strictly increasing time.
    pub fn new(samples: &[Sample], settings: ModelSettings) -> Result<SampledMotion, ModelError> {
        let n = samples.len();
        if n < settings.min_samples() {
            return Err(ModelError::TooFewSamples {
                got: n,
                need: settings.min_samples(),
            });
        }
        if let Some(i) = (1..n).find(|&i| {
            samples[i].t.partial_cmp(&samples[i - 1].t) != Some(std::cmp::Ordering::Greater)
        }) {
            return Err(ModelError::NonIncreasingTime { index: i });
        }
        let t: Vec<f64> = samples.iter().map(|s| s.t).collect();
        let mut r = Vec::with_capacity(n);
        let mut v = Vec::with_capacity(n);
        let mut q: Vec<Quat> = Vec::with_capacity(n);
        for s in samples {
            let g = Geodetic::from_radians(s.lat, s.lon, s.h);
            r.push(g.to_ecef());
            v.push(g.c_n_e().mul_vec(s.v_n));
            let mut qe = g.q_n_e().mul(s.q_b_n);
            // Same hemisphere as the previous knot, so the R⁴ curve is continuous.
            if let Some(prev) = q.last()
                && prev.dot4(qe) < 0.0
            {
                qe = qe.scale(-1.0);
            }
            q.push(qe);
        }
        let mut knots = Vec::with_capacity(n);
        let mut phi = Vec::with_capacity(settings.stencil);
        for i in 0..n {
            let st = stencil(i, settings.stencil, n);
            let w = fornberg(t[i], &t[st.clone()], 2);
            let mut a = Vec3::ZERO;
            let mut j = Vec3::ZERO;
            phi.clear();
            for (m, k) in st.clone().enumerate() {
                // Velocity differences relative to the centre keep the sums well scaled.
                let dv = v[k] - v[i];
                a += dv * w[1][m];
                j += dv * w[2][m];
                phi.push(q[i].conj().mul(q[k]).to_rotvec());
            }
            let mut omega = Vec3::ZERO;
            let mut omega_dot = Vec3::ZERO;
            for (m, p) in phi.iter().enumerate() {
                omega += *p * w[1][m];
                omega_dot += *p * w[2][m];
            }
            // q̇ = ½ q ⊗ ω and q̈ = q ⊗ (−|ω|²/4, ω̇/2): consistent with |q| = 1 to second order.
            let qd = q[i].mul(Quat {
                w: 0.0,
                v: omega * 0.5,
            });
            let qdd = q[i].mul(Quat {
                w: -0.25 * omega.dot(omega),
                v: omega_dot * 0.5,
            });
            knots.push(Knot {
                t: t[i],
                r: r[i],
                v: v[i],
                a,
                j,
                q: q[i],
                qd,
                qdd,
            });
        }
        Ok(SampledMotion {
            knots,
            degree: settings.degree,
        })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.knots.len()
    }

    /// Always false: a model has at least `min_samples` samples.
    pub fn is_empty(&self) -> bool {
        self.knots.is_empty()
    }

    /// Full ECEF state at t on segment i (knots i and i+1).
    #[inline]
    fn state(&self, i: usize, t: f64) -> (EcefState, Vec3) {
        let k0 = &self.knots[i];
        let k1 = &self.knots[i + 1];
        let h = k1.t - k0.t;
        let s = (t - k0.t) / h;
        let b = Basis::new(self.degree, s);
        let dr = k1.r - k0.r;
        let r_rel =
            dr * b.h1 + (k0.v * b.g0 + k1.v * b.g1) * h + (k0.a * b.k0 + k1.a * b.k1) * (h * h);
        let dv = k1.v - k0.v;
        let v = k0.v
            + dv * b.h1
            + (k0.a * b.g0 + k1.a * b.g1) * h
            + (k0.j * b.k0 + k1.j * b.k1) * (h * h);
        let a = dv * (b.dh1 / h) + k0.a * b.dg0 + k1.a * b.dg1 + (k0.j * b.dk0 + k1.j * b.dk1) * h;
        let dq = k1.q.add(k0.q.scale(-1.0));
        let p =
            k0.q.add(dq.scale(b.h1))
                .add(k0.qd.scale(b.g0 * h).add(k1.qd.scale(b.g1 * h)))
                .add(k0.qdd.scale(b.k0 * h * h).add(k1.qdd.scale(b.k1 * h * h)));
        let pd = dq
            .scale(b.dh1 / h)
            .add(k0.qd.scale(b.dg0).add(k1.qd.scale(b.dg1)))
            .add(k0.qdd.scale(b.dk0 * h).add(k1.qdd.scale(b.dk1 * h)));
        let n2 = p.norm2();
        // For q = p/|p|: ω = 2 vec(q* ⊗ q̇) = 2 vec(p* ⊗ ṗ)/|p|².
        let omega_eb_b = p.conj().mul(pd).v * (2.0 / n2);
        let q_b_e = p.scale(1.0 / n2.sqrt());
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
        self.knots[0].t
    }
    fn end(&self) -> f64 {
        self.knots[self.knots.len() - 1].t
    }
    fn piece_at(&self, t: f64, hint: usize) -> usize {
        let last = self.knots.len() - 2;
        let ks = &self.knots;
        let h = hint.min(last);
        if ks[h].t <= t && (h == last || t < ks[h + 1].t) {
            return h;
        }
        if h < last && ks[h + 1].t <= t && (h + 1 == last || t < ks[h + 2].t) {
            return h + 1;
        }
        // Index of the last knot with time ≤ t, clamped to a valid segment.
        let idx = ks.partition_point(|k| k.t <= t);
        idx.saturating_sub(1).min(last)
    }
    fn piece_end(&self, piece: usize) -> f64 {
        if piece + 2 >= self.knots.len() {
            f64::INFINITY
        } else {
            self.knots[piece + 1].t
        }
    }
    #[inline]
    fn sense(&self, piece: usize, t: f64) -> Sensed {
        sense_ecef(&self.state(piece, t).0)
    }
    fn pose(&self, t: f64) -> Pose {
        let i = self.piece_at(t, 0);
        let (s, _) = self.state(i, t);
        let q_n_e = s.pos.q_n_e();
        Pose {
            t,
            lat: s.pos.lat(),
            lon: s.pos.lon(),
            h: s.pos.h,
            v_n: s.pos.c_n_e().tr_mul_vec(s.v_e),
            q_b_n: q_n_e.conj().mul(s.q_b_e),
        }
    }
}
