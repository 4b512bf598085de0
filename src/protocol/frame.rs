//! The data a codec run passes around: the encoder's state from frame to frame, a decoded frame
//! and why a frame does not decode. No logic beyond reading a decoded frame back as the record
//! contract.

use super::faults::FaultInjector;
use super::framing::BitWriter;
use super::spec::{Channel, Source};
use crate::math::Vec3;

/// Encoder state carried from frame to frame (the counter) and the run's time reference.
#[derive(Clone, Debug, Default)]
pub struct EncoderState {
    /// Frames encoded so far (dropped ones included).
    pub frames: u64,
    /// Frames on which the counter did not advance (stale-counter faults).
    pub stalled: u64,
    /// Frames not sent because a value was not finite and their message has no status word to
    /// report the failure (their counter values are skipped).
    pub withheld: u64,
    /// Frames sent with a value clipped at its field's range (or at the float type's largest)
    /// that no status bit of their message reports: as a unit without such a bit would send
    /// them, but a caller encoding records of its own may refuse them.
    pub unreported: u64,
    /// Faults to inject, if any (boxed: the state travels inside the job's encoding).
    pub faults: Option<Box<FaultInjector>>,
    /// The synchronous line of an SDLC transport (NRZI level across frames).
    pub line: Option<Box<BitWriter>>,
    /// Reused buffer of a frame before its transport.
    pub scratch: Vec<u8>,
    /// Δθ and ΔV summed since an accumulating message was last sent.
    pub sums: [Vec3; 2],
    /// GPS week of the record time t = 0.
    pub gps_week0: u32,
    /// GPS seconds of week of the record time t = 0. GPS fields carry (week0, sow0) + t, kept
    /// split so that seconds of week stay exact to the record's own time resolution. With
    /// both 0, record times are GPS seconds since the epoch (1980-01-06).
    pub gps_sow0: f64,
    /// The magnetic field (T, the IMU's axes) the next frame's `mag.*` fields carry: the
    /// latest magnetometer sample, 0 without a magnetometer (set by the caller per record).
    pub mag: Vec3,
    /// The next frame carries a magnetometer sample no earlier frame carried.
    pub mag_fresh: bool,
    /// What each increment source's integer field could not express in the frames sent so far
    /// (physical units, slots of `layout::carry_slot`): added to the next frame's increment,
    /// as a real unit's accumulator keeps the remainder of its counts, so that the counts sum to
    /// the summed increments within one count instead of drifting by up to half a count a frame.
    pub carry: Vec<f64>,
}

/// The single-axis channels of an N-channel unit (a skew-redundant one) for one frame, next
/// to the record that carries its time tag.
#[derive(Clone, Copy, Debug)]
pub struct Channels<'a> {
    /// Interval-mean readings: the gyros' (rad/s), then the accelerometers' (m/s²).
    pub values: &'a [f64],
    /// How many of `values` are gyros.
    pub gyros: usize,
    /// The sample interval (s): a channel's increment is its mean times it.
    pub dt: f64,
    /// Bit i set while channel i (the index into `values`) has an active failure.
    pub failed: u64,
}

impl Channels<'_> {
    /// The value a `Source::Channel(c, i)` field carries; NaN for a channel the unit does
    /// not have (the frame then reports a failure, or is withheld).
    pub fn value(&self, c: Channel, i: usize) -> f64 {
        let (k, n) = if c.is_gyro() {
            (i, self.gyros)
        } else {
            (
                self.gyros + i,
                self.values.len() - self.gyros.min(self.values.len()),
            )
        };
        match self.values.get(k) {
            Some(v) if i < n => {
                if c.is_increment() {
                    v * self.dt
                } else {
                    *v
                }
            }
            _ => f64::NAN,
        }
    }
}

/// Seconds in a GPS week.
pub const GPS_WEEK_S: f64 = 604_800.0;

/// Why a frame does not decode.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecodeError {
    /// Fewer bytes than a frame.
    #[error("{got} bytes, a frame has {need}")]
    Short {
        /// Bytes given.
        got: usize,
        /// Frame length.
        need: usize,
    },
    /// A constant field (sync word, fixed status) has another value.
    #[error("field `{field}`: {got:#x}, expected {expected:#x}")]
    Constant {
        /// Field name.
        field: String,
        /// Value found.
        got: i64,
        /// Value expected.
        expected: i64,
    },
    /// A truncated frame's length field is out of range.
    #[error("length field {got}: expected 1 to {max}")]
    Length {
        /// Value found.
        got: i64,
        /// Full payload length.
        max: usize,
    },
    /// The integrity check does not match.
    #[error("check: frame carries {got:#x}, computed {computed:#x}")]
    Check {
        /// Transmitted.
        got: u64,
        /// Computed.
        computed: u64,
        /// Length of the frame whose boundary was found.
        len: usize,
    },
}

/// A decoded frame: every quantity field's value in SI, by field order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Decoded {
    /// (source, value) of each quantity, counter and status field, in wire order.
    pub values: Vec<(Source, f64)>,
    /// Some status word differs from its healthy value.
    pub flagged: bool,
    /// Index of the message layout (0 for single-layout protocols).
    pub message: usize,
    /// Bytes the frame took (before any transport).
    pub len: usize,
}

impl Decoded {
    /// The value of a source, if the frame carries it.
    pub fn get(&self, s: Source) -> Option<f64> {
        self.values.iter().find(|v| v.0 == s).map(|v| v.1)
    }

    /// The frame's time tag (s): its time field, else its GPS seconds of week, whole or as
    /// whole seconds plus microseconds or milliseconds (iMAR iXCOM's `tow_seconds`,
    /// `tow_micros`).
    pub fn time(&self) -> Option<f64> {
        let split = || {
            let whole = self.get(Source::GpsWholeSeconds)?;
            let sub = match self.get(Source::GpsMicros) {
                Some(us) => us * 1e-6,
                None => self.get(Source::GpsMillis)? * 1e-3,
            };
            Some(whole + sub)
        };
        self.get(Source::Time)
            .or(self.get(Source::GpsSeconds))
            .or_else(split)
    }

    /// The record contract's columns `t, gyro, accel, dtheta, dv` (13) from this frame: the
    /// time from its time tag ([`Decoded::time`]); a rate the frame lacks from its increment
    /// over `dt`, an increment from its rate times `dt` (None without `dt`).
    pub fn contract(&self, dt: Option<f64>) -> [Option<f64>; 13] {
        let mut out = [None; 13];
        out[0] = self.time();
        for a in 0..3 {
            for (rate, inc, col) in [
                (Source::Gyro(a), Source::DTheta(a), 1 + a),
                (Source::Accel(a), Source::Dv(a), 4 + a),
            ] {
                let (r, i) = (self.get(rate), self.get(inc));
                out[col] = r.or_else(|| Some(i? / dt?));
                out[col + 6] = i.or_else(|| Some(r? * dt?));
            }
        }
        out
    }

    /// True for the quantities [`Decoded::contract`] carries.
    pub fn in_contract(s: Source) -> bool {
        matches!(
            s,
            Source::Gyro(_)
                | Source::Accel(_)
                | Source::DTheta(_)
                | Source::Dv(_)
                | Source::Time
                | Source::GpsSeconds
        )
    }
}
