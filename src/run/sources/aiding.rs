//! The aiding sensors as frame sources of a run: the GNSS receiver's epochs (one stream per
//! wire format, plus their truth rows), each emitted at its emission time (time of validity
//! plus latency), and the odometer's, barometer's and magnetometer's CSV rows, each at its
//! sample's time. No I/O.

use crate::aiding::sensors::SensorRows;
use crate::aiding::stream::truth_row;
use crate::aiding::{GnssEncoder, Receiver};
use crate::engine::EngineError;
use crate::engine::frames::{EmitWindow, Emitter, Part, Until, WindowSource};
use crate::source::AnyMotion;

/// One epoch's frames, one per stream, and its emission time (ns after t₀).
type Epoch = (Vec<Vec<u8>>, i64);

/// A GNSS receiver's epochs over a span: a stream per encoder, then the truth rows if asked.
pub struct GnssSource {
    rx: Receiver,
    motion: AnyMotion,
    encoders: Vec<GnssEncoder>,
    truth: bool,
    span: (f64, f64),
    origin: f64,
    /// An epoch made but not yet due: per stream its bytes, and its emission time (ns).
    pending: Option<Epoch>,
    done: bool,
    row: String,
}

impl GnssSource {
    /// The epochs of `rx` on `motion` with time of validity in `span` (s), in each encoder's
    /// format, and their truth rows when `truth`; emission times in ns after `origin`.
    pub fn new(
        rx: Receiver,
        motion: AnyMotion,
        encoders: Vec<GnssEncoder>,
        truth: bool,
        span: (f64, f64),
        origin: f64,
    ) -> GnssSource {
        GnssSource {
            rx,
            motion,
            encoders,
            truth,
            span,
            origin,
            pending: None,
            done: false,
            row: String::new(),
        }
    }

    fn ns(&self, t: f64) -> i64 {
        ((t - self.origin) * 1e9).round() as i64
    }

    /// Makes the next epoch's frames; `None` after the last.
    fn make(&mut self) -> Result<Option<Epoch>, EngineError> {
        let Some(e) = (self.rx).next_epoch(&self.motion, self.span.0, self.span.1) else {
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
        let mut frames: Vec<Vec<u8>> = Vec::with_capacity(self.streams());
        for enc in self.encoders.iter_mut() {
            let mut b = Vec::new();
            enc.encode(&e, &mut b);
            frames.push(b);
        }
        if self.truth {
            self.row.clear();
            truth_row(&e, &mut self.row);
            frames.push(self.row.as_bytes().to_vec());
        }
        Ok(Some((frames, self.ns(e.t_emit))))
    }
}

impl WindowSource for GnssSource {
    fn streams(&self) -> usize {
        self.encoders.len() + usize::from(self.truth)
    }

    fn fill(&mut self, until: Until, parts: &mut [Part]) -> Result<(), EngineError> {
        let until_ns = until.ns;
        while !self.done {
            if self.pending.is_none() {
                let t = self.rx.next_time(self.span.0);
                if t > self.span.1 {
                    self.done = true;
                    break;
                }
                // Not valid by the window's end: not made yet (its motion may not be known).
                if self.ns(t) > until_ns {
                    break;
                }
                match self.make()? {
                    Some(p) => self.pending = Some(p),
                    None => {
                        self.done = true;
                        break;
                    }
                }
            }
            let Some((frames, at)) = self.pending.take_if(|p| p.1 <= until_ns) else {
                break;
            };
            for (f, p) in frames.iter().zip(parts.iter_mut()) {
                p.push(f, at);
            }
        }
        Ok(())
    }

    fn done(&self) -> bool {
        self.done
    }

    fn next_due_ns(&self) -> Option<i64> {
        match &self.pending {
            Some((_, at)) => Some(*at),
            None if self.done => None,
            None => Some(self.ns(self.rx.next_time(self.span.0))),
        }
    }
}

/// A sensor's CSV rows as a frame stream: each row emitted at its sample's time.
pub struct SensorFrames {
    rows: SensorRows<AnyMotion>,
    row: String,
}

/// The rows of `rows` as a one-stream source, each emitted at its sample's time counted from
/// `origin` (the run's t₀, s).
pub fn sensor_source(rows: SensorRows<AnyMotion>, origin: f64) -> EmitWindow<SensorFrames> {
    EmitWindow::new(
        SensorFrames {
            rows,
            row: String::new(),
        },
        origin,
    )
}

impl Emitter for SensorFrames {
    fn next_time(&self) -> Option<f64> {
        self.rows.next_time()
    }

    fn next_frame(&mut self, out: &mut Vec<u8>) -> Result<Option<f64>, EngineError> {
        let t = self.rows.next_row(&mut self.row)?;
        out.extend_from_slice(self.row.as_bytes());
        Ok(t)
    }
}
