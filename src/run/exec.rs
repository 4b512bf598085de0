//! Running a checked [`Run`]: the sinks opened, the sources built (at once on a known motion,
//! at the first state of a live one), then one of four drivers moves simulated time forward —
//! offline (window after window, as fast as the sinks take them), lockstep (each live state
//! releases what it completes), paced and real time (`super::wall`, on the pacer's thread) —
//! and every output is kept or removed as a whole.

use std::io::{ErrorKind, Write};

use crate::engine::frames::Until;
use crate::live::stats::InputStats;
use crate::live::transport::Receiver;
use crate::live::{Decoder, InputFormat};
use crate::motion::causal::CausalMotion;
use crate::output::failure::ReaderLeft;
use crate::output::{AtomicFile, SinkAddr};
use crate::sim::SimulationBuilder;

use super::build::{LivePlan, Run, Signal};
use super::clock::Clock;
use super::error::RunError;
use super::pipeline::{Built, Control, Outlets, gps_ref, input_base, modulo, unit_streams};
use super::routing::StreamPlan;
use super::spec::TimeBase;
use super::status::{RunReport, StreamCounts};

/// Records per offline window of the fastest stream.
const WINDOW_RECORDS: f64 = crate::engine::BLOCK as f64;

impl Run {
    /// Runs to the end (of the span, of the input) or until `ctl` asks it to stop, and tells
    /// what it did. Outputs are kept when the run completes (a paced or real-time run also
    /// when stopped, its normal end) and removed when it fails.
    pub fn execute(self, ctl: &Control) -> Result<RunReport, RunError> {
        let alone = self.stdout_alone();
        let ran = match &self.clock {
            Clock::Free => self.free(ctl),
            Clock::Lockstep => self.lockstep(ctl),
            #[cfg(feature = "realtime")]
            Clock::Paced(_) | Clock::Realtime(_) => super::wall::run(self, ctl),
            #[cfg(not(feature = "realtime"))]
            Clock::Paced(_) | Clock::Realtime(_) => Err(RunError::spec(
                "--speed",
                "this build has no real-time emulator (the `realtime` feature): give --speed max"
                    .into(),
            )),
        };
        match ran {
            Err(RunError::Output(e)) if alone && e.kind() == ErrorKind::BrokenPipe => {
                Err(ReaderLeft.into())
            }
            ran => ran,
        }
    }

    /// Whether standard output is the run's only output (no other sink, input record or time
    /// marks): its reader leaving is then the `… | head` of a shell, not a lost output.
    fn stdout_alone(&self) -> bool {
        let mut outs = (self.layout.streams.iter()).flat_map(|s| s.sinks.iter().map(|(a, _)| a));
        let only =
            matches!((outs.next(), outs.next()), (Some(SinkAddr::File(p)), None) if p == "-");
        let record = matches!(&self.signal, Signal::Live { input, .. } if input.record.is_some());
        only && !record && self.sync.time_marks.is_empty()
    }

    /// The offline driver: window after window of simulated time, as fast as the sinks take
    /// the frames.
    fn free(self, ctl: &Control) -> Result<RunReport, RunError> {
        let Run {
            signal,
            layout,
            links,
            time_base,
            start_at,
            ..
        } = self;
        // An unpaced run on a GPS or UTC time base dates t₀ at the instant given.
        let leap = crate::timebase::LeapTable::builtin();
        let gps = match start_at {
            Some(s) if time_base != TimeBase::Sim => {
                let utc0 = crate::timebase::parse_start(&s, 0, &leap)
                    .map_err(|e| RunError::spec("--start-at", e))?;
                let r = gps_ref(time_base, utc0, |u| leap.utc_to_gps_ns(u));
                if let Some(((week, sow), _)) = r {
                    ctl.note(&format!(
                        "time base {}: t₀ at week {week}, {sow} s",
                        time_base.name()
                    ));
                }
                r
            }
            _ => None,
        };
        let mut built = layout.build(signal, gps, false)?;
        let mut out = Outlets::open(&layout.streams, &links, 1.0, false, ctl)?;
        out.preamble(&built.preambles)?;
        let fastest = (layout.streams.iter())
            .map(|s| s.rate_hz)
            .fold(0.0, f64::max);
        let window = if fastest > 0.0 {
            (WINDOW_RECORDS / fastest * 1e9).clamp(1e6, 1e12) as i64
        } else {
            1_000_000_000
        };
        let mut counts = vec![StreamCounts::default(); layout.streams.len()];
        let mut until = 0i64;
        let ended = loop {
            if ctl.stopped() {
                break Ok("stopped");
            }
            if built.sources.done() {
                break Ok("complete");
            }
            until = until.saturating_add(window);
            let step = (built.sources.fill(Until::ns(built.origin, until)))
                .map_err(RunError::from)
                .and_then(|()| out.write(&built.sources.parts, &mut counts));
            if let Err(e) = step {
                break Err(e);
            }
            ctl.publish(|s| {
                s.started = true;
                s.streams.clone_from(&counts);
            });
        };
        finish(out, ended, counts, layout.streams, built, None, ctl, false)
    }

    /// The lockstep driver: each live state releases the records (and aiding frames) it
    /// completes, written at once; the output depends only on the messages.
    fn lockstep(self, ctl: &Control) -> Result<RunReport, RunError> {
        let Run {
            signal,
            layout,
            links,
            time_base,
            ..
        } = self;
        let Signal::Live {
            builder,
            rig,
            input,
        } = signal
        else {
            unreachable!("lockstep follows a live input")
        };
        let mut out = Outlets::open(&layout.streams, &links, 1.0, false, ctl)?;
        let mut feed = match Feed::open(&input, &builder, time_base, ctl) {
            Ok(f) => f,
            Err(e) => {
                // Stopped (or failed) before a sender connected: no output file is left.
                out.close(false)?;
                return Err(e);
            }
        };
        let mut counts = vec![StreamCounts::default(); layout.streams.len()];
        let mut built: Option<Built> = None;
        let ended = loop {
            if ctl.stopped() {
                break Ok("stopped");
            }
            match feed.next() {
                Err(e) => break Err(e),
                // A stop ends the input's wait: the run was stopped, not ended by its input.
                Ok(None) if ctl.stopped() => break Ok("stopped"),
                Ok(None) => break Ok("input ended"),
                Ok(Some(false)) => continue,
                Ok(Some(true)) => {}
            }
            if built.is_none() {
                let week = feed.decoder.epoch_week();
                let b = layout.build_live(&builder, rig, &feed.model, week, false);
                match b.and_then(|b| out.preamble(&b.preambles).map(|()| b)) {
                    Ok(b) => built = Some(b),
                    Err(e) => break Err(e),
                }
            }
            let b = built.as_mut().expect("built above");
            if feed.model.knots() < 2 {
                // One knot is t₀ but no piece yet: the motion is not known even at t₀ (an
                // aiding epoch falling on t₀ would read NaN).
                continue;
            }
            let until = Until::state(b.origin, feed.model.newest());
            let step = (b.sources.fill(until))
                .map_err(RunError::from)
                .and_then(|()| out.write(&b.sources.parts, &mut counts));
            if let Err(e) = step {
                break Err(e);
            }
            ctl.publish(|s| {
                s.started = true;
                s.streams.clone_from(&counts);
            });
            if b.sources.done() {
                break Ok("duration reached");
            }
        };
        let (name, need) = (feed.name.clone(), feed.need);
        let stats = feed.close()?;
        let Some(built) = built else {
            out.close(false)?;
            ended?;
            return Err(RunError::TooFewStates {
                input: name,
                states: stats.states,
                need,
                why: stats.why_unused(),
            });
        };
        finish(
            out,
            ended,
            counts,
            layout.streams,
            built,
            Some(stats),
            ctl,
            false,
        )
    }
}

/// Ends a run: closes the sinks (keeping the outputs if it succeeded, or was stopped and
/// `keep_stopped`), and reports.
#[allow(clippy::too_many_arguments)] // the run's parts, each distinct
pub(super) fn finish(
    mut out: Outlets,
    ended: Result<&'static str, RunError>,
    counts: Vec<StreamCounts>,
    streams: Vec<StreamPlan>,
    built: Built,
    input: Option<InputStats>,
    ctl: &Control,
    keep_stopped: bool,
) -> Result<RunReport, RunError> {
    let keep = matches!(ended, Ok(e) if e != "stopped" || keep_stopped);
    let closed = out.close(keep);
    let ended = ended?;
    closed?;
    let mut status = ctl.status();
    status.streams.clone_from(&counts);
    status.sinks = out.stats();
    ctl.set(status.clone());
    let mut units = built.units;
    for (u, i) in units.iter_mut().zip(unit_streams(&streams)) {
        u.records = counts.get(i).map_or(0, |c| c.frames + c.skipped);
    }
    Ok(RunReport {
        ended,
        stopped: ended == "stopped",
        streams,
        status,
        units,
        faults: built.faults,
        input,
        failures: out.failures(),
    })
}

/// A live input read on the calling thread (lockstep): each message decoded and taken into
/// the motion model, every message recorded when asked.
pub(super) struct Feed {
    rx: Receiver,
    pub(super) name: String,
    pub(super) decoder: Decoder,
    pub(super) model: CausalMotion,
    pub(super) need: usize,
    modulo: u64,
    stats: InputStats,
    record: Option<(AtomicFile, std::path::PathBuf)>,
    csv: bool,
}

impl Feed {
    /// Opens the input of `input`, its model on `builder`'s motion-model settings.
    pub(super) fn open(
        input: &LivePlan,
        builder: &SimulationBuilder,
        base: TimeBase,
        ctl: &Control,
    ) -> Result<Feed, RunError> {
        let settings = builder.model_settings()?;
        let idle = Some(std::time::Duration::from_secs_f64(input.idle_s));
        let rx = Receiver::open_until(&input.endpoint, input.format, idle, Some(ctl.flag()))
            .map_err(|e| RunError::io(format!("--motion {}: opening", input.source), e))?;
        let record = match &input.record {
            Some(p) => Some((
                AtomicFile::create(p)
                    .map_err(|e| RunError::io(format!("creating {}", p.display()), e))?,
                p.clone(),
            )),
            None => None,
        };
        // Lockstep follows the tags alone: a step it cannot bridge is refused, not computed.
        let model = CausalMotion::new(settings);
        model.refuse_gaps();
        let name = rx.name().to_string();
        ctl.note(&format!("following {name} in lockstep"));
        Ok(Feed {
            rx,
            name,
            decoder: Decoder::with_base(input.format, input_base(base), None),
            model,
            need: settings.stencil.max(3),
            modulo: modulo(input.format),
            stats: InputStats::default(),
            record,
            csv: input.format == InputFormat::Csv,
        })
    }

    /// Takes the next message: `Some(true)` when the model has a knot to release records up
    /// to, `Some(false)` when the message gave none (malformed, refused, no knot yet),
    /// `None` at the end of the input.
    pub(super) fn next(&mut self) -> Result<Option<bool>, RunError> {
        let name = &self.name;
        let m = self.rx.next_message();
        let Some(m) = m.map_err(|e| RunError::io(format!("reading {name}"), e))? else {
            return Ok(None);
        };
        if let Some((r, _)) = self.record.as_mut() {
            let nl: &[u8] = if self.csv { b"\n" } else { b"" };
            (r.write_all(&m.bytes).and_then(|()| r.write_all(nl)))
                .map_err(|e| RunError::io("writing the input record", e))?;
        }
        self.stats.message(&m);
        match self.decoder.decode(&m.bytes) {
            Ok(Some(d)) => {
                let outcome = self.model.push(&d.state);
                let place = format!("{}: {}", self.name, m.place);
                self.stats.state(&d, &outcome, self.modulo, &place);
                Ok(Some(outcome.is_ok() && self.model.knots() > 0))
            }
            Ok(None) => {
                self.stats.no_state();
                Ok(Some(false))
            }
            Err(e) if e.fatal => Err(RunError::TimeBase(format!(
                "{}: {}: {}",
                self.name,
                m.place.at(e.offset),
                e.message
            ))),
            Err(e) => {
                let at = format!("{}: {}", self.name, m.place.at(e.offset));
                self.stats.malformed(&at, &e.message);
                Ok(Some(false))
            }
        }
    }

    /// The input's final counts; the input record is kept whatever happened (it is how a
    /// failed run is reproduced).
    pub(super) fn close(mut self) -> Result<InputStats, RunError> {
        self.stats.transport(&self.rx);
        if let Some((r, p)) = self.record.take() {
            r.commit()
                .map_err(|e| RunError::io(format!("writing {}", p.display()), e))?;
        }
        Ok(self.stats)
    }
}
