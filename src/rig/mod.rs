//! A sensor rig on one clock: several units (three-axis IMUs with an error template, or
//! skew-redundant units of single-axis sensors) on one body, driven by one motion. Each unit
//! has its own placement (mounting and lever arm, `geometry`), rate, seed, output and
//! scheduled sensor failures (`failure`); units at the same rate and time grid share one
//! evaluation of the motion per instant.
//!
//! Built by [`crate::sim::SimulationBuilder::build_rig`] from a scene file's `[[imu]]` list or
//! from code; docs/rig.md describes the scene-file schema and the outputs.
//!
//! `unit` is what a unit is; `shared` makes the blocks of a unit that shares its grid's
//! evaluation, `produced` those of a unit with a producer of its own; `stream` lays every
//! unit's frames out as the run's streams; `protocols` adds a unit's further protocols; this
//! file holds the rig and its offline writer.

pub mod failure;
pub mod geometry;
mod produced;
mod protocols;
mod shared;
pub mod skew;
mod spec;
pub mod stream;
mod unit;

use std::io::Write;
use std::ops::ControlFlow;

use crate::aiding::mag_samples::FrameMag;
use crate::engine::frames::{Part, Until, WindowSource};
use crate::engine::{self, Encoding, EngineError};
use crate::generator::RotationTerms;
use crate::record::Record;
use crate::source::AnyMotion;

pub use crate::output::SinkAddr;
pub use failure::{Failure, FailureKind, FailureSet, FailureSpec, Pick};
pub use geometry::Placement;
pub use skew::{SkewLayout, SkewSensor, dodecahedron_axes};
pub use spec::{UnitModel, UnitSpec};
pub use stream::RigStream;
pub(crate) use unit::Body;
pub use unit::Unit;

/// Reused per-unit buffers: nothing is allocated per block once they have grown.
#[derive(Default)]
struct Scratch {
    recs: Vec<Record>,
    truth: Vec<Record>,
    rot: Vec<RotationTerms>,
    vals: Vec<f64>,
    tvals: Vec<f64>,
    masks: Vec<u64>,
    buf: Vec<u8>,
    side: Vec<u8>,
    row: Vec<f64>,
    ends: Vec<usize>,
    mag: Vec<FrameMag>,
    /// A producer-backed unit's block: the end of each truth row in `side`, each frame's
    /// emission time (ns after the run's t₀), the interval each record covers (s), the
    /// samples skipped before each (frame counters step over them), and each record's time
    /// of validity, of the accelerometers' validity and of emission (s, record time axis).
    side_ends: Vec<usize>,
    emit: Vec<i64>,
    spans: Vec<f64>,
    gaps: Vec<u32>,
    times: Vec<[f64; 3]>,
    /// Each record's index (0-based) and time of validity (ns after the run's t₀), for the
    /// time marks and pulses that follow the unit's records.
    marks: Vec<(u64, i64)>,
    /// The block's frames in each further protocol, with their ends.
    extra: Vec<(Vec<u8>, Vec<usize>)>,
}

/// Where one unit's outputs go.
pub struct UnitOutputs<'a> {
    /// The unit's readings (records, frames, or a skew unit's channels as CSV).
    pub main: &'a mut dyn Write,
    /// The error-free readings at the unit's place and in its axes, with a `failed` column
    /// (bit i: channel i has an active failure), CSV.
    pub truth: Option<&'a mut dyn Write>,
    /// The resolved failure schedule, CSV (one line per failure).
    pub failures: Option<&'a mut dyn Write>,
}

/// An assembled rig: the motion, the quadrature and the units.
pub struct Rig {
    pub(crate) motion: AnyMotion,
    pub(crate) nodes: usize,
    pub(crate) units: Vec<Unit>,
    pub(crate) warnings: Vec<String>,
    /// The GNSS receiver's settings (scene file `[gnss]`), when given.
    pub(crate) gnss: Option<crate::aiding::GnssConfig>,
    /// The odometer, barometer and magnetometer settings (scene file), when given.
    pub(crate) sensors: crate::aiding::sensors::SensorSet,
    /// The rig's master seed (the receiver's and sensors' errors draw from it).
    pub(crate) seed: u64,
    /// GPS week and second of record time 0, when given.
    pub(crate) gps_time: Option<(u32, f64)>,
    /// True GPS time of record time 0 for the GNSS streams when the units' reference is UTC.
    pub(crate) gnss_time: Option<(u32, f64)>,
}

impl Rig {
    /// Sets the GPS time of record time t = 0 (week, seconds of week) for every unit's frames
    /// and the GNSS streams (a time base chosen after building, as
    /// [`crate::sim::Simulation::set_gps_time`] for one IMU).
    pub fn set_gps_time(&mut self, week: u32, seconds_of_week: f64) {
        self.gps_time = Some((week, seconds_of_week));
        for u in self.units.iter_mut() {
            let state = match &mut u.body {
                Body::Triad { encoding, .. } | Body::Produced { encoding, .. } => {
                    match &mut **encoding {
                        Encoding::Frames { state, .. } => Some(state),
                        Encoding::Records(_) => None,
                    }
                }
                Body::Skew { frames, .. } => frames.as_deref_mut().map(|f| &mut f.1),
            };
            let extra = u.extra.iter_mut().filter_map(|e| match e {
                Encoding::Frames { state, .. } => Some(state),
                Encoding::Records(_) => None,
            });
            for st in state.into_iter().chain(extra) {
                st.gps_week0 = week;
                st.gps_sow0 = seconds_of_week;
            }
        }
    }

    /// Sets the true GPS time of record time t = 0 for the GNSS streams only (see
    /// [`crate::sim::Simulation::set_gnss_gps_time`]).
    pub fn set_gnss_gps_time(&mut self, week: u32, seconds_of_week: f64) {
        self.gnss_time = Some((week, seconds_of_week));
    }

    /// The GPS time (week, seconds of week) of record time 0, when one was set.
    pub fn gps_time(&self) -> Option<(u32, f64)> {
        self.gps_time
    }

    /// The units, in the order given.
    pub fn units(&self) -> &[Unit] {
        &self.units
    }

    /// The motion every unit follows.
    pub fn motion(&self) -> &AnyMotion {
        &self.motion
    }

    /// Things worth telling the user that do not stop the run.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The groups of units that share a time grid (indices into [`Rig::units`]): each group
    /// costs one evaluation of the motion per instant. A unit with a producer of its own
    /// ([`Unit::has_own_producer`]: an output filter, timing errors) is in none.
    pub fn groups(&self) -> Vec<Vec<usize>> {
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for (i, u) in self.units.iter().enumerate() {
            if u.has_own_producer() {
                continue;
            }
            match groups.iter_mut().find(|g| self.units[g[0]].grid == u.grid) {
                Some(g) => g.push(i),
                None => groups.push(vec![i]),
            }
        }
        groups
    }

    /// Writes every unit's outputs (`outs[i]` for unit i); `progress(records_done)`, summed
    /// over units, is called after each window of simulated time and may stop the run
    /// ([`EngineError::Stopped`]). The bytes are those the rig's frame source
    /// ([`Rig::stream`]) gives `imu-emu run` and `generate`.
    pub fn write(
        self,
        outs: &mut [UnitOutputs<'_>],
        mut progress: impl FnMut(u64) -> ControlFlow<()>,
    ) -> Result<(), EngineError> {
        if outs.len() != self.units.len() {
            return Err(EngineError::Outputs {
                given: outs.len(),
                need: self.units.len(),
            });
        }
        let n = self.units.len();
        for (u, o) in self.units.iter().zip(outs.iter_mut()) {
            if let Some(f) = o.failures.as_mut() {
                f.write_all(u.failure_csv().as_bytes())?;
            }
        }
        let fastest = (self.units.iter())
            .map(|u| u.grid.rate_hz)
            .fold(0.0, f64::max);
        let wanted: Vec<bool> = outs.iter().map(|o| o.truth.is_some()).collect();
        let mut stream = self.stream().with_truth(&wanted);
        let preambles = stream.preambles();
        let mut truth_pre = preambles[n..].iter();
        for (o, p) in outs.iter_mut().zip(&preambles) {
            o.main.write_all(p)?;
            if let Some(t) = o.truth.as_mut() {
                t.write_all(truth_pre.next().expect("a truth stream per truth output"))?;
            }
        }
        // Windows of about a block of the fastest unit's records.
        let window = (engine::BLOCK as f64 / fastest * 1e9).clamp(1e6, 1e12) as i64;
        let origin = stream.origin();
        let mut parts = vec![Part::default(); stream.streams()];
        let (mut until, mut done) = (0i64, 0u64);
        while !stream.done() {
            until = until.saturating_add(window);
            parts.iter_mut().for_each(Part::clear);
            stream.fill(Until::ns(origin, until), &mut parts)?;
            for (i, o) in outs.iter_mut().enumerate() {
                o.main.write_all(&parts[i].bytes)?;
                done += parts[i].ends.len() as u64;
                if let (Some(t), Some(w)) = (stream.truth_stream(i), o.truth.as_mut()) {
                    w.write_all(&parts[t].bytes)?;
                }
            }
            if progress(done).is_break() {
                return Err(EngineError::Stopped);
            }
        }
        for o in outs.iter_mut() {
            o.main.flush()?;
            for w in [o.truth.as_mut(), o.failures.as_mut()]
                .into_iter()
                .flatten()
            {
                w.flush()?;
            }
        }
        Ok(())
    }
}
