//! The parts every driver of a run shares: the stop flag and status ([`Control`]), the sinks
//! per stream ([`Outlets`]), the frame sources with their streams laid out one after another
//! ([`Sources`]), and the sources built from a signal ([`Built`]) on the run's GPS time.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use crate::engine::frames::{Part, Until, WindowSource};
use crate::live::{InputFormat, TimeBase as InputBase};
use crate::motion::causal::CausalMotion;
use crate::output::failure::absorb;
use crate::output::sink::Sink;
use crate::sim::SimulationBuilder;

use super::build::Signal;
use super::error::RunError;
use super::routing::{Layout, StreamPlan};
use super::sinks::{self, Links};
use super::spec::TimeBase;
use super::status::{RunStatus, StreamCounts, UnitReport};

/// Stop requests, notes and the live status, shared between a run and whoever started it.
#[derive(Clone)]
pub struct Control {
    stop: Arc<AtomicBool>,
    status: Arc<Mutex<RunStatus>>,
    notes: Arc<dyn Fn(&str) + Send + Sync>,
}

impl Default for Control {
    fn default() -> Control {
        Control {
            stop: Arc::new(AtomicBool::new(false)),
            status: Arc::default(),
            notes: Arc::new(|_| {}),
        }
    }
}

impl Control {
    /// A control that drops the run's notes.
    pub fn new() -> Control {
        Control::default()
    }

    /// A control that hands the run's notes (a pty's path, what it waits for) to `notes`.
    pub fn with_notes(notes: impl Fn(&str) + Send + Sync + 'static) -> Control {
        Control {
            notes: Arc::new(notes),
            ..Control::default()
        }
    }

    /// Asks the run to stop at its next step; its report says it was stopped.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// Whether a stop was asked for.
    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// The run's figures now.
    pub fn status(&self) -> RunStatus {
        self.status
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The shared stop flag (threads of the run and the lockstep input's reads watch it).
    pub(super) fn flag(&self) -> Arc<AtomicBool> {
        self.stop.clone()
    }

    /// Tells whoever started the run.
    pub(super) fn note(&self, text: &str) {
        (self.notes)(text)
    }

    /// Updates the shared status, never waiting for the lock.
    pub(super) fn publish(&self, f: impl FnOnce(&mut RunStatus)) {
        if let Ok(mut s) = self.status.try_lock() {
            f(&mut s);
        }
    }

    /// Sets the final status, waiting for the lock.
    pub(super) fn set(&self, s: RunStatus) {
        *self.status.lock().unwrap_or_else(|e| e.into_inner()) = s;
    }
}

/// The sinks of a run, per stream. Dropped before [`Outlets::close`] (a run that ends early
/// with an error), every file it opened is removed.
pub(super) struct Outlets {
    pub(super) sinks: Vec<Vec<Box<dyn Sink>>>,
    /// Told when a sink is retired and the run goes on.
    ctl: Control,
}

impl Outlets {
    /// Opens every stream's sinks; frames per wall-clock second are the streams' rates times
    /// `speed` (the serial links are checked against them); `paced`: files written live.
    pub(super) fn open(
        streams: &[StreamPlan],
        links: &Links,
        speed: f64,
        paced: bool,
        ctl: &Control,
    ) -> Result<Outlets, RunError> {
        let note = |s: &str| ctl.note(s);
        let mut out = Outlets {
            sinks: Vec::with_capacity(streams.len()),
            ctl: ctl.clone(),
        };
        for s in streams {
            out.sinks
                .push(sinks::open(s, links, s.rate_hz * speed, paced, &note)?);
        }
        Ok(out)
    }

    /// Hands the sinks over (to the pacer's thread), leaving none to remove on drop.
    #[cfg(feature = "realtime")]
    pub(super) fn take(mut self) -> Vec<Vec<Box<dyn Sink>>> {
        std::mem::take(&mut self.sinks)
    }

    /// Applies `f` to every sink, flat index `k`; a failure is [`absorb`]ed: the sink retired
    /// beside a live link still working, else the run's error.
    fn each(
        &mut self,
        mut f: impl FnMut(usize, &mut dyn Sink) -> std::io::Result<()>,
    ) -> Result<(), RunError> {
        let mut k = 0;
        for i in 0..self.sinks.len() {
            for j in 0..self.sinks[i].len() {
                if let Err(e) = f(i, self.sinks[i][j].as_mut()) {
                    let mut all: Vec<&mut (dyn Sink + 'static)> = (self.sinks.iter_mut().flatten())
                        .map(|s| s.as_mut())
                        .collect();
                    let warning = absorb(&mut all, k, e).map_err(RunError::Output)?;
                    self.ctl.note(&format!("warning: {warning}"));
                }
                k += 1;
            }
        }
        Ok(())
    }

    /// Writes each stream's preamble (a CSV header) to its sinks.
    pub(super) fn preamble(&mut self, preambles: &[Vec<u8>]) -> Result<(), RunError> {
        self.each(|i, s| match preambles.get(i) {
            Some(p) if !p.is_empty() => s.preamble(p),
            _ => Ok(()),
        })
    }

    /// Writes the frames of `parts` (one per stream) to their sinks; counts them.
    pub(super) fn write(
        &mut self,
        parts: &[Part],
        counts: &mut [StreamCounts],
    ) -> Result<(), RunError> {
        self.each(|i, s| match parts.get(i) {
            Some(p) if !p.ends.is_empty() => s.write(&p.bytes, &p.ends),
            _ => Ok(()),
        })?;
        for (c, p) in counts.iter_mut().zip(parts) {
            c.frames += p.ends.len() as u64;
        }
        Ok(())
    }

    /// Per sink: its stream, label and counts.
    pub(super) fn stats(&self) -> Vec<(usize, String, crate::output::sink::SinkStats)> {
        (self.sinks.iter().enumerate())
            .flat_map(|(i, v)| v.iter().map(move |s| (i, s.label().to_string(), s.stats())))
            .collect()
    }

    /// The sinks retired while the run went on: each one's failure and what it lost.
    pub(super) fn failures(&self) -> Vec<String> {
        (self.sinks.iter().flatten())
            .filter_map(|s| s.failure())
            .collect()
    }

    /// Flushes every sink, then keeps every output (`keep`) or removes the files. Every sink is
    /// flushed before any file is kept, so that one that cannot be written keeps none of the
    /// others (unless a live link carries the run: then only it is lost).
    pub(super) fn close(&mut self, keep: bool) -> Result<(), RunError> {
        let flushed = self.each(|_, s| s.finish());
        let mut first = flushed.err();
        if keep && first.is_none() {
            for s in self.sinks.iter_mut().flatten() {
                if let Err(e) = s.commit() {
                    first.get_or_insert(RunError::Output(e));
                }
            }
        }
        if !keep || first.is_some() {
            self.sinks.iter_mut().flatten().for_each(|s| s.discard());
        }
        first.map_or(Ok(()), Err)
    }
}

impl Drop for Outlets {
    fn drop(&mut self) {
        // Kept outputs are no longer the sinks' to remove: discarding them does nothing.
        self.sinks.iter_mut().flatten().for_each(|s| s.discard());
    }
}

/// A run's frame sources, their streams laid out one after another.
pub(super) struct Sources {
    list: Vec<Box<dyn WindowSource>>,
    /// Per source: its first stream.
    first: Vec<usize>,
    /// Per stream: the frames of the window being filled.
    pub(super) parts: Vec<Part>,
}

impl Sources {
    pub(super) fn new(list: Vec<Box<dyn WindowSource>>) -> Sources {
        let mut first = Vec::new();
        let mut n = 0;
        for s in &list {
            first.push(n);
            n += s.streams();
        }
        Sources {
            list,
            first,
            parts: vec![Part::default(); n],
        }
    }

    /// Fills every stream with the frames due by `until` (the parts are cleared first).
    pub(super) fn fill(&mut self, until: Until) -> Result<(), crate::engine::EngineError> {
        self.parts.iter_mut().for_each(Part::clear);
        for (s, &at) in self.list.iter_mut().zip(&self.first) {
            let n = s.streams();
            s.fill(until, &mut self.parts[at..at + n])?;
        }
        Ok(())
    }

    /// True once every source has given every frame.
    pub(super) fn done(&self) -> bool {
        self.list.iter().all(|s| s.done())
    }

    /// The earliest emission time (ns after t₀) a frame not yet given can have.
    #[cfg(feature = "realtime")] // for the wall-clock drivers (run/wall/)
    pub(super) fn next_due(&self) -> Option<i64> {
        self.list.iter().filter_map(|s| s.next_due_ns()).min()
    }

    /// Flags every record from now on carries (stale input).
    #[cfg(feature = "realtime")] // for the wall-clock drivers (run/wall/)
    pub(super) fn set_flags(&mut self, flags: u8) {
        self.list.iter_mut().for_each(|s| s.set_flags(flags));
    }

    /// A trigger edge closed the interval (lo, hi] (s after t₀).
    #[cfg(feature = "realtime")] // for the wall-clock drivers (run/wall/)
    pub(super) fn edge(&mut self, lo: f64, hi: f64) {
        self.list.iter_mut().for_each(|s| s.edge(lo, hi));
    }
}

/// The sources of a run on a known motion, their preambles, units and fault tally; the
/// GPS time of record time 0 set first when the time base gives one (`gps`: frames, `gnss`:
/// the GNSS streams' true GPS time).
pub(super) struct Built {
    pub(super) sources: Sources,
    pub(super) preambles: Vec<Vec<u8>>,
    pub(super) units: Vec<UnitReport>,
    pub(super) faults: Option<crate::protocol::FaultTally>,
    /// The run's t₀ (s): emission times count from it.
    pub(super) origin: f64,
}

/// GPS time of record time 0 for the frames and for the GNSS streams, when the time base
/// (or the live input's GPS week) gives them.
pub(super) type GpsRef = Option<((u32, f64), (u32, f64))>;

impl Layout {
    /// Builds the sources of `signal` (a known motion), after setting its GPS time.
    pub(super) fn build(
        &self,
        signal: Signal,
        gps: GpsRef,
        triggered: bool,
    ) -> Result<Built, RunError> {
        match signal {
            Signal::Imu(mut sim) => {
                if let Some((frames, gnss)) = gps {
                    let t0 = sim.grid().t0;
                    sim.set_gps_time(frames.0, frames.1 - t0);
                    sim.set_gnss_gps_time(gnss.0, gnss.1 - t0);
                }
                let units = vec![UnitReport {
                    name: "imu".into(),
                    grid: sim.grid(),
                    records: 0,
                }];
                let faults = sim.faults().map(|f| f.tally());
                let origin = sim.grid().t0;
                let (list, preambles) = self.imu_sources(*sim, triggered)?;
                Ok(Built {
                    sources: Sources::new(list),
                    preambles,
                    units,
                    faults,
                    origin,
                })
            }
            Signal::Rig(mut rig) => {
                let origin = rig.span().0;
                if let Some((frames, gnss)) = gps {
                    rig.set_gps_time(frames.0, frames.1 - origin);
                    rig.set_gnss_gps_time(gnss.0, gnss.1 - origin);
                }
                let units = (rig.units().iter())
                    .map(|u| UnitReport {
                        name: u.name().to_string(),
                        grid: u.grid(),
                        records: 0,
                    })
                    .collect();
                let (list, preambles) = self.rig_sources(*rig, triggered)?;
                Ok(Built {
                    sources: Sources::new(list),
                    preambles,
                    units,
                    faults: None,
                    origin,
                })
            }
            Signal::Live { .. } => unreachable!("a live signal is built on its motion"),
        }
    }

    /// Builds the sources of the live `builder` on `model`, now that it has its first knot;
    /// GPS-tagged input counts from GPS week `week`: record time 0 is that week's start.
    pub(super) fn build_live(
        &self,
        builder: &SimulationBuilder,
        rig: bool,
        model: &CausalMotion,
        week: Option<u32>,
        triggered: bool,
    ) -> Result<Built, RunError> {
        let b = builder.clone().live_motion(model.clone());
        let (signal, t0) = if rig {
            let r = b.build_rig()?;
            let t0 = r.span().0;
            (Signal::Rig(Box::new(r)), t0)
        } else {
            let s = b.build()?;
            let t0 = s.grid().t0;
            (Signal::Imu(Box::new(s)), t0)
        };
        // The motion is known from its first knot on: before it there is nothing to sense.
        let first = crate::motion::Motion::start(model);
        if t0 < first - 1e-9 {
            return Err(RunError::spec(
                "--start",
                format!(
                    "{t0} s is before the live motion's first piece, at {first} s (the first state with a full stencil behind it): give a later start, or none to start there"
                ),
            ));
        }
        // `build` takes the GPS time of t₀, which is t₀ seconds into the week.
        let gps = week.map(|w| ((w, t0), (w, t0)));
        self.build(signal, gps, triggered)
    }
}

/// The GPS time of t₀ for the frames (on `base`) and for the GNSS streams (true GPS time) of
/// a run whose t₀ falls on UTC instant `utc0` (ns); `to_gps` turns UTC into GPS time (the
/// host clock's view, or the leap-second table's).
pub(super) fn gps_ref(base: TimeBase, utc0: i128, to_gps: impl Fn(i128) -> i128) -> GpsRef {
    let frames = match base {
        TimeBase::Sim => return None,
        TimeBase::Gps => to_gps(utc0),
        TimeBase::Utc => utc0 - crate::timebase::GPS_EPOCH_UNIX_S as i128 * 1_000_000_000,
    };
    Some((
        crate::timebase::week_sow(frames),
        crate::timebase::week_sow(to_gps(utc0)),
    ))
}

/// The stream of each unit's own readings, in unit order.
pub(super) fn unit_streams(streams: &[StreamPlan]) -> impl Iterator<Item = usize> + '_ {
    let mut seen = Vec::new();
    (streams.iter().enumerate()).filter_map(move |(i, s)| match s.unit {
        Some(u) if !seen.contains(&u) => {
            seen.push(u);
            Some(i)
        }
        _ => None,
    })
}

/// How the input's time tags are taken on the run's time base.
pub(super) fn input_base(base: TimeBase) -> InputBase {
    match base {
        TimeBase::Gps => InputBase::Gps,
        _ => InputBase::Sim,
    }
}

/// The range of a format's sequence numbers.
pub(super) fn modulo(format: InputFormat) -> u64 {
    match format {
        InputFormat::Mavlink => 256,
        _ => 1 << 32,
    }
}
