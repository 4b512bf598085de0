//! What a lockstep run releases records from, once the live motion model has its first
//! knot: one IMU's simulation ([`SimTarget`], one output) or every unit of a rig
//! ([`RigTarget`], one output per unit, each at its own rate, in its own format, with its
//! own placement, seed and failures). The driver ([`super::lockstep::Lockstep`]) is the same
//! for both: it decodes, feeds the model and asks the target for everything up to the
//! newest knot.

use std::io::Write;

use super::lockstep::LiveError;
use crate::engine::frames::Part;
use crate::engine::{Grid, Producer};
use crate::motion::causal::CausalMotion;
use crate::rig::RigStream;
use crate::sim::{SimError, SimulationBuilder};

/// Records per block handed to a producer at most.
const BLOCK: usize = 4096;

/// A producer of records on the live motion, built when the model has its first knot.
pub trait Target {
    /// How many outputs it writes (one per stream: the IMU, or each unit of a rig).
    fn outputs(&self) -> usize;
    /// Assembles the producers on the live motion (the builder's, now with a first knot)
    /// and writes each output's preamble (a CSV header; nothing for frames). With
    /// `gps_week` (GPS-tagged input, counted from that week's start) the frames' GPS time
    /// fields carry the input's GPS time.
    fn start(
        &mut self,
        outs: &mut [&mut dyn Write],
        gps_week: Option<u32>,
    ) -> Result<(), LiveError>;
    /// Writes into `outs` every record whose interval ends at or before `t` (s).
    fn release(&mut self, t: f64, outs: &mut [&mut dyn Write]) -> Result<(), LiveError>;
    /// True once every output's duration is written.
    fn complete(&self) -> bool;
    /// Per output: its grid and the records written so far (empty before the start).
    fn written(&self) -> Vec<(Grid, u64)>;
}

/// One IMU: the simulation the builder describes, its producer writing one output.
pub struct SimTarget {
    builder: Option<SimulationBuilder>,
    producer: Option<(Producer, Grid)>,
    done: u64,
    buf: Vec<u8>,
    ends: Vec<usize>,
}

impl SimTarget {
    /// The simulation of `builder` on the live `motion`, its settings checked now on a
    /// stand-in motion so that a bad one is refused before any state arrives.
    pub fn new(builder: SimulationBuilder, motion: &CausalMotion) -> Result<SimTarget, SimError> {
        stand_in(&builder).build()?;
        Ok(SimTarget {
            builder: Some(builder.live_motion(motion.clone())),
            producer: None,
            done: 0,
            buf: Vec::new(),
            ends: Vec::new(),
        })
    }
}

/// The builder (without a live motion) on a motion known in advance (the static scene over
/// 1000 s), to check every setting but the motion's before the first state arrives.
pub fn stand_in(builder: &SimulationBuilder) -> SimulationBuilder {
    builder.clone().scene("static").start(0.0).duration(1000.0)
}

fn write_all(out: &mut dyn Write, b: &[u8]) -> Result<(), LiveError> {
    out.write_all(b).map_err(|source| LiveError::Io {
        what: "writing the output".into(),
        source,
    })
}

impl Target for SimTarget {
    fn outputs(&self) -> usize {
        1
    }

    fn start(
        &mut self,
        outs: &mut [&mut dyn Write],
        gps_week: Option<u32>,
    ) -> Result<(), LiveError> {
        let builder = self.builder.take().expect("started once");
        let mut sim = builder.build()?;
        if let Some(week) = gps_week {
            sim.set_gps_time(week, 0.0);
        }
        let grid = sim.grid();
        let p = sim.producer()?;
        write_all(outs[0], p.preamble().as_bytes())?;
        self.producer = Some((p, grid));
        Ok(())
    }

    fn release(&mut self, t: f64, outs: &mut [&mut dyn Write]) -> Result<(), LiveError> {
        let Some((p, grid)) = self.producer.as_mut() else {
            return Ok(());
        };
        let upto = crate::engine::released(grid, t).min(grid.count);
        while self.done < upto {
            let n = ((upto - self.done) as usize).min(BLOCK);
            self.buf.clear();
            self.ends.clear();
            if p.next_block(n, &mut self.buf, &mut self.ends).is_none() {
                p.finished()?;
                break;
            }
            write_all(outs[0], &self.buf)?;
            self.done += n as u64;
        }
        Ok(())
    }

    fn complete(&self) -> bool {
        self.producer
            .as_ref()
            .is_some_and(|(p, _)| p.remaining() == 0)
    }

    fn written(&self) -> Vec<(Grid, u64)> {
        self.producer
            .as_ref()
            .map(|(_, g)| (*g, self.done))
            .into_iter()
            .collect()
    }
}

/// Every unit of a rig: output i is unit i's records or frames, as a rig run from a file
/// writes them (units on the same grid share one evaluation of the motion per instant).
pub struct RigTarget {
    builder: Option<SimulationBuilder>,
    units: usize,
    stream: Option<RigStream>,
    grids: Vec<Grid>,
    parts: Vec<Part>,
    done: Vec<u64>,
}

impl RigTarget {
    /// The rig of `builder` on the live `motion`, checked now on a stand-in motion.
    pub fn new(builder: SimulationBuilder, motion: &CausalMotion) -> Result<RigTarget, SimError> {
        let units = stand_in(&builder).build_rig()?.units().len();
        Ok(RigTarget {
            builder: Some(builder.live_motion(motion.clone())),
            units,
            stream: None,
            grids: Vec::new(),
            parts: vec![Part::default(); units],
            done: vec![0; units],
        })
    }
}

impl Target for RigTarget {
    fn outputs(&self) -> usize {
        self.units
    }

    fn start(
        &mut self,
        outs: &mut [&mut dyn Write],
        gps_week: Option<u32>,
    ) -> Result<(), LiveError> {
        let builder = self.builder.take().expect("started once");
        let mut rig = builder.build_rig()?;
        if let Some(week) = gps_week {
            rig.set_gps_time(week, 0.0);
        }
        let stream = rig.stream();
        for (u, out) in stream.units().iter().zip(outs.iter_mut()) {
            write_all(*out, u.headers().0.as_bytes())?;
        }
        self.grids = stream.units().iter().map(|u| u.grid()).collect();
        self.stream = Some(stream);
        Ok(())
    }

    fn release(&mut self, t: f64, outs: &mut [&mut dyn Write]) -> Result<(), LiveError> {
        let Some(stream) = self.stream.as_mut() else {
            return Ok(());
        };
        self.parts.iter_mut().for_each(Part::clear);
        stream.release_upto(t, &mut self.parts)?;
        for ((p, out), done) in (self.parts.iter()).zip(outs.iter_mut()).zip(&mut self.done) {
            write_all(*out, &p.bytes)?;
            *done += p.ends.len() as u64;
        }
        Ok(())
    }

    fn complete(&self) -> bool {
        (self.grids.iter().zip(&self.done)).all(|(g, d)| *d >= g.count) && self.stream.is_some()
    }

    fn written(&self) -> Vec<(Grid, u64)> {
        self.grids
            .iter()
            .copied()
            .zip(self.done.iter().copied())
            .collect()
    }
}
