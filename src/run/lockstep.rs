//! Lockstep: no wall clock. Each state taken into the causal model releases every record whose
//! interval it completes (t_k at or before the state's time), produced by the same producer —
//! generator, error chain, encoder — as a run from a file: one IMU's, or every unit's of a rig
//! ([`super::target`]). The output depends only on the order and contents of the messages,
//! so the same input gives the same bytes, and a run replayed from its recorded input
//! (`--record-input`) gives the bytes of the original.

use std::io::Write;

use super::target::{RigTarget, SimTarget, Target};
use crate::engine::{EngineError, Grid};
use crate::live::stats::InputStats;
use crate::live::transport::{Message, Receiver};
use crate::live::{Decoded, Decoder, InputFormat, TimeBase};
use crate::motion::causal::CausalMotion;
use crate::sim::{SimError, SimulationBuilder};

/// Why a live run stopped.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The simulation could not be assembled.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Production stopped (a non-finite value, a setting).
    #[error(transparent)]
    Job(#[from] EngineError),
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
    /// The caller gave a number of outputs other than the run writes.
    #[error("{given} outputs given for a run that writes {need}")]
    Outputs {
        /// Outputs given.
        given: usize,
        /// Outputs the run writes.
        need: usize,
    },
}

/// How a lockstep run ended.
#[derive(Clone, Debug)]
pub struct LiveSummary {
    /// What happened to the input.
    pub stats: InputStats,
    /// The run's time grid (t₀, rate; `count` is the most it would have written); a rig's
    /// first unit's.
    pub grid: Grid,
    /// Records written (over every output).
    pub records: u64,
    /// Per output (the IMU, or each unit of a rig): its grid and the records written.
    pub outputs: Vec<(Grid, u64)>,
    /// Time of the newest state taken (s).
    pub newest: f64,
}

/// A lockstep run in progress: feed it messages or decoded states; it writes what they
/// release. `T` is what the records come from: one IMU ([`Lockstep::new`]) or a rig
/// ([`Lockstep::rig`]).
pub struct Lockstep<T = SimTarget> {
    target: T,
    started: bool,
    model: CausalMotion,
    need: usize,
    decoder: Decoder,
    modulo: u64,
    stats: InputStats,
}

impl Lockstep<SimTarget> {
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
        Lockstep::with_target(builder, format, base, SimTarget::new)
    }

    /// Decodes and takes one message (`input` names its source in reports), writing the
    /// records it releases into `out`.
    pub fn message(
        &mut self,
        m: &Message,
        input: &str,
        out: &mut dyn Write,
    ) -> Result<(), LiveError> {
        self.message_to(m, input, &mut [out])
    }

    /// Takes one decoded state, writing the records it releases into `out`.
    pub fn state(
        &mut self,
        d: &Decoded,
        place: &str,
        out: &mut dyn Write,
    ) -> Result<(), LiveError> {
        self.state_to(d, place, &mut [out])
    }

    /// Runs to the end of the input (or of the duration), recording every message received
    /// into `record` when given; `tick` is called after each message.
    pub fn run(
        self,
        rx: &mut Receiver,
        out: &mut dyn Write,
        record: Option<&mut dyn Write>,
        tick: impl FnMut(&Lockstep),
    ) -> Result<LiveSummary, LiveError> {
        self.run_to(rx, &mut [out], record, tick)
    }
}

impl Lockstep<RigTarget> {
    /// A run of every unit of the rig `builder` describes (its `[[imu]]` list or units added
    /// in code), whose motion comes from messages of `format`: output i is unit i's. All
    /// units start at the builder's start time, else at the model's first knot.
    pub fn rig(
        builder: SimulationBuilder,
        format: InputFormat,
    ) -> Result<Lockstep<RigTarget>, SimError> {
        Lockstep::with_target(builder, format, TimeBase::Sim, RigTarget::new)
    }
}

impl<T: Target> Lockstep<T> {
    fn with_target(
        builder: SimulationBuilder,
        format: InputFormat,
        base: TimeBase,
        target: impl FnOnce(SimulationBuilder, &CausalMotion) -> Result<T, SimError>,
    ) -> Result<Lockstep<T>, SimError> {
        let settings = builder.model_settings()?;
        let model = CausalMotion::new(settings);
        Ok(Lockstep {
            target: target(builder, &model)?,
            started: false,
            model,
            need: settings.stencil.max(3),
            decoder: Decoder::with_base(format, base, None),
            modulo: match format {
                InputFormat::Mavlink => 256,
                _ => 1 << 32,
            },
            stats: InputStats::default(),
        })
    }

    /// What happened to the input so far.
    pub fn stats(&self) -> &InputStats {
        &self.stats
    }

    /// Records written so far (over every output).
    pub fn records(&self) -> u64 {
        self.target.written().iter().map(|w| w.1).sum()
    }

    /// How many outputs the run writes (one per unit of a rig).
    pub fn outputs(&self) -> usize {
        self.target.outputs()
    }

    /// True once the run's duration is written.
    pub fn complete(&self) -> bool {
        self.started && self.target.complete()
    }

    /// Decodes and takes one message (`input` names its source in reports), writing the
    /// records it releases into `outs` (one per output).
    pub fn message_to(
        &mut self,
        m: &Message,
        input: &str,
        outs: &mut [&mut dyn Write],
    ) -> Result<(), LiveError> {
        self.stats.messages += 1;
        match self.decoder.decode(&m.bytes) {
            Ok(Some(d)) => self.state_to(&d, &format!("{input}: {}", m.place), outs),
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

    /// Takes one decoded state, writing the records it releases into `outs`.
    pub fn state_to(
        &mut self,
        d: &Decoded,
        place: &str,
        outs: &mut [&mut dyn Write],
    ) -> Result<(), LiveError> {
        if outs.len() != self.target.outputs() {
            return Err(LiveError::Outputs {
                given: outs.len(),
                need: self.target.outputs(),
            });
        }
        let outcome = self.model.push(&d.state);
        self.stats.state(d, &outcome, self.modulo, place);
        if outcome.is_err() || self.model.knots() == 0 {
            return Ok(());
        }
        if !self.started {
            self.target.start(outs, self.decoder.epoch_week())?;
            self.started = true;
        }
        self.target.release(self.model.newest(), outs)
    }

    /// Runs to the end of the input (or of the duration), writing output i into `outs[i]`
    /// and every message received into `record` when given; `tick` is called after each
    /// message.
    pub fn run_to(
        mut self,
        rx: &mut Receiver,
        outs: &mut [&mut dyn Write],
        mut record: Option<&mut dyn Write>,
        mut tick: impl FnMut(&Lockstep<T>),
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
            self.message_to(&m, &name, outs)?;
            tick(&self);
        }
        self.stats.skipped_bytes = rx.skipped_bytes();
        for out in outs.iter_mut() {
            out.flush().map_err(|source| LiveError::Io {
                what: "writing the output".into(),
                source,
            })?;
        }
        let outputs = self.target.written();
        let Some(&(grid, _)) = outputs.first().filter(|_| self.started) else {
            return Err(LiveError::TooFewStates {
                input: name,
                states: self.stats.states,
                need: self.need,
            });
        };
        Ok(LiveSummary {
            stats: self.stats,
            grid,
            records: outputs.iter().map(|w| w.1).sum(),
            outputs,
            newest: self.model.newest(),
        })
    }

    /// The live motion model (for its start, newest time and pose).
    pub fn motion(&self) -> &CausalMotion {
        &self.model
    }
}
