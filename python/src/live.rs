//! The live emulator from Python: a paced run (the library's `RunSpec` → `Run`) on a thread
//! of its own, with the `Control` that stops it. `imu_emu.Emulator` wraps it in a context
//! manager.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use imu_emu::output::SinkAddr;
use imu_emu::run::{Control, RunError, RunReport, RunSpec, Speed, StreamId};

use crate::errors::{err, invalid};
use crate::simulate::{Settings, builder};

/// A paced run of one IMU (or a scene file's rig) to its sinks, started by `start()` and
/// stopped by `stop()`; see `imu_emu.Emulator`.
#[pyclass(module = "imu_emu._native")]
pub struct LiveRun {
    spec: Option<RunSpec>,
    ctl: Control,
    notes: Arc<Mutex<Vec<String>>>,
    thread: Option<JoinHandle<Result<RunReport, RunError>>>,
    report: Option<Result<RunReport, String>>,
}

#[pymethods]
impl LiveRun {
    /// Describes the run; nothing is opened until `start()`.
    #[new]
    #[pyo3(signature = (
        scene=None, *, scene_file=None, trajectory=None, motion_def=None, imu=None, format=None,
        sinks=None, speed=1.0, rate=None, duration=None, seed=None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        scene: Option<String>,
        scene_file: Option<PathBuf>,
        trajectory: Option<PathBuf>,
        motion_def: Option<PathBuf>,
        imu: Option<Bound<'_, PyAny>>,
        format: Option<String>,
        sinks: Option<Vec<String>>,
        speed: f64,
        rate: Option<f64>,
        duration: Option<f64>,
        seed: Option<u64>,
    ) -> PyResult<LiveRun> {
        let settings = Settings {
            rate,
            duration,
            seed,
            format,
            ..Settings::default()
        };
        let b = builder(
            scene,
            scene_file,
            trajectory,
            None,
            motion_def,
            imu.as_ref(),
            &settings,
        )?;
        let b = b.defaults("ln200", "ln200");
        let mut spec = RunSpec::from_signal(b).map_err(err)?;
        if let Some(sinks) = sinks {
            spec.replace_routes(|s| matches!(s, StreamId::Unit { unit: None, .. }));
            for v in sinks {
                let (addr, protocol) = imu_emu::output::SinkAddr::parse_with_protocol(&v)
                    .map_err(|e| invalid(format!("sink `{v}`: {e}")))?;
                let stream = StreamId::Unit {
                    unit: None,
                    protocol,
                };
                spec.add_route(stream, addr, format!("sinks: `{v}`"));
            }
        }
        if !(speed > 0.0 && speed.is_finite()) {
            return Err(invalid(format!(
                "speed {speed}: expected a positive factor of real time (1 = real time)"
            )));
        }
        if !spec.signal.is_rig() && spec.routes.is_empty() {
            spec.add_route(
                StreamId::imu(),
                SinkAddr::Pty(None),
                "the default pty".into(),
            );
        }
        spec.clock.speed = Some(Speed::Factor(speed));
        Ok(LiveRun {
            spec: Some(spec),
            ctl: Control::new(),
            notes: Arc::default(),
            thread: None,
            report: None,
        })
    }

    /// Builds the run (every refusal is raised here, before anything is opened) and starts it
    /// on a thread; returns the run's description (`imu-emu run --describe`).
    fn start(&mut self, py: Python<'_>) -> PyResult<String> {
        let spec = self
            .spec
            .take()
            .ok_or_else(|| invalid("the run was already started"))?;
        let run = py.detach(|| spec.build()).map_err(err)?;
        let describe = run.describe();
        let notes = self.notes.clone();
        self.ctl = Control::with_notes(move |n| {
            notes
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(n.to_string())
        });
        let ctl = self.ctl.clone();
        self.thread = Some(std::thread::spawn(move || run.execute(&ctl)));
        Ok(describe)
    }

    /// Asks the run to stop at its next frame (it keeps its sinks' frames sent so far).
    fn stop(&self) {
        self.ctl.stop();
    }

    /// Whether the run's thread has ended.
    fn finished(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Waits (without the GIL) until the run ends or `timeout` seconds pass; returns the
    /// report (`None` on a timeout). A run that failed raises its error.
    #[pyo3(signature = (timeout=None))]
    fn wait<'py>(
        &mut self,
        py: Python<'py>,
        timeout: Option<f64>,
    ) -> PyResult<Option<Bound<'py, PyDict>>> {
        if let Some(t) = self.thread.take() {
            let deadline = timeout.map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
            let done = py.detach(|| {
                while !t.is_finished() {
                    if deadline.is_some_and(|d| Instant::now() >= d) {
                        return false;
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
                true
            });
            if !done {
                self.thread = Some(t);
                return Ok(None);
            }
            let r = t
                .join()
                .unwrap_or_else(|_| {
                    Err(RunError::io(
                        "the run",
                        std::io::Error::other("the run's thread panicked"),
                    ))
                })
                .map_err(|e| crate::errors::message(&e));
            self.report = Some(r);
        }
        match &self.report {
            None => Err(invalid("the run was not started")),
            Some(Err(e)) => Err(invalid(e.clone())),
            Some(Ok(r)) => {
                let d = PyDict::new(py);
                d.set_item("ended", r.ended)?;
                d.set_item("stopped", r.stopped)?;
                d.set_item("frames", r.status.frames())?;
                d.set_item("summary", r.summary())?;
                Ok(Some(d))
            }
        }
    }

    /// The run's figures now: started, seconds since the first frame, per stream frames sent
    /// and skipped.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.ctl.status();
        let d = PyDict::new(py);
        d.set_item("started", s.started)?;
        d.set_item("elapsed_s", s.elapsed_s)?;
        let streams = PyList::empty(py);
        for c in &s.streams {
            let e = PyDict::new(py);
            e.set_item("frames", c.frames)?;
            e.set_item("skipped", c.skipped)?;
            streams.append(e)?;
        }
        d.set_item("streams", streams)?;
        d.set_item("lateness", s.lateness)?;
        Ok(d)
    }

    /// What the run told its starter so far (a pty's path, what it waits for).
    fn notes(&self) -> Vec<String> {
        self.notes.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

impl Drop for LiveRun {
    /// A run whose object goes away stops with it.
    fn drop(&mut self) {
        self.ctl.stop();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
