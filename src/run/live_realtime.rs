//! Real-time mode: states arrive on their own thread and update the causal model and the
//! clock map ([`crate::live::clockmap`]); the emitter produces record k just before its deadline
//! — the host instant simulation time t_k maps to, plus a constant output delay — from what
//! has arrived by then, and hands the frame to the pacer ([`crate::realtime::pacer`]), which
//! writes it at that deadline to every sink.
//!
//! What the emitter integrates is the chain of [`crate::motion::chain`]: the received
//! pieces while states come in time, a bounded extrapolation when one is late, a smooth
//! bridge back when it arrives. When the input goes silent for the receiver's timeout (or a
//! stream ends), [`OnTimeout`] decides.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use tokio::sync::mpsc::{Receiver as BlockRx, Sender as BlockTx};

use super::lockstep::LiveError;
use crate::engine::Grid;
use crate::live::clockmap::{ClockMap, GivenMap};
use crate::live::stats::InputStats;
use crate::live::transport::Receiver;
use crate::live::{Decoder, InputFormat, TimeBase};
use crate::motion::causal::CausalMotion;
use crate::motion::chain::{ChainSettings, Corrections, Tail};
use crate::protocol::Plan;
use crate::realtime::FrameBlock;
use crate::realtime::clock::{monotonic_ns, sleep_until};
use crate::record::FLAG_STALE;
use crate::sim::{SimError, SimulationBuilder};

mod rig;
pub use rig::RigRealtimeSummary;

/// The emitter wakes this long before a frame's deadline to produce it (s): what it
/// computes for one frame takes microseconds; the rest absorbs its own wake-up lateness.
pub const LEAD_S: f64 = 0.001;

/// Scheduling margin added to the default output delay (s): the emitter's lead and the
/// input thread's wake-up on a loaded machine.
pub const MARGIN_S: f64 = 0.003;

/// What happens once the input is silent for the timeout (or its stream ended).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnTimeout {
    /// Keep extrapolating (bounded, then holding), frames keep coming.
    Extrapolate,
    /// Hold at once: constant acceleration and angular rate.
    Hold,
    /// Emit up to the newest state, then stop the run.
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

/// Settings of a real-time run.
#[derive(Clone, Copy, Debug)]
pub struct RealtimeSettings {
    /// Output delay (s); `None`: [`ClockMap::default_delay`] at the first knot.
    pub delay: Option<f64>,
    /// Extrapolation bound and correction horizon.
    pub chain: ChainSettings,
    /// What a silent input leads to.
    pub on_timeout: OnTimeout,
    /// The host clock reads GPS time and the input's tags are GPS time: the map is given,
    /// not estimated.
    pub gps: Option<GpsBase>,
}

/// The host's GPS clock read once: the tags (GPS seconds since the GPS epoch) map to the
/// host's monotonic clock directly. Tags are taken relative to the start of `week`, so the
/// motion model works in seconds of that week (resolution 1e-10 s, where GPS seconds since
/// 1980 have 2.4e-7 s), and the frames' GPS-time fields carry the tags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GpsBase {
    /// The GPS week the run's simulation time counts from.
    pub week: u32,
    /// The host instant (CLOCK_MONOTONIC ns) at which that week began.
    pub host_at_week_ns: i128,
}

impl GpsBase {
    /// The base for GPS time `gps_ns` (ns since the GPS epoch) read at host instant
    /// `mono_ns`.
    pub fn at(gps_ns: i128, mono_ns: i128) -> GpsBase {
        let week_ns = 604_800 * 1_000_000_000i128;
        let week = gps_ns.div_euclid(week_ns);
        GpsBase {
            week: week as u32,
            host_at_week_ns: mono_ns - (gps_ns - week * week_ns),
        }
    }

    /// GPS seconds since the epoch at the start of the week.
    pub fn epoch_s(&self) -> f64 {
        self.week as f64 * 604_800.0
    }
}

/// Largest distance between a state's mapped instant and its arrival (s) before a given GPS
/// map is refused: tags that are not GPS time (simulation seconds) land years away.
pub const GPS_TAG_TOLERANCE_S: f64 = 60.0;

/// Live figures of a real-time run (the CLI prints them once a second).
#[derive(Clone, Debug, Default)]
pub struct LiveStatus {
    /// What the newest frame's motion was doing.
    pub tail: Option<Tail>,
    /// The input has gone silent (or ended).
    pub stale: bool,
    /// States per second over the clock map's window.
    pub rate: f64,
    /// Arrival jitter over the window (s).
    pub jitter: f64,
    /// The sender's clock against the host's (fitted or given; s per s).
    pub clock_rate: f64,
    /// Output delay in use (s).
    pub delay: f64,
    /// What happened to the input.
    pub stats: InputStats,
    /// Largest corrections so far.
    pub corrections: Corrections,
    /// Frames produced, and how many of them were extrapolated or held.
    pub frames: u64,
    /// Frames whose motion was extrapolated or held past the newest state.
    pub extrapolated: u64,
}

impl LiveStatus {
    /// One line: state, input rate, jitter, loss, delay, corrections.
    pub fn line(&self) -> String {
        let state = match (self.stale, self.tail) {
            (true, _) => "stale",
            (_, None) => "waiting",
            (_, Some(Tail::Following)) => "following",
            (_, Some(Tail::Extrapolating)) => "extrapolating",
            (_, Some(Tail::Holding)) => "holding",
        };
        let c = &self.corrections;
        format!(
            "{state}; input {:.1} Hz, jitter {:.2} ms, clock {:+.1} ppm, {} missing, {} late; delay {:.2} ms; {} frames ({} extrapolated); {} corrections, max {:.3e} m, {:.3e} m/s, {:.3e} rad",
            self.rate,
            self.jitter * 1e3,
            self.clock_rate * 1e6,
            self.stats.missing,
            self.stats.reordered,
            self.delay * 1e3,
            self.frames,
            self.extrapolated,
            c.count,
            c.position,
            c.velocity,
            c.attitude
        )
    }
}

/// How a real-time run ended.
#[derive(Clone, Debug)]
pub struct RealtimeSummary {
    /// The final figures.
    pub status: LiveStatus,
    /// The run's grid.
    pub grid: Grid,
    /// Why the run ended.
    pub ended: &'static str,
}

/// Where the frames go: the pacer's channel, the buffers it returns, and the pacer's start
/// instant (frame deadlines are sent relative to it).
pub struct FrameOut {
    /// Blocks to the pacer.
    pub tx: BlockTx<FrameBlock>,
    /// Blocks back from the pacer, for reuse.
    pub recycle: BlockRx<FrameBlock>,
    /// The pacer's start instant (CLOCK_MONOTONIC ns).
    pub anchor_ns: i128,
}

/// The input thread's shared state and its wake-up.
type Shared = (Mutex<Input>, Condvar);

struct Input {
    stats: InputStats,
    map: ClockMap,
    ended: bool,
    error: Option<std::io::Error>,
    /// The GPS week the states' times count from, once a GPS tag has come.
    week: Option<u32>,
}

/// A real-time run, ready to follow an input.
pub struct Realtime {
    builder: SimulationBuilder,
    model: CausalMotion,
    format: InputFormat,
    settings: RealtimeSettings,
    need: usize,
}

impl Realtime {
    /// A run of the simulation `builder` describes, following messages of `format`.
    pub fn new(
        builder: SimulationBuilder,
        format: InputFormat,
        settings: RealtimeSettings,
    ) -> Result<Realtime, SimError> {
        Realtime::checked(builder, format, settings, |b| b.build().map(drop))
    }

    /// A run of every unit of the rig `builder` describes (its scene file lists `[[imu]]`
    /// units), following messages of `format`: see [`Realtime::run_rig`].
    pub fn rig(
        builder: SimulationBuilder,
        format: InputFormat,
        settings: RealtimeSettings,
    ) -> Result<Realtime, SimError> {
        Realtime::checked(builder, format, settings, |b| b.build_rig().map(drop))
    }

    /// The run, its settings checked by `check` on a stand-in motion before any state.
    fn checked(
        builder: SimulationBuilder,
        format: InputFormat,
        settings: RealtimeSettings,
        check: impl Fn(SimulationBuilder) -> Result<(), SimError>,
    ) -> Result<Realtime, SimError> {
        let model_settings = builder.model_settings()?;
        check(super::target::stand_in(&builder))?;
        let model = CausalMotion::new(model_settings);
        model.enable_chain(settings.chain);
        Ok(Realtime {
            builder: builder.live_motion(model.clone()),
            model,
            format,
            settings,
            need: model_settings.stencil.max(3),
        })
    }

    /// Starts the input thread on `rx` and waits for the model's first knot: the shared
    /// input state, the output delay in use and the input's name.
    fn start_input<W: Write + Send + 'static>(
        &self,
        mut rx: Receiver,
        record: Arc<Mutex<Option<W>>>,
        stop: &Arc<AtomicBool>,
    ) -> Result<(Arc<Shared>, f64, String), LiveError> {
        let shared = Arc::new((
            Mutex::new(Input {
                stats: InputStats::default(),
                map: match self.settings.gps {
                    Some(g) => ClockMap::given(GivenMap {
                        t0: 0.0,
                        host0_ns: g.host_at_week_ns,
                        rate: 0.0,
                    }),
                    None => ClockMap::new(),
                },
                ended: false,
                error: None,
                week: None,
            }),
            Condvar::new(),
        ));
        let name = rx.name().to_string();
        {
            let (shared, model, stop) = (shared.clone(), self.model.clone(), Arc::clone(stop));
            let format = self.format;
            let epoch = self.settings.gps.map(|g| g.week);
            std::thread::Builder::new()
                .name("imu-live-input".into())
                .spawn(move || receive(&mut rx, format, epoch, &model, &record, &shared, &stop))
                .map_err(|source| LiveError::Io {
                    what: "starting the input thread".into(),
                    source,
                })?;
        }
        let (lock, cv) = &*shared;
        let get = || lock.lock().unwrap_or_else(|e| e.into_inner());
        // Wait for the model's first knot.
        let delay = loop {
            let g = get();
            if self.model.knots() > 0 {
                break self.settings.delay.unwrap_or(g.map.default_delay(MARGIN_S));
            }
            if g.ended || stop.load(Ordering::Relaxed) {
                let states = g.stats.states;
                if let Some(source) = get_error(g) {
                    return Err(LiveError::Io {
                        what: format!("reading {name}"),
                        source,
                    });
                }
                return Err(LiveError::TooFewStates {
                    input: name,
                    states,
                    need: self.need,
                });
            }
            drop(cv.wait_timeout(g, Duration::from_millis(50)));
        };
        if self.settings.gps.is_some() {
            let newest = self.model.newest();
            let off = (get().map.host_ns(newest) - monotonic_ns()) as f64 / 1e9;
            if off.abs() > GPS_TAG_TOLERANCE_S {
                return Err(LiveError::TimeBase(format!(
                    "{name}: the state at {newest} s of GPS week {} maps {off:+.3e} s from now on the host's GPS clock: with the GPS time base the input's time tags must be GPS time (binary: a GPS week; CSV: gps_week,gps_sow)",
                    self.settings.gps.map_or(0, |g| g.week)
                )));
            }
        }
        Ok((shared, delay, name))
    }

    /// Follows `rx` until the input ends (and the policy stops), `stop` is set, or the
    /// duration is done; `record`, when given, receives every message as it arrives.
    /// `extra` are the sinks' other protocols. `status` is refreshed after every frame block.
    pub fn run<W: Write + Send + 'static>(
        self,
        rx: Receiver,
        record: Arc<Mutex<Option<W>>>,
        extra: Vec<Plan>,
        mut out: FrameOut,
        stop: Arc<AtomicBool>,
        status: Arc<Mutex<LiveStatus>>,
    ) -> Result<RealtimeSummary, LiveError> {
        let (shared, delay, name) = self.start_input(rx, record, &stop)?;
        let (lock, _) = &*shared;
        let get = || lock.lock().unwrap_or_else(|e| e.into_inner());
        let delay_ns = (delay * 1e9).round() as i128;
        let lead_ns = (LEAD_S * 1e9) as i128;
        let mut sim = self.builder.build()?;
        // GPS-tagged states count from a week's start: the frames carry their GPS time.
        if let Some(week) = self.settings.gps.map(|g| g.week).or(get().week) {
            sim.set_gps_time(week, 0.0);
        }
        let grid = sim.grid();
        let extra: Vec<_> = extra.into_iter().map(|p| sim.frames_encoding(p)).collect();
        let streams = 1 + extra.len();
        let mut producer = sim.producer()?.with_extra_encodings(extra);
        let block_max = crate::realtime::block_len(grid.rate_hz);
        let time = |k: u64| grid.t0 + k as f64 / grid.rate_hz;
        let mut st = LiveStatus {
            delay,
            ..LiveStatus::default()
        };
        let mut k = 0u64;
        let mut held = false;
        // How far (s) an IMU with timing errors emits ahead of the nominal grid (a sensor
        // clock running fast): the emitter wakes that much earlier, so the pacer still
        // writes each frame at its own emission instant.
        let mut ahead = 0.0f64;
        let ended = loop {
            if stop.load(Ordering::Relaxed) {
                break "interrupted";
            }
            if producer.remaining() == 0 {
                break "duration reached";
            }
            let deadline = get().map.host_ns(time(k + 1) - ahead) + delay_ns;
            let wake = deadline - lead_ns;
            sleep_to(wake, &stop);
            let now = monotonic_ns();
            let (map, input_ended) = observe(&mut st, &get());
            st.stale = input_ended;
            let newest = self.model.newest();
            if input_ended {
                match self.settings.on_timeout {
                    OnTimeout::Stop if time(k + 1) > newest => break "input ended",
                    OnTimeout::Hold if !held => {
                        self.model.hold_from(time(k));
                        held = true;
                    }
                    _ => {}
                }
            }
            // Every frame due by now (after a stall, several), within one block.
            let mut n = 1u64;
            while (n as usize) < block_max
                && n < producer.remaining()
                && map.host_ns(time(k + n + 1) - ahead) + delay_ns <= now + lead_ns
                && !(input_ended
                    && self.settings.on_timeout == OnTimeout::Stop
                    && time(k + n + 1) > newest)
            {
                n += 1;
            }
            let tail = self.model.prepare(time(k), time(k + n));
            // Frames that no longer follow the input say so where their protocol can.
            producer.mark(if input_ended || tail == Tail::Holding {
                FLAG_STALE
            } else {
                0
            });
            let mut b = out.recycle.try_recv().unwrap_or_default();
            b.streams.resize_with(streams, Default::default);
            for (bytes, ends) in b.streams.iter_mut() {
                bytes.clear();
                ends.clear();
            }
            let Some(block) = producer.next_block_multi(n as usize, &mut b.streams) else {
                if let Some(e) = producer.take_error() {
                    return Err(e.into());
                }
                break "duration reached";
            };
            b.first = block.first;
            b.emit_ns.clear();
            b.tov_ns.clear();
            let wall = |t: f64| (map.host_ns(t) + delay_ns - out.anchor_ns) as i64;
            match &block.times {
                // Each frame at its emission instant on the sensor's own clock and latency.
                Some(times) => {
                    b.emit_ns
                        .extend(times.emit.iter().map(|e| wall(times.t0 + e)));
                    let last = times.emit.len() as u64;
                    if let Some(e) = times.emit.last() {
                        ahead = (time(k + last) - times.t0 - e).max(0.0);
                    }
                }
                None => b.emit_ns.extend((1..=n).map(|i| wall(time(k + i)))),
            }
            k += n;
            st.tail = Some(tail);
            st.frames = k;
            if tail != Tail::Following {
                st.extrapolated += n;
            }
            st.corrections = self.model.corrections();
            if let Ok(mut s) = status.try_lock() {
                *s = st.clone();
            }
            if out.tx.blocking_send(b).is_err() {
                break "the output closed";
            }
        };
        drop(out);
        close(get(), &mut st, &self.model, &status, &name)?;
        Ok(RealtimeSummary {
            status: st,
            grid,
            ended,
        })
    }
}

fn get_error(mut g: std::sync::MutexGuard<'_, Input>) -> Option<std::io::Error> {
    g.error.take()
}

/// Sleeps until `wake` (CLOCK_MONOTONIC ns) or a stop request, in slices of at most 100 ms
/// so that a stop is seen promptly.
fn sleep_to(wake: i128, stop: &AtomicBool) {
    while monotonic_ns() < wake && !stop.load(Ordering::Relaxed) {
        sleep_until(wake.min(monotonic_ns() + 100_000_000));
    }
}

/// Takes the input's counts and clock-map figures into the status; returns the clock map
/// and whether the input has ended.
fn observe(st: &mut LiveStatus, g: &Input) -> (ClockMap, bool) {
    st.stats = g.stats.clone();
    st.rate = g.map.rate();
    st.jitter = g.map.jitter();
    st.clock_rate = g.map.clock_rate();
    (g.map.clone(), g.ended)
}

/// Publishes the run's last status, with the input's final counts; the input's read error,
/// if it had one, becomes the run's.
fn close(
    g: std::sync::MutexGuard<'_, Input>,
    st: &mut LiveStatus,
    model: &CausalMotion,
    status: &Mutex<LiveStatus>,
    name: &str,
) -> Result<(), LiveError> {
    st.stats = g.stats.clone();
    st.corrections = model.corrections();
    *status.lock().unwrap_or_else(|e| e.into_inner()) = st.clone();
    match get_error(g) {
        Some(source) => Err(LiveError::Io {
            what: format!("reading {name}"),
            source,
        }),
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
    let modulo = match format {
        InputFormat::Mavlink => 256,
        _ => 1 << 32,
    };
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
        g.stats.messages += 1;
        match decoded {
            Ok(Some(d)) => {
                let outcome = model.push(&d.state);
                let place = format!("{name}: {}", m.place);
                g.stats.state(&d, &outcome, modulo, &place);
                if outcome.is_ok() {
                    g.map.observe(d.state.sample.t, arrival_ns);
                }
                g.week = decoder.epoch_week();
            }
            Ok(None) => {}
            Err(e) if e.fatal => {
                let what = format!("{}, byte {}: {}", m.place, e.offset, e.message);
                break Some(std::io::Error::new(std::io::ErrorKind::InvalidData, what));
            }
            Err(e) => {
                let at = format!("{name}: {}, byte {}", m.place, e.offset);
                g.stats.malformed(&at, &e.message);
            }
        }
        drop(g);
        cv.notify_all();
    };
    let mut g = lock.lock().unwrap_or_else(|e| e.into_inner());
    g.ended = true;
    g.error = error;
    g.stats.skipped_bytes = rx.skipped_bytes();
    drop(g);
    cv.notify_all();
}
