//! `imu-emu generate`: records or frames offline, as fast as the machine allows.

use std::io::{IsTerminal, Write};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Instant;

use anyhow::{Context, Result};

use imu_emu::aiding::GnssFormat;
use imu_emu::output::AtomicFile;
use imu_emu::sim::{AidingStreams, SideOutputs};

use super::setup::{SimArgs, announce};
use imu_emu::realtime::signal::Interrupted;

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
    #[arg(long = "gnss", value_parser = parse_gnss_output)]
    pub gnss: Vec<(GnssFormat, PathBuf)>,
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

/// `FORMAT:FILE` of `--gnss`.
fn parse_gnss_output(s: &str) -> Result<(GnssFormat, PathBuf), String> {
    let (name, path) = s
        .split_once(':')
        .ok_or_else(|| format!("`{s}`: expected FORMAT:FILE, e.g. nmea:run.nmea"))?;
    let f = GnssFormat::from_name(name).ok_or_else(|| {
        format!(
            "GNSS format `{name}`: expected one of {}",
            GnssFormat::NAMES.join(", ")
        )
    })?;
    if path.is_empty() {
        return Err(format!("`{s}`: no file after the format"));
    }
    Ok((f, PathBuf::from(path)))
}

/// Writes the GNSS files of `a` into uncommitted files (committed with the others).
fn write_gnss(sim: &AidingStreams<'_>, a: &GenerateArgs) -> Result<Vec<(AtomicFile, PathBuf)>> {
    let mut files = Vec::new();
    if a.gnss.is_empty() && a.gnss_truth.is_none() {
        return Ok(files);
    }
    for (_, p) in &a.gnss {
        files.push(create(p)?);
    }
    let mut truth = a.gnss_truth.as_deref().map(create).transpose()?;
    {
        let mut outs: Vec<_> = files.iter_mut().map(|(f, _)| buffered(f)).collect();
        let mut streams: Vec<(GnssFormat, &mut dyn Write)> = a
            .gnss
            .iter()
            .zip(outs.iter_mut())
            .map(|((fmt, _), w)| (*fmt, w as &mut dyn Write))
            .collect();
        let mut truth_out = truth.as_mut().map(|(f, _)| buffered(f));
        sim.write_gnss(
            &mut streams,
            truth_out.as_mut().map(|w| w as &mut dyn Write),
        )
        .context("writing the GNSS streams")?;
        for w in outs.iter_mut().chain(truth_out.as_mut()) {
            w.flush()?;
        }
    }
    files.extend(truth);
    Ok(files)
}

/// Writes every aiding file `a` asks for (GNSS, odometer, barometer, magnetometer) into
/// uncommitted files: a single IMU's and a rig's `generate` share it, so a rig scene writes
/// the same streams as one IMU on its motion and seed.
pub(super) fn write_aiding(
    aid: &AidingStreams<'_>,
    a: &GenerateArgs,
) -> Result<Vec<(AtomicFile, PathBuf)>> {
    let mut files = write_gnss(aid, a)?;
    files.extend(write_sensor(a.odometer.as_deref(), |w| {
        aid.write_odometer(w)
    })?);
    files.extend(write_sensor(a.baro.as_deref(), |w| aid.write_baro(w))?);
    files.extend(write_sensor(a.magnetometer.as_deref(), |w| {
        aid.write_magnetometer(w)
    })?);
    Ok(files)
}

/// Writes one CSV aiding stream to `path`, if asked, uncommitted.
fn write_sensor(
    path: Option<&Path>,
    write: impl FnOnce(&mut dyn Write) -> Result<u64, imu_emu::sim::SimError>,
) -> Result<Option<(AtomicFile, PathBuf)>> {
    let Some(path) = path else {
        return Ok(None);
    };
    let (mut f, p) = create(path)?;
    {
        let mut w = buffered(&mut f);
        write(&mut w).with_context(|| format!("writing {}", p.display()))?;
        w.flush()?;
    }
    Ok(Some((f, p)))
}

fn buffered(f: &mut AtomicFile) -> std::io::BufWriter<&mut AtomicFile> {
    std::io::BufWriter::with_capacity(1 << 20, f)
}

/// A file committed only when the whole run succeeded (dropped, it leaves nothing behind).
fn create(path: &Path) -> Result<(AtomicFile, PathBuf)> {
    let f = AtomicFile::create(path).with_context(|| format!("creating {}", path.display()))?;
    Ok((f, path.to_path_buf()))
}

pub fn generate(a: GenerateArgs) -> Result<()> {
    if a.sim.builder("ideal", "csv")?.is_rig() {
        return super::rig::generate(a);
    }
    let sim = a.sim.builder("ideal", "csv")?.build()?;
    announce(&sim);
    let grid = sim.grid();
    let output = a
        .output
        .clone()
        .or(sim.output_path().map(Path::to_path_buf));
    let show = std::io::stderr().is_terminal() && grid.count >= 500_000;
    let bar = if show {
        indicatif::ProgressBar::new(grid.count)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let faults = sim.faults().cloned();
    let gnss_files = write_aiding(&sim.aiding(), &a)?;
    let caught = imu_emu::realtime::signal::watch()?;
    let started = Instant::now();
    let mut truth_file = a.truth.as_deref().map(create).transpose()?;
    let mut errors_file = a.truth_errors.as_deref().map(create).transpose()?;
    let to_stdout = output.as_deref().is_none_or(|p| p == Path::new("-"));
    let mut file = match (&output, to_stdout) {
        (Some(path), false) => Some(create(path)?),
        _ => None,
    };
    let label = file
        .as_ref()
        .map_or("stdout".to_string(), |(_, p)| p.display().to_string());
    {
        let mut truth_out = truth_file.as_mut().map(|(f, _)| buffered(f));
        let mut errors_out = errors_file.as_mut().map(|(f, _)| buffered(f));
        let mut out: Box<dyn Write + '_> = match file.as_mut() {
            Some((f, _)) => Box::new(buffered(f)),
            None => Box::new(std::io::BufWriter::with_capacity(
                1 << 20,
                std::io::stdout().lock(),
            )),
        };
        let side = SideOutputs {
            truth: truth_out.as_mut().map(|w| w as &mut dyn Write),
            injected: errors_out.as_mut().map(|w| w as &mut dyn Write),
        };
        let result = sim.write_with(&mut out, side, |k| {
            bar.set_position(k);
            match caught.load(Ordering::Relaxed) {
                0 => ControlFlow::Continue(()),
                _ => ControlFlow::Break(()),
            }
        });
        let sig = caught.load(Ordering::Relaxed);
        if sig != 0 {
            // The unfinished files are removed when they drop.
            bar.finish_and_clear();
            let e = Interrupted(sig);
            eprintln!("imu-emu: {e}: stopped before the end, unfinished output files removed");
            return Err(e.into());
        }
        result.with_context(|| format!("writing {label}"))?;
        out.flush()?;
        for w in [truth_out.as_mut(), errors_out.as_mut()]
            .into_iter()
            .flatten()
        {
            w.flush()?;
        }
    }
    let files = [file, truth_file, errors_file].into_iter().flatten();
    for (f, p) in files.chain(gnss_files) {
        f.commit()
            .with_context(|| format!("finishing {}", p.display()))?;
    }
    bar.finish_and_clear();
    if let Some(f) = faults {
        eprintln!("imu-emu: faults injected: {}", f.tally().summary());
    }
    if show {
        let s = started.elapsed().as_secs_f64();
        eprintln!(
            "{} records in {s:.2} s ({:.3e} records/s)",
            grid.count,
            grid.count as f64 / s
        );
    }
    Ok(())
}
