//! `analyze` (statistics, octave Allan deviation with its χ² bands, Welch PSD, IEEE terms,
//! the verdict against a template) and `fit` (a template fitted to a static recording), on
//! records in memory or a recording file, as `imu-emu analyze` and `imu-emu fit` compute them.

use std::path::PathBuf;

use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use imu_emu::analysis::analyzer::{Analysis, Analyzer, CHANNELS};
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
            let rows = a
                .rows()
                .into_iter()
                .map(|r| std::array::from_fn(|i| r[i]))
                .collect();
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

/// Reads the input through an analyzer, as the CLI's `InputArgs::analyze` does.
fn analysis(input: &Input, rate: Option<f64>, segment: usize) -> Result<Analysis, String> {
    if let Some(r) = rate
        && !(r > 0.0 && r.is_finite())
    {
        return Err(format!("rate: expected a positive number of Hz, got {r}"));
    }
    let mut an = Analyzer::new(segment);
    let label = match input {
        Input::Rows(rows) => {
            for r in rows {
                an.push(r[0], &std::array::from_fn(|i| r[i + 1]));
            }
            "records"
        }
        Input::File(p, format) => {
            // The CLI's reader: a CSV of some axes, transients found and left out.
            let mut r = Recording::new(p.clone(), format.clone());
            r.rate = rate;
            return r
                .read(segment)
                .map(|read| read.analysis)
                .map_err(|e| crate::errors::message(&e));
        }
    };
    if an.samples() < 8 {
        return Err(format!(
            "{label}: {} samples; the analysis needs at least 8",
            an.samples()
        ));
    }
    let dt = match (rate, an.measured_dt()) {
        (Some(r), _) => 1.0 / r,
        (None, Some(dt)) => dt,
        (None, None) => {
            return Err(format!(
                "{label}: no usable time column; give the sampling rate with rate="
            ));
        }
    };
    Ok(an.finish(dt))
}

/// Analyses records or a recording; see `imu_emu.analyze`.
#[pyfunction]
#[pyo3(signature = (records=None, *, path=None, format=None, rate=None, imu=None, segment=imu_emu::analysis::analyzer::DEFAULT_SEGMENT))]
pub fn analyze<'py>(
    py: Python<'py>,
    records: Option<PyReadonlyArray2<'py, f64>>,
    path: Option<PathBuf>,
    format: Option<String>,
    rate: Option<f64>,
    imu: Option<String>,
    segment: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let (inp, _) = input(records, path, format)?;
    let model = imu
        .as_deref()
        .map(imu_emu::errors::template::load)
        .transpose()
        .map_err(err)?;
    let (res, rows) = py
        .detach(|| {
            let res = analysis(&inp, rate, segment)?;
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
#[pyo3(signature = (records=None, *, path=None, format=None, rate=None, name=None, segment=imu_emu::analysis::analyzer::DEFAULT_SEGMENT))]
pub fn fit(
    py: Python<'_>,
    records: Option<PyReadonlyArray2<'_, f64>>,
    path: Option<PathBuf>,
    format: Option<String>,
    rate: Option<f64>,
    name: Option<String>,
    segment: usize,
) -> PyResult<String> {
    use imu_emu::fit::recording_fit::{self, Settings};
    let (inp, source) = input(records, path, format)?;
    py.detach(|| {
        let rec = analysis(&inp, rate, segment)?;
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
