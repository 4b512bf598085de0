//! What a run is doing while it goes ([`RunStatus`], refreshed a few times a second) and what
//! it did ([`RunReport`]), with the lines the command line prints.

use crate::engine::Grid;
use crate::live::stats::InputStats;
use crate::motion::chain::{Corrections, Tail};
use crate::output::sink::SinkStats;
use crate::protocol::FaultTally;

use super::routing::StreamPlan;

/// Live figures of a run following live input in real time.
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
    /// Times the clock map was estimated afresh after a step in the input's delay (a pause).
    pub relocks: u64,
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
    /// Trigger edges after the first that closed no sample interval: mapped before the run's
    /// t₀ (the input not yet followed) or not after the previous edge.
    pub edges_unused: u64,
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
        let mut departed = c.departed.map_or_else(String::new, |t| {
            format!(
                "; first frame past the newest state at t = {t:.6} s; longest extrapolation corrected {:.1} ms",
                c.longest * 1e3
            )
        });
        if let Some(t) = c.rejoined {
            departed += &format!("; back on the input from t = {t:.6} s");
        }
        if self.edges_unused > 0 {
            departed += &format!(
                "; {} trigger edges closed no interval (before t₀ or not after the previous)",
                self.edges_unused
            );
        }
        format!(
            "{state}; input {:.1} Hz, jitter {:.2} ms, clock {:+.1} ppm, {} re-locks, {} missing, {} late; delay {:.2} ms; {} frames ({} extrapolated); {} corrections, max {:.3e} m, {:.3e} m/s, {:.3e} rad{departed}",
            self.rate,
            self.jitter * 1e3,
            self.clock_rate * 1e6,
            self.relocks,
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

/// One stream's counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamCounts {
    /// Frames handed to the sinks.
    pub frames: u64,
    /// Frames skipped as too late to send.
    pub skipped: u64,
}

/// What a run is doing.
#[derive(Clone, Debug, Default)]
pub struct RunStatus {
    /// The run has started producing (a live run waits for its first state before).
    pub started: bool,
    /// Seconds of wall clock since the first frame was due (paced and real-time runs).
    pub elapsed_s: f64,
    /// Per stream, in source order.
    pub streams: Vec<StreamCounts>,
    /// Per sink: its stream, label and counts.
    pub sinks: Vec<(usize, String, SinkStats)>,
    /// Write lateness of the frames (paced and real-time runs): a one-line summary.
    pub lateness: Option<String>,
    /// Trigger edge to frame hand-over (triggered runs): a one-line summary.
    pub edge_latency: Option<String>,
    /// The phase lock to a PPS, in words.
    pub lock: Option<String>,
    /// Whether `SCHED_FIFO` was granted (`None`: not asked).
    pub fifo: Option<bool>,
    /// The live input's figures (real-time live runs; lockstep runs fill `stats` only).
    pub live: Option<LiveStatus>,
}

impl RunStatus {
    /// Frames handed to the sinks over every stream.
    pub fn frames(&self) -> u64 {
        self.streams.iter().map(|s| s.frames).sum()
    }

    /// Frames skipped as too late over every stream.
    pub fn skipped(&self) -> u64 {
        self.streams.iter().map(|s| s.skipped).sum()
    }

    /// Frames sinks dropped (slow consumer or no reader).
    pub fn dropped(&self) -> u64 {
        self.sinks.iter().map(|s| s.2.dropped + s.2.no_reader).sum()
    }

    /// The one-line live status.
    pub fn line(&self, streams: &[StreamPlan]) -> String {
        let mut line = format!("{:.1} s", self.elapsed_s);
        for (s, c) in streams.iter().zip(&self.streams) {
            line += &format!(" | {}: {}", s.id, c.frames);
            if c.skipped > 0 {
                line += &format!(" ({} skipped)", c.skipped);
            }
        }
        if let Some(l) = &self.lateness {
            line += &format!(" | late {l}");
        }
        if let Some(e) = &self.edge_latency {
            line += &format!(" | edge to frame {e}");
        }
        if let Some(l) = &self.lock {
            line += &format!(" | {l}");
        }
        line + &format!(" | {} dropped", self.dropped())
    }
}

/// One unit's share of a run.
#[derive(Clone, Debug)]
pub struct UnitReport {
    /// The unit's name (`imu` for the single IMU).
    pub name: String,
    /// Its grid (t₀, rate, the most records it would write).
    pub grid: Grid,
    /// Records it produced.
    pub records: u64,
}

/// What a run did.
#[derive(Clone, Debug)]
pub struct RunReport {
    /// Why it ended: `complete`, `input ended`, `duration reached`, `stopped`, …
    pub ended: &'static str,
    /// The run was stopped from outside (a signal) before its end.
    pub stopped: bool,
    /// The streams, in source order.
    pub streams: Vec<StreamPlan>,
    /// The final counts.
    pub status: RunStatus,
    /// Per unit, its grid and the records it produced.
    pub units: Vec<UnitReport>,
    /// Faults injected into the frames, when the run injects any.
    pub faults: Option<FaultTally>,
    /// What happened to the live input, when there is one.
    pub input: Option<InputStats>,
    /// The sinks that failed while the run went on for its live links, each with its flag,
    /// the reason and the frames it lost: a run with any did not write every output (the
    /// command line exits 1 after the summary).
    pub failures: Vec<String>,
}

impl RunReport {
    /// The end-of-run summary: how a live run followed its input, then per stream what was
    /// sent of what was planned, per sink its counts, the pacer's figures, each unit's span.
    pub fn summary(&self) -> String {
        let s = &self.status;
        let mut out = String::new();
        if let Some(i) = &self.input {
            let live = s
                .live
                .as_ref()
                .map_or(String::new(), |l| format!("; {}", l.line()));
            let head = match self.units.as_slice() {
                [u] => format!(
                    "{} frames at {} Hz from t = {} s ({})",
                    u.records, u.grid.rate_hz, u.grid.t0, self.ended
                ),
                units => format!(
                    "{} records of {} units ({})",
                    units.iter().map(|u| u.records).sum::<u64>(),
                    units.len(),
                    self.ended
                ),
            };
            out += &format!("{head}{live}; input: {}\n", i.summary());
            for p in &i.problems {
                out += &format!("  {p}\n");
            }
        }
        out += &format!(
            "{} frames of {} streams ({})",
            s.frames(),
            self.streams.len(),
            self.ended
        );
        if let Some(l) = &s.lateness {
            out += &format!(", write lateness {l}, {} skipped (too late)", s.skipped());
        }
        if let Some(e) = &s.edge_latency {
            out += &format!(", trigger edge to frame {e}");
        }
        if let Some(l) = &s.lock {
            out += &format!(", {l}");
        }
        if let Some(f) = s.fifo {
            out += if f {
                ", SCHED_FIFO"
            } else {
                ", SCHED_FIFO refused"
            };
        }
        for (i, st) in self.streams.iter().enumerate() {
            let c = s.streams.get(i).copied().unwrap_or_default();
            let planned = st.planned.map_or(String::new(), |n| format!(" of {n}"));
            // A unit's own readings are the unit; the rest are side or aiding streams.
            let kind = if st.unit.is_some() { "unit" } else { "stream" };
            out += &format!(
                "\n  {kind} {}: {}{planned} {}, {} skipped (too late)",
                st.id, c.frames, st.what, c.skipped
            );
            for (_, label, k) in s.sinks.iter().filter(|x| x.0 == i) {
                out += &format!(
                    "\n    {label}: {} sent, {} dropped (slow consumer), {} dropped (no reader), {} bytes",
                    k.sent, k.dropped, k.no_reader, k.bytes
                );
                if k.lost > 0 {
                    out += &format!(", {} lost (the sink failed)", k.lost);
                }
            }
        }
        for u in &self.units {
            let g = u.grid;
            out += &format!(
                "\n  unit {}: {} records at {} Hz from t = {} s to {} s",
                u.name,
                u.records,
                g.rate_hz,
                g.t0,
                g.t0 + u.records as f64 / g.rate_hz
            );
        }
        if let Some(f) = &self.faults {
            out += &format!("\n  faults injected: {}", f.summary());
        }
        for f in &self.failures {
            out += &format!("\n  sink failed: {f}");
        }
        out
    }
}
