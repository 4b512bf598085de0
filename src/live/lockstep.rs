//! Lockstep: no wall clock. Each state taken into the causal model releases every record whose
//! interval it completes (t_k at or before the state's time), produced by the same producer —
//! generator, error chain, encoder — as a run from a file. The output depends only on the
//! order and contents of the messages, so the same input gives the same bytes, and a run
//! replayed from its recorded input (`--record-input`) gives the bytes of the original.

use std::io::Write;

use super::stats::InputStats;
use super::transport::{Message, Receiver};
use super::{Decoded, Decoder, InputFormat, TimeBase};
use crate::job::{Grid, JobError, Producer};
use crate::motion::causal::CausalMotion;
use crate::sim::{SimError, SimulationBuilder};

/// Records per block handed to the producer at most.
const BLOCK: usize = 4096;

/// Why a live run stopped.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The simulation could not be assembled.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Production stopped (a non-finite value, a setting).
    #[error(transparent)]
    Job(#[from] JobError),
    /// Reading the input, or writing the output or the input record, failed.
    #[error("{what}: {source}")]
    Io {
        /// What was being read or written.
        what: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The input ended before the model had its first piece.
    #[error(
        "{input}: the input ended after {states} usable states; the motion model needs {need} before the first record"
    )]
    TooFewStates {
        /// The input's name.
        input: String,
        /// States taken.
        states: u64,
        /// States needed.
        need: usize,
    },
    /// The input's time tags do not fit the time base chosen.
    #[error("{0}")]
    TimeBase(String),
}

/// How a lockstep run ended.
#[derive(Clone, Debug)]
pub struct LiveSummary {
    /// What happened to the input.
    pub stats: InputStats,
    /// The run's time grid (t₀, rate; `count` is the most it would have written).
    pub grid: Grid,
    /// Records written.
    pub records: u64,
    /// Time of the newest state taken (s).
    pub newest: f64,
}

/// A lockstep run in progress: feed it messages or decoded states; it writes what they release.
pub struct Lockstep {
    builder: Option<SimulationBuilder>,
    model: CausalMotion,
    need: usize,
    decoder: Decoder,
    modulo: u64,
    producer: Option<(Producer, Grid)>,
    done: u64,
    stats: InputStats,
    buf: Vec<u8>,
    ends: Vec<usize>,
}

impl Lockstep {
    /// A run of the simulation `builder` describes (IMU, rate, encoding, duration…), whose
    /// motion comes from messages of `format`. Starts at the builder's start time, else at the
    /// model's first knot.
    pub fn new(builder: SimulationBuilder, format: InputFormat) -> Result<Lockstep, SimError> {
        Lockstep::with_time_base(builder, format, TimeBase::Sim)
    }

    /// [`Lockstep::new`], with the input's time tags taken on `base`. GPS-tagged states count
    /// from the first GPS week seen, and the frames' GPS time fields carry their GPS time.
    pub fn with_time_base(
        builder: SimulationBuilder,
        format: InputFormat,
        base: TimeBase,
    ) -> Result<Lockstep, SimError> {
        let settings = builder.model_settings()?;
        // Every other setting (IMU, rate, encoding, faults…) is checked now, on a stand-in
        // motion, rather than when the first states have arrived.
        (builder.clone().scene("static").start(0.0).duration(1000.0)).build()?;
        let model = CausalMotion::new(settings);
        Ok(Lockstep {
            builder: Some(builder.live_motion(model.clone())),
            model,
            need: settings.stencil.max(3),
            decoder: Decoder::with_base(format, base, None),
            modulo: match format {
                InputFormat::Mavlink => 256,
                _ => 1 << 32,
            },
            producer: None,
            done: 0,
            stats: InputStats::default(),
            buf: Vec::new(),
            ends: Vec::new(),
        })
    }

    /// What happened to the input so far.
    pub fn stats(&self) -> &InputStats {
        &self.stats
    }

    /// Records written so far.
    pub fn records(&self) -> u64 {
        self.done
    }

    /// True once the run's duration is written.
    pub fn complete(&self) -> bool {
        self.producer
            .as_ref()
            .is_some_and(|(p, _)| p.remaining() == 0)
    }

    /// Decodes and takes one message (`input` names its source in reports), writing the
    /// records it releases into `out`.
    pub fn message(
        &mut self,
        m: &Message,
        input: &str,
        out: &mut dyn Write,
    ) -> Result<(), LiveError> {
        self.stats.messages += 1;
        match self.decoder.decode(&m.bytes) {
            Ok(Some(d)) => self.state(&d, &format!("{input}: {}", m.place), out),
            Ok(None) => Ok(()),
            Err(e) if e.fatal => Err(LiveError::TimeBase(format!(
                "{input}: {}, byte {}: {}",
                m.place, e.offset, e.message
            ))),
            Err(e) => {
                let at = format!("{input}: {}, byte {}", m.place, e.offset);
                self.stats.malformed(&at, &e.message);
                Ok(())
            }
        }
    }

    /// Takes one decoded state, writing the records it releases into `out`.
    pub fn state(
        &mut self,
        d: &Decoded,
        place: &str,
        out: &mut dyn Write,
    ) -> Result<(), LiveError> {
        let outcome = self.model.push(&d.state);
        self.stats.state(d, &outcome, self.modulo, place);
        if outcome.is_err() || self.model.knots() == 0 {
            return Ok(());
        }
        if self.producer.is_none() {
            let builder = self.builder.take().expect("built once");
            let mut sim = builder.build()?;
            if let Some(week) = self.decoder.epoch_week() {
                sim.set_gps_time(week, 0.0);
            }
            let grid = sim.grid();
            let p = sim.producer()?;
            let pre = p.preamble();
            write_all(out, pre.as_bytes())?;
            self.producer = Some((p, grid));
        }
        self.release(out)
    }

    /// Writes every record up to the newest knot.
    fn release(&mut self, out: &mut dyn Write) -> Result<(), LiveError> {
        let newest = self.model.newest();
        let Some((p, grid)) = self.producer.as_mut() else {
            return Ok(());
        };
        let upto = released(grid, newest).min(grid.count);
        while self.done < upto {
            let n = ((upto - self.done) as usize).min(BLOCK);
            self.buf.clear();
            self.ends.clear();
            if p.next_block(n, &mut self.buf, &mut self.ends).is_none() {
                p.finished()?;
                break;
            }
            write_all(out, &self.buf)?;
            self.done += n as u64;
        }
        Ok(())
    }

    /// Runs to the end of the input (or of the duration), recording every message received
    /// into `record` when given; `tick` is called after each message.
    pub fn run(
        mut self,
        rx: &mut Receiver,
        out: &mut dyn Write,
        mut record: Option<&mut dyn Write>,
        mut tick: impl FnMut(&Lockstep),
    ) -> Result<LiveSummary, LiveError> {
        let name = rx.name().to_string();
        let csv = self.decoder.is_csv();
        while !self.complete() {
            let m = rx.next_message().map_err(|source| LiveError::Io {
                what: format!("reading {name}"),
                source,
            })?;
            let Some(m) = m else { break };
            if let Some(r) = record.as_deref_mut() {
                let io = |source| LiveError::Io {
                    what: "writing the input record".into(),
                    source,
                };
                r.write_all(&m.bytes).map_err(io)?;
                if csv {
                    r.write_all(b"\n").map_err(io)?;
                }
            }
            self.message(&m, &name, out)?;
            tick(&self);
        }
        self.stats.skipped_bytes = rx.skipped_bytes();
        out.flush().map_err(|source| LiveError::Io {
            what: "writing the output".into(),
            source,
        })?;
        let Some((_, grid)) = self.producer else {
            return Err(LiveError::TooFewStates {
                input: name,
                states: self.stats.states,
                need: self.need,
            });
        };
        Ok(LiveSummary {
            stats: self.stats,
            grid,
            records: self.done,
            newest: self.model.newest(),
        })
    }

    /// The live motion model (for its start, newest time and pose).
    pub fn motion(&self) -> &CausalMotion {
        &self.model
    }
}

fn write_all(out: &mut dyn Write, b: &[u8]) -> Result<(), LiveError> {
    out.write_all(b).map_err(|source| LiveError::Io {
        what: "writing the output".into(),
        source,
    })
}

/// Number of records k ≥ 1 of `grid` with t_k = t₀ + k/rate at or before `t` (times computed
/// as the generator computes them, so the last released interval never passes `t`).
pub fn released(grid: &Grid, t: f64) -> u64 {
    let time = |k: u64| grid.t0 + k as f64 / grid.rate_hz;
    if t.is_nan() || t < grid.t0 {
        return 0;
    }
    let mut k = ((t - grid.t0) * grid.rate_hz).floor() as u64;
    while time(k + 1) <= t {
        k += 1;
    }
    while k > 0 && time(k) > t {
        k -= 1;
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn released_counts_records_at_or_before() {
        let g = Grid {
            t0: 0.08,
            rate_hz: 400.0,
            count: 1000,
        };
        assert_eq!(released(&g, 0.05), 0);
        assert_eq!(released(&g, 0.08), 0);
        assert_eq!(released(&g, 0.09), 4);
        assert_eq!(released(&g, 0.0925), 5);
        for k in 1..900u64 {
            let t = g.t0 + k as f64 / g.rate_hz;
            assert_eq!(released(&g, t), k, "at t_{k} itself");
        }
    }
}
