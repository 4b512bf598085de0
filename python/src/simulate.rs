//! `simulate`: one IMU's records from a scene file, a built-in scene, a trajectory file, a
//! motion definition or trajectory arrays, with its error-free truth, the error each stage
//! injected, and the main output's bytes (records or a protocol's frames) as `generate`
//! writes them.

use std::path::{Path, PathBuf};

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use imu_emu::csvio::{FileError, Place};
use imu_emu::errors::{Sensor, StageKind};
use imu_emu::motion::sampled::Sample;
use imu_emu::sim::{Simulation, SimulationBuilder};

use crate::errors::{err, invalid};

/// Names of the trajectory array columns, in the order of a trajectory CSV's.
const ARRAY_COLUMNS: [&str; 10] = [
    "t",
    "lat",
    "lon",
    "h",
    "v_ned[:, 0]",
    "v_ned[:, 1]",
    "v_ned[:, 2]",
    "rpy[:, 0]",
    "rpy[:, 1]",
    "rpy[:, 2]",
];

/// The label of trajectory arrays in messages.
const ARRAYS: &str = "trajectory arrays";

/// Trajectory rows (n × 10: t, lat°, lon°, h, v_N, v_E, v_D, roll°, pitch°, yaw°) as samples,
/// checked exactly as a trajectory file's lines are: the rows are written as CSV with
/// shortest round-trip decimals (which read back to the same doubles) and parsed by the
/// library's reader. A refusal names the row and array instead of a line and column.
fn samples(rows: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<Sample>> {
    let a = rows.as_array();
    if a.ncols() != 10 {
        return Err(invalid(format!(
            "{ARRAYS}: {} columns, expected 10 (t, lat, lon, h, v_ned ×3, rpy ×3)",
            a.ncols()
        )));
    }
    let mut text = String::with_capacity(a.nrows() * 200 + 64);
    text.push_str("t,lat,lon,h,vn,ve,vd,roll,pitch,yaw\n");
    let mut buf = ryu::Buffer::new();
    for row in a.rows() {
        for (i, v) in row.iter().enumerate() {
            if i > 0 {
                text.push(',');
            }
            // ryu prints NaN and inf as words the reader refuses with the row named.
            text.push_str(buf.format(*v));
        }
        text.push('\n');
    }
    imu_emu::trajectory::parse(&text, Path::new(ARRAYS)).map_err(|e| invalid(row_message(&e)))
}

/// A trajectory reader's error about the CSV made of the arrays, in terms of rows and arrays.
fn row_message(e: &FileError) -> String {
    let row = match e.place {
        // Line 1 is the header, line 2 row 0.
        Place::Line(l) if l >= 2 => format!(" row {}", l - 2),
        _ => String::new(),
    };
    let column = match &e.column {
        Some((i, _)) if (1..=10).contains(i) => format!(" `{}`", ARRAY_COLUMNS[i - 1]),
        _ => String::new(),
    };
    let sep = if row.is_empty() && column.is_empty() {
        ""
    } else {
        ","
    };
    format!("{ARRAYS}:{row}{sep}{column}: {}", e.message).replace(":,", ":")
}

/// The builder the arguments describe (see `imu_emu.simulate`).
#[allow(clippy::too_many_arguments)]
pub fn builder(
    scene: Option<String>,
    scene_file: Option<PathBuf>,
    trajectory: Option<PathBuf>,
    trajectory_rows: Option<Vec<Sample>>,
    motion_def: Option<PathBuf>,
    imu: Option<&Bound<'_, PyAny>>,
    settings: &Settings,
) -> PyResult<SimulationBuilder> {
    let given = [
        scene.is_some(),
        trajectory.is_some() || trajectory_rows.is_some(),
        motion_def.is_some(),
    ];
    if given.iter().filter(|g| **g).count() > 1 {
        return Err(invalid(
            "give one of scene, trajectory and motion_def (a scene_file may come with any)",
        ));
    }
    let mut b = match &scene_file {
        Some(p) => Simulation::from_scene_file(p).map_err(err)?,
        None => Simulation::builder(),
    };
    b = b.defaults("ideal", "csv");
    if let Some(s) = scene {
        b = b.scene(s);
    }
    if let Some(p) = trajectory {
        b = b.trajectory(p);
    }
    if let Some(rows) = trajectory_rows {
        b = b.trajectory_samples(ARRAYS, rows);
    }
    if let Some(p) = motion_def {
        b = b.motion_def(p);
    }
    if let Some(imu) = imu {
        if let Ok(d) = imu.cast::<PyDict>() {
            b = b.imu_model(crate::template::model_from_dict(d)?);
        } else if let Ok(name) = imu.extract::<PathBuf>() {
            b = b.imu(name.to_string_lossy().into_owned());
        } else {
            return Err(invalid(format!(
                "imu: {} is not a template name, a template file or a dict",
                imu.get_type().name()?
            )));
        }
    }
    settings.apply(b)
}

/// The settings every entry point shares (rate, span, seed, output format, model).
#[derive(Default)]
pub struct Settings {
    pub rate: Option<f64>,
    pub duration: Option<f64>,
    pub start: Option<f64>,
    pub seed: Option<u64>,
    pub format: Option<String>,
    pub protocol_file: Option<PathBuf>,
    pub interpolation: Option<String>,
    pub stencil: Option<usize>,
    pub quadrature: Option<usize>,
}

impl Settings {
    /// `b` with these settings over its scene file's.
    fn apply(&self, mut b: SimulationBuilder) -> PyResult<SimulationBuilder> {
        if let Some(r) = self.rate {
            b = b.rate(r);
        }
        if let Some(d) = self.duration {
            b = b.duration(d);
        }
        if let Some(s) = self.start {
            b = b.start(s);
        }
        if let Some(s) = self.seed {
            b = b.seed(s);
        }
        if let Some(f) = &self.format {
            b = b.format(f.clone());
        }
        if let Some(p) = &self.protocol_file {
            b = b.protocol_file(p.clone());
        }
        if let Some(i) = &self.interpolation {
            b = b.interpolation(i.clone());
        }
        if let Some(s) = self.stencil {
            b = b.stencil(s);
        }
        if let Some(q) = self.quadrature {
            b = b.quadrature_nodes(q);
        }
        Ok(b)
    }
}

/// What one simulation produced, in flat buffers (row-major) until handed to numpy.
struct Produced {
    records: Vec<f64>,
    /// t, lat°, lon°, h, v_N, v_E, v_D, roll°, pitch°, yaw° at t₀ + k/rate, k = 0 ..= count.
    pose: Vec<f64>,
    truth: Vec<f64>,
    errors: Vec<f64>,
    output: Vec<u8>,
    rate: f64,
    seed: u64,
    imu: String,
    warnings: Vec<String>,
}

/// Values per injected-error row: t, then gyro and accel xyz per stage kind.
const ERROR_WIDTH: usize = 1 + 6 * StageKind::ALL.len();

/// Records one call returns at most: its arrays are held in memory, where `imu-emu generate`
/// streams to a file. 2^25 is 9.3 h at 1 kHz, 3.5 GB for each 13-column array; rate=1e5,
/// duration=1e4 once asked for 10^9 records and aborted the interpreter.
pub const MAX_RECORDS: u64 = 1 << 25;

/// Bytes of the main output per record at most, for the estimate of what a call holds (a
/// CSV line of 13 shortest round-trip numbers; a binary record or a frame is shorter).
const OUTPUT_BYTES: u64 = 13 * 25;

/// Refuses a call of `count` records beyond [`MAX_RECORDS`] (`ImuEmuError`), or whose arrays
/// (`per_record` bytes each, with the output) need more memory than the machine has
/// available (`MemoryError`), before anything is allocated.
fn check_size(count: u64, per_record: u64) -> PyResult<()> {
    if count > MAX_RECORDS {
        return Err(invalid(format!(
            "rate × duration make {count} records, more than the {MAX_RECORDS} (2^25) one call returns in memory: lower the rate, shorten the duration, or write them to a file with `imu-emu generate`, which streams"
        )));
    }
    let need = count.saturating_mul(per_record + OUTPUT_BYTES);
    if let Some(free) = available_memory()
        && need > free
    {
        return Err(PyMemoryError::new_err(format!(
            "{count} records need about {} MB of arrays, more than the {} MB of memory available",
            need >> 20,
            free >> 20
        )));
    }
    Ok(())
}

/// The memory the kernel says is available to a new allocation without swapping (bytes);
/// `None` where it does not say (not Linux).
fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Runs the simulation into flat buffers (no Python object touched: runs without the GIL).
fn produce(b: SimulationBuilder, truth: bool, errors: bool, pose: bool) -> PyResult<Produced> {
    if b.is_rig() {
        return Err(invalid(
            "the scene file lists `[[imu]]` units (a rig): simulate runs one IMU; run the rig with `imu_emu.LiveRun` or the CLI",
        ));
    }
    let sim = b.build().map_err(err)?;
    let (rate, seed, imu) = (sim.grid().rate_hz, sim.seed(), sim.imu().name.clone());
    let warnings = sim.warnings().to_vec();
    let widths = 13 + 13 * usize::from(truth) + ERROR_WIDTH * usize::from(errors);
    let per_record = 8 * (widths + 10 * usize::from(pose)) as u64;
    check_size(sim.grid().count, per_record)?;
    let count = sim.grid().count as usize;
    let poses = if pose { poses(&sim) } else { Vec::new() };
    let mut p = sim.producer().map_err(err)?;
    if errors {
        p = p.with_components();
    }
    p.set_keep_truth(truth);
    let mut out = Produced {
        records: Vec::with_capacity(count * 13),
        pose: poses,
        truth: Vec::with_capacity(if truth { count * 13 } else { 0 }),
        errors: Vec::with_capacity(if errors { count * ERROR_WIDTH } else { 0 }),
        output: p.preamble().into_bytes(),
        rate,
        seed,
        imu,
        warnings,
    };
    let mut ends = Vec::new();
    let mut buf = Vec::new();
    while let Some(b) = p.next_block(imu_emu::engine::BLOCK, &mut buf, &mut ends) {
        for r in b.records {
            out.records.extend_from_slice(&r.values());
        }
        for r in b.truth {
            out.truth.extend_from_slice(&r.values());
        }
        for (r, c) in b.records.iter().zip(b.components) {
            out.errors.push(r.t);
            for kind in &c.0 {
                for v in kind {
                    out.errors.extend_from_slice(v.as_slice());
                }
            }
        }
        out.output.extend_from_slice(&buf);
        buf.clear();
        ends.clear();
    }
    p.finished().map_err(err)?;
    Ok(out)
}

/// The truth trajectory at t₀ + k/rate, k = 0 ..= count (as `imu-emu trajectory --rate`
/// samples it: degrees for angles), 10 values per row.
fn poses(sim: &Simulation) -> Vec<f64> {
    use imu_emu::motion::Motion;
    let g = sim.grid();
    let mut v = Vec::with_capacity((g.count as usize + 1) * 10);
    for k in 0..=g.count {
        let p = sim.motion().pose(g.t0 + k as f64 / g.rate_hz);
        let (r, pi, y) = imu_emu::math::euler_from_quat(p.q_b_n);
        v.extend_from_slice(&[
            p.t,
            p.lat.to_degrees(),
            p.lon.to_degrees(),
            p.h,
            p.v_n.x,
            p.v_n.y,
            p.v_n.z,
            r.to_degrees(),
            pi.to_degrees(),
            y.to_degrees(),
        ]);
    }
    v
}

/// A row-major buffer of `width` columns as a numpy array that owns it (no copy).
fn array<'py>(py: Python<'py>, v: Vec<f64>, width: usize) -> PyResult<Bound<'py, PyAny>> {
    let rows = v.len() / width;
    let a = Array2::from_shape_vec((rows, width), v).map_err(|e| invalid(e.to_string()))?;
    Ok(a.into_pyarray(py).into_any())
}

/// The injected-error column names after `t`: `KIND_SENSOR_AXIS`, as `--truth-errors` writes.
fn error_columns() -> Vec<String> {
    let mut cols = Vec::new();
    for k in StageKind::ALL {
        for s in Sensor::BOTH {
            for a in ["x", "y", "z"] {
                cols.push(format!("{}_{}_{a}", k.name(), s.name()));
            }
        }
    }
    cols
}

/// Simulates one IMU; see `imu_emu.simulate` for the arguments and the result.
#[pyfunction]
#[pyo3(signature = (
    scene=None, *, scene_file=None, trajectory=None, trajectory_rows=None, motion_def=None,
    imu=None, rate=None, duration=None, start=None, seed=None, format=None, protocol_file=None,
    interpolation=None, stencil=None, quadrature=None, truth=true, errors=true, pose=false
))]
#[allow(clippy::too_many_arguments)]
pub fn simulate<'py>(
    py: Python<'py>,
    scene: Option<String>,
    scene_file: Option<PathBuf>,
    trajectory: Option<PathBuf>,
    trajectory_rows: Option<PyReadonlyArray2<'py, f64>>,
    motion_def: Option<PathBuf>,
    imu: Option<Bound<'py, PyAny>>,
    rate: Option<f64>,
    duration: Option<f64>,
    start: Option<f64>,
    seed: Option<u64>,
    format: Option<String>,
    protocol_file: Option<PathBuf>,
    interpolation: Option<String>,
    stencil: Option<usize>,
    quadrature: Option<usize>,
    truth: bool,
    errors: bool,
    pose: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let rows = trajectory_rows.as_ref().map(samples).transpose()?;
    let settings = Settings {
        rate,
        duration,
        start,
        seed,
        format,
        protocol_file,
        interpolation,
        stencil,
        quadrature,
    };
    let b = builder(
        scene,
        scene_file,
        trajectory,
        rows,
        motion_def,
        imu.as_ref(),
        &settings,
    )?;
    let p = py.detach(|| produce(b, truth, errors, pose))?;
    let d = PyDict::new(py);
    d.set_item("records", array(py, p.records, 13)?)?;
    if truth {
        d.set_item("truth", array(py, p.truth, 13)?)?;
    }
    if errors {
        d.set_item("errors", array(py, p.errors, ERROR_WIDTH)?)?;
        d.set_item("error_columns", error_columns())?;
    }
    if pose {
        d.set_item("pose", array(py, p.pose, 10)?)?;
    }
    d.set_item("output", PyBytes::new(py, &p.output))?;
    d.set_item("rate", p.rate)?;
    d.set_item("seed", p.seed)?;
    d.set_item("imu", p.imu)?;
    d.set_item("warnings", p.warnings)?;
    Ok(d)
}

/// The built-in scenes, templates and protocols.
#[pyfunction]
pub fn names<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("scenes", imu_emu::scenes::NAMES.to_vec())?;
    d.set_item("templates", imu_emu::errors::template::builtin_names())?;
    d.set_item("protocols", imu_emu::protocol::builtin_names())?;
    Ok(d)
}
