//! The files of an offline run (`imu-emu generate`): the records or frames, their truth, the
//! injected errors and the aiding streams, each to a file, unpaced. A rig writes one file per
//! unit into a directory (`NAME.csv`/`NAME.bin` or the unit's `path`), and its truth as each
//! unit's error-free readings and failure schedule.

use std::path::{Path, PathBuf};

use crate::aiding::GnssFormat;
use crate::output::SinkAddr;
use crate::sim::SimulationBuilder;

use super::RunError;
use super::error::refuse;
use super::spec::{RunSpec, Speed, StreamId};

/// The files an offline run writes, in `imu-emu generate`'s words; `None` or empty: not
/// written.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OfflineFiles {
    /// `--output`: the records (`-`: stdout) [default: the scene file's `output.path`, else
    /// stdout]; for a rig the units' directory [default `.`].
    pub output: Option<PathBuf>,
    /// `--truth`: the error-free records (a rig: a directory of each unit's readings and
    /// failure schedule).
    pub truth: Option<PathBuf>,
    /// `--truth-errors`: the error each stage injected into each record (single IMU).
    pub truth_errors: Option<PathBuf>,
    /// `--gnss FORMAT:FILE`.
    pub gnss: Vec<String>,
    /// `--gnss-truth`: each GNSS epoch's truth (CSV).
    pub gnss_truth: Option<PathBuf>,
    /// The odometer's, barometer's and magnetometer's files, in
    /// [`SensorKind::ALL`](crate::aiding::sensors::SensorKind::ALL)'s order.
    pub sensors: [Option<PathBuf>; 3],
}

/// An offline run as described: its spec, the directories to create once it is built (so that
/// a refused run leaves nothing behind), and what the user should be told before it runs.
#[derive(Debug)]
pub struct Offline {
    /// The run, on the unpaced clock.
    pub spec: RunSpec,
    /// Directories its files go to.
    pub dirs: Vec<PathBuf>,
    /// Notes for the user (settings of the scene file that an offline run sets aside).
    pub notes: Vec<String>,
}

fn file(p: &Path) -> SinkAddr {
    SinkAddr::File(p.display().to_string())
}

impl RunSpec {
    /// The offline run of `signal` writing `files`. The scene file's `[run]` table and unit
    /// sinks belong to a paced run: set aside with a note (a live input is refused).
    pub fn offline(signal: SimulationBuilder, files: &OfflineFiles) -> Result<Offline, RunError> {
        let out_path = (files.output.clone()).or(signal.output_path().map(Path::to_path_buf));
        let rig = signal.is_rig();
        let units = if rig {
            signal.unit_specs()?
        } else {
            Vec::new()
        };
        let mut spec = RunSpec::from_signal(signal)?;
        let mut notes = Vec::new();
        spec.routes.clear();
        let contents = spec.signal.scene_contents();
        let sinks = contents.imu.sink.is_some() || units.iter().any(|(_, u)| !u.sinks.is_empty());
        if contents.run.is_some() || sinks {
            let path = spec
                .signal
                .scene_file_path()
                .map(|p| p.display().to_string());
            let path = path.unwrap_or_default();
            if contents.run.as_ref().is_some_and(|r| r.input.is_some()) {
                let why = "a live input is followed by `imu-emu run`, not generate";
                return Err(refuse(&format!("{path}: `run.input`"), why));
            }
            notes.push(format!(
                "note: {path}: the [run] table and the units' `sink` keys are `imu-emu run`'s; generate writes the files its flags name, unpaced"
            ));
            spec.clock = Default::default();
            spec.sync = Default::default();
            spec.link = Default::default();
            spec.file_keys.clear();
        }
        spec.clock.speed = Some(Speed::Max);
        let mut dirs = Vec::new();
        if rig {
            let dir = out_path.unwrap_or_else(|| PathBuf::from("."));
            if dir == Path::new("-") {
                let why = "a rig writes one file per unit: give --output a directory, not `-`";
                return Err(refuse("--output -", why));
            }
            if files.truth_errors.is_some() {
                let why = "does not apply to a rig (the scene file lists `[[imu]]` units): each unit's --truth file carries its error-free readings";
                return Err(refuse("--truth-errors", why));
            }
            dirs.push(dir.clone());
            dirs.extend(files.truth.clone());
            for (_, u) in &units {
                let ext = match u.format.as_deref() {
                    None | Some("csv") => "csv",
                    _ => "bin",
                };
                let name = (u.path.clone()).unwrap_or_else(|| format!("{}.{ext}", u.name).into());
                let origin = format!("unit `{}`", u.name);
                spec.add_route(StreamId::unit(&u.name), file(&dir.join(name)), origin);
                if let Some(t) = &files.truth {
                    let unit = Some(u.name.clone());
                    let tf = t.join(format!("{}.csv", u.name));
                    spec.add_route(StreamId::Truth { unit }, file(&tf), "--truth".into());
                    let ff = t.join(format!("{}.failures.csv", u.name));
                    let failures = StreamId::Failures {
                        unit: u.name.clone(),
                    };
                    spec.add_route(failures, file(&ff), "--truth".into());
                }
            }
        } else {
            let main = out_path.unwrap_or_else(|| PathBuf::from("-"));
            spec.add_route(StreamId::imu(), file(&main), "--output".into());
            if let Some(t) = &files.truth {
                spec.add_route(StreamId::Truth { unit: None }, file(t), "--truth".into());
            }
            if let Some(t) = &files.truth_errors {
                spec.add_route(StreamId::Errors, file(t), "--truth-errors".into());
            }
        }
        for v in &files.gnss {
            let flag = format!("--gnss `{v}`");
            let Some((name, path)) = v.split_once(':') else {
                return Err(refuse(&flag, "expected FORMAT:FILE, e.g. nmea:run.nmea"));
            };
            if GnssFormat::from_name(name).is_none() {
                let names = GnssFormat::NAMES.join(", ");
                return Err(refuse(
                    &flag,
                    format!("GNSS format `{name}`: expected one of {names}"),
                ));
            }
            if path.is_empty() {
                return Err(refuse(&flag, "no file after the format"));
            }
        }
        let sensors = (files.sensors.clone()).map(|p| p.map(|p| p.display().to_string()));
        let sensors = sensors.map(|p| p.into_iter().collect::<Vec<_>>());
        let sensors = [&sensors[0][..], &sensors[1], &sensors[2]];
        spec.aiding_sinks(&files.gnss, sensors, |s| Ok(SinkAddr::File(s.to_string())))?;
        if let Some(t) = &files.gnss_truth {
            spec.add_route(StreamId::GnssTruth, file(t), "--gnss-truth".into());
        }
        Ok(Offline { spec, dirs, notes })
    }
}
