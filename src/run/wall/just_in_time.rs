//! The just-in-time drivers: each frame is made just before it is due (its deadline minus
//! [`LEAD_S`]) from what has arrived by then, in one loop ([`just_in_time`]) for both time
//! sources — a trigger line's edges on a known motion ([`Edges`]), a live input's states
//! through its clock map and the output delay ([`Follow`]) — and for one IMU or a rig alike.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use crate::engine::EngineError;
use crate::engine::frames::{Part, Until};
use crate::engine::trigger::Trigger;
use crate::live::clockmap::ClockMap;
use crate::live::transport::Receiver;
use crate::motion::causal::CausalMotion;
use crate::motion::chain::Tail;
use crate::output::AtomicFile;
use crate::realtime::clock::{self, monotonic_ns, sleep_until};
use crate::realtime::hostclock::GpsClock;
use crate::realtime::lock::Schedule;
use crate::record::FLAG_STALE;
use crate::timebase::LeapTable;

use super::pacer_thread::{PacerFeed, PacerThread, ScheduleWatch, clocking, extras};
use super::{LEAD_S, end, time_base_ref};
use crate::run::build::{OnTimeout, Run, Signal};
use crate::run::clock::Wall;
use crate::run::error::RunError;
use crate::run::input::{self, GPS_TAG_TOLERANCE_S, GpsBase, MARGIN_S};
use crate::run::pipeline::{Control, Outlets, Sources};
use crate::run::spec::TimeBase;
use crate::run::status::{LiveStatus, RunReport, RunStatus};

/// [`LEAD_S`] in ns.
const LEAD_NS: i128 = (LEAD_S * 1e9) as i128;

/// What the shared loop asks of a just-in-time driver's time source.
trait JustInTime {
    /// What the run ended with once every frame was made.
    const COMPLETE: &'static str;
    /// What it ended with when the trigger's edge source went away (`None`: it goes on).
    const EDGES_GONE: Option<&'static str>;
    /// The CLOCK_MONOTONIC instant (ns) to wake at for the frame due `next` ns after t₀ on
    /// the simulation's axis (`None`: none is due yet).
    fn wake(&mut self, next: Option<i64>) -> i128;
    /// A trigger edge at CLOCK_MONOTONIC `e`: the sample interval it closes goes to `sources`.
    fn edge(&mut self, e: i128, sources: &mut Sources) -> Result<(), RunError>;
    /// How far to make frames at `now` (`Continue(None)`: nothing yet; `Break`: the run ends,
    /// with that reason).
    fn horizon(
        &mut self,
        now: i128,
        sources: &mut Sources,
    ) -> ControlFlow<&'static str, Option<Until>>;
    /// After the frames up to the horizon were made: their deadlines on the pacer's clock.
    fn made(&mut self, parts: &mut [Part]);
    /// Adds the source's own figures to the status published after each hand-over.
    fn report(&self, status: &mut RunStatus);
}

/// The loop both just-in-time drivers share: wait for the next frame's wake-up (taking the
/// trigger's `edges` meanwhile, if any), make what is due [`LEAD_S`] from now, put it on the
/// pacer's clock and hand it over; the reason the run ended.
fn just_in_time<J: JustInTime>(
    clock: &mut J,
    sources: &mut Sources,
    edges: Option<&std::sync::mpsc::Receiver<i128>>,
    feed: &mut PacerFeed,
    pacer: &PacerThread,
    ctl: &Control,
) -> Result<&'static str, RunError> {
    let stop = ctl.flag();
    let mut gone = false;
    let mut status = RunStatus {
        started: true,
        ..RunStatus::default()
    };
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok("stopped");
        }
        if sources.done() {
            return Ok(J::COMPLETE);
        }
        let wake = clock.wake(sources.next_due());
        match edges {
            Some(rx) => {
                if let Some(e) = wait_edge(rx, wake, &stop, &mut gone) {
                    clock.edge(e, sources)?;
                    // Edges that queued meanwhile; one that closes no interval is passed over.
                    while let Ok(e) = rx.try_recv() {
                        let _ = clock.edge(e, sources);
                    }
                } else if gone && let Some(why) = J::EDGES_GONE {
                    return Ok(why);
                }
            }
            None => sleep_to(wake, &stop),
        }
        let until = match clock.horizon(monotonic_ns(), sources) {
            ControlFlow::Break(why) => return Ok(why),
            ControlFlow::Continue(None) => continue,
            ControlFlow::Continue(Some(u)) => u,
        };
        sources.fill(until)?;
        clock.made(&mut sources.parts);
        if !feed.send(&sources.parts) {
            return Ok("the output closed");
        }
        pacer.observe(&mut status);
        clock.report(&mut status);
        ctl.publish(|s| *s = status.clone());
    }
}

/// A trigger line on a known motion: t₀ is the first edge, where the pacer's clock starts.
struct Edges {
    /// The first edge (CLOCK_MONOTONIC ns).
    first: i128,
    /// The run's t₀ on the simulation's axis (s).
    origin: f64,
    trigger: Trigger,
}

impl JustInTime for Edges {
    const COMPLETE: &'static str = "complete";
    const EDGES_GONE: Option<&'static str> = Some("trigger ended");

    fn wake(&mut self, next: Option<i64>) -> i128 {
        next.map_or(monotonic_ns() + 100_000_000, |d| {
            self.first + d as i128 - LEAD_NS
        })
    }

    fn edge(&mut self, e: i128, sources: &mut Sources) -> Result<(), RunError> {
        match self.trigger.edge(e) {
            Ok(Some((lo, hi))) => sources.edge(lo, hi),
            Ok(None) => {}
            Err(m) => return Err(RunError::Engine(EngineError::Trigger(m))),
        }
        Ok(())
    }

    fn horizon(&mut self, now: i128, _: &mut Sources) -> ControlFlow<&'static str, Option<Until>> {
        let until = Until::ns(self.origin, (now + LEAD_NS - self.first) as i64);
        ControlFlow::Continue(Some(until))
    }

    fn made(&mut self, parts: &mut [Part]) {
        // The pacer's clock starts at the first edge, t₀: the deadlines are the emission times.
        to_wall(parts, |ns| ns);
    }

    fn report(&self, _: &mut RunStatus) {}
}

/// A live input in real time: its clock map puts simulation time on the host's clock, plus
/// the output delay; a PPS lock may slew the pacer's deadlines.
struct Follow<'a> {
    st: &'a mut LiveStatus,
    shared: &'a input::Shared,
    model: &'a CausalMotion,
    on_timeout: OnTimeout,
    /// The input's idle timeout (ns) when a silence that long ends it (UDP, TCP).
    idle_ns: Option<i128>,
    /// The pacer's schedule once a phase lock slewed it.
    slewed: ScheduleWatch,
    /// The pacer's start (CLOCK_MONOTONIC ns).
    anchor: i128,
    delay_ns: i128,
    /// The run's t₀ on the simulation's axis (s).
    origin: f64,
    /// The clock map and the pacer's schedule at the last wake-up.
    map: ClockMap,
    sched: Option<Schedule>,
    /// Simulation time made so far; the horizon, newest state and tail of the fill under way.
    emitted: f64,
    horizon: f64,
    newest: f64,
    tail: Tail,
    held: bool,
    /// The simulation time of the previous trigger edge, if any.
    prev_edge: Option<f64>,
}

impl Follow<'_> {
    /// The host instant (CLOCK_MONOTONIC ns) simulation time `t` is due at.
    fn host(&self, t: f64) -> i128 {
        self.map.host_ns(t) + self.delay_ns
    }

    /// The pacer's deadline of the host instant `h`.
    fn due(&self, h: i128) -> i128 {
        self.sched.map_or(h, |s| s.at(h - self.anchor))
    }

    /// The host instant due at the pacer's deadline `w`.
    fn undue(&self, w: i128) -> i128 {
        self.sched.map_or(w, |s| self.anchor + s.nominal(w))
    }
}

impl JustInTime for Follow<'_> {
    const COMPLETE: &'static str = "duration reached";
    const EDGES_GONE: Option<&'static str> = None;

    fn wake(&mut self, next: Option<i64>) -> i128 {
        self.map = input::observe(self.st, self.shared).0;
        self.sched = self.slewed.get();
        next.map_or(monotonic_ns() + 10_000_000, |d| {
            self.due(self.host(self.origin + d as f64 * 1e-9)) - LEAD_NS
        })
    }

    fn edge(&mut self, e: i128, sources: &mut Sources) -> Result<(), RunError> {
        // The edge asks for the sample the output delay puts at its instant.
        let t = self.map.sim_at(e - self.delay_ns);
        if let Some(p) = self.prev_edge.replace(t) {
            if t > p && p >= self.origin {
                sources.edge(p - self.origin, t - self.origin);
            } else {
                // Before the run's t₀ (the input not yet followed) or not after the previous:
                // no interval to sample; said in the summary.
                self.st.edges_unused += 1;
            }
        }
        Ok(())
    }

    fn horizon(
        &mut self,
        now: i128,
        sources: &mut Sources,
    ) -> ControlFlow<&'static str, Option<Until>> {
        let input::Seen {
            map,
            end,
            last_arrival_ns,
        } = input::observe_end(self.st, self.shared);
        let input_ended = end.is_some();
        self.st.stale = input_ended;
        let newest = self.model.newest();
        let mut horizon = map.sim_at(self.undue(now + LEAD_NS) - self.delay_ns);
        // A run that stops after a silence makes no frame due after the silence would be over:
        // however late the silence is noticed, its extrapolation lasts the timeout at most.
        if let (OnTimeout::Stop, Some(a), Some(idle)) =
            (self.on_timeout, last_arrival_ns, self.idle_ns)
        {
            let over = map.sim_at(self.undue(a + idle) - self.delay_ns);
            horizon = horizon.min(over.max(newest));
        }
        if let Some(silence) = end {
            match self.on_timeout {
                OnTimeout::Stop => {
                    // The records on the newest state's time are still the input's, as in
                    // lockstep (`Until::state`); after a silence, so are those that fell due
                    // while it was waited out, however late this wake-up comes.
                    let waited = silence.map(|ns| map.sim_at(self.undue(ns) - self.delay_ns));
                    let last = Until::state(self.origin, newest.max(waited.unwrap_or(newest)));
                    let next = sources.next_due();
                    if next.is_none_or(|d| d > last.ns) {
                        return ControlFlow::Break("input ended");
                    }
                    horizon = horizon.min(last.t);
                }
                OnTimeout::Hold if !self.held => {
                    self.model.hold_from(self.emitted);
                    self.held = true;
                }
                _ => {}
            }
        }
        if horizon <= self.emitted {
            return ControlFlow::Continue(None);
        }
        let tail = self.model.prepare(self.emitted, horizon);
        // Frames that no longer follow the input say so where their protocol can.
        let stale = input_ended || tail == Tail::Holding;
        sources.set_flags(if stale { FLAG_STALE } else { 0 });
        (self.horizon, self.newest, self.tail) = (horizon, newest, tail);
        ControlFlow::Continue(Some(Until::time(self.origin, horizon)))
    }

    fn made(&mut self, parts: &mut [Part]) {
        self.emitted = self.horizon;
        // The units' records, and those of them past the newest state (made from the
        // extrapolated or held motion).
        let newest_ns = Until::state(self.origin, self.newest).ns;
        for p in parts.iter().filter(|p| p.marks_records) {
            self.st.frames += p.records.len() as u64;
            self.st.extrapolated += p.records.iter().filter(|r| r.1 > newest_ns).count() as u64;
        }
        self.st.tail = Some(self.tail);
        self.st.corrections = self.model.corrections();
        let this = &*self;
        to_wall(parts, |ns| {
            (this.host(this.origin + ns as f64 * 1e-9) - this.anchor) as i64
        });
    }

    fn report(&self, status: &mut RunStatus) {
        status.live = Some(self.st.clone());
    }
}

/// Sleeps until `wake` (CLOCK_MONOTONIC ns) or a stop request, in slices of at most 100 ms.
fn sleep_to(wake: i128, stop: &AtomicBool) {
    while monotonic_ns() < wake && !stop.load(Ordering::Relaxed) {
        sleep_until(wake.min(monotonic_ns() + 100_000_000));
    }
}

/// Waits until `wake` for a trigger edge (CLOCK_MONOTONIC ns); `None` at `wake`, on a stop,
/// or when the edge source has gone (then `gone` is set).
fn wait_edge(
    edges: &std::sync::mpsc::Receiver<i128>,
    wake: i128,
    stop: &AtomicBool,
    gone: &mut bool,
) -> Option<i128> {
    use std::sync::mpsc::RecvTimeoutError;
    loop {
        if stop.load(Ordering::Relaxed) {
            return None;
        }
        let left = (wake - monotonic_ns()).clamp(0, 100_000_000);
        match edges.recv_timeout(std::time::Duration::from_nanos(left as u64)) {
            Ok(e) => return Some(e),
            Err(RecvTimeoutError::Disconnected) => {
                *gone = true;
                sleep_to(wake, stop);
                return None;
            }
            Err(RecvTimeoutError::Timeout) if monotonic_ns() >= wake => return None,
            Err(RecvTimeoutError::Timeout) => {}
        }
    }
}

/// Puts the window's emission times (ns after t₀ on the simulation's axis) on the pacer's
/// clock: `wall(ns)` is the frame's deadline in ns after the pacer's start. A record's time
/// of validity keeps its simulation value (time marks report it) and gets its wall instant.
fn to_wall(parts: &mut [Part], wall: impl Fn(i64) -> i64) {
    for p in parts.iter_mut() {
        for e in p.emit_ns.iter_mut() {
            *e = wall(*e);
        }
        p.tov_wall_ns.clear();
        if p.marks_records {
            let w: Vec<i64> = p.records.iter().map(|r| wall(r.1)).collect();
            p.tov_wall_ns = w;
        }
    }
}

/// A paced run of a known motion whose units sample at a trigger line's edges: t₀ is the
/// first edge, each later edge closes a sample interval, and every frame is made just in time.
pub(super) fn triggered(run: Run, wall: Wall, ctl: &Control) -> Result<RunReport, RunError> {
    use crate::realtime::pps;
    let Run {
        signal,
        layout,
        links,
        sync,
        time_base,
        ..
    } = run;
    let spec = sync.trigger.clone().expect("a trigger");
    let stop = ctl.flag();
    let mut out = Outlets::open(&layout.streams, &links, 1.0, true, ctl)?;
    let open = pps::open_for("--trigger", &spec)
        .map_err(|e| RunError::io(format!("--trigger {spec}"), e))?;
    let edges = pps::spawn(open, stop.clone()).map_err(|e| RunError::io("--trigger", e))?;
    ctl.note(&format!("waiting for the first trigger edge on {spec}"));
    let mut gone = false;
    let first = loop {
        if let Some(e) = wait_edge(&edges, monotonic_ns() + 100_000_000, &stop, &mut gone) {
            break e;
        }
        if gone {
            return Err(RunError::spec(
                "--trigger",
                format!("{spec}: the edge source stopped"),
            ));
        }
        if stop.load(Ordering::Relaxed) {
            out.close(false)?;
            return Err(RunError::spec(
                "--trigger",
                "stopped before the first edge".into(),
            ));
        }
    };
    let utc0 = first + clock::host_offset().utc_minus_mono;
    let gps = time_base_ref(time_base, utc0, ctl);
    let mut built = layout.build(signal, gps, true)?;
    out.preamble(&built.preambles)?;
    let extras = extras(&sync, &layout.streams, 1.0, &stop)?;
    if !sync.time_marks.is_empty() {
        ctl.note(&clock::describe_offset());
    }
    let c = clocking(&layout.streams, &wall, Some(first))?.with_edges();
    let (pacer, mut feed) = PacerThread::start(out, &layout.streams, c, extras, stop.clone())?;
    let mut trigger = Trigger::new(f64::INFINITY);
    let _ = trigger.edge(first);
    let mut edge_clock = Edges {
        first,
        origin: built.origin,
        trigger,
    };
    let ended = just_in_time(
        &mut edge_clock,
        &mut built.sources,
        Some(&edges),
        &mut feed,
        &pacer,
        ctl,
    );
    drop(feed);
    end(pacer, ended, layout.streams, built, None, ctl)
}

/// A real-time run behind a live input: the input thread feeds the model and the clock map;
/// frames go out at the host instants of their simulation time plus the output delay.
pub(super) fn realtime(run: Run, wall: Wall, ctl: &Control) -> Result<RunReport, RunError> {
    let Run {
        signal,
        layout,
        links,
        sync,
        time_base,
        ..
    } = run;
    let Signal::Live {
        builder,
        rig,
        input: live,
    } = signal
    else {
        unreachable!("real time follows a live input")
    };
    let stop = ctl.flag();
    let mut out = Outlets::open(&layout.streams, &links, 1.0, true, ctl)?;
    let settings = builder.model_settings()?;
    let model = CausalMotion::new(settings);
    model.enable_chain(live.chain);
    let need = settings.stencil.max(3);
    let gps = (time_base == TimeBase::Gps).then(|| {
        let host = GpsClock::new(LeapTable::builtin());
        // GPS time on the host's clocks through the run's one reading of their offset
        // (clock::host_offset), as every other UTC or GPS instant of the run.
        let mono_ns = monotonic_ns();
        let gps_ns = host.utc_to_gps_ns(mono_ns + clock::host_offset().utc_minus_mono);
        ctl.note(&format!(
            "time base gps: the input's time tags are GPS time, mapped to {}; {}",
            host.describe(clock::realtime_ns()),
            clock::describe_offset()
        ));
        GpsBase::at(gps_ns, mono_ns)
    });
    let rx = match Receiver::open_until(
        &live.endpoint,
        live.format,
        Some(std::time::Duration::from_secs_f64(live.idle_s)),
        Some(stop.clone()),
    ) {
        Ok(rx) => rx,
        Err(e) => {
            // Stopped (or failed) before a sender connected: no output file is left behind.
            out.close(false)?;
            return Err(RunError::io(
                format!("--motion {}: opening", live.source),
                e,
            ));
        }
    };
    let name = rx.name().to_string();
    ctl.note(&format!("following {name} in real time"));
    let record = Arc::new(Mutex::new(match &live.record {
        Some(p) => Some(
            AtomicFile::create(p)
                .map_err(|e| RunError::io(format!("creating {}", p.display()), e))?,
        ),
        None => None,
    }));
    let shared = input::start(rx, live.format, gps, &model, record.clone(), &stop)?;
    let keep_record = |record: &Arc<Mutex<Option<AtomicFile>>>| -> Result<(), RunError> {
        let taken = record.lock().unwrap_or_else(|e| e.into_inner()).take();
        if let (Some(r), Some(p)) = (taken, &live.record) {
            r.commit()
                .map_err(|e| RunError::io(format!("writing {}", p.display()), e))?;
        }
        Ok(())
    };
    let started = input::first_knot(&shared, &model, &stop, &name, need);
    let started = match started {
        Ok(Some(())) => Ok(()),
        Ok(None) => Err(None),
        Err(e) => Err(Some(e)),
    };
    if let Err(e) = started {
        out.close(false)?;
        keep_record(&record)?;
        return match e {
            Some(e) => Err(e),
            None => {
                // One lock: a second in the same expression would wait for the first.
                let stats = input::lock(&shared).stats.clone();
                Err(RunError::TooFewStates {
                    input: name,
                    states: stats.states,
                    need,
                    why: stats.why_unused(),
                })
            }
        };
    }
    let mut st = LiveStatus::default();
    let (map, _) = input::observe(&mut st, &shared);
    let delay = live.delay.unwrap_or_else(|| map.default_delay(MARGIN_S));
    st.delay = delay;
    if let Some(g) = gps {
        let newest = model.newest();
        let off = (map.host_ns(newest) - monotonic_ns()) as f64 / 1e9;
        if off.abs() > GPS_TAG_TOLERANCE_S {
            out.close(false)?;
            keep_record(&record)?;
            return Err(RunError::TimeBase(format!(
                "{name}: the state at {newest} s of GPS week {} maps {off:+.3e} s from now on the host's GPS clock: with the GPS time base the input's time tags must be GPS time (binary: a GPS week; CSV: gps_week,gps_sow)",
                g.week
            )));
        }
    }
    let week = gps.map(|g| g.week).or(input::lock(&shared).week);
    let triggered = sync.trigger.is_some();
    let mut built = match layout.build_live(&builder, rig, &model, week, triggered) {
        Ok(b) => b,
        Err(e) => {
            out.close(false)?;
            keep_record(&record)?;
            return Err(e);
        }
    };
    out.preamble(&built.preambles)?;
    let mut extras = extras(&sync, &layout.streams, 1.0, &stop)?;
    if !sync.time_marks.is_empty() && time_base != TimeBase::Gps {
        ctl.note(&clock::describe_offset());
    }
    // The pacer's whole seconds are what a PPS lock pulls onto its edges: on the GPS time
    // base they are the host's whole GPS seconds (the week began on one), so the lock
    // disciplines the map from the input's GPS tags to the host clock.
    let now = monotonic_ns();
    let anchor = match gps {
        Some(g) => now - (now - g.host_at_week_ns).rem_euclid(1_000_000_000),
        None => now,
    };
    // With a lock the pacer slews its deadlines: frames are made before the slewed ones.
    let slewed = ScheduleWatch::default();
    if sync.pps_in.is_some() {
        extras.hooks.push(Box::new(slewed.clone()));
    }
    let mut c = clocking(&layout.streams, &wall, Some(anchor))?;
    if triggered {
        c = c.with_edges();
    }
    let (pacer, mut feed) = PacerThread::start(out, &layout.streams, c, extras, stop.clone())?;
    let edges = match &sync.trigger {
        Some(spec) => {
            use crate::realtime::pps;
            let open = pps::open_for("--trigger", spec)
                .map_err(|e| RunError::io(format!("--trigger {spec}"), e))?;
            Some(pps::spawn(open, stop.clone()).map_err(|e| RunError::io("--trigger", e))?)
        }
        None => None,
    };
    let origin = built.origin;
    let mut follow = Follow {
        st: &mut st,
        shared: &shared,
        model: &model,
        on_timeout: live.on_timeout,
        idle_ns: (!matches!(live.endpoint, crate::live::transport::Endpoint::Stream(_)))
            .then(|| (live.idle_s * 1e9).round() as i128),
        slewed,
        anchor,
        delay_ns: (delay * 1e9).round() as i128,
        origin,
        map: Default::default(),
        sched: None,
        emitted: origin,
        horizon: origin,
        newest: origin,
        tail: Tail::Following,
        held: false,
        prev_edge: None,
    };
    let ended = just_in_time(
        &mut follow,
        &mut built.sources,
        edges.as_ref(),
        &mut feed,
        &pacer,
        ctl,
    );
    st.corrections = model.corrections();
    let (_, _) = input::observe(&mut st, &shared);
    let read = input::take_error(&shared, &name);
    keep_record(&record)?;
    let ended = match (ended, read) {
        (Err(e), _) => Err(e),
        (Ok(_), Err(e)) => Err(e),
        (Ok(x), Ok(())) => Ok(x),
    };
    let stats = st.stats.clone();
    drop(feed);
    let mut report = end(pacer, ended, layout.streams, built, Some(stats), ctl)?;
    report.status.live = Some(st);
    ctl.set(report.status.clone());
    Ok(report)
}
