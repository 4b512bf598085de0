//! A GNSS receiver as a real-time frame source: each epoch's frames, emitted at the epoch's
//! emission time (time of validity plus latency), window by window of simulated time, for the
//! merger and pacer of `imu-emu run` (`realtime::merge`). No I/O.

use super::gnss::{GnssEpoch, Receiver};
use super::stream::GnssEncoder;
use crate::emission::{Part, WindowSource};
use crate::job::JobError;
use crate::motion::Motion;

/// One GNSS stream: the epochs with time of validity in `[t_from, t_to]`, encoded by one
/// encoder, their emission times counted from `origin`.
pub struct GnssWindow<M> {
    rx: Receiver,
    motion: M,
    enc: GnssEncoder,
    span: (f64, f64),
    origin: f64,
    /// The next epoch, computed but not yet due.
    pending: Option<GnssEpoch>,
    done: bool,
    bytes: Vec<u8>,
}

impl<M: Motion> GnssWindow<M> {
    /// Epochs of `rx` on `motion` with time of validity in `[t_from, t_to]` (s), encoded by
    /// `enc`; emission times are ns after `origin` (the run's t₀, s).
    pub fn new(
        rx: Receiver,
        motion: M,
        enc: GnssEncoder,
        (t_from, t_to): (f64, f64),
        origin: f64,
    ) -> GnssWindow<M> {
        GnssWindow {
            rx,
            motion,
            enc,
            span: (t_from, t_to),
            origin,
            pending: None,
            done: false,
            bytes: Vec::new(),
        }
    }

    /// Emission time of `e` (ns after the origin).
    fn emit_ns(&self, e: &GnssEpoch) -> i64 {
        ((e.t_emit - self.origin) * 1e9).round() as i64
    }
}

impl<M: Motion + Send> WindowSource for GnssWindow<M> {
    fn streams(&self) -> usize {
        1
    }

    fn fill(&mut self, until_ns: i64, parts: &mut [Part]) -> Result<(), JobError> {
        while !self.done {
            let e = match self.pending.take() {
                Some(e) => e,
                None => match self.rx.next_epoch(&self.motion, self.span.0, self.span.1) {
                    Some(e) => e,
                    None => {
                        self.done = true;
                        break;
                    }
                },
            };
            let at = self.emit_ns(&e);
            if at > until_ns {
                self.pending = Some(e);
                break;
            }
            // A non-finite motion would put NaN into the sentences: stop as the IMU does.
            let m = &e.measured;
            let values = [
                ("gnss_lat", m.lat),
                ("gnss_lon", m.lon),
                ("gnss_h", m.h),
                ("gnss_vn", m.v_n.x),
                ("gnss_ve", m.v_n.y),
                ("gnss_vd", m.v_n.z),
            ];
            if let Some(&(quantity, value)) = values.iter().find(|v| !v.1.is_finite()) {
                return Err(JobError::NonFinite {
                    t: e.t,
                    quantity,
                    value,
                    stage: "in the GNSS epoch",
                });
            }
            self.bytes.clear();
            self.enc.encode(&e, &mut self.bytes);
            parts[0].push(&self.bytes, at);
        }
        Ok(())
    }

    fn done(&self) -> bool {
        self.done
    }
}
