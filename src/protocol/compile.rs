//! Compiling one message's `[[field]]`s, `[check]` and `[truncate]` into a [`Layout`] of byte
//! offsets and conversions, refusing what cannot be used with the file and field named.

use std::borrow::Cow;
use std::path::Path;

use super::check::Check;
use super::layout::{CheckOp, Layout, Op, StatusModel, Truncate, What};
use super::spec::{
    ByteOrder, CheckSpec, FieldSpec, MAX_FIELDS, MAX_FRAME_BYTES, Source, SpecError, TruncateSpec,
    channel_range, compact,
};
use crate::record::{FLAG_ACCEL_SATURATED, FLAG_GYRO_SATURATED};

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
        line: None,
        field: field.to_string(),
        message,
    };
    let fields = &expand_channels(fields).map_err(|(f, m)| ferr(&f, m))?[..];
    let status_model = |f: &FieldSpec| {
        f.status.as_ref().map(|st| {
            Box::new(StatusModel {
                ok: st.ok,
                gyro: st.gyro_overrange.unwrap_or_default(),
                accel: st.accel_overrange.unwrap_or_default(),
                failure: st.failure,
                channels_at: st.failed_channels,
                mag: st.mag_updated,
            })
        })
    };
    if fields.len() > MAX_FIELDS {
        return Err(SpecError::Syntax {
            path: path.to_path_buf(),
            message: format!(
                "message `{name}` has {} fields; a message has at most {MAX_FIELDS}",
                fields.len()
            ),
        });
    }
    let mut ops: Vec<Op> = Vec::with_capacity(fields.len());
    let mut offset = 0;
    for f in fields {
        if ops.iter().any(|op| op.name == f.name) {
            return Err(ferr(
                &f.name,
                format!("a second field of this name in message `{name}`"),
            ));
        }
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
                    ferr(&f.name, format!("unknown source quantity `{src}` (gyro.x…z, accel.*, dtheta.*, dv.*, mag.*, time, counter, temperature, status, gps.*, gyro[i], accel[i], dtheta[i], dv[i], state.*, raw)"))
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
                            && (!modulo.is_power_of_two() || !(m.ok as u64).is_multiple_of(modulo))
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
                                    ferr(&f.name, format!("{t} ticks/s is not a whole number of ticks per frame at {} Hz", compact(rate)))
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
                        if !(lsb.is_finite() && lsb > 0.0) {
                            return Err(ferr(
                                &f.name,
                                format!(
                                    "lsb = {}: expected a finite size > 0 of one wire unit (a reversed axis takes `sign = -1`)",
                                    compact(lsb)
                                ),
                            ));
                        }
                        let sign = f.sign.unwrap_or(1.0);
                        if !(sign.is_finite() && sign != 0.0) {
                            return Err(ferr(
                                &f.name,
                                format!(
                                    "sign = {}: expected a finite non-zero factor",
                                    compact(sign)
                                ),
                            ));
                        }
                        let flag = match source {
                            _ if f.flags_overrange == Some(false) => 0,
                            Source::Gyro(_) | Source::DTheta(_) => FLAG_GYRO_SATURATED,
                            Source::Accel(_) | Source::Dv(_) => FLAG_ACCEL_SATURATED,
                            Source::Channel(c, _) if c.is_gyro() => FLAG_GYRO_SATURATED,
                            Source::Channel(..) => FLAG_ACCEL_SATURATED,
                            _ => 0,
                        };
                        if accumulate && matches!(source, Source::Channel(c, _) if c.is_increment())
                        {
                            return Err(ferr(
                                &f.name,
                                "an accumulating message sums three-axis Δθ/ΔV only, not single-axis channels".into(),
                            ));
                        }
                        if let Some(other) = ops.iter().find(|op| {
                            matches!(source, Source::Channel(..))
                                && matches!(op.what, What::Quantity { source: s, .. } if s == source)
                        }) {
                            return Err(ferr(
                                &f.name,
                                format!("`{src}` is already carried by field `{}`", other.name),
                            ));
                        }
                        let wrap = f.wrap.unwrap_or(false);
                        if wrap && f.ty.int_range().is_none() {
                            return Err(ferr(&f.name, "`wrap` needs an integer type".into()));
                        }
                        What::Quantity {
                            source,
                            scale: sign / lsb,
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
        if offset > MAX_FRAME_BYTES {
            return Err(ferr(
                &f.name,
                format!("ends at byte {offset}: a frame has at most {MAX_FRAME_BYTES} bytes"),
            ));
        }
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
    check_channel_bits(&ops).map_err(|(f, m)| ferr(&f, m))?;
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

/// The fields with every channel range (`source = "dtheta[0..6]"`) written out one field per
/// channel, named `NAME_i` (`dtheta[i]`, each with the range's type, LSB and sign); the
/// fields as given when there is none. `Err((field, problem))` for a malformed index.
fn expand_channels(fields: &[FieldSpec]) -> Result<Cow<'_, [FieldSpec]>, (String, String)> {
    let mut out: Option<Vec<FieldSpec>> = None;
    for (k, f) in fields.iter().enumerate() {
        let range = match f.source.as_deref().and_then(channel_range) {
            Some(r) => r.map_err(|m| (f.name.clone(), m))?,
            None => {
                if let Some(v) = out.as_mut() {
                    v.push(f.clone());
                }
                continue;
            }
        };
        if range.1.len() == 1 {
            if let Some(v) = out.as_mut() {
                v.push(f.clone());
            }
            continue;
        }
        let v = out.get_or_insert_with(|| fields[..k].to_vec());
        let kind = f.source.as_deref().and_then(|s| s.split_once('['));
        let kind = kind.map_or("", |k| k.0);
        for i in range.1 {
            let mut one = f.clone();
            one.name = format!("{}_{i}", f.name);
            one.source = Some(format!("{kind}[{i}]"));
            v.push(one);
        }
        if v.len() > MAX_FIELDS {
            return Err((
                f.name.clone(),
                format!("expands past {MAX_FIELDS} fields in its message"),
            ));
        }
    }
    Ok(out.map_or(Cow::Borrowed(fields), Cow::Owned))
}

/// Every channel's failure bit of a status word fits in it: bit `failed_channels + i` for
/// the i-th channel (gyros, then accelerometers) of this message.
fn check_channel_bits(ops: &[Op]) -> Result<(), (String, String)> {
    let (gyros, accels) = channel_counts(ops);
    for op in ops {
        let m = match &op.what {
            What::Status(m) => m,
            What::Counter {
                status: Some(m), ..
            } => m,
            _ => continue,
        };
        let Some(at) = m.channels_at else { continue };
        let bits = op.ty.bytes() as u32 * 8;
        let n = (gyros + accels) as u32;
        if n == 0 || at + n > bits {
            return Err((
                op.name.clone(),
                format!(
                    "`failed_channels` = {at}: {n} channel bits from bit {at} do not fit in {:?} ({bits} bits){}",
                    op.ty,
                    if n == 0 {
                        "; the message carries no channel"
                    } else {
                        ""
                    }
                ),
            ));
        }
    }
    Ok(())
}

/// The gyro and accelerometer channels a layout's fields carry (highest index + 1 of each).
pub(super) fn channel_counts(ops: &[Op]) -> (usize, usize) {
    let (mut g, mut a) = (0, 0);
    for op in ops {
        if let What::Quantity {
            source: Source::Channel(c, i),
            ..
        } = op.what
        {
            let n = if c.is_gyro() { &mut g } else { &mut a };
            *n = (*n).max(i + 1);
        }
    }
    (g, a)
}
