//! Lockstep for a program that holds its own input and outputs: feed it messages (or decoded
//! states) and it writes into the caller's writers what each releases — one IMU's records or
//! frames, or each unit's of a rig. The same sources and release rule as a lockstep
//! [`Run`](super::Run): the output depends only on the order and contents of the messages,
//! so a run replayed from its recorded input gives the original bytes.

use std::io::Write;

use super::error::RunError;
use super::pipeline::{Built, input_base, modulo};
use super::routing::{Layout, Units};
use super::spec::{Route, StreamId};
use crate::engine::Grid;
use crate::engine::frames::Until;
use crate::live::stats::InputStats;
use crate::live::transport::{Message, Receiver};
use crate::live::{Decoded, Decoder, InputFormat};
use crate::motion::causal::CausalMotion;
use crate::output::SinkAddr;
use crate::sim::SimulationBuilder;

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
/// release.
pub struct Lockstep {
    builder: SimulationBuilder,
    rig: bool,
    layout: Layout,
    model: CausalMotion,
    need: usize,
    decoder: Decoder,
    modulo: u64,
    stats: InputStats,
    built: Option<Built>,
    written: Vec<u64>,
    grids: Vec<Grid>,
}

impl Lockstep {
    /// A run of the simulation `builder` describes (IMU, rate, encoding, duration…), whose
    /// motion comes from messages of `format`. Starts at the builder's start time, else at
    /// the model's first knot.
    pub fn new(builder: SimulationBuilder, format: InputFormat) -> Result<Lockstep, RunError> {
        Lockstep::with_time_base(builder, format, crate::live::TimeBase::Sim)
    }

    /// [`Lockstep::new`] with the input's time tags on `base`: GPS-tagged states count from
    /// the first GPS week seen, and the frames' GPS-time fields carry their GPS time.
    pub fn with_time_base(
        builder: SimulationBuilder,
        format: InputFormat,
        base: crate::live::TimeBase,
    ) -> Result<Lockstep, RunError> {
        Lockstep::make(builder, format, base, false)
    }

    /// A run of every unit of the rig `builder` describes: output i is unit i's.
    pub fn rig(builder: SimulationBuilder, format: InputFormat) -> Result<Lockstep, RunError> {
        Lockstep::make(builder, format, crate::live::TimeBase::Sim, true)
    }

    fn make(
        builder: SimulationBuilder,
        format: InputFormat,
        base: crate::live::TimeBase,
        rig: bool,
    ) -> Result<Lockstep, RunError> {
        let builder = builder.unbounded_duration(super::FOREVER_S);
        let settings = builder.model_settings()?;
        let stand_in = super::build::stand_in(&builder);
        // Each unit's own stream, with no sink: the caller's writers take the frames.
        let route = |stream| Route {
            stream,
            sink: SinkAddr::File("-".into()),
            origin: "lockstep output".into(),
        };
        let layout = if rig {
            let r = stand_in.build_rig()?;
            let routes: Vec<Route> = r
                .units()
                .iter()
                .map(|u| route(StreamId::unit(u.name())))
                .collect();
            Layout::resolve(&routes, &Units::Rig(&r))?
        } else {
            Layout::resolve(&[route(StreamId::imu())], &Units::Imu(&stand_in.build()?))?
        };
        // Lockstep follows the tags alone: a step it cannot bridge is refused, not computed.
        let model = CausalMotion::new(settings);
        model.refuse_gaps();
        let base = match base {
            crate::live::TimeBase::Gps => super::spec::TimeBase::Gps,
            crate::live::TimeBase::Sim => super::spec::TimeBase::Sim,
        };
        Ok(Lockstep {
            rig,
            written: vec![0; layout.streams.len()],
            layout,
            builder,
            model,
            need: settings.stencil.max(3),
            decoder: Decoder::with_base(format, input_base(base), None),
            modulo: modulo(format),
            stats: InputStats::default(),
            built: None,
            grids: Vec::new(),
        })
    }

    /// What happened to the input so far.
    pub fn stats(&self) -> &InputStats {
        &self.stats
    }

    /// Records written so far (over every output).
    pub fn records(&self) -> u64 {
        self.written.iter().sum()
    }

    /// How many outputs the run writes (one per unit of a rig).
    pub fn outputs(&self) -> usize {
        self.layout.streams.len()
    }

    /// True once the run's duration is written.
    pub fn complete(&self) -> bool {
        self.built.as_ref().is_some_and(|b| b.sources.done())
    }

    /// The live motion model (for its start, newest time and pose).
    pub fn motion(&self) -> &CausalMotion {
        &self.model
    }

    /// Decodes and takes one message (`input` names its source in reports), writing the
    /// records it releases into `outs` (one per output).
    pub fn message_to(
        &mut self,
        m: &Message,
        input: &str,
        outs: &mut [&mut dyn Write],
    ) -> Result<(), RunError> {
        self.stats.message(m);
        match self.decoder.decode(&m.bytes) {
            Ok(Some(d)) => self.state_to(&d, &format!("{input}: {}", m.place), outs),
            Ok(None) => {
                self.stats.no_state();
                Ok(())
            }
            Err(e) if e.fatal => Err(RunError::TimeBase(format!(
                "{input}: {}: {}",
                m.place.at(e.offset),
                e.message
            ))),
            Err(e) => {
                let at = format!("{input}: {}", m.place.at(e.offset));
                self.stats.malformed(&at, &e.message);
                Ok(())
            }
        }
    }

    /// [`Lockstep::message_to`] for a run with one output.
    pub fn message(
        &mut self,
        m: &Message,
        input: &str,
        out: &mut dyn Write,
    ) -> Result<(), RunError> {
        self.message_to(m, input, &mut [out])
    }

    /// Takes one decoded state, writing the records it releases into `outs`.
    pub fn state_to(
        &mut self,
        d: &Decoded,
        place: &str,
        outs: &mut [&mut dyn Write],
    ) -> Result<(), RunError> {
        if outs.len() != self.outputs() {
            return Err(crate::engine::EngineError::Outputs {
                given: outs.len(),
                need: self.outputs(),
            }
            .into());
        }
        let outcome = self.model.push(&d.state);
        self.stats.state(d, &outcome, self.modulo, place);
        if outcome.is_err() || self.model.knots() == 0 {
            return Ok(());
        }
        let io = |e| RunError::io("writing the output", e);
        if self.built.is_none() {
            let week = self.decoder.epoch_week();
            let b = self
                .layout
                .build_live(&self.builder, self.rig, &self.model, week, false)?;
            for (out, p) in outs.iter_mut().zip(&b.preambles) {
                out.write_all(p).map_err(io)?;
            }
            self.grids = b.units.iter().map(|u| u.grid).collect();
            self.built = Some(b);
        }
        let b = self.built.as_mut().expect("built above");
        b.sources
            .fill(Until::state(b.origin, self.model.newest()))?;
        for ((p, out), n) in (b.sources.parts.iter())
            .zip(outs.iter_mut())
            .zip(self.written.iter_mut())
        {
            out.write_all(&p.bytes).map_err(io)?;
            *n += p.ends.len() as u64;
        }
        Ok(())
    }

    /// [`Lockstep::state_to`] for a run with one output.
    pub fn state(&mut self, d: &Decoded, place: &str, out: &mut dyn Write) -> Result<(), RunError> {
        self.state_to(d, place, &mut [out])
    }

    /// Runs to the end of the input (or of the duration), writing output i into `outs[i]`
    /// and every message received into `record` when given; `tick` is called after each
    /// message.
    pub fn run_to(
        mut self,
        rx: &mut Receiver,
        outs: &mut [&mut dyn Write],
        mut record: Option<&mut dyn Write>,
        mut tick: impl FnMut(&Lockstep),
    ) -> Result<LiveSummary, RunError> {
        if outs.len() != self.outputs() {
            return Err(crate::engine::EngineError::Outputs {
                given: outs.len(),
                need: self.outputs(),
            }
            .into());
        }
        let name = rx.name().to_string();
        let csv = self.decoder.is_csv();
        while !self.complete() {
            let m = rx
                .next_message()
                .map_err(|e| RunError::io(format!("reading {name}"), e))?;
            let Some(m) = m else { break };
            if let Some(r) = record.as_deref_mut() {
                let nl: &[u8] = if csv { b"\n" } else { b"" };
                (r.write_all(&m.bytes).and_then(|()| r.write_all(nl)))
                    .map_err(|e| RunError::io("writing the input record", e))?;
            }
            self.message_to(&m, &name, outs)?;
            tick(&self);
        }
        self.stats.transport(rx);
        for out in outs.iter_mut() {
            out.flush()
                .map_err(|e| RunError::io("writing the output", e))?;
        }
        let outputs: Vec<(Grid, u64)> = self
            .grids
            .iter()
            .copied()
            .zip(self.written.iter().copied())
            .collect();
        let Some(&(grid, _)) = outputs.first() else {
            return Err(RunError::TooFewStates {
                input: name,
                states: self.stats.states,
                need: self.need,
                why: self.stats.why_unused(),
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

    /// [`Lockstep::run_to`] for a run with one output.
    pub fn run(
        self,
        rx: &mut Receiver,
        out: &mut dyn Write,
        record: Option<&mut dyn Write>,
        tick: impl FnMut(&Lockstep),
    ) -> Result<LiveSummary, RunError> {
        self.run_to(rx, &mut [out], record, tick)
    }
}
