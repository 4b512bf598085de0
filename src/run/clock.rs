//! When a run's frames go out: as fast as possible, at wall-clock rate, behind a live input in
//! real time, or in lockstep with it — decided from the clock settings, the input and the
//! sinks, with the settings that cannot apply to that clock refused.

use crate::output::SinkAddr;

use super::error::{RunError, refuse};
use super::spec::{ClockSpec, LiveSpec, Route, Speed};

/// Default limit of burst catch-up after a stall (ms).
pub const DEFAULT_MAX_BEHIND_MS: f64 = 100.0;

/// When the frames go out.
#[derive(Clone, Debug, PartialEq)]
pub enum Clock {
    /// As fast as the machine allows, no wall clock.
    Free,
    /// As the live input arrives: each state releases what it completes.
    Lockstep,
    /// Known motion at wall-clock rate.
    Paced(Wall),
    /// Live motion at the host instants of its simulation time plus an output delay.
    Realtime(Wall),
}

/// The wall-clock side of a paced or real-time run.
#[derive(Clone, Debug, PartialEq)]
pub struct Wall {
    /// Simulated seconds per wall-clock second.
    pub speed: f64,
    /// Wall-clock instant of t₀ as given.
    pub start_at: Option<String>,
    /// Frames later than this are skipped (ns).
    pub max_behind_ns: i128,
    /// Ask for `SCHED_FIFO`.
    pub fifo: bool,
}

impl Clock {
    /// The wall-clock settings of a paced or real-time run.
    pub fn wall(&self) -> Option<&Wall> {
        match self {
            Clock::Paced(w) | Clock::Realtime(w) => Some(w),
            Clock::Free | Clock::Lockstep => None,
        }
    }
}

/// The clock the settings give.
pub(super) fn decide_clock(
    c: &ClockSpec,
    input: Option<&LiveSpec>,
    routes: &[Route],
) -> Result<Clock, RunError> {
    let max_behind = c.max_behind_ms.unwrap_or(DEFAULT_MAX_BEHIND_MS);
    if !(max_behind.is_finite() && max_behind >= 0.0) {
        return Err(refuse(
            &format!("--max-behind-ms {max_behind}"),
            "expected a non-negative number",
        ));
    }
    if let Some(Speed::Factor(x)) = c.speed
        && !(x.is_finite() && x > 0.0)
    {
        return Err(refuse(
            &format!("--speed {x}"),
            "expected a positive factor (1 = real time) or `max`",
        ));
    }
    let wall = |speed: f64| Wall {
        speed,
        start_at: c.start_at.clone(),
        max_behind_ns: (max_behind * 1e6) as i128,
        fifo: c.realtime_priority,
    };
    let mode = match input {
        Some(i) => {
            if c.speed.is_some() {
                return Err(refuse(
                    "--speed",
                    "a --motion run follows its input's clock (lockstep: as the states come; realtime: at their instants)",
                ));
            }
            if c.start_at.is_some() {
                return Err(refuse(
                    "--start-at",
                    "a --motion run starts with its first state",
                ));
            }
            if i.lockstep {
                Clock::Lockstep
            } else {
                Clock::Realtime(wall(1.0))
            }
        }
        None => {
            let only_files =
                !routes.is_empty() && routes.iter().all(|r| matches!(r.sink, SinkAddr::File(_)));
            match c.speed {
                Some(Speed::Max) => Clock::Free,
                Some(Speed::Factor(x)) => Clock::Paced(wall(x)),
                None if only_files => Clock::Free,
                None => Clock::Paced(wall(1.0)),
            }
        }
    };
    if matches!(mode, Clock::Free | Clock::Lockstep) {
        let why = match mode {
            Clock::Lockstep => {
                "lockstep has no wall clock: each state releases its records at once"
            }
            _ => "an unpaced run has no wall clock (give --speed 1, or a sink that is not a file)",
        };
        let wall_only = [
            ("--max-behind-ms", c.max_behind_ms.is_some()),
            ("--realtime", c.realtime_priority),
        ];
        if let Some((flag, _)) = wall_only.iter().find(|x| x.1) {
            return Err(refuse(flag, why));
        }
    }
    if let (Clock::Paced(_) | Clock::Free, Some(s)) = (&mode, &c.start_at)
        && let Err(e) = crate::timebase::parse_start(s, 0, &crate::timebase::LeapTable::builtin())
    {
        return Err(refuse("--start-at", e));
    }
    Ok(mode)
}
