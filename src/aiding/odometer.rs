//! Odometer / wheel-speed sensor: a wheel at a lever arm from the IMU reference point whose
//! encoder counts `counts_per_m` ticks per metre rolled along the body x axis, with a scale
//! factor error, slip windows, and quantization to whole ticks (the counter keeps the
//! fraction, so no tick is ever lost).

use serde::Deserialize;

use crate::earth;
use crate::math::{QuatExt, Vec3};
use crate::motion::Motion;

/// Odometer settings: the scene file's `[odometer]` table (every key optional).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct OdometerConfig {
    /// Samples per second, in (0, 1000].
    pub rate_hz: f64,
    /// Encoder ticks per metre of nominal rolling distance.
    pub counts_per_m: f64,
    /// Scale factor error (fraction: 0.01 counts 1 % too many ticks).
    pub scale_factor: f64,
    /// Wheel contact point from the IMU reference point, body axes (m).
    pub lever_arm_m: [f64; 3],
    /// Windows `[start, end, slip]` (s, s, fraction): the wheel turns (1 + slip) times the
    /// distance it travels (spin > 0, skid < 0).
    pub slip: Vec<[f64; 3]>,
}

impl Default for OdometerConfig {
    /// 100 ticks per metre at 10 Hz at the reference point, no errors.
    fn default() -> OdometerConfig {
        OdometerConfig {
            rate_hz: 10.0,
            counts_per_m: 100.0,
            scale_factor: 0.0,
            lever_arm_m: [0.0; 3],
            slip: Vec::new(),
        }
    }
}

impl OdometerConfig {
    /// Checks every value; the error names the `[odometer]` key.
    pub fn validate(&self) -> Result<(), super::gnss::ConfigError> {
        let c = super::gnss::Checks::new("odometer");
        c.rate("rate_hz", self.rate_hz)?;
        let n = self.counts_per_m;
        c.that(n.is_finite() && n > 0.0, "counts_per_m", || {
            format!("{n} must be > 0")
        })?;
        let k = self.scale_factor;
        c.that(k.is_finite() && k > -1.0, "scale_factor", || {
            format!("{k} must be > −1")
        })?;
        c.finite3("lever_arm_m", &self.lever_arm_m)?;
        for (i, s) in self.slip.iter().enumerate() {
            let ok = s.iter().all(|x| x.is_finite()) && s[0] < s[1] && s[2] > -1.0;
            c.that(ok, "slip", || {
                format!(
                    "window {i} {s:?} must be [start, end, slip] with start < end and slip > −1"
                )
            })?;
        }
        Ok(())
    }
}

/// One odometer sample at the end of an interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OdoSample {
    /// Time (s).
    pub t: f64,
    /// Cumulative encoder count.
    pub ticks: i64,
    /// Ticks in the interval.
    pub delta_ticks: i64,
    /// Speed from the ticks: Δticks / (counts_per_m · Δt) (m/s).
    pub speed_m_s: f64,
    /// True distance rolled along body x over the interval (m).
    pub true_distance_m: f64,
}

/// An odometer following a motion.
#[derive(Clone, Debug)]
pub struct Odometer {
    cfg: OdometerConfig,
    lever: Vec3,
    counted_m: f64,
    ticks: i64,
    hint: usize,
}

/// Gauss–Legendre nodes and weights on [−1, 1], three points (exact for degree 5).
const GL3: [(f64, f64); 3] = [
    (-0.774_596_669_241_483_4, 5.0 / 9.0),
    (0.0, 8.0 / 9.0),
    (0.774_596_669_241_483_4, 5.0 / 9.0),
];

impl Odometer {
    /// An odometer with `cfg`, its counter at zero.
    pub fn new(cfg: OdometerConfig) -> Odometer {
        Odometer {
            lever: Vec3::from(cfg.lever_arm_m),
            counted_m: 0.0,
            ticks: 0,
            hint: 0,
            cfg,
        }
    }

    /// Speed of the wheel's contact point along body x at `t` (m/s):
    /// x̂ · (C_n^b v^n + ω_eb^b × l), ω_eb^b = ω_ib^b − C_n^b ω_ie^n.
    pub fn forward_speed(&mut self, motion: &impl Motion, t: f64) -> f64 {
        self.hint = motion.piece_at(t, self.hint);
        let p = motion.pose(t);
        let (s, c) = p.lat.sin_cos();
        let w_eb =
            motion.sense(self.hint, t).omega_ib_b - p.q_b_n.rotate_inv(earth::omega_ie_n(s, c));
        (p.q_b_n.rotate_inv(p.v_n) + w_eb.cross(&self.lever)).x
    }

    /// The sample at the end of `(t_prev, t]`: the distance rolled is integrated by
    /// three-point Gauss–Legendre, scaled, slipped and counted.
    pub fn sample(&mut self, motion: &impl Motion, t_prev: f64, t: f64) -> OdoSample {
        let (mid, half) = (0.5 * (t + t_prev), 0.5 * (t - t_prev));
        let mut true_d = 0.0;
        let mut turned = 0.0;
        for (x, w) in GL3 {
            let tn = mid + half * x;
            let d = w * half * self.forward_speed(motion, tn);
            let slip = (self.cfg.slip.iter())
                .filter(|s| (s[0]..s[1]).contains(&tn))
                .map(|s| s[2])
                .sum::<f64>();
            true_d += d;
            turned += d * (1.0 + slip);
        }
        self.counted_m += turned * (1.0 + self.cfg.scale_factor);
        let ticks = (self.counted_m * self.cfg.counts_per_m).floor() as i64;
        let delta = ticks - self.ticks;
        self.ticks = ticks;
        OdoSample {
            t,
            ticks,
            delta_ticks: delta,
            speed_m_s: delta as f64 / (self.cfg.counts_per_m * (t - t_prev)),
            true_distance_m: true_d,
        }
    }
}
