//! The aiding sensors as frame sources: a GNSS receiver's epochs, emitted at each epoch's
//! emission time (time of validity plus latency), and the odometer's, barometer's and
//! magnetometer's CSV rows, each at its sample's time, through
//! [`crate::engine::frames::EmitWindow`]. No I/O.

use crate::aiding::sensors::SensorRows;
use crate::aiding::{GnssEncoder, Receiver};
use crate::engine::EngineError;
use crate::engine::frames::{EmitWindow, Emitter};
use crate::motion::Motion;

/// One GNSS stream: the epochs with time of validity in a span, encoded by one encoder.
pub struct GnssFrames<M> {
    rx: Receiver,
    motion: M,
    enc: GnssEncoder,
    span: (f64, f64),
}

/// A GNSS stream as a window source for the merger.
pub type GnssWindow<M> = EmitWindow<GnssFrames<M>>;

impl<M: Motion> GnssFrames<M> {
    /// Epochs of `rx` on `motion` with time of validity in `[t_from, t_to]` (s), encoded by
    /// `enc`.
    pub fn new(rx: Receiver, motion: M, enc: GnssEncoder, (t_from, t_to): (f64, f64)) -> Self {
        GnssFrames {
            rx,
            motion,
            enc,
            span: (t_from, t_to),
        }
    }

    /// The stream as a window source, emission times counted from `origin` (the run's t₀, s).
    pub fn window(self, origin: f64) -> GnssWindow<M>
    where
        M: Send,
    {
        EmitWindow::new(self, origin)
    }
}

impl<M: Motion + Send> Emitter for GnssFrames<M> {
    fn next_frame(&mut self, out: &mut Vec<u8>) -> Result<Option<f64>, EngineError> {
        let Some(e) = self.rx.next_epoch(&self.motion, self.span.0, self.span.1) else {
            return Ok(None);
        };
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
            return Err(EngineError::NonFinite {
                t: e.t,
                quantity,
                value,
                stage: "in the GNSS epoch",
            });
        }
        self.enc.encode(&e, out);
        Ok(Some(e.t_emit))
    }
}

/// How many epochs at `rate` (Hz) fall in `[t0, t1]` (outages included: they are sent
/// without a fix).
pub fn epoch_count(rate: f64, (t0, t1): (f64, f64)) -> u64 {
    ((t1 * rate).floor() - (t0 * rate).ceil() + 1.0).max(0.0) as u64
}

/// A sensor's CSV rows as a frame stream: each row emitted at its sample's time.
pub struct SensorFrames<M> {
    rows: SensorRows<M>,
    row: String,
}

/// A sensor's rows as a window source for the merger.
pub type SensorWindow<M> = EmitWindow<SensorFrames<M>>;

/// The rows of `rows` as a stream, each emitted at its sample's time counted from `origin`
/// (the run's t₀, s).
pub fn sensor_window<M: Motion + Send>(rows: SensorRows<M>, origin: f64) -> SensorWindow<M> {
    EmitWindow::new(
        SensorFrames {
            rows,
            row: String::new(),
        },
        origin,
    )
}

impl<M: Motion + Send> Emitter for SensorFrames<M> {
    fn next_frame(&mut self, out: &mut Vec<u8>) -> Result<Option<f64>, EngineError> {
        let t = self.rows.next_row(&mut self.row)?;
        out.extend_from_slice(self.row.as_bytes());
        Ok(t)
    }
}
