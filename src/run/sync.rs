//! The sync lines of a run — time marks, a pulse, a PPS lock, a trigger — checked against its
//! clock, its units and their sinks: each belongs to a wall clock, names a unit the run has,
//! and a pulse drives a line that exists.

use crate::output::SinkAddr;

use super::clock::Clock;
use super::error::{RunError, refuse};
use super::routing::Layout;
use super::spec::{SyncSpec, TimeBase};

/// The sync lines, checked.
#[derive(Clone, Debug, Default)]
pub struct Sync {
    /// Time-mark targets, each of one unit (index into the units).
    pub time_marks: Vec<(usize, String)>,
    /// The pulse: its spec as given, the line it drives, the unit it marks.
    pub pulse: Option<(String, PulseOut, usize)>,
    /// The PPS source the output phase-locks to.
    pub pps_in: Option<String>,
    /// The trigger source every unit samples on.
    pub trigger: Option<String>,
}

/// The line a pulse drives.
#[derive(Clone, Debug)]
pub enum PulseOut {
    /// A serial device's modem line.
    Port(String),
    /// A line given in code.
    #[cfg(feature = "realtime")]
    Line(super::spec::PulseLine),
}

/// The sync lines against the clock and the units.
pub(super) fn check_sync(
    s: SyncSpec,
    mode: &Clock,
    units: &[String],
    layout: &Layout,
    time_base: TimeBase,
) -> Result<Sync, RunError> {
    let any =
        !s.time_marks.is_empty() || s.pulse.is_some() || s.pps_in.is_some() || s.trigger.is_some();
    let flag = if !s.time_marks.is_empty() {
        "--time-marks"
    } else if s.pulse.is_some() {
        "--pulse"
    } else if s.pps_in.is_some() {
        "--pps-in"
    } else {
        "--trigger"
    };
    #[cfg(feature = "realtime")]
    if s.pulse.is_none() && s.pulse_line.is_some() {
        return Err(refuse(
            "--pulse",
            "a pulse line was given in code (RunSpec::pulse_on) without the pulse: give RunSpec::pulse",
        ));
    }
    if s.pulse.is_none() {
        if s.pulse_port.is_some() {
            return Err(refuse("--pulse-port", "without --pulse"));
        }
        if s.pulse_unit.is_some() {
            return Err(refuse("--pulse-unit", "without --pulse"));
        }
    }
    let speed = match mode {
        Clock::Free if any => {
            return Err(refuse(
                flag,
                "needs a paced run: time marks, pulses, a PPS lock and a trigger live on the wall clock (give --speed 1)",
            ));
        }
        Clock::Lockstep if any => {
            return Err(refuse(
                flag,
                "needs a wall clock, which lockstep does not have (--time-mode realtime)",
            ));
        }
        Clock::Paced(w) | Clock::Realtime(w) => w.speed,
        _ => 1.0,
    };
    if (s.pps_in.is_some() || s.trigger.is_some()) && speed != 1.0 {
        let f = if s.pps_in.is_some() {
            "--pps-in"
        } else {
            "--trigger"
        };
        return Err(refuse(
            f,
            "locks to real seconds and real edges: give --speed 1",
        ));
    }
    if s.trigger.is_some() && s.pps_in.is_some() {
        return Err(refuse(
            "--trigger",
            "the units sample at its edges, not on the schedule a PPS lock slews: drop --pps-in",
        ));
    }
    if s.trigger.is_some() && matches!(mode, Clock::Paced(w) if w.start_at.is_some()) {
        return Err(refuse(
            "--trigger",
            "sets t₀ at its first edge: drop --start-at",
        ));
    }
    if s.pps_in.is_some() && matches!(mode, Clock::Realtime(_)) && time_base == TimeBase::Sim {
        return Err(refuse(
            "--pps-in",
            "with --motion the output's seconds follow the sender's clock, which a PPS cannot discipline: use --time-base gps (the input's tags and the PPS are both GPS time)",
        ));
    }
    let unit = |name: &Option<String>, flag: &str| -> Result<Option<usize>, RunError> {
        match name {
            None => Ok(None),
            Some(n) => (units.iter().position(|u| u == n))
                .map(Some)
                .ok_or_else(|| {
                    refuse(flag, format!("no unit `{n}` (units: {})", units.join(", ")))
                }),
        }
    };
    let mut time_marks = Vec::new();
    for (u, target) in &s.time_marks {
        match unit(u, "--time-marks")? {
            Some(i) => time_marks.push((i, target.clone())),
            None if units.len() == 1 => time_marks.push((0, target.clone())),
            None => {
                return Err(refuse(
                    "--time-marks",
                    format!(
                        "`{target}`: a rig's time marks are per unit: give UNIT={target} (units: {})",
                        units.join(", ")
                    ),
                ));
            }
        }
    }
    let pulse = match &s.pulse {
        None => None,
        Some(p) => {
            check_pulse_spec(p)?;
            let i = unit(&s.pulse_unit, "--pulse-unit")?.unwrap_or(0);
            let serial = (layout.streams.iter())
                .filter(|st| st.unit == Some(i))
                .flat_map(|st| &st.sinks)
                .find_map(|(a, _)| match a {
                    SinkAddr::Serial(d) => Some(d.clone()),
                    _ => None,
                });
            #[cfg(feature = "realtime")]
            if let Some(line) = &s.pulse_line {
                if s.pulse_port.is_some() {
                    return Err(refuse(
                        "--pulse-port",
                        "the pulse drives the line given in code (RunSpec::pulse_on): give one",
                    ));
                }
                return Ok(Sync {
                    time_marks,
                    pulse: Some((p.clone(), PulseOut::Line(line.clone()), i)),
                    pps_in: s.pps_in,
                    trigger: s.trigger,
                });
            }
            let port = s.pulse_port.clone().or(serial).ok_or_else(|| {
                refuse(
                    "--pulse",
                    format!(
                        "drives a serial port's modem line: give --pulse-port DEV or a serial sink of unit `{}`",
                        units[i]
                    ),
                )
            })?;
            Some((p.clone(), PulseOut::Port(port), i))
        }
    };
    Ok(Sync {
        time_marks,
        pulse,
        pps_in: s.pps_in,
        trigger: s.trigger,
    })
}

#[cfg(feature = "realtime")]
fn check_pulse_spec(p: &str) -> Result<(), RunError> {
    p.parse::<crate::realtime::pulse::PulseSpec>()
        .map(drop)
        .map_err(|e| refuse("--pulse", e))
}

#[cfg(not(feature = "realtime"))]
fn check_pulse_spec(_: &str) -> Result<(), RunError> {
    Err(refuse(
        "--pulse",
        "this build has no real-time emulator (the `realtime` feature)",
    ))
}
