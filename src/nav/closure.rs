//! Closure runs: generate a motion's records block by block (error-free, or through an error
//! chain), navigate them from the true initial state and measure the error against the
//! truth — what the closure tests and `validate` need.

use super::strapdown::{NavState, Navigator, Settings, SettingsError, StateError};
use crate::engine::{self, BLOCK, EngineError, Grid, Producer, SourceSpec};
use crate::errors::ErrorChain;
use crate::motion::Motion;
use crate::motion::sampled::ModelSettings;
use crate::scenes::SceneParams;
use crate::source::AnyMotion;

/// Outcome of one closure run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closure {
    /// Records navigated.
    pub records: u64,
    /// Error at the last record.
    pub last: StateError,
    /// Largest 3-D position error over the run (m).
    pub max_pos: f64,
    /// Largest 3-D velocity error over the run (m/s).
    pub max_vel: f64,
    /// Largest attitude error angle over the run (rad).
    pub max_att: f64,
}

/// Navigates the records of `motion` on `grid` (corrupted by `chain` when given) from the
/// true state at t₀ and returns the errors against the truth, checked at every
/// `check_every`-th record and at the last.
pub fn close(
    motion: &AnyMotion,
    grid: &Grid,
    settings: Settings,
    chain: Option<ErrorChain>,
    check_every: u64,
) -> Result<Closure, CloseError> {
    let start = NavState::from_pose(&motion.pose(grid.t0));
    let mut nav = Navigator::new(start, grid.rate_hz, settings)?;
    let mut producer = Producer::records(motion.clone(), *grid, chain);
    let mut out = Closure {
        records: grid.count,
        last: StateError::default(),
        max_pos: 0.0,
        max_vel: 0.0,
        max_att: 0.0,
    };
    let every = check_every.max(1);
    while let Some(b) = producer.next_records(BLOCK) {
        for (i, r) in b.records.iter().enumerate() {
            nav.step(r.dtheta, r.dv);
            let kk = b.first + 1 + i as u64;
            if kk.is_multiple_of(every) || kk == grid.count {
                let s = nav.state();
                let e = StateError::of(&s, &motion.pose(s.t));
                out.max_pos = out.max_pos.max(e.pos_ned.norm());
                out.max_vel = out.max_vel.max(e.vel_ned.norm());
                out.max_att = out.max_att.max(e.att_ned.norm());
                out.last = e;
            }
        }
    }
    producer.finished()?;
    Ok(out)
}

/// Why a scene closure could not run.
#[derive(Debug, thiserror::Error)]
pub enum CloseError {
    /// Unknown scene, bad span or rate.
    #[error(transparent)]
    Job(#[from] EngineError),
    /// Bad navigator settings.
    #[error(transparent)]
    Settings(#[from] SettingsError),
}

/// Navigates built-in scene `name` (default parameters) error-free for `seconds` (default:
/// the scene's span, 60 s when unbounded) at `rate_hz` with the default navigator, and
/// returns the closure error — the check `validate` reports.
pub fn close_scene(name: &str, rate_hz: f64, seconds: Option<f64>) -> Result<Closure, CloseError> {
    let source = SourceSpec::Scene(name.to_string(), SceneParams::defaults_for(name));
    let motion = engine::build_motion(&source, ModelSettings::default())?;
    let grid = engine::plan(&motion, rate_hz, None, seconds)?;
    close(&motion, &grid, Settings::default(), None, 100)
}
