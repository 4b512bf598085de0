//! One seeded run of one unit over one mission: its records navigated free-inertially or
//! GNSS-aided around outage windows, the errors sampled along each window. Pure computation,
//! no I/O.
//!
//! Free-inertial (no GNSS): the windows lie back to back from the start; the navigator starts
//! from the truth and is reset to the truth at each window's start (its record history is
//! kept), so each window is one outage scored from a perfect start.
//!
//! GNSS-aided: the loosely coupled filter of [`crate::nav::aided`] takes every fix of the
//! simulated receiver outside the windows; inside a window (an outage) it runs free-inertial
//! on what it learnt (its position, velocity, attitude and bias estimates). Window w starts
//! after `aided` records of fixes since the previous window ended: at record
//! aided + w·(aided + outage). The first sample of each window (elapsed 0) is the aided error
//! at the outage start. With no outage length, one window spans the run and GNSS is never off:
//! the samples are the aided error along the run.

use super::unit::Candidate;
use crate::aiding::GnssConfig;
use crate::aiding::gnss::Receiver;
use crate::engine::{EngineError, Grid};
use crate::errors::model::TriadModel;
use crate::errors::template::ImuModel;
use crate::motion::Motion;
use crate::nav::aided::{AidedConfig, AidedNavigator, GnssFix};
use crate::nav::strapdown::{NavState, Navigator, Settings, SettingsError, StateError};
use crate::source::AnyMotion;

/// Where the windows lie, in records of the unit's grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Windows {
    /// Records before the first window.
    pub first: u64,
    /// Records between a window's end and the next one's start (GNSS on).
    pub gap: u64,
    /// Records per window.
    pub len: u64,
    /// Number of windows.
    pub count: u64,
}

impl Windows {
    /// Start (elapsed records) of window `w`.
    pub fn start(&self, w: u64) -> u64 {
        self.first + w * (self.gap + self.len)
    }

    /// Whether the state after record `k` lies inside an outage (after a window's start,
    /// up to and including its end).
    fn in_outage(&self, k: u64) -> bool {
        if k <= self.first {
            return false;
        }
        let e = k - self.first - 1;
        let period = self.gap + self.len;
        e / period < self.count && e % period < self.len
    }
}

/// How a run is navigated.
#[derive(Clone, Debug)]
pub enum Mode {
    /// Free-inertial, reset to the truth at each window start.
    Free,
    /// GNSS-aided outside the windows; `outage`: whether the windows are outages (else one
    /// window over the run, always aided).
    Aided {
        /// The receiver's settings.
        gnss: Box<GnssConfig>,
        /// Whether the windows are outages.
        outage: bool,
    },
}

/// What went wrong in one run.
#[derive(Debug, thiserror::Error)]
pub enum FlyError {
    /// The engine refused the unit's run.
    #[error(transparent)]
    Engine(#[from] EngineError),
    /// Bad navigator settings.
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// The receiver refused its settings.
    #[error("GNSS receiver: {0}")]
    Gnss(String),
    /// A non-finite error (a diverged navigator or a non-finite record).
    #[error("unit `{unit}`: the navigation error is not finite at t = {t} s")]
    NonFinite {
        /// The unit.
        unit: String,
        /// Record time.
        t: f64,
    },
}

/// The sample offsets (elapsed records since a window's start) in every window.
pub fn offsets(len: u64, points: usize, with_start: bool) -> Vec<u64> {
    let p = (points as u64).clamp(1, len.max(1));
    let ends = (1..=p).map(|i| (i * len + p / 2) / p);
    with_start.then_some(0).into_iter().chain(ends).collect()
}

/// Navigates one run of `unit` over `grid` with errors from `seed` and returns, window by
/// window and offset by offset, the 3-D position (m), velocity (m/s) and attitude (rad)
/// errors.
#[allow(clippy::too_many_arguments)]
pub fn fly(
    unit: &Candidate,
    motion: &AnyMotion,
    grid: Grid,
    windows: Windows,
    offs: &[u64],
    mode: &Mode,
    settings: Settings,
    seed: u64,
) -> Result<Vec<[f64; 3]>, FlyError> {
    let g = grid;
    let grid = Grid {
        count: windows.start(windows.count - 1) + windows.len,
        ..g
    };
    let mut records = unit.records(motion, grid, unit.seed(seed))?;
    let time = |k: u64| g.t0 + k as f64 / g.rate_hz;
    let truth = |k: u64| unit.truth(motion, time(k));
    let mut nav = match mode {
        Mode::Free => Nav::Free(Box::new(Navigator::new(truth(0), g.rate_hz, settings)?)),
        Mode::Aided { gnss, .. } => {
            let cfg = filter_model(&unit.model, gnss, unit);
            let rx = Receiver::new(receiver_config(gnss, motion), seed)
                .map_err(|e| FlyError::Gnss(e.to_string()))?;
            Nav::Aided(
                Box::new(AidedNavigator::new(truth(0), g.rate_hz, settings, cfg)?),
                Box::new(rx),
            )
        }
    };
    let outages = matches!(mode, Mode::Aided { outage: true, .. });
    // Sample instants (elapsed records), window by window: increasing.
    let samples: Vec<u64> = (0..windows.count)
        .flat_map(|w| offs.iter().map(move |o| windows.start(w) + o))
        .collect();
    let mut out = Vec::with_capacity(samples.len());
    let sample = |nav: &Nav, k: u64, out: &mut Vec<[f64; 3]>| -> Result<(), FlyError> {
        let s = nav.state();
        let e = match unit.at_reference() {
            true => StateError::of(&s, &motion.pose(s.t)),
            false => StateError::of(&s, &truth(k).pose()),
        };
        let v = [e.pos_ned.norm(), e.vel_ned.norm(), e.att_ned.norm()];
        if !v.iter().all(|x| x.is_finite()) {
            return Err(FlyError::NonFinite {
                unit: unit.name.clone(),
                t: time(k),
            });
        }
        out.push(v);
        Ok(())
    };
    let mut next = 0usize;
    while samples.get(next) == Some(&0) {
        sample(&nav, 0, &mut out)?;
        next += 1;
    }
    let half = 0.5 / g.rate_hz;
    while let Some(b) = records.next_block() {
        for (i, r) in b.records.iter().enumerate() {
            let k = b.first + i as u64;
            match &mut nav {
                Nav::Free(n) => {
                    let before = k - 1;
                    if before > 0 && before.is_multiple_of(windows.len) {
                        n.reset(&truth(before));
                    }
                    n.step(r.dtheta, r.dv);
                }
                Nav::Aided(n, rx) => {
                    n.step(r.dtheta, r.dv);
                    let t = time(k);
                    let off = outages && windows.in_outage(k);
                    while rx.next_time(g.t0) <= t + half {
                        let Some(e) = rx.next_epoch(motion, g.t0, t + half) else {
                            break;
                        };
                        // Fixes before the first record: the start is the truth already.
                        if e.t > g.t0 + half
                            && !off
                            && let Some(fix) = GnssFix::from_epoch(&e)
                        {
                            n.update(&fix);
                        }
                    }
                }
            }
            while samples.get(next) == Some(&k) {
                sample(&nav, k, &mut out)?;
                next += 1;
            }
        }
    }
    records.finished()?;
    Ok(out)
}

/// The navigator of a run.
enum Nav {
    Free(Box<Navigator>),
    Aided(Box<AidedNavigator>, Box<Receiver>),
}

impl Nav {
    fn state(&self) -> NavState {
        match self {
            Nav::Free(n) => n.state(),
            Nav::Aided(n, _) => n.state(),
        }
    }
}

/// The receiver's settings with a motion definition's spans without GNSS visibility added
/// as further outages (as the GNSS stream of `generate` has them).
fn receiver_config(gnss: &GnssConfig, motion: &AnyMotion) -> GnssConfig {
    let mut cfg = gnss.clone();
    if let Some(m) = motion.defined() {
        cfg.outages_s.extend(m.gnss_outages());
    }
    cfg
}

/// The filter's model of the unit, from its template: the white-noise densities, the bias
/// random walks (a bias instability B taken as a random walk that reaches B in 100 s, the
/// scale of an outage) and the initial bias σ (constant, turn-on, instability and
/// Gauss–Markov terms together: the filter knows none of them); the antenna in the unit's
/// axes from its point. A start known to 0.1 m, 0.01 m/s, 0.01°: the navigator starts at the
/// truth. Floors keep the covariance positive for an error-free template.
pub fn filter_model(model: &ImuModel, gnss: &GnssConfig, unit: &Candidate) -> AidedConfig {
    let max = |v: [f64; 3]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let rw = |t: &TriadModel| max(t.random_walk).hypot(max(t.bias_instability) / 100f64.sqrt());
    let bias = |t: &TriadModel| {
        let gm = t.bias_gm.map_or(0.0, |(s, _)| max(s));
        let terms = [
            max(t.bias),
            max(t.bias_turn_on),
            max(t.bias_instability),
            gm,
        ];
        terms.iter().map(|x| x * x).sum::<f64>().sqrt()
    };
    let deg_h = 1f64.to_radians() / 3600.0;
    let place = crate::rig::geometry::Placement::new(unit.mounting_deg, unit.lever_arm_m);
    let antenna = crate::math::Vec3::from(gnss.lever_arm_m) - place.lever_b;
    AidedConfig {
        lever_arm_m: place.to_case(antenna).into(),
        gyro_arw: max(model.gyro.noise).max(1e-9),
        accel_vrw: max(model.accel.noise).max(1e-9),
        gyro_bias_rw: rw(&model.gyro).max(1e-12),
        accel_bias_rw: rw(&model.accel).max(1e-12),
        initial_sigma: [
            0.1,
            0.01,
            0.01f64.to_radians(),
            bias(&model.gyro).max(1e-3 * deg_h),
            bias(&model.accel).max(1e-6),
        ],
        ..AidedConfig::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outage_windows_and_offsets() {
        let w = Windows {
            first: 10,
            gap: 10,
            len: 5,
            count: 2,
        };
        assert_eq!((w.start(0), w.start(1)), (10, 25));
        let off: Vec<u64> = (0..40).filter(|&k| w.in_outage(k)).collect();
        assert_eq!(off, vec![11, 12, 13, 14, 15, 26, 27, 28, 29, 30]);
        assert_eq!(offsets(10, 4, false), vec![3, 5, 8, 10]);
        assert_eq!(offsets(3, 100, true), vec![0, 1, 2, 3]);
    }
}
