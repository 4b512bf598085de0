//! `imu-emu generate`: a run on the offline clock — records or frames, their truth, and the
//! aiding streams, each to a file, as fast as the machine allows.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

use imu_emu::aiding::GnssFormat;
use imu_emu::output::SinkAddr;
use imu_emu::run::{RunSpec, Speed, StreamId};

use super::setup::SimArgs;

#[derive(clap::Args)]
pub struct GenerateArgs {
    #[command(flatten)]
    pub sim: SimArgs,
    /// Output file, or - for stdout [default: the scene file's `output.path`, else stdout].
    /// For a rig (`[[imu]]` units): the directory of the units' files [default: `.`].
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Also write the error-free records here (same format and time grid). For a rig: a
    /// directory receiving each unit's error-free readings and failure schedule.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Also write the error each stage injected into each record here (same format).
    #[arg(long)]
    pub truth_errors: Option<PathBuf>,
    /// Also write the GNSS receiver's epochs (scene file `[gnss]`, else the default receiver)
    /// as FORMAT:FILE, FORMAT one of nmea, ubx, mavlink. Repeatable (docs/aiding.md).
    #[arg(long = "gnss")]
    pub gnss: Vec<String>,
    /// Also write the truth of each GNSS epoch here (CSV).
    #[arg(long)]
    pub gnss_truth: Option<PathBuf>,
    /// Also write the odometer's samples here (CSV; scene file `[odometer]`, else the default).
    #[arg(long)]
    pub odometer: Option<PathBuf>,
    /// Also write the barometer's samples here (CSV; scene file `[baro]`, else the default).
    #[arg(long)]
    pub baro: Option<PathBuf>,
    /// Also write the magnetometer's samples here (CSV; scene file `[magnetometer]`, else the
    /// default).
    #[arg(long)]
    pub magnetometer: Option<PathBuf>,
}

fn file(p: &Path) -> SinkAddr {
    SinkAddr::File(p.display().to_string())
}

/// The offline run the flags describe, and the directories its files go to (created once
/// the run is built, so that a refused run leaves nothing behind).
pub fn spec(a: &GenerateArgs) -> Result<(RunSpec, Vec<PathBuf>)> {
    let signal = a.sim.builder("ideal", "csv")?;
    let out_path = a
        .output
        .clone()
        .or(signal.output_path().map(Path::to_path_buf));
    let rig = signal.is_rig();
    let units = if rig {
        signal.unit_specs()?
    } else {
        Vec::new()
    };
    let mut spec = super::routes::from_scene(signal)?;
    let mut dirs = Vec::new();
    // The files of a generate run: the scene file's unit sinks are `run`'s.
    spec.routes.clear();
    // The `[run]` table and the units' `sink` keys are `run`'s: said, then set aside.
    let contents = spec.signal.scene_contents();
    let sinks = contents.imu.sink.is_some() || units.iter().any(|(_, u)| !u.sinks.is_empty());
    if contents.run.is_some() || sinks {
        let file = spec
            .signal
            .scene_file_path()
            .map(|p| p.display().to_string());
        let file = file.unwrap_or_default();
        if contents.run.as_ref().is_some_and(|r| r.input.is_some()) {
            bail!("{file}: `run.input`: a live input is followed by `imu-emu run`, not generate");
        }
        eprintln!(
            "imu-emu: note: {file}: the [run] table and the units' `sink` keys are `imu-emu run`'s; generate writes the files its flags name, unpaced"
        );
        spec.clock = Default::default();
        spec.sync = Default::default();
        spec.link = Default::default();
        spec.file_keys.clear();
    }
    spec.clock.speed = Some(Speed::Max);
    if rig {
        let dir = out_path.unwrap_or_else(|| PathBuf::from("."));
        if dir == Path::new("-") {
            bail!("a rig writes one file per unit: give --output a directory, not `-`");
        }
        let truth = a.truth.clone();
        dirs.push(dir.clone());
        dirs.extend(truth.clone());
        for (_, u) in &units {
            let ext = match u.format.as_deref() {
                None | Some("csv") => "csv",
                _ => "bin",
            };
            let main = dir.join(
                u.path
                    .clone()
                    .unwrap_or_else(|| format!("{}.{ext}", u.name).into()),
            );
            spec.add_route(
                StreamId::unit(&u.name),
                file(&main),
                format!("unit `{}`", u.name),
            );
            if let Some(t) = &truth {
                let unit = Some(u.name.clone());
                let (tf, ff) = (
                    t.join(format!("{}.csv", u.name)),
                    t.join(format!("{}.failures.csv", u.name)),
                );
                spec.add_route(StreamId::Truth { unit }, file(&tf), "--truth".into());
                spec.add_route(
                    StreamId::Failures {
                        unit: u.name.clone(),
                    },
                    file(&ff),
                    "--truth".into(),
                );
            }
        }
        if a.truth_errors.is_some() {
            bail!(
                "--truth-errors does not apply to a rig (the scene file lists `[[imu]]` units): each unit's --truth file carries its error-free readings"
            );
        }
    } else {
        let main = out_path.unwrap_or_else(|| PathBuf::from("-"));
        spec.add_route(StreamId::imu(), file(&main), "--output".into());
        if let Some(t) = &a.truth {
            spec.add_route(StreamId::Truth { unit: None }, file(t), "--truth".into());
        }
        if let Some(t) = &a.truth_errors {
            spec.add_route(StreamId::Errors, file(t), "--truth-errors".into());
        }
    }
    let gnss: Vec<String> = a.gnss.clone();
    for v in &gnss {
        let (name, path) = v.split_once(':').ok_or_else(|| {
            anyhow::anyhow!("--gnss `{v}`: expected FORMAT:FILE, e.g. nmea:run.nmea")
        })?;
        if GnssFormat::from_name(name).is_none() {
            bail!(
                "--gnss `{v}`: GNSS format `{name}`: expected one of {}",
                GnssFormat::NAMES.join(", ")
            );
        }
        if path.is_empty() {
            bail!("--gnss `{v}`: no file after the format");
        }
    }
    let sensors = [&a.odometer, &a.baro, &a.magnetometer].map(|p| {
        p.iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
    });
    super::routes::aiding(
        &mut spec,
        &gnss,
        [&sensors[0], &sensors[1], &sensors[2]],
        |s| Ok(SinkAddr::File(s.to_string())),
    )?;
    if let Some(t) = &a.gnss_truth {
        spec.add_route(StreamId::GnssTruth, file(t), "--gnss-truth".into());
    }
    Ok((spec, dirs))
}

pub fn generate(a: GenerateArgs) -> Result<()> {
    let (spec, dirs) = spec(&a)?;
    let run = spec.build()?;
    for d in dirs {
        std::fs::create_dir_all(&d)
            .map_err(|e| anyhow::anyhow!("creating directory {}: {e}", d.display()))?;
    }
    super::setup::announce_run(&run);
    super::flow::run(run, true).map(drop)
}
