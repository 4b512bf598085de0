//! A live input followed in real time: states arrive on a thread of their own, which records
//! every message, decodes it, feeds the causal motion model and the clock map from the
//! sender's time to the host's, and counts what happened. The driver (`super::wall`) reads
//! the map and the counts between its frames.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

use crate::live::clockmap::{ClockMap, GivenMap};
use crate::live::stats::InputStats;
use crate::live::transport::Receiver;
use crate::live::{Decoder, InputFormat, TimeBase};
use crate::motion::causal::CausalMotion;
use crate::realtime::clock::monotonic_ns;

use super::error::RunError;
use super::status::LiveStatus;

/// Scheduling margin added to the default output delay (s): the driver's lead and the input
/// thread's wake-up on a loaded machine.
pub const MARGIN_S: f64 = 0.003;

/// Largest distance between a state's mapped instant and its arrival (s) before a given GPS
/// map is refused: tags that are not GPS time (simulation seconds) land years away.
pub const GPS_TAG_TOLERANCE_S: f64 = 60.0;

/// Largest lead of a state's time tag over the time the clock map gives its arrival (s). A
/// state cannot have been sent after it arrived, so a tag ahead of its arrival's time is the
/// map's own error — its slew behind a path that got faster, a sender clock off its fitted
/// rate — far below this; a second leaves room for either. A tag beyond it (a clock in µs
/// read as s, a stray GPS time, a sender that jumped its clock) would pull every frame
/// towards a motion seconds away.
pub const MAX_AHEAD_S: f64 = 1.0;

/// Why a state with time tag `t` that arrived at `arrival_ns` is refused by the clock map:
/// its tag more than [`MAX_AHEAD_S`] ahead of the map's time for its arrival (none before
/// the map has a state).
fn ahead_of_clock(
    map: &ClockMap,
    t: f64,
    arrival_ns: i128,
) -> Option<crate::motion::causal::Rejected> {
    if !map.ready() {
        return None;
    }
    let by = t - map.sim_at(arrival_ns);
    (by > MAX_AHEAD_S).then_some(crate::motion::causal::Rejected::Ahead {
        by,
        limit: MAX_AHEAD_S,
    })
}

/// The host's GPS clock read once: the input's tags (GPS time) map to the host's monotonic
/// clock directly. Tags are taken relative to the start of `week`, so the motion model works
/// in seconds of that week (resolution 1e-10 s, where GPS seconds since 1980 have 2.4e-7 s).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GpsBase {
    /// The GPS week the run's record time counts from.
    pub week: u32,
    /// The host instant (CLOCK_MONOTONIC ns) at which that week began.
    pub host_at_week_ns: i128,
}

impl GpsBase {
    /// The base for GPS time `gps_ns` (ns since the GPS epoch) read at host instant `mono_ns`.
    pub fn at(gps_ns: i128, mono_ns: i128) -> GpsBase {
        let week_ns = 604_800 * 1_000_000_000i128;
        let week = gps_ns.div_euclid(week_ns);
        GpsBase {
            week: week as u32,
            host_at_week_ns: mono_ns - (gps_ns - week * week_ns),
        }
    }
}

/// What the input thread shares.
pub(super) struct Input {
    pub(super) stats: InputStats,
    pub(super) map: ClockMap,
    pub(super) ended: bool,
    /// When the silence that ended the input was over (CLOCK_MONOTONIC ns): the newest
    /// datagram's arrival plus the idle timeout; `None` for a stream's end.
    pub(super) silence_over_ns: Option<i128>,
    /// When the newest message arrived (CLOCK_MONOTONIC ns).
    pub(super) last_arrival_ns: Option<i128>,
    error: Option<std::io::Error>,
    /// The GPS week the states' times count from, once a GPS tag has come.
    pub(super) week: Option<u32>,
}

/// The input thread's shared state and its wake-up.
pub(super) type Shared = Arc<(Mutex<Input>, Condvar)>;

/// Locks the shared input state (a poisoned lock still holds the counts).
pub(super) fn lock(s: &Shared) -> MutexGuard<'_, Input> {
    s.0.lock().unwrap_or_else(|e| e.into_inner())
}

/// Starts the input thread on `rx` into `model`, with the map given by `gps` (the input's tags
/// are GPS time) or estimated; `record` receives every message.
pub(super) fn start<W: Write + Send + 'static>(
    mut rx: Receiver,
    format: InputFormat,
    gps: Option<GpsBase>,
    model: &CausalMotion,
    record: Arc<Mutex<Option<W>>>,
    stop: &Arc<AtomicBool>,
) -> Result<Shared, RunError> {
    let shared: Shared = Arc::new((
        Mutex::new(Input {
            stats: InputStats::default(),
            map: match gps {
                Some(g) => ClockMap::given(GivenMap {
                    t0: 0.0,
                    host0_ns: g.host_at_week_ns,
                    rate: 0.0,
                }),
                None => ClockMap::new(),
            },
            ended: false,
            silence_over_ns: None,
            last_arrival_ns: None,
            error: None,
            week: None,
        }),
        Condvar::new(),
    ));
    let (s, model, stop) = (shared.clone(), model.clone(), stop.clone());
    let epoch = gps.map(|g| g.week);
    std::thread::Builder::new()
        .name("imu-live-input".into())
        .spawn(move || receive(&mut rx, format, epoch, &model, &record, &s, &stop))
        .map_err(|e| RunError::io("starting the input thread", e))?;
    Ok(shared)
}

/// Waits for the model's first knot; the input's read error, or too few states, if it
/// ended first; `None` if stopped.
pub(super) fn first_knot(
    shared: &Shared,
    model: &CausalMotion,
    stop: &AtomicBool,
    name: &str,
    need: usize,
) -> Result<Option<()>, RunError> {
    loop {
        let mut g = lock(shared);
        if model.knots() > 0 {
            return Ok(Some(()));
        }
        if stop.load(Ordering::Relaxed) {
            return Ok(None);
        }
        if g.ended {
            if let Some(e) = g.error.take() {
                return Err(RunError::io(format!("reading {name}"), e));
            }
            return Err(RunError::TooFewStates {
                input: name.to_string(),
                states: g.stats.states,
                need,
                why: g.stats.why_unused(),
            });
        }
        drop(shared.1.wait_timeout(g, Duration::from_millis(50)));
    }
}

/// Takes the input's counts and clock-map figures into `st`; returns a snapshot of the map
/// and whether the input has ended.
pub(super) fn observe(st: &mut LiveStatus, shared: &Shared) -> (ClockMap, bool) {
    let seen = observe_end(st, shared);
    (seen.map, seen.end.is_some())
}

/// What [`observe_end`] sees of the input.
pub(super) struct Seen {
    /// The clock map.
    pub(super) map: ClockMap,
    /// How the input ended: `None` while it goes on, `Some(None)` at a stream's end,
    /// `Some(Some(ns))` after a silence that was over at host instant `ns`.
    pub(super) end: Option<Option<i128>>,
    /// When the newest message arrived (CLOCK_MONOTONIC ns).
    pub(super) last_arrival_ns: Option<i128>,
}

/// [`observe`], with how the input ended and when its newest message came.
pub(super) fn observe_end(st: &mut LiveStatus, shared: &Shared) -> Seen {
    let g = lock(shared);
    st.stats = g.stats.clone();
    st.rate = g.map.rate();
    st.jitter = g.map.jitter();
    st.clock_rate = g.map.clock_rate();
    st.relocks = g.map.relocks();
    Seen {
        map: g.map.clone(),
        end: g.ended.then_some(g.silence_over_ns),
        last_arrival_ns: g.last_arrival_ns,
    }
}

/// The input's read error, if it had one (the run's error then).
pub(super) fn take_error(shared: &Shared, name: &str) -> Result<(), RunError> {
    match lock(shared).error.take() {
        Some(e) => Err(RunError::io(format!("reading {name}"), e)),
        None => Ok(()),
    }
}

/// The input thread: receives, records, decodes, feeds the model and the clock map; GPS
/// tags are taken from the start of GPS week `epoch` (`None`: the first one seen), which
/// also sets the GPS time base.
fn receive<W: Write>(
    rx: &mut Receiver,
    format: InputFormat,
    epoch: Option<u32>,
    model: &CausalMotion,
    record: &Mutex<Option<W>>,
    shared: &(Mutex<Input>, Condvar),
    stop: &AtomicBool,
) {
    let base = match epoch {
        Some(_) => TimeBase::Gps,
        None => TimeBase::Sim,
    };
    let mut decoder = Decoder::with_base(format, base, epoch);
    let modulo = super::pipeline::modulo(format);
    let name = rx.name().to_string();
    let (lock, cv) = shared;
    let error = loop {
        if stop.load(Ordering::Relaxed) {
            break None;
        }
        let m = match rx.next_message() {
            Ok(Some(m)) => m,
            Ok(None) => break None,
            Err(e) => break Some(e),
        };
        let arrival_ns = monotonic_ns() - m.arrival.elapsed().as_nanos() as i128;
        if let Some(r) = record.lock().unwrap_or_else(|e| e.into_inner()).as_mut() {
            let nl: &[u8] = if format == InputFormat::Csv {
                b"\n"
            } else {
                b""
            };
            if let Err(e) = r.write_all(&m.bytes).and_then(|_| r.write_all(nl)) {
                break Some(e);
            }
        }
        let decoded = decoder.decode(&m.bytes);
        let mut g = lock.lock().unwrap_or_else(|e| e.into_inner());
        g.stats.message(&m);
        g.stats.transport(rx);
        g.last_arrival_ns = Some(arrival_ns);
        match decoded {
            Ok(Some(d)) => {
                let outcome = match ahead_of_clock(&g.map, d.state.sample.t, arrival_ns) {
                    Some(r) => Err(r),
                    None => model.push(&d.state),
                };
                let place = format!("{name}: {}", m.place);
                g.stats.state(&d, &outcome, modulo, &place);
                if outcome.is_ok() {
                    g.map.observe(d.state.sample.t, arrival_ns);
                }
                g.week = decoder.epoch_week();
            }
            Ok(None) => g.stats.no_state(),
            Err(e) if e.fatal => {
                let what = format!("{}: {}", m.place.at(e.offset), e.message);
                break Some(std::io::Error::new(std::io::ErrorKind::InvalidData, what));
            }
            Err(e) => {
                let at = format!("{name}: {}", m.place.at(e.offset));
                g.stats.malformed(&at, &e.message);
            }
        }
        drop(g);
        cv.notify_all();
    };
    let mut g = lock.lock().unwrap_or_else(|e| e.into_inner());
    g.ended = true;
    g.silence_over_ns = rx.silence_over_at().map(|at| {
        let now = std::time::Instant::now();
        let before = now.saturating_duration_since(at).as_nanos() as i128;
        monotonic_ns() - before
    });
    g.error = error;
    g.stats.transport(rx);
    drop(g);
    cv.notify_all();
}
