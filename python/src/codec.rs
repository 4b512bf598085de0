//! `encode` and `decode`: records to a protocol's frames and frames back, as `generate
//! --format NAME` writes them and `imu-emu decode` reads them.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use imu_emu::protocol::{Decoded, EncoderState, Plan, StreamDecoder};
use imu_emu::record::Record;

use crate::errors::{err, invalid};

/// The compiled protocol `protocol` (a built-in name or a spec file), at `rate` when given
/// (`"nominal"`: the spec's own rate).
fn plan(protocol: &str, rate: Option<&Bound<'_, PyAny>>) -> PyResult<(Plan, Option<f64>)> {
    let (_, mut plan) = imu_emu::protocol::load(protocol).map_err(err)?;
    let rate = match rate {
        None => None,
        Some(r) if r.extract::<String>().is_ok_and(|s| s == "nominal") => {
            Some(plan.rate_hz.ok_or_else(|| {
                invalid(format!(
                    "rate='nominal': the `{}` spec gives no nominal rate (`rate_hz`); give the stream's rate in Hz",
                    plan.name
                ))
            })?)
        }
        Some(r) => Some(r.extract::<f64>().map_err(|_| {
            invalid("rate: expected a rate in Hz or 'nominal'")
        })?),
    };
    if let Some(r) = rate {
        plan.set_rate(r)
            .map_err(|e| invalid(format!("rate: {e}")))?;
    }
    Ok((plan, rate))
}

/// Encodes records (n × 13: t, gyro, accel, dtheta, dv as `simulate` returns them) as frames
/// of `protocol`; see `imu_emu.encode`.
#[pyfunction]
#[pyo3(signature = (records, protocol, *, rate=None, temperature=25.0, gps_time=None))]
pub fn encode<'py>(
    py: Python<'py>,
    records: PyReadonlyArray2<'py, f64>,
    protocol: &str,
    rate: Option<Bound<'py, PyAny>>,
    temperature: f64,
    gps_time: Option<(u32, f64)>,
) -> PyResult<Bound<'py, PyBytes>> {
    let (plan, _) = plan(protocol, rate.as_ref())?;
    if let Some((g, a)) = plan.channels() {
        return Err(invalid(format!(
            "protocol `{}` carries {g} gyro and {a} accelerometer single-axis channels: not a record's triads",
            plan.name
        )));
    }
    let a = records.as_array();
    if a.ncols() != 13 {
        return Err(invalid(format!(
            "records: {} columns, expected 13 (t, gyro ×3, accel ×3, dtheta ×3, dv ×3)",
            a.ncols()
        )));
    }
    let rows: Vec<[f64; 13]> = a
        .rows()
        .into_iter()
        .map(|r| std::array::from_fn(|i| r[i]))
        .collect();
    // The producer never hands the encoder a value that is not a number; a NaN sent as 0
    // would read as a measurement of 0 wherever the protocol has no failure bit.
    for (k, r) in rows.iter().enumerate() {
        if let Some(i) = r.iter().position(|v| !v.is_finite()) {
            return Err(invalid(format!(
                "records: row {k}, column {i} (`{}`): {} is not a finite number",
                imu_emu::record::COLUMNS[i],
                r[i]
            )));
        }
    }
    let bytes = py.detach(|| {
        let mut state = EncoderState {
            gps_week0: gps_time.map_or(0, |g| g.0),
            gps_sow0: gps_time.map_or(0.0, |g| g.1),
            ..Default::default()
        };
        let mut out = Vec::with_capacity(rows.len() * plan.max_len());
        for (k, v) in rows.iter().enumerate() {
            plan.encode(&Record::from_values(v), temperature, &mut state, &mut out);
            // Clipped without a status bit, the value would read as a measurement of the
            // field's limit; a protocol with such bits sets them, as the CLI's frames do.
            if state.unreported > 0 {
                return Err(invalid(format!(
                    "records: row {k}: a value beyond the range of a `{}` field, whose frames have no status bit to report it (they would carry the field's limit as a measurement)",
                    plan.name
                )));
            }
        }
        Ok(out)
    })?;
    Ok(PyBytes::new(py, &bytes))
}

/// What decoding a byte stream gave: the column names, one row per good frame (NaN where the
/// frame has no value), its message index, and the tally.
struct Table {
    columns: Vec<String>,
    values: Vec<f64>,
    message: Vec<i64>,
    messages: Vec<String>,
    stats: imu_emu::protocol::StreamStats,
}

/// Decodes `data` with `plan` as `imu-emu decode` does: the record contract columns (unless
/// `native` or an N-channel frame), then every message's other fields merged by name.
fn decode_table(plan: Plan, data: &[u8], fixed_dt: Option<f64>, native: bool) -> Table {
    let contract = !native && plan.channels().is_none();
    let (columns, slots) = imu_emu::decode::columns(&plan, contract);
    let messages = (0..plan.messages())
        .map(|m| plan.message_name(m).to_string())
        .collect();
    let mut rows: Vec<(usize, Vec<Option<f64>>)> = Vec::new();
    let mut interval = imu_emu::protocol::FrameInterval::default();
    let width = columns.len();
    let mut each = |d: &Decoded| {
        let mut cells = vec![None; width];
        if contract {
            let dt = fixed_dt.or_else(|| interval.observe(d));
            cells[..13].copy_from_slice(&d.contract(dt));
        }
        for (slot, (_, v)) in slots[d.message].iter().zip(&d.values) {
            if let Some(i) = slot {
                cells[*i] = Some(*v);
            }
        }
        rows.push((d.message, cells));
    };
    let mut dec = StreamDecoder::new(plan);
    dec.feed(data, &mut each);
    dec.finish_frames(&mut each);
    let stats = dec.stats();
    Table {
        values: rows
            .iter()
            .flat_map(|r| r.1.iter().map(|c| c.unwrap_or(f64::NAN)))
            .collect(),
        message: rows.iter().map(|r| r.0 as i64).collect(),
        columns,
        messages,
        stats,
    }
}

/// Decodes a byte stream of `protocol` frames; see `imu_emu.decode`.
#[pyfunction]
#[pyo3(signature = (data, protocol, *, rate=None, native=false))]
pub fn decode<'py>(
    py: Python<'py>,
    data: &[u8],
    protocol: &str,
    rate: Option<Bound<'py, PyAny>>,
    native: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let (plan, rate) = plan(protocol, rate.as_ref())?;
    // The interval of the record columns a frame lacks: the rate given, else the time tags.
    let fixed_dt = rate.map(|r| 1.0 / r);
    let name = plan.name.clone();
    let t = py.detach(|| decode_table(plan, data, fixed_dt, native));
    if t.stats.frames == 0 {
        return Err(invalid(format!("no valid `{name}` frame in the input")));
    }
    let width = t.columns.len();
    let n = t.message.len();
    let d = PyDict::new(py);
    let values =
        Array2::from_shape_vec((n, width), t.values).map_err(|e| invalid(e.to_string()))?;
    d.set_item("columns", t.columns)?;
    d.set_item("values", values.into_pyarray(py))?;
    d.set_item("message", t.message.into_pyarray(py))?;
    d.set_item("messages", t.messages)?;
    let s = &t.stats;
    let stats = PyDict::new(py);
    for (k, v) in [
        ("frames", s.frames),
        ("check_failures", s.check_failures),
        ("counter_gaps", s.counter_gaps),
        ("duplicates", s.duplicates),
        ("stale_counters", s.stale_counters),
        ("status_flagged", s.status_flagged),
        ("skipped_bytes", s.skipped_bytes),
        ("framing_errors", s.framing_errors),
        ("truncated", s.truncated),
    ] {
        stats.set_item(k, v)?;
    }
    d.set_item("stats", stats)?;
    Ok(d)
}
