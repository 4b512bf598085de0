//! One message's fixed layout (compiled by [`super::compile`]): byte offsets and conversions,
//! the status words, the check and trailing-zero truncation; it encodes a record into a frame
//! and decodes a frame back. [`super::plan::Plan`] strings layouts together (schedules,
//! transports, faults).

use super::check::Check;
use super::faults::FrameFaults;
use super::frame::{Channels, DecodeError, Decoded, EncoderState, GPS_WEEK_S};
use super::spec::{BitEdit, ByteOrder, Source, WireType};
use super::wire::{get_int, get_value, put_int, put_value};
use crate::record::{FLAG_ACCEL_SATURATED, FLAG_GYRO_SATURATED, FLAG_INVALID, FLAG_STALE, Record};

/// One compiled field.
#[derive(Clone, Debug)]
pub(super) struct Op {
    pub(super) name: String,
    pub(super) offset: usize,
    pub(super) ty: WireType,
    pub(super) order: ByteOrder,
    pub(super) what: What,
}

#[derive(Clone, Debug)]
pub(super) enum What {
    Constant(i64),
    /// A quantity; `flag` is the record flag its saturation at the field's range raises (0:
    /// none).
    Quantity {
        source: Source,
        scale: f64,
        flag: u8,
        /// Wraps at the type's range (free-running timestamps) instead of saturating.
        wrap: bool,
    },
    /// A counter, possibly sharing its word with status bits above it.
    Counter {
        modulo: u64,
        step: u64,
        status: Option<Box<StatusModel>>,
        /// Internal tick rate (Hz): `step` = ticks / frame rate.
        ticks: Option<u64>,
    },
    Status(Box<StatusModel>),
    /// The sent payload length of a truncated frame.
    Length,
}

/// A compiled `[field.status]`.
#[derive(Clone, Debug)]
pub(super) struct StatusModel {
    pub(super) ok: i64,
    pub(super) gyro: BitEdit,
    pub(super) accel: BitEdit,
    pub(super) failure: Option<BitEdit>,
    /// Bit of channel 0's failure flag (channel i at this + i).
    pub(super) channels_at: Option<u32>,
    /// Edit of a frame with a new magnetometer sample.
    pub(super) mag: Option<BitEdit>,
}

impl StatusModel {
    fn value(&self, flags: u8, failure: bool, failed: u64, mag_fresh: bool) -> i64 {
        let mut v = self.ok;
        if mag_fresh && let Some(e) = self.mag {
            v = e.apply(v);
        }
        if let Some(at) = self.channels_at {
            v |= (failed << at) as i64;
        }
        if flags & FLAG_GYRO_SATURATED != 0 {
            v = self.gyro.apply(v);
        }
        if flags & FLAG_ACCEL_SATURATED != 0 {
            v = self.accel.apply(v);
        }
        // A value that is not a measurement is what a real unit's built-in test reports.
        if (failure || flags & (FLAG_INVALID | FLAG_STALE) != 0)
            && let Some(e) = self.failure
        {
            v = e.apply(v);
        }
        v
    }

    /// Whether a received word `v` reports all well: the healthy value, with or without the
    /// new-magnetometer-sample edit.
    fn healthy(&self, v: i64) -> bool {
        v == self.ok || self.mag.is_some_and(|e| v == e.apply(self.ok))
    }
}

/// The compiled check.
#[derive(Clone, Debug)]
pub(super) struct CheckOp {
    pub(super) check: Check,
    pub(super) offset: usize,
    pub(super) ty: WireType,
    pub(super) order: ByteOrder,
    pub(super) from: usize,
    pub(super) pad_to: usize,
    pub(super) append: Vec<u8>,
}

/// Compiled `[truncate]`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Truncate {
    /// Offset and type of the length field.
    pub(super) len_at: usize,
    pub(super) len_ty: WireType,
    pub(super) len_order: ByteOrder,
    /// First payload byte.
    pub(super) from: usize,
}

/// One message layout: fixed offsets, optional check, optional truncation.
#[derive(Clone, Debug)]
pub(super) struct Layout {
    pub(super) name: String,
    pub(super) ops: Vec<Op>,
    pub(super) check: Option<CheckOp>,
    pub(super) truncate: Option<Truncate>,
    pub(super) accumulate: bool,
    /// Full (untruncated) length.
    pub(super) len: usize,
}

impl Layout {
    /// Whether some status word of this layout has a failure model (can report a value that is
    /// not a measurement).
    pub(super) fn reports_failure(&self) -> bool {
        self.ops.iter().any(|op| match &op.what {
            What::Status(m)
            | What::Counter {
                status: Some(m), ..
            } => m.failure.is_some(),
            _ => false,
        })
    }

    /// Whether a status word of this layout has bits of its own for the saturation `flag`
    /// ([`FLAG_GYRO_SATURATED`] or [`FLAG_ACCEL_SATURATED`]).
    pub(super) fn reports_saturation(&self, flag: u8) -> bool {
        self.ops.iter().any(|op| match &op.what {
            What::Status(m)
            | What::Counter {
                status: Some(m), ..
            } => {
                let edit = if flag == FLAG_GYRO_SATURATED {
                    m.gyro
                } else {
                    m.accel
                };
                edit != BitEdit::default()
            }
            _ => false,
        })
    }

    /// The shortest frame of this layout (a truncated one keeps one payload byte).
    pub(super) fn shortest(&self) -> usize {
        match self.truncate {
            Some(t) => {
                let payload = self.check.as_ref().map_or(self.len, |c| c.offset) - t.from;
                self.len - payload + 1
            }
            None => self.len,
        }
    }

    /// Appends the frame's fields and check (before any transport); returns the record's flags
    /// with those the frame raised (a value beyond a field's range, a value that is not finite).
    /// No field carries a non-finite value: NaN is sent as 0 and ±∞ as the type's limit, with
    /// [`FLAG_INVALID`] raised (and the overrange flag of a saturated field).
    pub(super) fn encode(
        &self,
        r: &Record,
        ch: Option<&Channels<'_>>,
        temperature: f64,
        state: &mut EncoderState,
        faults: FrameFaults,
        out: &mut Vec<u8>,
    ) -> u8 {
        let start = out.len();
        out.resize(start + self.len, 0);
        let frame = &mut out[start..];
        let mut flags = r.flags;
        let sent = state.frames.wrapping_sub(state.stalled);
        let counter = |modulo: u64, step: u64| sent.wrapping_mul(step) % modulo;
        // Increment sources already sent in this frame: the remainder is carried once.
        let (mut carried, mut with_carry) = (0u64, [0.0f64; 64]);
        for op in &self.ops {
            let dst = &mut frame[op.offset..op.offset + op.ty.bytes()];
            match &op.what {
                What::Constant(v) => put_int(dst, op.ty, op.order, *v as i128),
                What::Counter {
                    modulo,
                    step,
                    status: None,
                    ..
                } => put_int(dst, op.ty, op.order, counter(*modulo, *step) as i128),
                What::Quantity {
                    source,
                    scale,
                    flag,
                    wrap,
                } => {
                    let q = match (*source, ch) {
                        (Source::Channel(c, i), Some(ch)) => ch.value(c, i),
                        // No channels given (a three-axis record): not a measurement.
                        (Source::Channel(..), None) => f64::NAN,
                        _ => quantity(r, temperature, state, *source),
                    };
                    if !q.is_finite() {
                        flags |= FLAG_INVALID;
                    }
                    let q = match (carry_slot(*source), op.ty.int_range()) {
                        // A second field of the same increment (a raw copy) sends the same.
                        (Some(k), Some(_)) if carried & (1 << k) != 0 => with_carry[k],
                        (Some(k), Some((lo, hi))) if q.is_finite() => {
                            carried |= 1 << k;
                            if state.carry.len() <= k {
                                state.carry.resize(k + 1, 0.0);
                            }
                            // The unit's accumulator keeps what a count could not express, so
                            // the sum of the counts sent follows the sum of the increments. A
                            // saturated count loses the excess, as the real unit's does.
                            let x = q + state.carry[k];
                            let counts = (x * scale).round().clamp(lo as f64, hi as f64);
                            let rest = x - counts / scale;
                            state.carry[k] = if (rest * scale).abs() <= 0.5 {
                                rest
                            } else {
                                0.0
                            };
                            with_carry[k] = x;
                            x
                        }
                        _ => q,
                    };
                    let x = q * scale;
                    if *wrap {
                        let (lo, hi) = op.ty.int_range().expect("checked at compile");
                        let v = if x.is_finite() { x.round() as i128 } else { 0 };
                        put_int(dst, op.ty, op.order, (v - lo).rem_euclid(hi - lo + 1) + lo);
                    } else if put_value(dst, op.ty, op.order, x) {
                        flags |= flag;
                    }
                }
                What::Status(_) | What::Counter { .. } | What::Length => {}
            }
        }
        let failed = ch.map_or(0, |c| c.failed);
        for op in &self.ops {
            let dst = &mut frame[op.offset..op.offset + op.ty.bytes()];
            match &op.what {
                What::Status(m) => put_int(
                    dst,
                    op.ty,
                    op.order,
                    m.value(flags, faults.status, failed, state.mag_fresh)
                        .into(),
                ),
                What::Counter {
                    modulo,
                    step,
                    status: Some(m),
                    ..
                } => {
                    let v = m.value(flags, faults.status, failed, state.mag_fresh) as u64
                        | counter(*modulo, *step);
                    put_int(dst, op.ty, op.order, v as i128)
                }
                _ => {}
            }
        }
        let mut end = self.len;
        if let Some(t) = self.truncate {
            // MAVLink 2: trailing zeros of the payload are not sent; at least one byte is.
            let pend = self.check.as_ref().map_or(self.len, |c| c.offset);
            let sent = frame[t.from..pend]
                .iter()
                .rposition(|b| *b != 0)
                .map_or(1, |i| i + 1);
            put_int(
                &mut frame[t.len_at..t.len_at + t.len_ty.bytes()],
                t.len_ty,
                t.len_order,
                sent as i128,
            );
            end = t.from + sent + self.check.as_ref().map_or(0, |c| c.ty.bytes());
        }
        if let Some(c) = &self.check {
            let at = end - c.ty.bytes();
            let mut v = c.compute(&frame[c.from..at]);
            if faults.corrupt {
                v ^= 1;
            }
            put_int(&mut frame[at..end], c.ty, c.order, v as i128);
        }
        out.truncate(start + end);
        flags
    }

    /// `Ok` when the constants inside `bytes` match (all of them, or the ones present). Of a
    /// truncating layout only the header's: the payload's are checked once it is rebuilt.
    pub(super) fn constants_match(&self, bytes: &[u8]) -> Result<(), DecodeError> {
        let end = self.truncate.map_or(usize::MAX, |t| t.from);
        self.constants_in(bytes, end)
    }

    /// `bytes` hold at least one of the header's constants whole, and every one they hold
    /// matches.
    pub(super) fn starts_frame(&self, bytes: &[u8]) -> bool {
        let end = self.truncate.map_or(usize::MAX, |t| t.from);
        self.ops.iter().any(|op| {
            matches!(op.what, What::Constant(_))
                && op.offset < end
                && op.offset + op.ty.bytes() <= bytes.len()
        }) && self.constants_in(bytes, end).is_ok()
    }

    /// Bits a frame of this layout matches that random bytes match only by chance: its
    /// constant fields' and its check's.
    pub(super) fn evidence_bits(&self) -> u32 {
        let constants: usize = self
            .ops
            .iter()
            .filter(|op| matches!(op.what, What::Constant(_)))
            .map(|op| 8 * op.ty.bytes())
            .sum();
        constants as u32 + self.check.as_ref().map_or(0, |c| 8 * c.ty.bytes() as u32)
    }

    /// Checks the constants that lie before byte `end` and inside `bytes`.
    fn constants_in(&self, bytes: &[u8], end: usize) -> Result<(), DecodeError> {
        for op in self.ops.iter().filter(|op| op.offset < end) {
            if let What::Constant(expected) = op.what {
                let Some(src) = bytes.get(op.offset..op.offset + op.ty.bytes()) else {
                    continue;
                };
                let got = get_int(src, op.ty, op.order) as i64;
                if got != expected {
                    return Err(DecodeError::Constant {
                        field: op.name.clone(),
                        got,
                        expected,
                    });
                }
            }
        }
        Ok(())
    }

    /// Length of the frame at the start of `bytes` (a truncated frame's from its length field).
    fn frame_len(&self, bytes: &[u8]) -> Result<usize, DecodeError> {
        let Some(t) = self.truncate else {
            return Ok(self.len);
        };
        let short = DecodeError::Short {
            got: bytes.len(),
            need: t.len_at + t.len_ty.bytes(),
        };
        let src = bytes
            .get(t.len_at..t.len_at + t.len_ty.bytes())
            .ok_or(short)?;
        let sent = get_int(src, t.len_ty, t.len_order) as i64;
        let pend = self.check.as_ref().map_or(self.len, |c| c.offset);
        let max = pend - t.from;
        if sent < 1 || sent as usize > max {
            return Err(DecodeError::Length { got: sent, max });
        }
        Ok(self.len - (max - sent as usize))
    }

    pub(super) fn decode(&self, bytes: &[u8]) -> Result<Decoded, DecodeError> {
        self.constants_match(bytes)?;
        let n = self.frame_len(bytes)?;
        if bytes.len() < n {
            return Err(DecodeError::Short {
                got: bytes.len(),
                need: n,
            });
        }
        let wire = &bytes[..n];
        if let Some(c) = &self.check {
            let at = n - c.ty.bytes();
            let got = get_int(&wire[at..], c.ty, c.order) as u64;
            let computed = c.compute(&wire[c.from..at]);
            if got != computed {
                return Err(DecodeError::Check {
                    got,
                    computed,
                    len: n,
                });
            }
        }
        // A truncated frame: the fields read from the payload zero-extended to full length.
        let full;
        let frame: &[u8] = if n < self.len {
            let mut v = wire.to_vec();
            let at = n - self.check.as_ref().map_or(0, |c| c.ty.bytes());
            v.splice(at..at, std::iter::repeat_n(0u8, self.len - n));
            full = v;
            self.constants_in(&full, usize::MAX)?;
            &full
        } else {
            wire
        };
        let mut out = Decoded {
            len: n,
            ..Decoded::default()
        };
        for op in &self.ops {
            let src = &frame[op.offset..op.offset + op.ty.bytes()];
            match &op.what {
                What::Constant(_) | What::Length => {}
                What::Counter { modulo, status, .. } => {
                    let raw = get_int(src, op.ty, op.order) as u64;
                    let c = raw % modulo;
                    if let Some(m) = status {
                        out.flagged |= !m.healthy((raw - c) as i64);
                    }
                    out.values.push((Source::Counter, c as f64));
                }
                What::Quantity { source, scale, .. } => out
                    .values
                    .push((*source, get_value(src, op.ty, op.order) / scale + 0.0)),
                What::Status(m) => {
                    let v = get_int(src, op.ty, op.order) as i64;
                    out.flagged |= !m.healthy(v);
                    out.values.push((Source::Status, v as f64));
                }
            }
        }
        Ok(out)
    }
}

impl CheckOp {
    /// The check over the covered bytes, zero-padded and extended (neither transmitted) when
    /// the protocol says so.
    fn compute(&self, covered: &[u8]) -> u64 {
        let pad = (self.pad_to - covered.len() % self.pad_to) % self.pad_to;
        const ZEROS: [u8; 16] = [0; 16];
        self.check
            .compute_parts(&[covered, &ZEROS[..pad.min(16)], &self.append])
    }
}

/// The carry slot of an increment source (Δθ, ΔV, a single-axis channel's increment):
/// three-axis Δθ 0–2, ΔV 3–5, then channel i of a kind at 6 + 2i (gyros) or 7 + 2i; `None`
/// for a quantity that is not an increment (rates, time, status…). Slots past 63 (more than
/// 28 channels of a kind) are not carried.
fn carry_slot(s: Source) -> Option<usize> {
    let k = match s {
        Source::DTheta(i) => i,
        Source::Dv(i) => 3 + i,
        Source::Channel(c, i) if c.is_increment() => 6 + 2 * i + usize::from(!c.is_gyro()),
        _ => return None,
    };
    (k < 64).then_some(k)
}

fn quantity(r: &Record, temperature: f64, st: &EncoderState, s: Source) -> f64 {
    // Seconds of week from the run's reference plus the record time, so they stay exact.
    let gps = || {
        let sow = st.gps_sow0 + r.t;
        let weeks = (sow / GPS_WEEK_S).floor();
        (st.gps_week0 as f64 + weeks, sow - weeks * GPS_WEEK_S)
    };
    match s {
        Source::GpsWeek => gps().0,
        Source::GpsSeconds => gps().1,
        Source::GpsWholeSeconds => gps().1.floor(),
        Source::GpsMicros => {
            let sow = gps().1;
            ((sow - sow.floor()) * 1e6).round().min(999_999.0)
        }
        Source::GpsMillis => (gps().1 * 1e3).round(),
        Source::Gyro(i) => r.gyro[i],
        Source::Accel(i) => r.accel[i],
        Source::DTheta(i) => r.dtheta[i],
        Source::Dv(i) => r.dv[i],
        Source::Time => r.t,
        Source::Temperature => temperature,
        Source::Mag(i) => st.mag[i],
        // No IMU output carries a vehicle's state.
        Source::State(_) => f64::NAN,
        Source::Counter | Source::Status | Source::Channel(..) | Source::Raw => 0.0,
    }
}
