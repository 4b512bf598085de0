//! GNSS receiver output from the same motion and clock as the IMU: the antenna's position and
//! velocity at each epoch (lever arm applied exactly), corrupted per NED axis by white and
//! first-order Gauss–Markov errors, with latency, outage windows and the fix quality,
//! satellite count and accuracy fields that follow from the configured errors.

use serde::Deserialize;

use crate::earth::{self, Geodetic};
use crate::errors::process::GaussMarkov;
use crate::math::{QuatExt, Vec3};
use crate::motion::Motion;
use crate::rng::NormalStream;

/// The receiver's settings: the scene file's `[gnss]` table (every key optional).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct GnssConfig {
    /// Epochs per second, 1 to 20; epochs fall on whole multiples of 1/rate of GPS time.
    pub rate_hz: f64,
    /// Antenna phase centre from the IMU reference point, body axes (m).
    pub lever_arm_m: [f64; 3],
    /// White position error σ per NED axis (m).
    pub pos_white_m: [f64; 3],
    /// Gauss–Markov position error σ per NED axis (m).
    pub pos_gm_m: [f64; 3],
    /// Correlation time of the position Gauss–Markov errors per NED axis (s).
    pub pos_gm_tau_s: [f64; 3],
    /// White velocity error σ per NED axis (m/s).
    pub vel_white_m_s: [f64; 3],
    /// Gauss–Markov velocity error σ per NED axis (m/s).
    pub vel_gm_m_s: [f64; 3],
    /// Correlation time of the velocity Gauss–Markov errors per NED axis (s).
    pub vel_gm_tau_s: [f64; 3],
    /// Delay from an epoch's time of validity to its emission (s).
    pub latency_s: f64,
    /// Windows `[start, end)` of time of validity (s) without a fix.
    pub outages_s: Vec<[f64; 2]>,
    /// Satellites used in a fix (at least 4 for a 3-D fix).
    pub satellites: u8,
    /// User-equivalent range error (m): dilutions of precision are the σ's over it.
    pub uere_m: f64,
    /// GPS − UTC (s) from the built-in table's last leap second on (18 since 2017-01-01);
    /// before it the encoders take the table's value ([`super::GnssEncoder::new`]).
    pub leap_seconds: i64,
    /// Master seed of the receiver's errors (default: the run's seed).
    pub seed: Option<u64>,
}

impl Default for GnssConfig {
    /// A single-frequency code receiver in open sky.
    fn default() -> GnssConfig {
        GnssConfig {
            rate_hz: 5.0,
            lever_arm_m: [0.0; 3],
            pos_white_m: [0.5, 0.5, 1.0],
            pos_gm_m: [1.0, 1.0, 2.0],
            pos_gm_tau_s: [300.0; 3],
            vel_white_m_s: [0.05, 0.05, 0.1],
            vel_gm_m_s: [0.0; 3],
            vel_gm_tau_s: [60.0; 3],
            latency_s: 0.0,
            outages_s: Vec::new(),
            satellites: 12,
            uere_m: 2.0,
            leap_seconds: 18,
            seed: None,
        }
    }
}

/// An aiding sensor's setting outside what it can be.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{table}.{key}: {message}")]
pub struct ConfigError {
    /// The scene-file table (`gnss`, `odometer`).
    pub table: &'static str,
    /// The key in that table.
    pub key: &'static str,
    /// What is wrong and what is expected.
    pub message: String,
}

/// Range checks of one aiding table's settings: each failed check is a [`ConfigError`]
/// naming the table and the key, with the messages every aiding sensor shares.
pub(crate) struct Checks {
    table: &'static str,
}

impl Checks {
    /// Checks of the scene-file table `table` (`odometer`, `baro`, `magnetometer`).
    pub(crate) fn new(table: &'static str) -> Checks {
        Checks { table }
    }

    /// `Ok` when `ok`, else the error `message()` on `key`.
    pub(crate) fn that(
        &self,
        ok: bool,
        key: &'static str,
        message: impl FnOnce() -> String,
    ) -> Result<(), ConfigError> {
        match ok {
            true => Ok(()),
            false => Err(ConfigError {
                table: self.table,
                key,
                message: message(),
            }),
        }
    }

    /// A sample rate in (0, 1000] Hz.
    pub(crate) fn rate(&self, key: &'static str, hz: f64) -> Result<(), ConfigError> {
        let ok = hz > 0.0 && hz <= 1000.0;
        self.that(ok, key, || format!("{hz} Hz is outside (0, 1000] Hz"))
    }

    /// A finite value ≥ 0 (a σ, a random-walk density).
    pub(crate) fn non_negative(&self, key: &'static str, v: f64) -> Result<(), ConfigError> {
        self.that(v.is_finite() && v >= 0.0, key, || {
            format!("{v} must be ≥ 0")
        })
    }

    /// Three finite values (a lever arm, a hard-iron offset).
    pub(crate) fn finite3(&self, key: &'static str, v: &[f64; 3]) -> Result<(), ConfigError> {
        let ok = v.iter().all(|x| x.is_finite());
        self.that(ok, key, || format!("{v:?} has a non-finite value"))
    }
}

/// Lowest and highest epoch rate (Hz) of the receivers modelled.
pub const RATE_RANGE_HZ: (f64, f64) = (1.0, 20.0);

impl GnssConfig {
    /// Checks every value; the error names the key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |key, message: String| {
            Err(ConfigError {
                table: "gnss",
                key,
                message,
            })
        };
        let (lo, hi) = RATE_RANGE_HZ;
        if !(lo..=hi).contains(&self.rate_hz) {
            return bad(
                "rate_hz",
                format!("{} Hz is outside {lo}–{hi} Hz", self.rate_hz),
            );
        }
        for (key, v) in [
            ("lever_arm_m", self.lever_arm_m),
            ("pos_white_m", self.pos_white_m),
            ("pos_gm_m", self.pos_gm_m),
            ("vel_white_m_s", self.vel_white_m_s),
            ("vel_gm_m_s", self.vel_gm_m_s),
        ] {
            if v.iter().any(|x| !x.is_finite()) {
                return bad(key, format!("{v:?} has a non-finite value"));
            }
            if key != "lever_arm_m" && v.iter().any(|&x| x < 0.0) {
                return bad(key, format!("{v:?}: a σ cannot be negative"));
            }
        }
        for (key, v) in [
            ("pos_gm_tau_s", self.pos_gm_tau_s),
            ("vel_gm_tau_s", self.vel_gm_tau_s),
        ] {
            if v.iter().any(|&x| !(x.is_finite() && x > 0.0)) {
                return bad(key, format!("{v:?}: correlation times must be > 0 s"));
            }
        }
        if !(self.latency_s.is_finite() && self.latency_s >= 0.0) {
            return bad("latency_s", format!("{} must be ≥ 0 s", self.latency_s));
        }
        for (i, w) in self.outages_s.iter().enumerate() {
            if !(w[0].is_finite() && w[1].is_finite() && w[0] < w[1]) {
                return bad(
                    "outages_s",
                    format!("window {i} {w:?} must be [start, end] with start < end"),
                );
            }
        }
        if self.satellites < 4 {
            return bad(
                "satellites",
                format!("{}: a 3-D fix needs at least 4", self.satellites),
            );
        }
        if !(self.uere_m.is_finite() && self.uere_m > 0.0) {
            return bad("uere_m", format!("{} must be > 0 m", self.uere_m));
        }
        if !(0..=100).contains(&self.leap_seconds) {
            return bad(
                "leap_seconds",
                format!("{} is outside 0–100 s", self.leap_seconds),
            );
        }
        Ok(())
    }

    /// Total 1σ position error per NED axis (m): white and Gauss–Markov are independent.
    pub fn sigma_pos(&self) -> Vec3 {
        rss(self.pos_white_m, self.pos_gm_m)
    }

    /// Total 1σ velocity error per NED axis (m/s).
    pub fn sigma_vel(&self) -> Vec3 {
        rss(self.vel_white_m_s, self.vel_gm_m_s)
    }

    /// The kind of fix the configured horizontal error stands for.
    pub fn fix_kind(&self) -> Fix {
        let s = self.sigma_pos();
        Fix::for_horizontal_sigma(s.x.hypot(s.y))
    }
}

fn rss(a: [f64; 3], b: [f64; 3]) -> Vec3 {
    Vec3::new(a[0].hypot(b[0]), a[1].hypot(b[1]), a[2].hypot(b[2]))
}

/// The kind of solution an epoch carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fix {
    /// No position (an outage).
    None,
    /// Autonomous code solution (GPS SPS).
    Autonomous,
    /// Differential code solution (DGPS / SBAS).
    Differential,
    /// Carrier-phase solution with float ambiguities (RTK float).
    RtkFloat,
    /// Carrier-phase solution with fixed ambiguities (RTK fixed).
    RtkFixed,
}

impl Fix {
    /// The solution whose typical horizontal 1σ error is `sigma_h` (m): ≤ 5 cm RTK fixed,
    /// ≤ 0.5 m RTK float, ≤ 1.5 m differential, else autonomous.
    pub fn for_horizontal_sigma(sigma_h: f64) -> Fix {
        if sigma_h <= 0.05 {
            Fix::RtkFixed
        } else if sigma_h <= 0.5 {
            Fix::RtkFloat
        } else if sigma_h <= 1.5 {
            Fix::Differential
        } else {
            Fix::Autonomous
        }
    }
    /// Whether the epoch carries a position.
    pub fn is_valid(self) -> bool {
        self != Fix::None
    }
}

/// The antenna's true state at an epoch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AntennaState {
    /// Geodetic latitude (rad).
    pub lat: f64,
    /// Longitude (rad).
    pub lon: f64,
    /// Ellipsoidal height (m).
    pub h: f64,
    /// Velocity relative to the Earth in the antenna's NED axes (m/s).
    pub v_n: Vec3,
}

/// One receiver epoch: what the receiver reports, and the truth it came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssEpoch {
    /// Epoch index: the time of validity is `k / rate` (s of record time).
    pub k: i64,
    /// Time of validity (s of record time).
    pub t: f64,
    /// When the receiver emits the epoch: `t` + latency (s).
    pub t_emit: f64,
    /// The solution kind; [`Fix::None`] in an outage.
    pub fix: Fix,
    /// Satellites used (0 in an outage).
    pub satellites: u8,
    /// Reported antenna state: truth plus the errors (in an outage, the truth is not reported
    /// and this holds it uncorrupted; encoders leave it out).
    pub measured: AntennaState,
    /// True antenna state.
    pub truth: AntennaState,
    /// Position error, NED (m).
    pub pos_err_n: Vec3,
    /// Velocity error, NED (m/s).
    pub vel_err_n: Vec3,
    /// Reported 1σ position accuracy per NED axis (m).
    pub sigma_pos: Vec3,
    /// Reported 1σ velocity accuracy per NED axis (m/s).
    pub sigma_vel: Vec3,
    /// Horizontal dilution of precision.
    pub hdop: f64,
    /// Vertical dilution of precision.
    pub vdop: f64,
    /// User-equivalent range error (m), the RMS of the range residuals.
    pub uere: f64,
}

impl GnssEpoch {
    /// Position dilution of precision √(HDOP² + VDOP²).
    pub fn pdop(&self) -> f64 {
        self.hdop.hypot(self.vdop)
    }
}

/// Per-axis error of one quantity: white plus Gauss–Markov, each on its own stream.
#[derive(Clone, Debug)]
struct AxisError {
    white_sigma: f64,
    white: NormalStream,
    gm: Option<GaussMarkov>,
}

impl AxisError {
    fn new(seed: u64, name: &str, white: f64, gm: f64, tau: f64, dt: f64) -> AxisError {
        AxisError {
            white_sigma: white,
            white: NormalStream::new(seed, &format!("{name}/white")),
            gm: (gm > 0.0).then(|| {
                GaussMarkov::new(gm, tau, dt, NormalStream::new(seed, &format!("{name}/gm")))
            }),
        }
    }
    /// The error at the next epoch (the first call gives the GM's initial state).
    fn next(&mut self, first: bool) -> f64 {
        let w = if self.white_sigma > 0.0 {
            self.white_sigma * self.white.draw()
        } else {
            0.0
        };
        let g = match &mut self.gm {
            Some(gm) if first => gm.value(),
            Some(gm) => gm.step(),
            None => 0.0,
        };
        w + g
    }
}

/// The receiver: produces consecutive epochs from a motion. Its error processes advance at
/// every epoch, outages included, so an outage removes epochs without changing the others.
#[derive(Clone, Debug)]
pub struct Receiver {
    cfg: GnssConfig,
    lever: Vec3,
    pos: [AxisError; 3],
    vel: [AxisError; 3],
    fix: Fix,
    sigma_pos: Vec3,
    sigma_vel: Vec3,
    next_k: Option<i64>,
    /// The grid's phase φ: epoch k is at record time (k − φ)/rate.
    phase: f64,
    hint: usize,
}

const AXES: [&str; 3] = ["n", "e", "d"];

impl Receiver {
    /// A receiver with settings `cfg` (checked) whose errors draw from master seed `seed`
    /// (unless `cfg.seed` gives one).
    pub fn new(cfg: GnssConfig, seed: u64) -> Result<Receiver, ConfigError> {
        cfg.validate()?;
        let seed = cfg.seed.unwrap_or(seed);
        let dt = 1.0 / cfg.rate_hz;
        let axis = |q: &str, i: usize, w: [f64; 3], g: [f64; 3], tau: [f64; 3]| {
            AxisError::new(
                seed,
                &format!("gnss/{q}/{}", AXES[i]),
                w[i],
                g[i],
                tau[i],
                dt,
            )
        };
        let pos = std::array::from_fn(|i| {
            axis("pos", i, cfg.pos_white_m, cfg.pos_gm_m, cfg.pos_gm_tau_s)
        });
        let vel = std::array::from_fn(|i| {
            axis(
                "vel",
                i,
                cfg.vel_white_m_s,
                cfg.vel_gm_m_s,
                cfg.vel_gm_tau_s,
            )
        });
        Ok(Receiver {
            lever: Vec3::from(cfg.lever_arm_m),
            pos,
            vel,
            fix: cfg.fix_kind(),
            sigma_pos: cfg.sigma_pos(),
            sigma_vel: cfg.sigma_vel(),
            next_k: None,
            phase: 0.0,
            hint: 0,
            cfg,
        })
    }

    /// The settings.
    pub fn config(&self) -> &GnssConfig {
        &self.cfg
    }

    /// The receiver with its epochs on whole multiples of 1/rate of GPS time, when record time
    /// 0 is GPS second of week `seconds_of_week` (without it: of record time).
    pub fn on_gps_grid(mut self, seconds_of_week: f64) -> Receiver {
        self.phase = grid_phase(self.cfg.rate_hz, seconds_of_week);
        self
    }

    /// Record time of epoch `k`.
    fn epoch_time(&self, k: i64) -> f64 {
        (k as f64 - self.phase) / self.cfg.rate_hz
    }

    /// The time of validity of the epoch [`Receiver::next_epoch`] gives next: the first at or
    /// after `t_from` (before the first call), else the one after the previous.
    pub fn next_time(&self, t_from: f64) -> f64 {
        let k = self.next_k.unwrap_or_else(|| self.first_epoch(t_from));
        self.epoch_time(k)
    }

    /// The next epoch at or after `t_from` (the first call) or after the previous one, if its
    /// time of validity is at most `t_to`.
    pub fn next_epoch(
        &mut self,
        motion: &impl Motion,
        t_from: f64,
        t_to: f64,
    ) -> Option<GnssEpoch> {
        let first = self.next_k.is_none();
        let k = match self.next_k {
            Some(k) => k,
            None => self.first_epoch(t_from),
        };
        self.next_k = Some(k);
        let t = self.epoch_time(k);
        if t > t_to {
            return None;
        }
        self.next_k = Some(k + 1);
        let pos_err_n = Vec3::from(std::array::from_fn(|i| self.pos[i].next(first)));
        let vel_err_n = Vec3::from(std::array::from_fn(|i| self.vel[i].next(first)));
        self.hint = motion.piece_at(t, self.hint);
        let truth = antenna_state(motion, self.hint, t, self.lever);
        let outage = self.cfg.outages_s.iter().any(|w| (w[0]..w[1]).contains(&t));
        let fix = if outage { Fix::None } else { self.fix };
        let measured = if outage {
            truth
        } else {
            displace(truth, pos_err_n, vel_err_n)
        };
        let uere = self.cfg.uere_m;
        Some(GnssEpoch {
            k,
            t,
            t_emit: t + self.cfg.latency_s,
            fix,
            satellites: if outage { 0 } else { self.cfg.satellites },
            measured,
            truth,
            pos_err_n,
            vel_err_n,
            sigma_pos: self.sigma_pos,
            sigma_vel: self.sigma_vel,
            hdop: self.sigma_pos.x.hypot(self.sigma_pos.y) / uere,
            vdop: self.sigma_pos.z / uere,
            uere,
        })
    }

    /// Index of the first epoch at or after `t_from`.
    fn first_epoch(&self, t_from: f64) -> i64 {
        let k = (t_from * self.cfg.rate_hz + self.phase).ceil() as i64;
        // The quotient can round below t_from by an ulp.
        if self.epoch_time(k) < t_from {
            k + 1
        } else {
            k
        }
    }

    /// Every epoch with time of validity in `[t_from, t_to]`, from a fresh receiver.
    pub fn epochs(mut self, motion: &impl Motion, t_from: f64, t_to: f64) -> Vec<GnssEpoch> {
        std::iter::from_fn(|| self.next_epoch(motion, t_from, t_to)).collect()
    }
}

/// The antenna's exact state at `t` (on motion piece `piece`) for lever arm `l` (body):
/// r_a^e = r^e + C_b^e l, and v_a^e = v^e + C_b^e (ω_eb^b × l) with ω_eb^b = ω_ib^b − C_n^b ω_ie^n
/// (the derivative of C_b^e l in the Earth frame), expressed in the antenna's own NED axes.
pub fn antenna_state(motion: &impl Motion, piece: usize, t: f64, l: Vec3) -> AntennaState {
    let p = motion.pose(t);
    if l == Vec3::zeros() {
        return AntennaState {
            lat: p.lat,
            lon: p.lon,
            h: p.h,
            v_n: p.v_n,
        };
    }
    let g = Geodetic::from_radians(p.lat, p.lon, p.h);
    let c_n_e = g.c_n_e();
    let w_ie_b = p.q_b_n.rotate_inv(earth::omega_ie_n(g.sin_lat, g.cos_lat));
    let w_eb_b = motion.sense(piece, t).omega_ib_b - w_ie_b;
    let r_a = g.to_ecef() + c_n_e * p.q_b_n.rotate(l);
    let v_a_e = c_n_e * (p.v_n + p.q_b_n.rotate(w_eb_b.cross(&l)));
    let ga = earth::ecef_to_geodetic(r_a);
    AntennaState {
        lat: ga.lat(),
        lon: ga.lon(),
        h: ga.h,
        v_n: ga.c_n_e().tr_mul(&(v_a_e)),
    }
}

/// `s` moved by a NED position error `dp` (m, on the local radii of curvature) and a NED
/// velocity error `dv`.
pub fn displace(s: AntennaState, dp: Vec3, dv: Vec3) -> AntennaState {
    let sin_lat = s.lat.sin();
    let rn = earth::radius_meridian(sin_lat) + s.h;
    let re = earth::radius_prime_vertical(sin_lat) + s.h;
    AntennaState {
        lat: s.lat + dp.x / rn,
        lon: s.lon + dp.y / (re * s.lat.cos()),
        h: s.h - dp.z,
        v_n: s.v_n + dv,
    }
}

/// The phase φ ∈ [0, 1) of the epoch grid at `rate` (Hz) when record time 0 is GPS second
/// `seconds_of_week`: epoch k at record time (k − φ)/rate is at GPS time
/// (⌊seconds_of_week·rate⌋ + k)/rate, a whole multiple of 1/rate, as a receiver reports.
pub fn grid_phase(rate: f64, seconds_of_week: f64) -> f64 {
    let x = (seconds_of_week * rate).fract();
    if x.is_finite() && x >= 0.0 { x } else { 0.0 }
}

/// How many epochs at `rate` (Hz) on a grid of phase `phase` ([`grid_phase`]) fall in
/// `[t0, t1]` (outages included: they are sent without a fix).
pub fn epoch_count(rate: f64, phase: f64, (t0, t1): (f64, f64)) -> u64 {
    ((t1 * rate + phase).floor() - (t0 * rate + phase).ceil() + 1.0).max(0.0) as u64
}
