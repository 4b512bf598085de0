//! The motion model of a trajectory that arrives live, state by state: the file model's
//! quintic Hermite pieces in ECEF (same knots, same evaluation, see [`super::sampled`]), with
//! knot derivatives taken only from the states received so far.
//!
//! The file model centres its finite-difference stencil on each knot, which needs states from
//! the future. Here knot n is fixed when state n arrives, from states n − s + 1 … n (the
//! one-sided stencil of Fornberg's weights, exact for polynomials of degree s − 1), or from
//! the rates the state carries: a given acceleration replaces the velocity difference, a given
//! body rate the attitude difference. A knot never changes once made, so the model between
//! two states is final as soon as the later one is in: value, first and second derivative
//! match at every knot, hence velocity, acceleration, attitude and angular rate are continuous
//! and the pieces pass exactly through every received position, velocity and attitude.
//!
//! The model is shared ([`CausalMotion`] clones are handles to one model): the input side
//! pushes states, the generator evaluates the pieces already complete.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use super::chain::{Chain, ChainSettings, Corrections, Tail};
use super::fd::fornberg;
use super::knot::GAP_FACTOR;
use super::limits::{Violation, check_given, check_sample, check_step};
use super::sampled::{Conv, Degree, Knot, ModelSettings, Sample, convert, hermite, knot_at};
use super::{Motion, Pose};
use crate::csvio::{num, num_sig};
use crate::earth::{Geodetic, OMEGA_IE, omega_en_n};
use crate::kinematics::{Sensed, sense_ecef};
use crate::math::{Quat, QuatExt, Vec3, all_finite};

/// Knots kept behind the newest (the generator steps back at most one record interval; a
/// consumer that falls further behind evaluates to NaN, which the producer refuses).
pub const KEEP_KNOTS: usize = 4096;

/// A received state: the trajectory sample and what the simulation knows exactly besides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiveSample {
    /// Time, position, NED velocity and attitude.
    pub sample: Sample,
    /// Body angular rate ω_ib^b (rad/s), what an ideal gyro senses, if given.
    pub omega_ib_b: Option<Vec3>,
    /// Time derivative of the NED velocity components v̇^n (m/s²), if given.
    pub accel_n: Option<Vec3>,
}

impl LiveSample {
    /// A state with position, velocity and attitude only.
    pub fn plain(sample: Sample) -> LiveSample {
        LiveSample {
            sample,
            omega_ib_b: None,
            accel_n: None,
        }
    }
}

/// A state in ECEF quantities, with its given derivatives converted to the knot's terms.
#[derive(Clone, Copy, Debug)]
struct Entry {
    conv: Conv,
    sample: Sample,
    /// r̈^e (m/s²).
    a_e: Option<Vec3>,
    /// ω_eb^b (rad/s).
    omega_eb_b: Option<Vec3>,
}

/// Why a state was not taken into the model.
#[derive(Clone, Debug, PartialEq)]
pub enum Rejected {
    /// Its time is not after the newest state's (a duplicate or a reordered, late state).
    NotAfter {
        /// Newest time in the model (s).
        newest: f64,
    },
    /// A value is beyond the limits of [`super::limits`] (alone or against the newest state).
    Limit(Violation),
    /// Its time is so far after the newest state's that the model cannot bridge the step
    /// ([`CausalMotion::refuse_gaps`]): a tag off the sender's time line, or an outage longer
    /// than the model's stencil can span.
    Gap {
        /// Newest time in the model (s).
        newest: f64,
        /// The step from it (s).
        step: f64,
        /// The longest step allowed there (s).
        limit: f64,
    },
    /// Its time tag lies further ahead of the time the clock map gives its arrival than any
    /// path delay or clock error explains (s): the sender's clock cannot have read it then.
    Ahead {
        /// How far ahead of the clock map (s).
        by: f64,
        /// The most allowed (s).
        limit: f64,
    },
}

impl std::fmt::Display for Rejected {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Rejected::NotAfter { newest } => write!(f, "not after the newest state ({newest} s)"),
            Rejected::Limit(v) if v.column.is_empty() => write!(f, "{}", v.message),
            Rejected::Limit(v) => write!(f, "`{}`: {}", v.column, v.message),
            Rejected::Gap {
                newest,
                step,
                limit,
            } => write!(
                f,
                "`t`: {} s after the newest state ({} s), beyond the longest step the model bridges there ({} s): a time tag off the sender's time line, or an outage too long to interpolate over",
                num_sig(*step, 9),
                num(*newest),
                num_sig(*limit, 9)
            ),
            Rejected::Ahead { by, limit } => write!(
                f,
                "`t`: {} s ahead of the sender's clock as the clock map reads it at the state's arrival (at most {} s): a time tag the sender's clock cannot have read then",
                num_sig(*by, 9),
                num(*limit)
            ),
        }
    }
}

struct Inner {
    degree: Degree,
    stencil: usize,
    recent: VecDeque<Entry>,
    knots: VecDeque<Knot>,
    /// Global index of `knots[0]`.
    base: usize,
    first: f64,
    /// The emitted chain of a real-time run (`None`: the received pieces as they are).
    chain: Option<Chain>,
    /// Whether steps the model cannot bridge are refused ([`CausalMotion::refuse_gaps`]).
    refuse_gaps: bool,
}

/// A live, causal motion model (a shared handle: clones see the same states).
#[derive(Clone)]
pub struct CausalMotion {
    inner: Arc<Mutex<Inner>>,
}

impl std::fmt::Debug for CausalMotion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let m = self.lock();
        f.debug_struct("CausalMotion")
            .field("knots", &(m.base + m.knots.len()))
            .finish_non_exhaustive()
    }
}

impl CausalMotion {
    /// An empty model; `settings.stencil` states make its first knot.
    pub fn new(settings: ModelSettings) -> CausalMotion {
        CausalMotion {
            inner: Arc::new(Mutex::new(Inner {
                degree: settings.degree,
                stencil: settings.stencil.max(3),
                recent: VecDeque::new(),
                knots: VecDeque::new(),
                base: 0,
                first: f64::NAN,
                chain: None,
                refuse_gaps: false,
            })),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        // Every update below is complete before the lock is released.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Takes the next state. A state not after the newest, or beyond the limits, is refused
    /// and leaves the model unchanged.
    pub fn push(&self, s: &LiveSample) -> Result<(), Rejected> {
        let mut m = self.lock();
        let prev = m.recent.back().map(|e| (e.sample, e.conv.q));
        if let Some((p, _)) = prev
            && s.sample.t.partial_cmp(&p.t) != Some(std::cmp::Ordering::Greater)
        {
            return Err(Rejected::NotAfter { newest: p.t });
        }
        if m.refuse_gaps
            && let Some((p, _)) = prev
        {
            let limit = gap_limit(&m.recent);
            let step = s.sample.t - p.t;
            if step > limit {
                return Err(Rejected::Gap {
                    newest: p.t,
                    step,
                    limit,
                });
            }
        }
        check_sample(&s.sample).map_err(Rejected::Limit)?;
        if let Some((p, _)) = prev {
            check_step(&p, &s.sample).map_err(Rejected::Limit)?;
        }
        check_given(s.omega_ib_b, s.accel_n).map_err(Rejected::Limit)?;
        let conv = convert(&s.sample, prev.map(|p| p.1));
        let x = &s.sample;
        let g = Geodetic::from_radians(x.lat, x.lon, x.h);
        let c_n_e = g.c_n_e();
        let a_e = s.accel_n.map(|a| {
            // v^e = C_n^e v^n, so r̈^e = C_n^e (v̇^n + ω_en^n × v^n).
            let w_en = omega_en_n(g.sin_lat, g.cos_lat, x.h, x.v_n);
            c_n_e * (a + w_en.cross(&x.v_n))
        });
        let omega_eb_b = s
            .omega_ib_b
            .map(|w| w - conv.q.rotate_inv(Vec3::new(0.0, 0.0, OMEGA_IE)));
        let entry = Entry {
            conv,
            sample: s.sample,
            a_e,
            omega_eb_b,
        };
        m.recent.push_back(entry);
        let dropped = if m.recent.len() > m.stencil {
            m.recent.pop_front()
        } else {
            None
        };
        if m.recent.len() == m.stencil {
            let k = causal_knot(m.recent.make_contiguous());
            if !knot_finite(&k) {
                // Within the limits every knot is finite; should a combination still overflow,
                // the state is refused like any other and the model stays as it was.
                m.recent.pop_back();
                if let Some(d) = dropped {
                    m.recent.push_front(d);
                }
                return Err(Rejected::Limit(Violation {
                    column: "",
                    message: "the motion through this state is not finite (its values are too large together with the previous states')".into(),
                }));
            }
            if m.knots.is_empty() && m.base == 0 {
                m.first = k.t;
            }
            m.knots.push_back(k);
            if m.knots.len() > KEEP_KNOTS {
                m.knots.pop_front();
                m.base += 1;
            }
        }
        Ok(())
    }

    /// Refuses from now on a state whose step from the newest is longer than the model can
    /// bridge ([`GAP_FACTOR`] times the longest step of the stencil before it, or
    /// [`FIRST_GAP_S`] after the first state), as [`Rejected::Gap`]. For a run that follows
    /// its input's time tags only (lockstep): there a tag off the time line would otherwise
    /// make the run compute every record up to it. A real-time run places tags by their
    /// arrival instead ([`Rejected::Ahead`]) and bridges outages by extrapolating.
    pub fn refuse_gaps(&self) {
        self.lock().refuse_gaps = true;
    }

    /// Time of the newest knot: the model is complete up to it (NaN before the first).
    pub fn newest(&self) -> f64 {
        self.lock().knots.back().map_or(f64::NAN, |k| k.t)
    }

    /// Number of knots made so far.
    pub fn knots(&self) -> usize {
        let m = self.lock();
        m.base + m.knots.len()
    }

    /// Makes this model emit through a chain ([`super::chain`]): it follows the received
    /// pieces while they cover what [`CausalMotion::prepare`] asks for, extrapolates past
    /// them, and bridges back when a late state arrives.
    pub fn enable_chain(&self, settings: ChainSettings) {
        self.lock().chain = Some(Chain::new(settings));
    }

    /// Extends the emitted chain to `upto`, the records up to `emitted` being already
    /// produced; returns what its end is doing (following without a chain).
    pub fn prepare(&self, emitted: f64, upto: f64) -> Tail {
        let mut m = self.lock();
        let Inner {
            knots, base, chain, ..
        } = &mut *m;
        match chain {
            Some(c) => {
                c.prepare(knots, *base, emitted, upto);
                c.tail()
            }
            None => Tail::Following,
        }
    }

    /// Holds the emitted motion from `emitted` on (constant acceleration and angular rate)
    /// until a newer state arrives.
    pub fn hold_from(&self, emitted: f64) {
        if let Some(c) = self.lock().chain.as_mut() {
            c.hold_from(emitted);
        }
    }

    /// The largest corrections the chain applied so far.
    pub fn corrections(&self) -> Corrections {
        self.lock()
            .chain
            .as_ref()
            .map_or_else(Corrections::default, |c| c.corrections)
    }

    /// The newest state received, if any.
    pub fn newest_state(&self) -> Option<Sample> {
        self.lock().recent.back().map(|e| e.sample)
    }
}

/// Largest step after the first state (s), before any step tells the input's spacing: an hour.
/// A run computes every record over the step, which must stay a bounded amount of work.
pub const FIRST_GAP_S: f64 = 3600.0;

/// The longest step [`CausalMotion::refuse_gaps`] allows after the newest of `recent`.
fn gap_limit(recent: &VecDeque<Entry>) -> f64 {
    let longest = (recent.iter().zip(recent.iter().skip(1)))
        .map(|(a, b)| b.sample.t - a.sample.t)
        .fold(0.0, f64::max);
    if longest > 0.0 {
        (GAP_FACTOR * longest).min(FIRST_GAP_S)
    } else {
        FIRST_GAP_S
    }
}

/// The knot of the last entry from the whole (one-sided) stencil.
fn causal_knot(st: &[Entry]) -> Knot {
    let c = st[st.len() - 1].conv;
    let times: Vec<f64> = st.iter().map(|e| e.conv.t).collect();
    let w = fornberg(c.t, &times, 2);
    // A given first derivative is used as is; the second derivative comes from differences
    // of the given first derivatives when every state of the stencil has them (one
    // differentiation instead of two), else from the values.
    let (a, j) = match (st[st.len() - 1].a_e, st.iter().all(|e| e.a_e.is_some())) {
        (Some(a), true) => {
            let a0 = a;
            let j = sum(st, &w[1], |e| e.a_e.unwrap_or(a0) - a0);
            (a, j)
        }
        (given, _) => {
            let a = sum(st, &w[1], |e| e.conv.v - c.v);
            (given.unwrap_or(a), sum(st, &w[2], |e| e.conv.v - c.v))
        }
    };
    // Rates in the rotation-vector chart centred on the knot, where they are φ̇ and φ̈.
    let phi = |e: &Entry| (c.q.conjugate() * e.conv.q).to_rotvec();
    let (omega, omega_dot) = match (
        st[st.len() - 1].omega_eb_b,
        st.iter().all(|e| e.omega_eb_b.is_some()),
    ) {
        (Some(om), true) => {
            // At the chart's centre φ̈ = ω̇, the derivative of the body-axis components.
            let rate = |e: &Entry| e.omega_eb_b.unwrap_or(om) - om;
            (om, sum(st, &w[1], rate))
        }
        (given, _) => {
            let om = sum(st, &w[1], phi);
            (given.unwrap_or(om), sum(st, &w[2], phi))
        }
    };
    knot_at(&c, a, j, omega, omega_dot)
}

/// Whether every value of a knot is finite.
fn knot_finite(k: &Knot) -> bool {
    let q = |q: &Quat| q.coords.iter().all(|x| x.is_finite());
    [k.r, k.v, k.a, k.j].iter().all(all_finite) && [k.q, k.qd, k.qdd].iter().all(q)
}

/// Σ_m w[m]·f(entry m).
fn sum(st: &[Entry], w: &[f64], f: impl Fn(&Entry) -> Vec3) -> Vec3 {
    st.iter()
        .zip(w)
        .fold(Vec3::zeros(), |acc, (e, wm)| acc + f(e) * *wm)
}

impl Inner {
    fn pair(&self, piece: usize) -> Option<(&Knot, &Knot)> {
        let i = piece.checked_sub(self.base)?;
        Some((self.knots.get(i)?, self.knots.get(i + 1)?))
    }
}

/// What a piece that is no longer (or not yet) held evaluates to: NaN, which the producer
/// refuses with the time it happened at.
const NAN3: Vec3 = Vec3::new(f64::NAN, f64::NAN, f64::NAN);

impl Motion for CausalMotion {
    fn start(&self) -> f64 {
        self.lock().first
    }
    /// Unbounded: the stream has no known end.
    fn end(&self) -> f64 {
        f64::INFINITY
    }
    fn piece_at(&self, t: f64, hint: usize) -> usize {
        let m = self.lock();
        if let Some(c) = &m.chain {
            return c.piece_at(t, hint);
        }
        let n = m.knots.len();
        if n < 2 {
            return m.base;
        }
        let at = |i: usize| m.knots[i].t;
        let last = n - 2;
        let h = hint.saturating_sub(m.base).min(last);
        if at(h) <= t && (h == last || t < at(h + 1)) {
            return m.base + h;
        }
        if h < last && at(h + 1) <= t && (h + 1 == last || t < at(h + 2)) {
            return m.base + h + 1;
        }
        let idx = m.knots.partition_point(|k| k.t <= t);
        m.base + idx.saturating_sub(1).min(last)
    }
    fn piece_end(&self, piece: usize) -> f64 {
        let m = self.lock();
        if let Some(c) = &m.chain {
            return c.piece_end(piece);
        }
        match piece.checked_sub(m.base).map(|i| i + 1) {
            // The newest piece may still grow: its end is the next knot, not yet known.
            Some(i) if i + 1 < m.knots.len() => m.knots[i].t,
            _ => f64::INFINITY,
        }
    }
    #[inline]
    fn sense(&self, piece: usize, t: f64) -> Sensed {
        let m = self.lock();
        if let Some(c) = &m.chain {
            return c.sense(piece, t).unwrap_or(Sensed {
                omega_ib_b: NAN3,
                f_b: NAN3,
            });
        }
        match m.pair(piece) {
            Some((k0, k1)) => sense_ecef(&hermite(m.degree, k0, k1, t).0),
            None => Sensed {
                omega_ib_b: NAN3,
                f_b: NAN3,
            },
        }
    }
    fn pose(&self, t: f64) -> Pose {
        let piece = self.piece_at(t, 0);
        let m = self.lock();
        let chained = m.chain.as_ref().map(|c| c.state(piece, t));
        let Some(s) =
            chained.unwrap_or_else(|| m.pair(piece).map(|(k0, k1)| hermite(m.degree, k0, k1, t).0))
        else {
            return Pose {
                t,
                lat: f64::NAN,
                lon: f64::NAN,
                h: f64::NAN,
                v_n: NAN3,
                q_b_n: Quat::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN),
            };
        };
        Pose {
            t,
            lat: s.pos.lat(),
            lon: s.pos.lon(),
            h: s.pos.h,
            v_n: s.pos.c_n_e().tr_mul(&s.v_e),
            q_b_n: s.pos.q_n_e().conjugate() * s.q_b_e,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::earth::ecef_to_geodetic;
    use crate::kinematics::EcefState;

    /// A closed-form motion: ECEF position a cubic in time, attitude C_b^e turning at a
    /// constant body rate. The one-sided stencil is exact on it (velocity is a quadratic, the
    /// attitude's rotation vector from any knot linear in time), so the model must reproduce
    /// the analytic sensed values to round-off.
    struct Cubic {
        r0: Vec3,
        v0: Vec3,
        a0: Vec3,
        j0: Vec3,
        q0: Quat,
        w: Vec3,
    }

    impl Cubic {
        fn new() -> Cubic {
            Cubic {
                r0: Geodetic::from_radians(0.8, 0.12, 300.0).to_ecef(),
                v0: Vec3::new(50.0, -30.0, 20.0),
                a0: Vec3::new(1.0, -2.0, 0.5),
                j0: Vec3::new(0.1, 0.05, -0.02),
                q0: Quat::from_rotvec(Vec3::new(0.3, -1.2, 2.0)),
                w: Vec3::new(0.02, -0.05, 0.3),
            }
        }
        fn state(&self, t: f64) -> (Vec3, EcefState) {
            let r = self.r0 + self.v0 * t + self.a0 * (t * t / 2.0) + self.j0 * (t * t * t / 6.0);
            let v = self.v0 + self.a0 * t + self.j0 * (t * t / 2.0);
            let s = EcefState {
                pos: ecef_to_geodetic(r),
                v_e: v,
                a_e: self.a0 + self.j0 * t,
                q_b_e: self.q0 * Quat::from_rotvec(self.w * t),
                omega_eb_b: self.w,
            };
            (r, s)
        }
        fn sample(&self, t: f64) -> Sample {
            let (_, s) = self.state(t);
            Sample {
                t,
                lat: s.pos.lat(),
                lon: s.pos.lon(),
                h: s.pos.h,
                v_n: s.pos.c_n_e().tr_mul(&s.v_e),
                q_b_n: s.pos.q_n_e().conjugate() * s.q_b_e,
            }
        }
    }

    /// Uneven state times (as a jittery sender gives them).
    fn times(n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| i as f64 * 0.01 + 0.002 * ((i * 7919) % 5) as f64 / 5.0)
            .collect()
    }

    fn worst(m: &CausalMotion, c: &Cubic, ts: &[f64]) -> (f64, f64) {
        let (mut ew, mut ef) = (0.0f64, 0.0f64);
        let mut hint = 0;
        for w in ts.windows(2).skip(8) {
            for x in [0.0, 0.17, 0.5, 0.93] {
                let t = w[0] + x * (w[1] - w[0]);
                hint = m.piece_at(t, hint);
                let got = m.sense(hint, t);
                let want = sense_ecef(&c.state(t).1);
                ew = ew.max((got.omega_ib_b - want.omega_ib_b).amax());
                ef = ef.max((got.f_b - want.f_b).amax());
            }
        }
        (ew, ef)
    }

    /// Round-off bounds: velocities of ~60 m/s hold ~1e-14 m/s, the one-sided second
    /// difference multiplies that by ~1e3/h² (h = 10 ms), giving jerk errors ~1e-5 m/s³ and
    /// acceleration errors of a few 1e-9 m/s² inside a piece; attitude components hold ~1e-16,
    /// giving rates to ~1e-12 rad/s. A one-sided stencil taken centred, a wrong sign of a
    /// weight or a skipped Earth-rate term is off by orders of magnitude more.
    #[test]
    fn exact_on_a_cubic_with_constant_body_rate() {
        let c = Cubic::new();
        let ts = times(60);
        let m = CausalMotion::new(ModelSettings::default());
        for &t in &ts {
            m.push(&LiveSample::plain(c.sample(t))).unwrap();
        }
        assert_eq!(m.knots(), 60 - 8);
        assert_eq!(m.start(), ts[8]);
        let (ew, ef) = worst(&m, &c, &ts);
        assert!(ew < 1e-11, "rate error {ew:e}");
        assert!(ef < 1e-7, "specific force error {ef:e}");
    }

    /// Given body rates and accelerations are used as the knot's derivatives: exact ones give
    /// the same model as the differences, and an acceleration offset by 1 m/s² north shows at
    /// a knot as exactly that offset in the body axes.
    #[test]
    fn given_rates_and_accelerations_are_used() {
        let c = Cubic::new();
        let ts = times(40);
        let exact = CausalMotion::new(ModelSettings::default());
        let offset = CausalMotion::new(ModelSettings::default());
        let w_ie = Vec3::new(0.0, 0.0, OMEGA_IE);
        for &t in &ts {
            let s = c.sample(t);
            let (_, e) = c.state(t);
            let g = Geodetic::from_radians(s.lat, s.lon, s.h);
            let w_en = omega_en_n(g.sin_lat, g.cos_lat, s.h, s.v_n);
            let a_n = g.c_n_e().tr_mul(&e.a_e) - w_en.cross(&s.v_n);
            let omega = Some(e.omega_eb_b + e.q_b_e.rotate_inv(w_ie));
            let given = |a_n| LiveSample {
                sample: s,
                omega_ib_b: omega,
                accel_n: Some(a_n),
            };
            exact.push(&given(a_n)).unwrap();
            offset.push(&given(a_n + Vec3::new(1.0, 0.0, 0.0))).unwrap();
        }
        let (ew, ef) = worst(&exact, &c, &ts);
        assert!(ew < 1e-11 && ef < 1e-7, "{ew:e} {ef:e}");
        let t = ts[20];
        let p = offset.piece_at(t, 0);
        let d = offset.sense(p, t).f_b - exact.sense(exact.piece_at(t, 0), t).f_b;
        let s = c.sample(t);
        let want = s.q_b_n.rotate_inv(Vec3::new(1.0, 0.0, 0.0));
        assert!((d - want).amax() < 1e-9, "{d:?} vs {want:?}");
    }

    /// Velocity, specific force and angular rate are continuous across a knot: both pieces
    /// meeting there agree on the knot's values (the quintic matches value, first and second
    /// derivative), even on data no polynomial fits.
    #[test]
    fn continuous_across_knots() {
        let m = CausalMotion::new(ModelSettings::default());
        for i in 0..30 {
            let t = i as f64 * 0.01;
            let wiggle = ((i * 37) % 11) as f64 * 0.1;
            let s = Sample {
                t,
                lat: 0.7,
                lon: 0.1,
                h: 10.0 + wiggle,
                v_n: Vec3::new(20.0 + wiggle, -wiggle, 0.1 * wiggle),
                q_b_n: crate::math::quat_from_euler(0.01 * wiggle, 0.0, 0.5 + 0.02 * wiggle),
            };
            m.push(&LiveSample::plain(s)).unwrap();
        }
        for i in 10..29 {
            let t = i as f64 * 0.01;
            let p = m.piece_at(t, 0);
            let left = m.sense(p - 1, t);
            let right = m.sense(p, t);
            assert!((left.f_b - right.f_b).amax() < 1e-9, "knot {i}");
            assert!(
                (left.omega_ib_b - right.omega_ib_b).amax() < 1e-12,
                "knot {i}"
            );
        }
    }

    /// Duplicates, reordered states and states beyond the limits are refused and leave the
    /// model as it was.
    #[test]
    fn refusals_leave_the_model_unchanged() {
        let c = Cubic::new();
        let m = CausalMotion::new(ModelSettings::default());
        for i in 0..12 {
            m.push(&LiveSample::plain(c.sample(i as f64 * 0.01)))
                .unwrap();
        }
        let before = (m.knots(), m.newest());
        let dup = LiveSample::plain(c.sample(0.11));
        assert_eq!(m.push(&dup), Err(Rejected::NotAfter { newest: 0.11 }));
        let old = LiveSample::plain(c.sample(0.05));
        assert!(matches!(m.push(&old), Err(Rejected::NotAfter { .. })));
        let mut high = c.sample(0.12);
        high.h = 1e12;
        assert!(matches!(
            m.push(&LiveSample::plain(high)),
            Err(Rejected::Limit(_))
        ));
        let mut nan = LiveSample::plain(c.sample(0.12));
        nan.omega_ib_b = Some(Vec3::new(f64::NAN, 0.0, 0.0));
        assert!(matches!(m.push(&nan), Err(Rejected::Limit(_))));
        // A huge but finite given rate or acceleration (issue 23: `wx = 1e300` deg/s once
        // made every record after it NaN) is refused naming its column.
        let mut huge = LiveSample::plain(c.sample(0.12));
        huge.omega_ib_b = Some(Vec3::new(1e300f64.to_radians(), 0.0, 0.0));
        assert!(matches!(m.push(&huge), Err(Rejected::Limit(v)) if v.column == "wx"));
        huge.omega_ib_b = None;
        huge.accel_n = Some(Vec3::new(1e300, 0.0, 0.0));
        assert!(matches!(m.push(&huge), Err(Rejected::Limit(v)) if v.column == "an"));
        assert_eq!((m.knots(), m.newest()), before);
        // The next sound state is taken, and the model stays finite.
        m.push(&LiveSample::plain(c.sample(0.12))).unwrap();
        let t = 0.115;
        let got = m.sense(m.piece_at(t, 0), t);
        assert!(
            all_finite(&got.omega_ib_b) && all_finite(&got.f_b),
            "{got:?}"
        );
        // Before the first knot and after the kept ones: NaN, never a stale piece.
        let fresh = CausalMotion::new(ModelSettings::default());
        assert!(fresh.sense(0, 0.0).f_b.x.is_nan());
    }

    /// With gaps refused, a step longer than [`GAP_FACTOR`] times the stencil's longest step
    /// is refused naming the limit, the model unchanged; a step just within it is taken.
    /// After the first state alone, the limit is [`FIRST_GAP_S`].
    #[test]
    fn steps_too_long_to_bridge_are_refused() {
        let c = Cubic::new();
        let m = CausalMotion::new(ModelSettings::default());
        m.refuse_gaps();
        m.push(&LiveSample::plain(c.sample(0.0))).unwrap();
        let far = LiveSample::plain(c.sample(FIRST_GAP_S * 1.001));
        assert!(matches!(m.push(&far), Err(Rejected::Gap { limit, .. }) if limit == FIRST_GAP_S));
        for i in 1..12 {
            m.push(&LiveSample::plain(c.sample(i as f64 * 0.01)))
                .unwrap();
        }
        let before = (m.knots(), m.newest());
        // The longest step of the stencil is 0.01 s give or take a rounding: the limit 1 s.
        let over = LiveSample::plain(c.sample(0.11 + 1.001));
        match m.push(&over) {
            Err(Rejected::Gap {
                newest,
                step,
                limit,
            }) => {
                assert_eq!(newest, 0.11);
                assert!((step - 1.001).abs() < 1e-12 && (limit - 1.0).abs() < 1e-12);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!((m.knots(), m.newest()), before);
        m.push(&LiveSample::plain(c.sample(0.11 + 0.999))).unwrap();
        // Without the rule (a real-time run) the same step is taken.
        let free = CausalMotion::new(ModelSettings::default());
        for i in 0..12 {
            free.push(&LiveSample::plain(c.sample(i as f64 * 0.01)))
                .unwrap();
        }
        free.push(&over).unwrap();
    }
}
