//! Navigating recorded increments against the reference they were generated from
//! (`imu-emu navigate`): free-inertially from the reference's state at the records' t₀, or
//! GNSS-aided with fixes read back from a `--gnss-truth` file; per record the navigated state
//! and its error, then the run's summary.
//!
//! The records must follow one another at one rate from a t₀ inside the reference: the rate
//! is given or read from the first two record times, and a gap, a wrong rate or a record past
//! the reference's end stops the run with the record named.

use std::path::Path;

use super::aided::{AidedConfig, AidedNavigator};
use super::gnss_fixes::{FixEpoch, read_fixes};
use super::strapdown::{NavState, Navigator, Settings, SettingsError, StateError};
use crate::csvio::{FileError, num};
use crate::math::Vec3;
use crate::motion::limits::{MAX_ACCEL_M_S2, MAX_RATE_RAD_S};
use crate::motion::{Motion, Pose};
use crate::record::Record;

/// Why recorded increments cannot be navigated; the input is named in each message.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The records (or the GNSS fixes) cannot be read.
    #[error(transparent)]
    Read(#[from] FileError),
    /// The navigator's settings or the rate are unusable.
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// The records do not fit the reference or one another.
    #[error("{0}")]
    Records(String),
}

/// The header of the error CSV: position (m), velocity (m/s) and attitude (rad) errors, NED,
/// and the position error's norm.
pub const ERROR_HEADER: &str =
    "t,north_m,east_m,down_m,vn_m_s,ve_m_s,vd_m_s,att_n_rad,att_e_rad,att_d_rad,position_m\n";

/// A vector for a message: `[x, y, z]`, each number as short as it reads back.
fn vec3(v: Vec3) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

/// The navigated state at one record time, and its error against the reference.
#[derive(Clone, Copy, Debug)]
pub struct Step {
    /// The navigated pose.
    pub pose: Pose,
    /// Its error against the reference at the same time.
    pub error: StateError,
}

impl Step {
    /// Appends the pose as a trajectory CSV row ([`crate::trajectory::COLUMNS`]).
    pub fn trajectory_row(&self, text: &mut String) {
        crate::trajectory::pose_row(text, &self.pose);
    }

    /// Appends the error as a row of the error CSV ([`ERROR_HEADER`]).
    pub fn error_row(&self, text: &mut String, fmt: &mut ryu::Buffer) {
        let e = &self.error;
        text.push_str(fmt.format(self.pose.t));
        for v in [e.pos_ned, e.vel_ned, e.att_ned] {
            for &x in v.iter() {
                text.push(',');
                text.push_str(fmt.format(x));
            }
        }
        text.push(',');
        text.push_str(fmt.format(e.pos_ned.norm()));
        text.push('\n');
    }
}

/// How GNSS fixes went into the solution.
#[derive(Clone, Debug, Default)]
pub struct Aiding {
    /// The fixes' file.
    pub source: String,
    /// Fixes applied.
    pub fixes_used: u64,
    /// The free-inertial solution's final position error (m).
    pub free_last: f64,
    /// … and its largest (m).
    pub free_max: f64,
}

/// A finished navigation.
#[derive(Clone, Debug)]
pub struct Summary {
    /// Records navigated.
    pub records: u64,
    /// Their rate (Hz).
    pub rate: f64,
    /// Time of the state the navigation started from (s).
    pub t0: f64,
    /// The navigator's settings.
    pub settings: Settings,
    /// The error at the last record.
    pub last: StateError,
    /// The largest position (m), velocity (m/s) and attitude (rad) errors.
    pub max: [f64; 3],
    /// The GNSS aiding, when fixes were given.
    pub aiding: Option<Aiding>,
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (last, [max_pos, max_vel, max_att]) = (&self.last, self.max);
        write!(
            f,
            "navigated {} records at {} Hz, {:.3} s from t₀ = {} s (samples {}, stages {})\n\
             final error: position NED [{:+.3e}, {:+.3e}, {:+.3e}] m (|{:.3e}| m), velocity |{:.3e}| m/s, attitude NED [{:+.3e}, {:+.3e}, {:+.3e}] rad\n\
             max error:   position {:.3e} m, velocity {:.3e} m/s, attitude {:.3e} rad\n",
            self.records,
            self.rate,
            self.records as f64 / self.rate,
            self.t0,
            self.settings.samples,
            self.settings.stages,
            last.pos_ned.x,
            last.pos_ned.y,
            last.pos_ned.z,
            last.pos_ned.norm(),
            last.vel_ned.norm(),
            last.att_ned.x,
            last.att_ned.y,
            last.att_ned.z,
            max_pos,
            max_vel,
            max_att,
        )?;
        if let Some(a) = &self.aiding {
            writeln!(
                f,
                "GNSS-aided with {} fixes from {}; free-inertial: final position error {:.3e} m, max {:.3e} m",
                a.fixes_used, a.source, a.free_last, a.free_max
            )?;
        }
        Ok(())
    }
}

/// Recorded increments about to be navigated: the rate and t₀ found, the start state taken
/// from the reference.
pub struct Replay<M, R> {
    name: String,
    motion: M,
    records: R,
    first: Vec<Record>,
    rate: f64,
    t0: f64,
    start: Pose,
    settings: Settings,
    nav: Navigator,
    aided: Option<(AidedNavigator, Vec<FixEpoch>, String)>,
}

impl<M: Motion, R: Iterator<Item = Result<Record, FileError>>> Replay<M, R> {
    /// Reads the first records of `records` (named `name` in messages) to find their rate
    /// (`rate`, else from the first two times) and t₀, which must lie inside `motion`, the
    /// reference; the navigator starts from the reference's state there.
    pub fn start(
        name: &str,
        mut records: R,
        motion: M,
        rate: Option<f64>,
        settings: Settings,
    ) -> Result<Self, ReplayError> {
        let first: Vec<Record> = records.by_ref().take(2).collect::<Result<_, _>>()?;
        let refuse = |m: String| Err(ReplayError::Records(format!("{name}: {m}")));
        let Some(r1) = first.first() else {
            return refuse("no records".into());
        };
        let rate = match (rate, first.get(1)) {
            (Some(r), _) => r,
            (None, Some(r2)) => 1.0 / (r2.t - r1.t),
            (None, None) => return refuse("one record only; give --rate to navigate it".into()),
        };
        if !(rate.is_finite() && rate > 0.0) {
            return refuse(format!(
                "record times {} and {} do not increase; give --rate",
                num(r1.t),
                num(first.get(1).map_or(f64::NAN, |r| r.t))
            ));
        }
        let t0 = r1.t - 1.0 / rate;
        if !(t0 >= motion.start() - 1e-9 && t0 <= motion.end()) {
            return refuse(format!(
                "the records start at t₀ = {} s, outside the reference [{}, {}] s",
                num(t0),
                num(motion.start()),
                num(motion.end())
            ));
        }
        let start = motion.pose(t0);
        let nav = Navigator::new(NavState::from_pose(&start), rate, settings)?;
        Ok(Replay {
            name: name.to_string(),
            motion,
            records,
            first,
            rate,
            t0,
            start,
            settings,
            nav,
            aided: None,
        })
    }

    /// Navigates GNSS-aided (a 15-state loosely coupled filter) with the fixes of `path` (a
    /// `generate --gnss-truth` CSV), whose 1σ errors per axis are `sigma_pos` (m) and
    /// `sigma_vel` (m/s), from an antenna at `lever_arm_m` (body axes, m); the free-inertial
    /// solution is still run, to report next to the aided one.
    pub fn aid(
        &mut self,
        path: &Path,
        sigma_pos: f64,
        sigma_vel: f64,
        lever_arm_m: [f64; 3],
    ) -> Result<(), ReplayError> {
        let mut fixes = read_fixes(path, Vec3::repeat(sigma_pos), Vec3::repeat(sigma_vel))?;
        fixes.reverse();
        let cfg = AidedConfig {
            lever_arm_m,
            ..AidedConfig::default()
        };
        let start = NavState::from_pose(&self.start);
        let nav = AidedNavigator::new(start, self.rate, self.settings, cfg)?;
        self.aided = Some((nav, fixes, path.display().to_string()));
        Ok(())
    }

    /// The state navigation starts from: the reference at t₀ (with zero error).
    pub fn first_step(&self) -> Step {
        Step {
            pose: self.start,
            error: StateError::default(),
        }
    }

    /// Navigates every record, handing each step to `each`; a step's error is `E`'s.
    pub fn run<E: From<ReplayError>>(
        self,
        mut each: impl FnMut(&Step) -> Result<(), E>,
    ) -> Result<Summary, E> {
        let Replay {
            name,
            motion,
            records,
            first,
            rate,
            t0,
            settings,
            mut nav,
            mut aided,
            ..
        } = self;
        let refuse = |m: String| E::from(ReplayError::Records(format!("{name}: {m}")));
        let mut aiding = aided.as_ref().map(|a| Aiding {
            source: a.2.clone(),
            ..Aiding::default()
        });
        let mut max = [0.0f64; 3];
        let mut last = StateError::default();
        let mut k = 0u64;
        for rec in first.into_iter().map(Ok).chain(records) {
            let rec = rec.map_err(|e| E::from(ReplayError::Read(e)))?;
            k += 1;
            let want = t0 + k as f64 / rate;
            let off = (rec.t - want).abs();
            if off.is_nan() || off > 1e-6 / rate + 1e-12 * want.abs() {
                return Err(refuse(format!(
                    "record {k}: t = {} s, expected {} s for a {} Hz stream starting at {} s (gap, or --rate wrong)",
                    num(rec.t),
                    num(want),
                    num(rate),
                    num(t0)
                )));
            }
            // Increments no IMU measures (beyond 1e4 rad/s and 1e5 m/s² over the interval)
            // make any navigation meaningless: the record is named rather than the navigator.
            let (wmax, fmax) = (MAX_RATE_RAD_S / rate, MAX_ACCEL_M_S2 / rate);
            if !(rec.dtheta.amax() <= wmax && rec.dv.amax() <= fmax) {
                return Err(refuse(format!(
                    "record {k} at t = {} s: increments dtheta {} rad, dv {} m/s are not finite or beyond what an IMU measures in 1/{} s ({} rad, {} m/s)",
                    num(rec.t),
                    vec3(rec.dtheta),
                    vec3(rec.dv),
                    num(rate),
                    num(wmax),
                    num(fmax)
                )));
            }
            nav.step(rec.dtheta, rec.dv);
            let s = match (aided.as_mut(), aiding.as_mut()) {
                (Some((an, fixes, _)), Some(a)) => {
                    let free = StateError::of(&nav.state(), &motion.pose(nav.state().t));
                    a.free_max = a.free_max.max(free.pos_ned.norm());
                    a.free_last = free.pos_ned.norm();
                    an.step(rec.dtheta, rec.dv);
                    // A fix applies at the first record at or after its time of validity.
                    while let Some(&(t, fix)) = fixes.last()
                        && t <= rec.t + 1e-9
                    {
                        fixes.pop();
                        if let Some(f) = fix {
                            an.update(&f);
                            a.fixes_used += 1;
                        }
                    }
                    an.state()
                }
                _ => nav.state(),
            };
            if s.t > motion.end() + 1e-9 {
                return Err(refuse(format!(
                    "record {k} at t = {} s is past the end of the reference ({} s)",
                    num(s.t),
                    num(motion.end())
                )));
            }
            let e = StateError::of(&s, &motion.pose(s.t));
            if !(e.pos_ned.norm().is_finite() && e.vel_ned.norm().is_finite()) {
                let which = if aided.is_some() {
                    "the GNSS-aided filter diverged"
                } else {
                    "the free-inertial solution overflowed"
                };
                return Err(refuse(format!(
                    "record {k} at t = {} s: the navigated state is not finite ({which})",
                    num(s.t)
                )));
            }
            for (m, v) in max.iter_mut().zip([e.pos_ned, e.vel_ned, e.att_ned]) {
                *m = m.max(v.norm());
            }
            last = e;
            each(&Step {
                pose: s.pose(),
                error: e,
            })?;
        }
        Ok(Summary {
            records: k,
            rate,
            t0,
            settings,
            last,
            max,
            aiding,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::Simulation;

    /// Error-free records of the circle at 400 Hz for 2 s, and the motion they came from.
    fn circle() -> (Vec<Record>, crate::source::AnyMotion) {
        let sim = Simulation::builder()
            .scene("circle")
            .rate(400.0)
            .duration(2.0)
            .build()
            .unwrap();
        let motion = sim.motion().clone();
        let records = sim.records().unwrap().flat_map(|b| b.unwrap()).collect();
        (records, motion)
    }

    /// Its own error-free records navigate back onto the reference (the closure `validate`
    /// bounds by 1 mm over 600 s; 2 s stay far inside it), one step per record.
    #[test]
    fn error_free_records_close_on_their_reference() {
        let (records, motion) = circle();
        let replay = Replay::start(
            "c",
            records.into_iter().map(Ok),
            motion,
            None,
            Settings::default(),
        )
        .unwrap();
        let mut steps = 0;
        let summary = replay
            .run(|_| {
                steps += 1;
                Ok::<(), ReplayError>(())
            })
            .unwrap();
        assert_eq!((summary.records, steps, summary.rate), (800, 800, 400.0));
        assert!(
            summary.max[0] < 1e-6,
            "max position error {}",
            summary.max[0]
        );
    }

    /// A missing record is named (its number and times), not navigated over.
    #[test]
    fn a_gap_names_the_record() {
        let (mut records, motion) = circle();
        records.remove(99);
        let replay = Replay::start(
            "gap.bin",
            records.into_iter().map(Ok),
            motion,
            None,
            Settings::default(),
        )
        .unwrap();
        let e = replay.run(|_| Ok::<(), ReplayError>(())).unwrap_err();
        assert_eq!(
            e.to_string(),
            "gap.bin: record 100: t = 0.2525 s, expected 0.25 s for a 400 Hz stream starting at 0 s (gap, or --rate wrong)"
        );
    }
}
