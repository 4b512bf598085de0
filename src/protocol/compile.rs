//! Compiling one message's `[[field]]`s, `[check]` and `[truncate]` into a [`Layout`] of byte
//! offsets and conversions, refusing what cannot be used with the file and field named.

use std::path::Path;

use super::check::Check;
use super::layout::{CheckOp, Layout, Op, StatusModel, Truncate, What};
use super::spec::{
    ByteOrder, CheckSpec, FieldSpec, MAX_FIELDS, MAX_FRAME_BYTES, Source, SpecError, TruncateSpec,
    compact,
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
                            _ => 0,
                        };
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
