//! A [`RunSpec`] checked as a whole and turned into a [`Run`]: the signal assembled (or, for a
//! live motion, checked on a stand-in motion), the routes resolved into streams, the clock
//! decided, and every combination that cannot mean anything refused with the reason — never
//! a setting silently left unused.

use std::path::PathBuf;

use crate::live::InputFormat;
use crate::live::transport::Endpoint;
use crate::motion::chain::ChainSettings;
use crate::motion::sampled::Degree;
use crate::output::SinkAddr;
use crate::rig::Rig;
use crate::sim::{Simulation, SimulationBuilder};

use super::error::RunError;
use super::routing::{Layout, Units};
use super::sinks::Links;
use super::spec::{LiveSpec, RunSpec, Speed, TimeBase};

/// Default longest extrapolation past the newest live state (s).
pub const DEFAULT_MAX_EXTRAPOLATION_S: f64 = 0.25;
/// Default duration of the correction after a late live state (s).
pub const DEFAULT_CORRECTION_HORIZON_S: f64 = 0.1;
/// Default silence after which a live input counts as ended (s).
pub const DEFAULT_INPUT_TIMEOUT_S: f64 = 10.0;
/// Default limit of burst catch-up after a stall (ms).
pub const DEFAULT_MAX_BEHIND_MS: f64 = 100.0;

/// What happens once a live input is silent for its timeout (or its stream ended).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnTimeout {
    /// Keep extrapolating (bounded, then holding): frames keep coming.
    Extrapolate,
    /// Hold at once: constant acceleration and angular rate.
    Hold,
    /// Emit up to the newest state, then end the run.
    Stop,
}

impl OnTimeout {
    /// The policy named `extrapolate`, `hold` or `stop`.
    pub fn from_name(s: &str) -> Option<OnTimeout> {
        match s {
            "extrapolate" => Some(OnTimeout::Extrapolate),
            "hold" => Some(OnTimeout::Hold),
            "stop" => Some(OnTimeout::Stop),
            _ => None,
        }
    }
}

/// A live motion source, checked.
#[derive(Clone, Debug)]
pub struct LivePlan {
    /// The source as given.
    pub source: String,
    /// Where to listen.
    pub endpoint: Endpoint,
    /// Wire format of the states.
    pub format: InputFormat,
    /// Real time: the output delay (s), `None` to measure it.
    pub delay: Option<f64>,
    /// Real time: extrapolation bound and correction horizon.
    pub chain: ChainSettings,
    /// Real time: what a silent input leads to.
    pub on_timeout: OnTimeout,
    /// Silence after which the input counts as ended (s).
    pub idle_s: f64,
    /// Every message, written here.
    pub record: Option<PathBuf>,
}

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

/// The sync lines, checked.
#[derive(Clone, Debug, Default)]
pub struct Sync {
    /// Time-mark targets, each of one unit (index into the units).
    pub time_marks: Vec<(usize, String)>,
    /// The pulse: its spec as given, the serial device of its modem line, the unit it marks.
    pub pulse: Option<(String, String, usize)>,
    /// The PPS source the output phase-locks to.
    pub pps_in: Option<String>,
    /// The trigger source every unit samples on.
    pub trigger: Option<String>,
}

/// What the run simulates.
pub enum Signal {
    /// One IMU on a known motion.
    Imu(Box<Simulation>),
    /// A rig on a known motion.
    Rig(Box<Rig>),
    /// One IMU or a rig (`rig`) on a live motion, assembled once the first state arrives.
    Live {
        /// The signal, still without its motion.
        builder: Box<SimulationBuilder>,
        /// The builder describes a rig.
        rig: bool,
        /// The input.
        input: LivePlan,
    },
}

/// A checked run, ready to [`execute`](Run::execute).
pub struct Run {
    pub(super) signal: Signal,
    pub(super) layout: Layout,
    pub(super) clock: Clock,
    pub(super) time_base: TimeBase,
    /// The start instant as given (an unpaced run dates its t₀ with it).
    pub(super) start_at: Option<String>,
    pub(super) sync: Sync,
    pub(super) links: Links,
    pub(super) units: Vec<String>,
    pub(super) warnings: Vec<String>,
    /// The motion and the engine in words (computed while the signal's builder was at hand).
    pub(super) motion_line: String,
    pub(super) engine_line: String,
}

impl Run {
    /// When the frames go out.
    pub fn clock(&self) -> &Clock {
        &self.clock
    }

    /// The streams, in source order, with their sinks.
    pub fn streams(&self) -> &[super::routing::StreamPlan] {
        &self.layout.streams
    }

    /// Things worth telling the user that do not stop the run.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The names of the units (`imu` for the single IMU).
    pub fn units(&self) -> &[String] {
        &self.units
    }

    /// What a user should know before the run starts: one IMU's template and seed when its
    /// records carry errors, each rig unit's records, rate and seed.
    pub fn announcements(&self) -> Vec<String> {
        match &self.signal {
            Signal::Imu(s) if s.has_errors() => {
                vec![format!("IMU `{}`, seed {}", s.imu().name, s.seed())]
            }
            Signal::Imu(_) | Signal::Live { .. } => Vec::new(),
            Signal::Rig(r) => (r.units().iter())
                .map(|u| {
                    format!(
                        "unit `{}`: {} records at {} Hz, seed {}",
                        u.name(),
                        u.grid().count,
                        u.grid().rate_hz,
                        u.seed()
                    )
                })
                .collect(),
        }
    }
}

/// A refusal naming a flag and its scene-file key.
fn refuse(flag: &str, why: impl Into<String>) -> RunError {
    RunError::spec(flag, why.into())
}

impl RunSpec {
    /// Checks the whole description and assembles the run.
    pub fn build(self) -> Result<Run, RunError> {
        let RunSpec {
            signal,
            input,
            routes,
            sync,
            clock,
            link,
        } = self;
        let time_base = clock.time_base.unwrap_or_default();
        let live = input.as_ref().map(|i| live_plan(i, &signal)).transpose()?;
        let mode = decide_clock(&clock, live.as_ref(), input.as_ref(), &routes)?;
        if time_base != TimeBase::Sim && signal.gps_time_given() {
            return Err(refuse(
                "--gps-time",
                "sets the GPS reference of --time-base sim only; with gps or utc the host clock gives it",
            ));
        }
        match (time_base, &mode) {
            (TimeBase::Sim, Clock::Free) if clock.start_at.is_some() => {
                return Err(refuse(
                    "--start-at",
                    "an unpaced run has no wall clock: its start instant only dates t₀ for --time-base gps or utc (give --speed 1 to start then)",
                ));
            }
            (TimeBase::Sim, _) => {}
            (_, Clock::Free) if clock.start_at.is_none() => {
                return Err(refuse(
                    &format!("--time-base {}", time_base.name()),
                    "an unpaced run has no wall clock to date t₀ from: give --start-at (or --speed 1, or --gps-time on the sim time base)",
                ));
            }
            (TimeBase::Utc, Clock::Lockstep | Clock::Realtime(_)) => {
                return Err(refuse(
                    "--time-base utc",
                    "a --motion run takes sim (the input's tags as sent) or gps (GPS time tags)",
                ));
            }
            _ => {}
        }
        let motion_line = match &live {
            Some(l) => live_line(l),
            None => {
                signal.model_settings()?;
                if signal.model_settings_given() && !signal.is_sampled()? {
                    return Err(refuse(
                        "--interp, --stencil",
                        "shape the motion model of a trajectory file or live input; this run's motion is analytic (a scene or a motion definition)",
                    ));
                }
                signal.source_label()?
            }
        };
        let engine_line = format!("{} Gauss–Legendre nodes per interval", signal.quadrature()?);
        // The signal: built now on a known motion; checked on a stand-in one for live input.
        let rig = signal.is_rig();
        let (sig, units_seen): (Signal, Vec<String>) = match live {
            None if rig => {
                let r = signal.build_rig()?;
                let names = r.units().iter().map(|u| u.name().to_string()).collect();
                (Signal::Rig(Box::new(r)), names)
            }
            None => (Signal::Imu(Box::new(signal.build()?)), vec!["imu".into()]),
            Some(input) => {
                let stand_in = stand_in(&signal);
                let names = if rig {
                    let r = stand_in.build_rig()?;
                    r.units().iter().map(|u| u.name().to_string()).collect()
                } else {
                    stand_in.build()?;
                    vec!["imu".into()]
                };
                let builder = Box::new(signal.unbounded_duration(super::FOREVER_S));
                (
                    Signal::Live {
                        builder,
                        rig,
                        input,
                    },
                    names,
                )
            }
        };
        let layout = match &sig {
            Signal::Imu(sim) => Layout::resolve(&routes, &Units::Imu(sim))?,
            Signal::Rig(r) => Layout::resolve(&routes, &Units::Rig(r))?,
            Signal::Live { builder, rig, .. } => {
                let stand_in = stand_in(builder);
                if *rig {
                    Layout::resolve(&routes, &Units::Rig(&stand_in.build_rig()?))?
                } else {
                    Layout::resolve(&routes, &Units::Imu(&stand_in.build()?))?
                }
            }
        };
        let mut layout = layout;
        if matches!(sig, Signal::Live { .. }) {
            // A live run has no planned length: it follows its input.
            layout.streams.iter_mut().for_each(|s| s.planned = None);
        }
        let sync = check_sync(sync, &mode, &units_seen, &layout, time_base)?;
        let links = check_links(link, &layout, &mode)?;
        check_stdout(&layout)?;
        let warnings = match &sig {
            Signal::Imu(s) => s.warnings().to_vec(),
            Signal::Rig(r) => r.warnings().to_vec(),
            Signal::Live { .. } => Vec::new(),
        };
        let run = Run {
            signal: sig,
            layout,
            clock: mode,
            time_base,
            start_at: clock.start_at.clone(),
            sync,
            links,
            units: units_seen,
            warnings,
            motion_line,
            engine_line,
        };
        Ok(run)
    }
}

/// The builder on a motion known in advance (the static scene over 1000 s from t = 0), to
/// check every setting but the motion's before a live input's first state arrives.
pub fn stand_in(builder: &SimulationBuilder) -> SimulationBuilder {
    builder.clone().scene("static").start(0.0).duration(1000.0)
}

/// The live input, checked.
fn live_plan(i: &LiveSpec, signal: &SimulationBuilder) -> Result<LivePlan, RunError> {
    let endpoint = Endpoint::parse(&i.source).map_err(|e| refuse("--motion", e))?;
    if signal.has_source() {
        return Err(refuse(
            "--motion",
            "replaces --scene, --trajectory and --motion-def: give one source",
        ));
    }
    let seconds = |flag: &str, v: Option<f64>, min: f64, default: f64| match v {
        None => Ok(default),
        Some(v) if v.is_finite() && v >= min => Ok(v),
        Some(v) => Err(refuse(
            &format!("{flag} {v}"),
            format!("expected a number of seconds of at least {min}"),
        )),
    };
    if i.lockstep {
        let realtime_only = [
            ("--output-delay", i.output_delay_s.is_some()),
            ("--max-extrapolation", i.max_extrapolation_s.is_some()),
            ("--correction-horizon", i.correction_horizon_s.is_some()),
            ("--on-timeout", i.on_timeout.is_some()),
        ];
        if let Some((flag, _)) = realtime_only.iter().find(|x| x.1) {
            return Err(refuse(
                flag,
                "applies to --time-mode realtime: in lockstep each state releases the records it completes, with no clock to run ahead of the input",
            ));
        }
    } else if signal.model_settings()?.degree != Degree::Quintic {
        return Err(refuse(
            "--interp",
            "--time-mode realtime needs the quintic motion model (--interp quintic)",
        ));
    }
    let on_timeout = match &i.on_timeout {
        None => OnTimeout::Stop,
        Some(s) => OnTimeout::from_name(s).ok_or_else(|| {
            refuse(
                &format!("--on-timeout {s}"),
                "expected stop, hold or extrapolate",
            )
        })?,
    };
    let idle = seconds(
        "--input-timeout",
        i.input_timeout_s,
        0.0,
        DEFAULT_INPUT_TIMEOUT_S,
    )?;
    if idle <= 0.0 {
        return Err(refuse(
            "--input-timeout",
            "expected a positive number of seconds",
        ));
    }
    Ok(LivePlan {
        source: i.source.clone(),
        endpoint,
        format: i.format.unwrap_or(InputFormat::Csv),
        delay: (i.output_delay_s)
            .map(|d| seconds("--output-delay", Some(d), 0.0, 0.0))
            .transpose()?,
        chain: ChainSettings {
            horizon: seconds(
                "--correction-horizon",
                i.correction_horizon_s,
                1e-3,
                DEFAULT_CORRECTION_HORIZON_S,
            )?,
            max_extrapolation: seconds(
                "--max-extrapolation",
                i.max_extrapolation_s,
                0.0,
                DEFAULT_MAX_EXTRAPOLATION_S,
            )?,
        },
        on_timeout,
        idle_s: idle,
        record: i.record.clone(),
    })
}

/// The live input in words.
fn live_line(l: &LivePlan) -> String {
    let format = match l.format {
        InputFormat::Csv => "csv",
        InputFormat::Binary => "bin",
        InputFormat::Mavlink => "mavlink",
    };
    let mut s = format!("live {} ({format}), input timeout {} s", l.source, l.idle_s);
    if let Some(r) = &l.record {
        s += &format!(", every message recorded to {}", r.display());
    }
    s
}

/// The clock the settings give.
fn decide_clock(
    c: &super::spec::ClockSpec,
    live: Option<&LivePlan>,
    input: Option<&LiveSpec>,
    routes: &[super::spec::Route],
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
    let mode = match (live, input) {
        (Some(_), Some(i)) => {
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
        _ => {
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

/// The sync lines against the clock and the units.
fn check_sync(
    s: super::spec::SyncSpec,
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
            let port = s.pulse_port.clone().or(serial).ok_or_else(|| {
                refuse(
                    "--pulse",
                    format!(
                        "drives a serial port's modem line: give --pulse-port DEV or a serial sink of unit `{}`",
                        units[i]
                    ),
                )
            })?;
            Some((p.clone(), port, i))
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

/// The link settings against the sinks they apply to.
fn check_links(
    l: super::spec::LinkSpec,
    layout: &Layout,
    _mode: &Clock,
) -> Result<Links, RunError> {
    let has = |f: fn(&SinkAddr) -> bool| {
        (layout.streams.iter()).any(|s| s.sinks.iter().any(|(a, _)| f(a)))
    };
    let serial = has(|a| matches!(a, SinkAddr::Serial(_)));
    if !serial {
        if l.baud.is_some() {
            return Err(refuse(
                "--baud",
                "applies to serial sinks, and the run has none",
            ));
        }
        if l.framing.is_some() {
            return Err(refuse(
                "--framing",
                "applies to serial sinks, and the run has none",
            ));
        }
    }
    if l.udp_batch.is_some() && !has(|a| matches!(a, SinkAddr::Udp(_))) {
        return Err(refuse(
            "--udp-batch",
            "applies to UDP sinks, and the run has none",
        ));
    }
    if l.take_over && !has(|a| matches!(a, SinkAddr::Pty(Some(_)))) {
        return Err(refuse(
            "--take-over",
            "applies to a pty published at a path, and the run has none",
        ));
    }
    let batch = l.udp_batch.unwrap_or(1);
    if batch == 0 {
        return Err(refuse(
            "--udp-batch",
            "0: expected at least 1 frame per datagram",
        ));
    }
    let framing = l.framing.unwrap_or_else(|| "8N1".into());
    #[cfg(feature = "realtime")]
    framing
        .parse::<crate::realtime::serial::Framing>()
        .map_err(|e| refuse("--framing", e))?;
    Ok(Links {
        baud: l.baud,
        framing,
        udp_batch: batch,
        take_over: l.take_over,
    })
}

/// At most one sink writes to stdout.
fn check_stdout(layout: &Layout) -> Result<(), RunError> {
    let stdout = (layout.streams.iter())
        .flat_map(|s| &s.sinks)
        .filter(|(a, _)| *a == SinkAddr::File("-".into()))
        .count();
    if stdout > 1 {
        return Err(refuse("-", "at most one stream can be written to stdout"));
    }
    Ok(())
}
