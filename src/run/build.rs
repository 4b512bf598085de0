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

use super::clock::{Clock, decide_clock};
use super::error::{RunError, refuse};
use super::routing::{Layout, Units, unrouted_aiding};
use super::sinks::Links;
use super::spec::{LiveSpec, Route, RunSpec, TimeBase};
use super::sync::{Sync, check_sync};

/// Default longest extrapolation past the newest live state (s).
pub const DEFAULT_MAX_EXTRAPOLATION_S: f64 = 0.25;
/// Default duration of the correction after a late live state (s).
pub const DEFAULT_CORRECTION_HORIZON_S: f64 = 0.1;
/// Default silence after which a live input counts as ended (s).
pub const DEFAULT_INPUT_TIMEOUT_S: f64 = 10.0;
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
    /// The motion model the states are joined by.
    pub model: crate::motion::sampled::ModelSettings,
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

impl RunSpec {
    /// Checks the whole description and assembles the run. A refused setting that a scene
    /// file's `[run]` table gave is named by its file and key.
    pub fn build(self) -> Result<Run, RunError> {
        let keys = RunSpec {
            signal: SimulationBuilder::default(),
            routes: Vec::new(),
            ..self.clone()
        };
        self.build_checked().map_err(|e| match e {
            RunError::Spec { what, why } => RunError::Spec {
                why: keys.why_of(&why),
                what: keys.origin_of(&what),
            },
            e => e,
        })
    }

    fn build_checked(self) -> Result<Run, RunError> {
        let RunSpec {
            signal,
            input,
            routes,
            sync,
            clock,
            link,
            file_keys: _,
        } = self;
        let time_base = clock.time_base.unwrap_or_default();
        one_writer_per_file(&routes, input.as_ref())?;
        let live = input.as_ref().map(|i| live_plan(i, &signal)).transpose()?;
        let mode = decide_clock(&clock, input.as_ref(), &routes)?;
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
        let signal_file = signal.scene_file_path().map(|p| p.display().to_string());
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
        // The aiding sensors configured but not routed are told, never silently dropped.
        let file = signal_file.as_deref();
        let (layout, unrouted) = match &sig {
            Signal::Imu(sim) => {
                let l = Layout::resolve(&routes, &Units::Imu(sim))?;
                let w = unrouted_aiding(&sim.aiding(), &l, file);
                (l, w)
            }
            Signal::Rig(r) => {
                let l = Layout::resolve(&routes, &Units::Rig(r))?;
                let w = unrouted_aiding(&r.aiding(), &l, file);
                (l, w)
            }
            Signal::Live { builder, rig, .. } => {
                let stand_in = stand_in(builder);
                if *rig {
                    let r = stand_in.build_rig()?;
                    let l = Layout::resolve(&routes, &Units::Rig(&r))?;
                    let w = unrouted_aiding(&r.aiding(), &l, file);
                    (l, w)
                } else {
                    let s = stand_in.build()?;
                    let l = Layout::resolve(&routes, &Units::Imu(&s))?;
                    let w = unrouted_aiding(&s.aiding(), &l, file);
                    (l, w)
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
        let mut warnings = match &sig {
            Signal::Imu(s) => s.warnings().to_vec(),
            Signal::Rig(r) => r.warnings().to_vec(),
            Signal::Live { .. } => Vec::new(),
        };
        warnings.extend(unrouted);
        warnings.extend(sync.trigger.as_ref().and_then(|_| triggered_filters(&sig)));
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
        model: signal.model_settings()?,
    })
}

/// The live input in words.
fn live_line(l: &LivePlan) -> String {
    let format = match l.format {
        InputFormat::Csv => "csv",
        InputFormat::Binary => "bin",
        InputFormat::Mavlink => "mavlink",
    };
    let m = l.model;
    let degree = match m.degree {
        Degree::Quintic => "quintic",
        Degree::Cubic => "cubic",
    };
    let mut s = format!(
        "live {} ({format}), input timeout {} s, motion model {degree}, stencil {}",
        l.source, l.idle_s, m.stencil
    );
    if let Some(r) = &l.record {
        s += &format!(", every message recorded to {}", r.display());
    }
    s
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

/// What a trigger makes of output filters, said once when the run is built: under external
/// sync the filter is a uniform averager over each interval between edges, whatever the
/// template's `[output_filter]` kind and taps (docs/timing.md, external sample trigger).
fn triggered_filters(sig: &Signal) -> Option<String> {
    let names: Vec<String> = match sig {
        Signal::Imu(s) => (s.imu().output_filter.is_some())
            .then(|| format!("template `{}`", s.imu().name))
            .into_iter()
            .collect(),
        Signal::Rig(r) => (r.units().iter())
            .filter(|u| u.has_output_filter())
            .map(|u| format!("unit `{}`", u.name()))
            .collect(),
        // Templates that do not load were refused already, when the signal was checked.
        Signal::Live { builder, .. } => builder.filtered_units().unwrap_or_default(),
    };
    (!names.is_empty()).then(|| {
        format!(
            "--trigger: the output filter of {} is a uniform average over each interval between edges (as KVH's 1775 under external sync), not its [output_filter] kind, taps and internal rate",
            names.join(", ")
        )
    })
}

/// Where a file output writes, to tell two names of one file apart: its folder resolved
/// (symbolic links, `..`) when it exists, else the path made absolute; `-` is stdout.
fn file_key(path: &str) -> PathBuf {
    if path == "-" {
        return PathBuf::from("-");
    }
    let p = std::path::Path::new(path);
    let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    match (abs.parent(), abs.file_name()) {
        (Some(dir), Some(name)) => dir
            .canonicalize()
            .map_or_else(|_| abs.clone(), |d| d.join(name)),
        _ => abs,
    }
}

/// Refuses two outputs on one file (or both on stdout), or an output on the file the live
/// input reads, before anything is opened: their bytes would interleave, or one would replace
/// the other (issue 38: `generate -o X --truth X`, `run --file X --record-input X`).
fn one_writer_per_file(routes: &[Route], input: Option<&LiveSpec>) -> Result<(), RunError> {
    let record = (input.and_then(|i| i.record.as_ref())).map(|p| {
        (
            p.to_string_lossy().into_owned(),
            "--record-input".to_string(),
        )
    });
    let files = (routes.iter())
        .filter_map(|r| match &r.sink {
            SinkAddr::File(p) => Some((p.clone(), r.origin.clone())),
            _ => None,
        })
        .chain(record);
    let mut seen: Vec<(PathBuf, String)> = Vec::new();
    for (path, origin) in files {
        let key = file_key(&path);
        // The same setting twice (two rig units of one name) is the rig's error, told there.
        if let Some((_, first)) = seen.iter().find(|(k, o)| *k == key && *o != origin) {
            let what = if path == "-" {
                "stdout".to_string()
            } else {
                path
            };
            return Err(refuse(
                &origin,
                format!("writes to {what}, as {first} does: give each output a file of its own"),
            ));
        }
        seen.push((key, origin));
    }
    let read = input
        .filter(|i| !i.source.contains("://") && i.source != "-")
        .map(|i| (file_key(&i.source), &i.source));
    if let Some((key, source)) = read
        && let Some((_, origin)) = seen.iter().find(|(k, _)| *k == key)
    {
        return Err(refuse(
            origin,
            format!(
                "writes to {source}, the file --motion reads: give the output a file of its own"
            ),
        ));
    }
    Ok(())
}
