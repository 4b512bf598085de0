//! `analyze` (statistics, octave Allan deviation with its χ² bands, Welch PSD, IEEE terms,
//! the verdict against a template) and `fit` (a template fitted to a static recording), on
//! records in memory or a recording file, as `imu-emu analyze` and `imu-emu fit` compute them.

use std::path::PathBuf;

use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use imu_emu::analysis::analyzer::{Analysis, CHANNELS};
use imu_emu::analysis::passes::{First, Passes, Sink};
use imu_emu::analysis::recording::Recording;

use crate::errors::{err, invalid};

/// Where the samples come from.
enum Input {
    /// Rows of t, gyro xyz, accel xyz (the first 7 columns of records).
    Rows(Vec<[f64; 7]>),
    /// A recording file in `format` (csv, bin or a protocol; None: by extension).
    File(PathBuf, Option<String>),
}

/// The input described by the arguments: an array or a file.
fn input(
    records: Option<PyReadonlyArray2<'_, f64>>,
    path: Option<PathBuf>,
    format: Option<String>,
) -> PyResult<(Input, String)> {
    match (records, path) {
        (Some(r), None) => {
            let a = r.as_array();
            if a.ncols() < 7 {
                return Err(invalid(format!(
                    "records: {} columns, expected at least 7 (t, gyro ×3, accel ×3, …)",
                    a.ncols()
                )));
            }
            let rows: Vec<[f64; 7]> = a
                .rows()
                .into_iter()
                .map(|r| std::array::from_fn(|i| r[i]))
                .collect();
            check_rows(&rows)?;
            Ok((Input::Rows(rows), "records".into()))
        }
        (None, Some(p)) => {
            let name = p.display().to_string();
            Ok((Input::File(p, format), name))
        }
        _ => Err(invalid(
            "give records (an array) or a recording file, not both",
        )),
    }
}

/// Refuses a row the CLI refuses in a recording file: a NaN or ±∞ (which would be every
/// statistic of its channel), or a rate no sensor measures; names the row and column.
fn check_rows(rows: &[[f64; 7]]) -> PyResult<()> {
    const NAMES: [&str; 7] = [
        "t", "gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z",
    ];
    for (k, r) in rows.iter().enumerate() {
        if let Some(i) = r.iter().position(|v| !v.is_finite()) {
            return Err(invalid(format!(
                "records: row {k}, column {i} ({}): {} is not a finite number",
                NAMES[i], r[i]
            )));
        }
        let v = std::array::from_fn(|i| r[i + 1]);
        if let Some((i, why)) = imu_emu::analysis::reader::implausible(&v) {
            return Err(invalid(format!(
                "records: row {k}, column {}: {why}",
                i + 1
            )));
        }
    }
    Ok(())
}

/// Reads the input through an analyzer, as the CLI's `InputArgs::analyze` does: transients
/// (knocks, spikes) found and left out of the statistics unless `keep_transients`.
fn analysis(
    input: &Input,
    rate: Option<f64>,
    segment: usize,
    keep_transients: bool,
) -> Result<Analysis, String> {
    if let Some(r) = rate {
        imu_emu::analysis::analyzer::check_rate(r)?;
    }
    imu_emu::analysis::analyzer::check_segment(segment)?;
    let rows = match input {
        Input::Rows(rows) => rows,
        Input::File(p, format) => {
            // The CLI's reader: a CSV of some axes, transients found and left out.
            let mut r = Recording::new(p.clone(), format.clone());
            r.rate = rate;
            r.keep_transients = keep_transients;
            return r
                .read(segment)
                .map(|read| read.analysis)
                .map_err(|e| crate::errors::message(&e));
        }
    };
    let replay = |sink: &mut Sink<'_>| {
        for r in rows {
            sink(r[0], &std::array::from_fn(|i| r[i + 1]));
        }
        Ok::<u64, String>(rows.len() as u64)
    };
    let mut first = First::new(segment);
    replay(&mut |t, v| first.push(t, v))?;
    if first.analyzer.samples() < 8 {
        return Err(format!(
            "records: {} samples; the analysis needs at least 8",
            first.analyzer.samples()
        ));
    }
    let dt = match (rate, first.analyzer.measured_dt()) {
        (Some(r), _) => 1.0 / r,
        (None, Some(dt)) => dt,
        (None, None) => {
            return Err(
                "records: no usable time column; give the sampling rate with rate=".to_string(),
            );
        }
    };
    let passes = Passes {
        segment,
        keep: keep_transients,
        missing: [false; 6],
        dt_given: rate.is_some(),
    };
    Ok(passes.finish(first, dt, "records", Ok(replay))?.0)
}

/// The record's transients as `analyze` returns them: None, or what was done with them and
/// each one (its first and last samples, the channel of its largest step, that step in the
/// channel's unit and in its step scales).
fn transients<'py>(py: Python<'py>, a: &Analysis) -> PyResult<Option<Bound<'py, PyDict>>> {
    use imu_emu::analysis::transients::Handling;
    let Some(t) = &a.transients else {
        return Ok(None);
    };
    let d = PyDict::new(py);
    let handling = match t.handling {
        Handling::LeftOut => "left out",
        Handling::Kept => "kept",
        Handling::HeavyTailed => "heavy-tailed",
    };
    d.set_item("handling", handling)?;
    d.set_item("threshold", t.z)?;
    d.set_item("left_out", t.left_out())?;
    let list = PyList::empty(py);
    for x in &t.list {
        let e = PyDict::new(py);
        e.set_item("first", x.first)?;
        e.set_item("last", x.last)?;
        e.set_item("channel", CHANNELS[x.channel])?;
        e.set_item("step", x.step)?;
        e.set_item("z", x.z)?;
        list.append(e)?;
    }
    d.set_item("list", list)?;
    Ok(Some(d))
}

/// Analyses records or a recording; see `imu_emu.analyze`.
#[pyfunction]
#[pyo3(signature = (records=None, *, path=None, format=None, rate=None, imu=None, segment=imu_emu::analysis::analyzer::DEFAULT_SEGMENT, keep_transients=false))]
#[allow(clippy::too_many_arguments)]
pub fn analyze<'py>(
    py: Python<'py>,
    records: Option<PyReadonlyArray2<'py, f64>>,
    path: Option<PathBuf>,
    format: Option<String>,
    rate: Option<f64>,
    imu: Option<String>,
    segment: usize,
    keep_transients: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let (inp, _) = input(records, path, format)?;
    let model = imu
        .as_deref()
        .map(imu_emu::errors::template::load)
        .transpose()
        .map_err(err)?;
    let (res, rows) = py
        .detach(|| {
            let res = analysis(&inp, rate, segment, keep_transients)?;
            let rows = model
                .as_ref()
                .map(|m| imu_emu::analysis::conformance::term_rows(m, &res));
            Ok::<_, String>((res, rows))
        })
        .map_err(invalid)?;
    let d = PyDict::new(py);
    d.set_item("samples", res.samples)?;
    d.set_item("dt", res.dt)?;
    let channels = PyList::empty(py);
    for (i, c) in res.channels.iter().enumerate() {
        let ch = PyDict::new(py);
        ch.set_item("name", CHANNELS[i])?;
        ch.set_item("mean", c.stats.mean)?;
        ch.set_item("std", c.stats.std())?;
        ch.set_item("min", c.stats.min)?;
        ch.set_item("max", c.stats.max)?;
        let col = |f: fn(&imu_emu::analysis::octave_adev::AdevPoint) -> f64| {
            c.adev.iter().map(f).collect::<Vec<f64>>().into_pyarray(py)
        };
        let adev = PyDict::new(py);
        adev.set_item("tau", col(|p| p.tau))?;
        adev.set_item("adev", col(|p| p.adev))?;
        adev.set_item("lo", col(|p| p.lo))?;
        adev.set_item("hi", col(|p| p.hi))?;
        adev.set_item("edf", col(|p| p.edf))?;
        ch.set_item("adev", adev)?;
        let psd = PyDict::new(py);
        psd.set_item("freq", c.psd.freq.clone().into_pyarray(py))?;
        psd.set_item("density", c.psd.density.clone().into_pyarray(py))?;
        psd.set_item("segments", c.psd.segments)?;
        ch.set_item("psd", psd)?;
        let terms = PyDict::new(py);
        for t in c.fit.terms {
            let e = PyDict::new(py);
            e.set_item("name", t.term.name())?;
            e.set_item("value", t.value)?;
            e.set_item("tau", t.tau)?;
            e.set_item("share", t.share)?;
            terms.set_item(t.term.symbol(), e)?;
        }
        ch.set_item("terms", terms)?;
        channels.append(ch)?;
    }
    d.set_item("channels", channels)?;
    d.set_item("transients", transients(py, &res)?)?;
    if let Some(rows) = rows {
        let list = PyList::empty(py);
        for r in rows {
            let e = PyDict::new(py);
            e.set_item("sensor", r.sensor)?;
            e.set_item("axis", r.axis)?;
            e.set_item("term", r.term.symbol())?;
            e.set_item("specified", r.specified)?;
            e.set_item("fitted", r.fitted)?;
            e.set_item("tau", r.tau)?;
            e.set_item("band", r.band)?;
            e.set_item("pass", r.pass)?;
            e.set_item("resolved", r.resolved)?;
            list.append(e)?;
        }
        d.set_item("template", list)?;
    }
    Ok(d)
}

/// Fits a template to a static recording; see `imu_emu.fit`.
#[pyfunction]
#[pyo3(signature = (records=None, *, path=None, format=None, rate=None, name=None, segment=imu_emu::analysis::analyzer::DEFAULT_SEGMENT, keep_transients=false))]
#[allow(clippy::too_many_arguments)]
pub fn fit(
    py: Python<'_>,
    records: Option<PyReadonlyArray2<'_, f64>>,
    path: Option<PathBuf>,
    format: Option<String>,
    rate: Option<f64>,
    name: Option<String>,
    segment: usize,
    keep_transients: bool,
) -> PyResult<String> {
    use imu_emu::fit::recording_fit::{self, Settings};
    let (inp, source) = input(records, path, format)?;
    py.detach(|| {
        let rec = analysis(&inp, rate, segment, keep_transients)?;
        // `imu-emu fit`'s fit (lines, resonances, filter, LSB), without its closure check.
        let settings = Settings {
            name: name.unwrap_or_else(|| "fitted".into()),
            source,
            template_path: PathBuf::from("fitted.toml"),
            closure: false,
            seed: 1,
            segment,
            plot: None,
        };
        let fitted = recording_fit::fit(&rec, &settings).map_err(|e| crate::errors::message(&e))?;
        Ok::<String, String>(fitted.toml)
    })
    .map_err(invalid)
}
