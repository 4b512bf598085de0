//! The IMU-selection campaign (`imu_emu::nav::campaign`) for Python: the spec from a dict
//! (as JSON, field by field), its tasks, one task's run → a small summary (JSON text), the
//! merge of summaries in any order → the rows of `imu-emu compare`'s median/95 % table, the
//! table, the growth CSV and plot. A `Campaign` pickles as its spec, so a Dask worker rebuilds
//! it (`imu_emu.campaign` caches one per worker and spec).

use std::path::PathBuf;
use std::sync::Arc;

use pyo3::prelude::*;
use pyo3::types::PyTuple;

use imu_emu::nav::campaign::{self, CampaignSpec, Row, Summary, Task, report};

use crate::errors::{err, invalid};

/// A resolved campaign (missions built, templates loaded); see `imu_emu.campaign`.
#[pyclass(module = "imu_emu._native", frozen)]
pub struct Campaign {
    inner: Arc<campaign::Campaign>,
    spec_json: String,
}

/// Rows from their JSON text.
fn rows(json: &str) -> PyResult<Vec<Row>> {
    serde_json::from_str(json).map_err(|e| invalid(format!("rows: {e}")))
}

#[pymethods]
impl Campaign {
    /// Resolves the spec (JSON of `CampaignSpec`: missions, templates, rate_hz, duration_s,
    /// outages_s, runs, seed, points, aiding, aided_s); every refusal is raised here.
    #[new]
    fn new(py: Python<'_>, spec_json: String) -> PyResult<Campaign> {
        let spec: CampaignSpec =
            serde_json::from_str(&spec_json).map_err(|e| invalid(format!("campaign spec: {e}")))?;
        let inner = py.detach(|| campaign::Campaign::new(spec)).map_err(err)?;
        Ok(Campaign {
            inner: Arc::new(inner),
            spec_json,
        })
    }

    /// Pickles as the spec: a worker rebuilds the campaign from it.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let cls = py.get_type::<Campaign>().into_any();
        let args = PyTuple::new(py, [slf.get().spec_json.clone()])?;
        Ok((cls, args))
    }

    /// The spec as given (JSON).
    #[getter]
    fn spec_json(&self) -> String {
        self.spec_json.clone()
    }

    /// The master seed the runs' seeds derive from.
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.seed
    }

    /// Notes for the table's header (e.g. a scene file's `[gnss]` not used).
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.inner.notes.clone()
    }

    /// Mission names, and per mission its units' names and rates.
    fn missions(&self) -> Vec<(String, Vec<(String, f64)>)> {
        (self.inner.missions.iter())
            .map(|m| {
                let units = (m.units.iter())
                    .map(|(u, g)| (u.name.clone(), g.rate_hz))
                    .collect();
                (m.name.clone(), units)
            })
            .collect()
    }

    /// Whether a mission's runs are GNSS-aided.
    fn aided(&self, mission: usize) -> bool {
        self.inner
            .missions
            .get(mission)
            .is_some_and(|m| m.gnss.is_some())
    }

    /// Every task as (mission, unit, outage, run), in the merge's order.
    fn tasks(&self) -> Vec<(usize, usize, usize, usize)> {
        (self.inner.tasks().into_iter())
            .map(|t| (t.mission, t.unit, t.outage, t.run))
            .collect()
    }

    /// Runs one task (without the GIL); returns its summary as JSON text (a few kB).
    fn run_task(&self, py: Python<'_>, task: (usize, usize, usize, usize)) -> PyResult<String> {
        let (mission, unit, outage, run) = task;
        let t = Task {
            mission,
            unit,
            outage,
            run,
        };
        if !self.inner.tasks().contains(&t) {
            return Err(invalid(format!(
                "task {task:?} is not one of this campaign's"
            )));
        }
        let inner = self.inner.clone();
        let s = py.detach(move || inner.run_task(&t)).map_err(err)?;
        serde_json::to_string(&s).map_err(|e| invalid(e.to_string()))
    }

    /// Merges summaries (JSON texts, any order, every task once) into the rows (JSON text).
    fn merge(&self, py: Python<'_>, summaries: Vec<String>) -> PyResult<String> {
        let all = (summaries.iter())
            .map(|s| serde_json::from_str::<Summary>(s))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| invalid(format!("summary: {e}")))?;
        let inner = self.inner.clone();
        let rows = py.detach(move || inner.merge(all)).map_err(err)?;
        serde_json::to_string(&rows).map_err(|e| invalid(e.to_string()))
    }

    /// Every task on `threads` local threads, merged (`imu-emu compare`'s run); rows as JSON.
    fn run_local(&self, py: Python<'_>, threads: usize) -> PyResult<String> {
        let inner = self.inner.clone();
        let rows = py
            .detach(move || inner.run_local(threads.max(1)))
            .map_err(err)?;
        serde_json::to_string(&rows).map_err(|e| invalid(e.to_string()))
    }

    /// The lines `imu-emu compare` prints above the table for rows (JSON): what the runs
    /// were (mission, rates, mode, runs, seed), then the notes.
    fn header(&self, rows_json: &str) -> PyResult<String> {
        let rows = rows(rows_json)?;
        let name = (self.inner.missions.first()).map_or(String::new(), |m| m.name.clone());
        let mut s = report::header(&self.inner, &rows, &name);
        s.push('\n');
        for n in &self.inner.notes {
            s.push_str(&format!("note: {n}\n"));
        }
        Ok(s)
    }

    /// The growth plot's subtitle, as `imu-emu compare --plot` titles it.
    fn plot_title(&self) -> String {
        report::plot_title(&self.inner)
    }

    /// The median/95 % table of rows (JSON), as `imu-emu compare` prints it.
    #[staticmethod]
    fn table(rows_json: &str) -> PyResult<String> {
        Ok(report::table(&rows(rows_json)?))
    }

    /// The growth CSV of rows (JSON), as `imu-emu compare --csv` writes it.
    #[staticmethod]
    fn growth_csv(rows_json: &str) -> PyResult<String> {
        Ok(report::growth_csv(&rows(rows_json)?))
    }

    /// The growth plot of rows (JSON) to `path` (.png or .svg), as `imu-emu compare --plot`
    /// draws it; `what` is its subtitle (e.g. `60 s outages`).
    #[staticmethod]
    fn plot(py: Python<'_>, rows_json: &str, path: PathBuf, what: &str) -> PyResult<()> {
        let rows = rows(rows_json)?;
        let panels = report::growth_panels(&rows, what);
        py.detach(|| imu_emu::plot::render(&path, &panels, 1, (1200, 1500)))
            .map_err(err)
    }
}
