//! A rig following live input in real time: the same input thread, clock map and output
//! delay as one IMU ([`super::Realtime::run`]), and the records a lockstep rig releases
//! ([`crate::rig::RigStream::release_upto`]), released here up to the simulation time the
//! clock map gives the host's present instant. The units' frames are merged in emission
//! order ([`crate::run::merge::merge_into`]) onto one pacer, each at the host instant
//! of its simulation time plus the delay.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use super::super::lockstep::LiveError;
use super::{FrameOut, LEAD_S, LiveStatus, OnTimeout, Realtime, close, observe, sleep_to};
use crate::engine::Grid;
use crate::engine::frames::Part;
use crate::live::transport::Receiver;
use crate::motion::chain::Tail;
use crate::realtime::clock::monotonic_ns;
use crate::run::merge::merge_into;

/// Simulated time released per step (s): short against any output delay worth having,
/// long enough that a step's merge and channel traffic are negligible.
const STEP_S: f64 = 0.005;

/// Steps released in one block at most after a stall (one block per step otherwise).
const MAX_STEPS: u32 = 40;

/// How a real-time rig run ended.
#[derive(Clone, Debug)]
pub struct RigRealtimeSummary {
    /// The final figures (`frames`: of every unit together).
    pub status: LiveStatus,
    /// Per unit: its grid and the records it was given.
    pub units: Vec<(Grid, u64)>,
    /// Why the run ended.
    pub ended: &'static str,
}

impl Realtime {
    /// Follows `rx` with every unit of the rig (a run made by [`Realtime::rig`]) until the
    /// input ends (and the policy stops), `stop` is set, or every unit's duration is done;
    /// stream i of the blocks sent on `out` is unit i. `record` and `status` as in
    /// [`Realtime::run`]. The GPS time base is not supported here.
    pub fn run_rig<W: Write + Send + 'static>(
        self,
        rx: Receiver,
        record: Arc<Mutex<Option<W>>>,
        mut out: FrameOut,
        stop: Arc<AtomicBool>,
        status: Arc<Mutex<LiveStatus>>,
    ) -> Result<RigRealtimeSummary, LiveError> {
        if self.settings.gps.is_some() {
            return Err(LiveError::TimeBase(
                "a rig following live input takes the simulation time base (sim)".into(),
            ));
        }
        let (shared, delay, name) = self.start_input(rx, record, &stop)?;
        let get = || shared.0.lock().unwrap_or_else(|e| e.into_inner());
        let delay_ns = (delay * 1e9).round() as i128;
        let lead_ns = (LEAD_S * 1e9) as i128;
        let mut stream = self.builder.build_rig()?.stream();
        let origin = stream.origin();
        let grids: Vec<Grid> = stream.units().iter().map(|u| u.grid()).collect();
        let mut done = vec![0u64; grids.len()];
        let mut parts = vec![Part::default(); grids.len()];
        let mut order = Vec::new();
        let mut st = LiveStatus {
            delay,
            ..LiveStatus::default()
        };
        let end = grids.iter().map(|g| g.t0 + g.count as f64 / g.rate_hz);
        let end = end.fold(f64::NEG_INFINITY, f64::max);
        // Simulation time released so far; the records ending by it are out.
        let mut t = origin;
        let mut held = false;
        let mut first = 0u64;
        let ended = loop {
            if stop.load(Ordering::Relaxed) {
                break "interrupted";
            }
            if t >= end {
                break "duration reached";
            }
            let wake = get().map.host_ns(t + STEP_S) + delay_ns - lead_ns;
            sleep_to(wake, &stop);
            let now = monotonic_ns();
            let (map, input_ended) = observe(&mut st, &get());
            st.stale = input_ended;
            let newest = self.model.newest();
            let stopping = input_ended && self.settings.on_timeout == OnTimeout::Stop;
            if stopping && newest <= t {
                break "input ended";
            }
            if input_ended && self.settings.on_timeout == OnTimeout::Hold && !held {
                self.model.hold_from(t);
                held = true;
            }
            // Every step due by now (after a stall, several).
            let mut upto = t + STEP_S;
            let mut steps = 1;
            while steps < MAX_STEPS && map.host_ns(upto + STEP_S) + delay_ns <= now + lead_ns {
                upto += STEP_S;
                steps += 1;
            }
            if stopping {
                upto = upto.min(newest);
            }
            let tail = self.model.prepare(t, upto);
            parts.iter_mut().for_each(Part::clear);
            stream.release_upto(upto, &mut parts)?;
            t = upto;
            for (d, p) in done.iter_mut().zip(&parts) {
                *d += p.ends.len() as u64;
            }
            // Emission times after t₀ in simulated ns become host instants after the anchor.
            for p in parts.iter_mut() {
                for e in p.emit_ns.iter_mut() {
                    let sim = origin + *e as f64 / 1e9;
                    *e = (map.host_ns(sim) + delay_ns - out.anchor_ns) as i64;
                }
            }
            st.tail = Some(tail);
            st.frames = done.iter().sum();
            if tail != Tail::Following {
                st.extrapolated += parts.iter().map(|p| p.ends.len() as u64).sum::<u64>();
            }
            st.corrections = self.model.corrections();
            if let Ok(mut s) = status.try_lock() {
                *s = st.clone();
            }
            if parts.iter().any(|p| !p.ends.is_empty()) {
                let mut b = out.recycle.try_recv().unwrap_or_default();
                merge_into(&parts, &mut b, &mut order);
                b.tov_ns.clear();
                b.first = first;
                first += b.len() as u64;
                if out.tx.blocking_send(b).is_err() {
                    break "the output closed";
                }
            }
        };
        drop(out);
        close(get(), &mut st, &self.model, &status, &name)?;
        Ok(RigRealtimeSummary {
            status: st,
            units: grids.into_iter().zip(done).collect(),
            ended,
        })
    }
}
