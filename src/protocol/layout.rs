//! One message's fixed layout, compiled from its fields: byte offsets and conversions, the
//! status words, the check and trailing-zero truncation; it encodes a record into a frame and
//! decodes a frame back. [`super::plan::Plan`] strings layouts together (schedules,
//! transports, faults).

use std::path::Path;

use super::check::Check;
use super::faults::FrameFaults;
use super::plan::{DecodeError, Decoded, EncoderState, GPS_WEEK_S};
use super::spec::{
    BitEdit, ByteOrder, CheckSpec, FieldSpec, Source, SpecError, TruncateSpec, WireType,
};
use crate::errors::chain::{FLAG_ACCEL_SATURATED, FLAG_GYRO_SATURATED};
use crate::record::Record;

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
}

impl StatusModel {
    fn value(&self, flags: u8, failure: bool) -> i64 {
        let mut v = self.ok;
        if flags & FLAG_GYRO_SATURATED != 0 {
            v = self.gyro.apply(v);
        }
        if flags & FLAG_ACCEL_SATURATED != 0 {
            v = self.accel.apply(v);
        }
        if failure && let Some(e) = self.failure {
            v = e.apply(v);
        }
        v
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

/// The step of a counter of `ticks` per second in frames at `rate` Hz, if whole.
pub(super) fn tick_step(ticks: u64, rate: f64) -> Option<u64> {
    let step = ticks as f64 / rate;
    (rate > 0.0 && step >= 1.0 && (step - step.round()).abs() < 1e-9).then(|| step.round() as u64)
}

/// Compiles one layout's fields, check and truncation.
#[allow(clippy::too_many_arguments)] // the parts of one layout, each distinct
pub(super) fn compile_layout(
    name: &str,
    fields: &[FieldSpec],
    check: Option<&CheckSpec>,
    truncate: Option<&TruncateSpec>,
    accumulate: bool,
    default_order: ByteOrder,
    rate_hz: Option<f64>,
    path: &Path,
) -> Result<Layout, SpecError> {
    let ferr = |field: &str, message: String| SpecError::Field {
        path: path.to_path_buf(),
        field: field.to_string(),
        message,
    };
    let status_model = |f: &FieldSpec| {
        f.status.as_ref().map(|st| {
            Box::new(StatusModel {
                ok: st.ok,
                gyro: st.gyro_overrange.unwrap_or_default(),
                accel: st.accel_overrange.unwrap_or_default(),
                failure: st.failure,
            })
        })
    };
    let mut ops = Vec::with_capacity(fields.len());
    let mut offset = 0;
    for f in fields {
        let order = f.byte_order.unwrap_or(default_order);
        let is_length = truncate.is_some_and(|t| t.length_field == f.name);
        let what = match (&f.value, &f.source) {
            _ if is_length => {
                if f.value.is_some() || f.source.is_some() || f.ty.int_range().is_none() {
                    return Err(ferr(
                        &f.name,
                        "the truncation length field is an integer with no `value` or `source`"
                            .into(),
                    ));
                }
                What::Length
            }
            (Some(_), Some(_)) => {
                return Err(ferr(
                    &f.name,
                    "give either `value` or `source`, not both".into(),
                ));
            }
            (None, None) => {
                return Err(ferr(
                    &f.name,
                    "needs a `value` (constant) or a `source` (quantity)".into(),
                ));
            }
            (Some(v), None) => {
                if let Some((lo, hi)) = f.ty.int_range()
                    && ((*v as i128) < lo || (*v as i128) > hi)
                {
                    return Err(ferr(
                        &f.name,
                        format!("constant {v} does not fit in {:?}", f.ty),
                    ));
                }
                What::Constant(*v)
            }
            (None, Some(src)) => {
                let source = Source::from_name(src).ok_or_else(|| {
                    ferr(&f.name, format!("unknown source quantity `{src}` (gyro.x…z, accel.*, dtheta.*, dv.*, mag.*, time, counter, temperature, status, gps.*)"))
                })?;
                match source {
                    Source::Status => {
                        let m = status_model(f).ok_or_else(|| {
                            ferr(
                                &f.name,
                                "a `status` field needs a `[field.status]` table with `ok`".into(),
                            )
                        })?;
                        if f.ty.int_range().is_none() {
                            return Err(ferr(
                                &f.name,
                                "a status word needs an integer type".into(),
                            ));
                        }
                        What::Status(m)
                    }
                    Source::Counter => {
                        let range = f.ty.int_range().ok_or_else(|| {
                            ferr(&f.name, "a counter needs an integer type".into())
                        })?;
                        let modulo = f.modulo.unwrap_or((range.1 + 1) as u64);
                        if modulo == 0 || modulo as i128 > range.1 + 1 {
                            return Err(ferr(
                                &f.name,
                                format!("modulo {modulo} does not fit in {:?}", f.ty),
                            ));
                        }
                        let status = status_model(f);
                        if let Some(m) = &status
                            && (!modulo.is_power_of_two() || (m.ok as u64) % modulo != 0)
                        {
                            return Err(ferr(
                                &f.name,
                                format!(
                                    "a counter sharing its word with status bits needs a power-of-two modulo and status bits above it (ok = {:#x}, modulo {modulo})",
                                    m.ok
                                ),
                            ));
                        }
                        let step = match (f.ticks_per_second, f.step) {
                            (Some(_), Some(_)) => {
                                return Err(ferr(
                                    &f.name,
                                    "give `step` or `ticks_per_second`, not both".into(),
                                ));
                            }
                            (Some(t), None) => {
                                let rate = rate_hz.ok_or_else(|| {
                                    ferr(
                                        &f.name,
                                        "`ticks_per_second` needs the spec's `rate_hz`".into(),
                                    )
                                })?;
                                tick_step(t, rate).ok_or_else(|| {
                                    ferr(&f.name, format!("{t} ticks/s is not a whole number of ticks per frame at {rate} Hz"))
                                })?
                            }
                            (None, s) => s.unwrap_or(1),
                        };
                        What::Counter {
                            modulo,
                            step,
                            status,
                            ticks: f.ticks_per_second,
                        }
                    }
                    _ => {
                        let lsb = f.lsb.unwrap_or(1.0);
                        if !(lsb.is_finite() && lsb != 0.0) {
                            return Err(ferr(
                                &f.name,
                                format!("lsb {lsb} must be finite and non-zero"),
                            ));
                        }
                        let flag = match source {
                            _ if f.flags_overrange == Some(false) => 0,
                            Source::Gyro(_) | Source::DTheta(_) => FLAG_GYRO_SATURATED,
                            Source::Accel(_) | Source::Dv(_) => FLAG_ACCEL_SATURATED,
                            _ => 0,
                        };
                        let wrap = f.wrap.unwrap_or(false);
                        if wrap && f.ty.int_range().is_none() {
                            return Err(ferr(&f.name, "`wrap` needs an integer type".into()));
                        }
                        What::Quantity {
                            source,
                            scale: f.sign.unwrap_or(1.0) / lsb,
                            flag,
                            wrap,
                        }
                    }
                }
            }
        };
        if f.status.is_some() && !matches!(what, What::Status(_) | What::Counter { .. }) {
            return Err(ferr(
                &f.name,
                "`[field.status]` belongs to a field with `source = \"status\"` or `\"counter\"`"
                    .into(),
            ));
        }
        ops.push(Op {
            name: f.name.clone(),
            offset,
            ty: f.ty,
            order,
            what,
        });
        offset += f.ty.bytes();
    }
    let cerr = |message: String| SpecError::Check {
        path: path.to_path_buf(),
        message,
    };
    let check = match check {
        None => None,
        Some(c) => {
            let check = Check::from_toml(&c.kind).map_err(|e| cerr(e.to_string()))?;
            let from = c.from.unwrap_or(0);
            let pad_to = c.pad_to_multiple_of.unwrap_or(1);
            if !(1..=16).contains(&pad_to) {
                return Err(cerr(format!(
                    "pad_to_multiple_of = {pad_to}: expected 1 to 16"
                )));
            }
            if from >= offset {
                return Err(cerr(format!(
                    "coverage starts at byte {from}, outside the {offset}-byte frame"
                )));
            }
            if c.ty.bytes() < check.width_bytes() || c.ty.int_range().is_none() {
                return Err(cerr(format!(
                    "a {}-byte check does not fit in {:?}",
                    check.width_bytes(),
                    c.ty
                )));
            }
            Some(CheckOp {
                check,
                offset,
                ty: c.ty,
                order: c.byte_order.unwrap_or(default_order),
                from,
                pad_to,
                append: c.append.clone(),
            })
        }
    };
    let truncate = match truncate {
        None => None,
        Some(t) => {
            let find = |n: &str| ops.iter().find(|op| op.name == n);
            let terr = |message: String| SpecError::Syntax {
                path: path.to_path_buf(),
                message: format!("`truncate`: {message}"),
            };
            let l = find(&t.length_field)
                .ok_or_else(|| terr(format!("no field `{}`", t.length_field)))?;
            let p = find(&t.payload_from)
                .ok_or_else(|| terr(format!("no field `{}`", t.payload_from)))?;
            if l.offset >= p.offset {
                return Err(terr("the length field must come before the payload".into()));
            }
            if check.as_ref().is_some_and(|c| c.from > p.offset) {
                return Err(cerr("coverage must include the payload".into()));
            }
            Some(Truncate {
                len_at: l.offset,
                len_ty: l.ty,
                len_order: l.order,
                from: p.offset,
            })
        }
    };
    let len = offset + check.as_ref().map_or(0, |c| c.ty.bytes());
    if offset == 0 {
        return Err(SpecError::Syntax {
            path: path.to_path_buf(),
            message: format!("message `{name}` has no fields"),
        });
    }
    Ok(Layout {
        name: name.to_string(),
        ops,
        check,
        truncate,
        accumulate,
        len,
    })
}

impl Layout {
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

    /// Appends the frame's fields and check (before any transport).
    pub(super) fn encode(
        &self,
        r: &Record,
        temperature: f64,
        state: &EncoderState,
        faults: FrameFaults,
        out: &mut Vec<u8>,
    ) {
        let start = out.len();
        out.resize(start + self.len, 0);
        let frame = &mut out[start..];
        let mut flags = r.flags;
        let counter = |modulo: u64, step: u64| {
            let n = state.frames.wrapping_sub(state.stalled);
            n.wrapping_mul(step) % modulo
        };
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
                    let x = quantity(r, temperature, state, *source) * scale;
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
        for op in &self.ops {
            let dst = &mut frame[op.offset..op.offset + op.ty.bytes()];
            match &op.what {
                What::Status(m) => {
                    put_int(dst, op.ty, op.order, m.value(flags, faults.status).into())
                }
                What::Counter {
                    modulo,
                    step,
                    status: Some(m),
                    ..
                } => {
                    let v = m.value(flags, faults.status) as u64 | counter(*modulo, *step);
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
    }

    /// `Ok` when the constants inside `bytes` match (all of them, or the ones present). Of a
    /// truncating layout only the header's: the payload's are checked once it is rebuilt.
    pub(super) fn constants_match(&self, bytes: &[u8]) -> Result<(), DecodeError> {
        let end = self.truncate.map_or(usize::MAX, |t| t.from);
        self.constants_in(bytes, end)
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
                        out.flagged |= (raw - c) as i64 != m.ok;
                    }
                    out.values.push((Source::Counter, c as f64));
                }
                What::Quantity { source, scale, .. } => out
                    .values
                    .push((*source, get_value(src, op.ty, op.order) / scale + 0.0)),
                What::Status(m) => {
                    let v = get_int(src, op.ty, op.order) as i64;
                    out.flagged |= v != m.ok;
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
        Source::Gyro(i) => r.gyro.0[i],
        Source::Accel(i) => r.accel.0[i],
        Source::DTheta(i) => r.dtheta.0[i],
        Source::Dv(i) => r.dv.0[i],
        Source::Time => r.t,
        Source::Temperature => temperature,
        // The magnetometer is not simulated.
        Source::Mag(_) => 0.0,
        Source::Counter | Source::Status => 0.0,
    }
}

/// Writes a physical value: floats as they are, integers rounded and saturated at the type's
/// range (a real unit flags overrange rather than wrapping). Returns whether it saturated.
fn put_value(dst: &mut [u8], ty: WireType, order: ByteOrder, x: f64) -> bool {
    match ty {
        WireType::F32 => {
            put_bytes(dst, &(x as f32).to_be_bytes(), order);
            x.is_finite() && (x as f32).is_infinite()
        }
        WireType::F64 => {
            put_bytes(dst, &x.to_be_bytes(), order);
            false
        }
        _ => {
            let (lo, hi) = ty.int_range().expect("integer type");
            let v = if x.is_nan() { 0 } else { x.round() as i128 };
            put_int(dst, ty, order, v.clamp(lo, hi));
            v < lo || v > hi
        }
    }
}

fn get_value(src: &[u8], ty: WireType, order: ByteOrder) -> f64 {
    match ty {
        WireType::F32 => {
            let mut b = [0u8; 4];
            get_bytes(src, &mut b, order);
            f32::from_be_bytes(b) as f64
        }
        WireType::F64 => {
            let mut b = [0u8; 8];
            get_bytes(src, &mut b, order);
            f64::from_be_bytes(b)
        }
        _ => get_int(src, ty, order) as f64,
    }
}

/// Writes the low `ty.bytes()` bytes of v (two's complement) in `order`.
pub(super) fn put_int(dst: &mut [u8], ty: WireType, order: ByteOrder, v: i128) {
    let n = ty.bytes();
    let be = v.to_be_bytes();
    put_bytes(dst, &be[16 - n..], order);
}

pub(super) fn get_int(src: &[u8], ty: WireType, order: ByteOrder) -> i128 {
    let n = ty.bytes();
    let mut be = [0u8; 16];
    get_bytes(src, &mut be[16 - n..], order);
    let raw = i128::from_be_bytes(be);
    match ty.int_range() {
        Some((lo, _)) if lo < 0 && raw >= -lo => raw - 2 * (-lo),
        _ => raw,
    }
}

/// Copies big-endian bytes `be` into `dst` in the wire order.
fn put_bytes(dst: &mut [u8], be: &[u8], order: ByteOrder) {
    match order {
        ByteOrder::Big => dst.copy_from_slice(be),
        ByteOrder::Little => dst
            .iter_mut()
            .zip(be.iter().rev())
            .for_each(|(d, s)| *d = *s),
    }
}

/// Reads wire bytes `src` into big-endian `be`.
fn get_bytes(src: &[u8], be: &mut [u8], order: ByteOrder) {
    match order {
        ByteOrder::Big => be.copy_from_slice(src),
        ByteOrder::Little => be
            .iter_mut()
            .zip(src.iter().rev())
            .for_each(|(d, s)| *d = *s),
    }
}
