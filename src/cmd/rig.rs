//! `imu-emu generate` on a scene file with an `[[imu]]` list: one output per unit in a
//! directory, and with `--truth DIR` each unit's error-free readings and failure schedule.

use std::io::Write;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

use anyhow::{Context, Result, bail};

use imu_emu::output::AtomicFile;
use imu_emu::realtime::signal::Interrupted;
use imu_emu::rig::UnitOutputs;

use super::generate::GenerateArgs;

/// Flags that set one IMU's output, which each `[[imu]]` entry gives for itself.
fn refuse_single_imu_flags(a: &GenerateArgs) -> Result<()> {
    let s = &a.sim;
    let given = [
        ("--imu", s.imu.is_some()),
        ("--format", s.format.is_some()),
        ("--protocol-file", s.protocol_file.is_some()),
        ("--fault", !s.faults.is_empty()),
        ("--truth-errors", a.truth_errors.is_some()),
    ];
    if let Some((flag, _)) = given.iter().find(|g| g.1) {
        bail!(
            "{flag} does not apply to a rig (the scene file lists `[[imu]]` units): give each unit its `model`, `format` and `[[imu.failure]]` entries"
        );
    }
    Ok(())
}

/// A directory for the outputs, created if missing.
fn directory(p: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(p).with_context(|| format!("creating directory {}", p.display()))?;
    Ok(p.to_path_buf())
}

fn buffered(f: &mut AtomicFile) -> std::io::BufWriter<&mut AtomicFile> {
    std::io::BufWriter::with_capacity(1 << 16, f)
}

fn create(path: PathBuf) -> Result<(AtomicFile, PathBuf)> {
    let f = AtomicFile::create(&path).with_context(|| format!("creating {}", path.display()))?;
    Ok((f, path))
}

/// Writes every unit of the rig; all files appear together only when the whole run worked.
pub fn generate(a: GenerateArgs) -> Result<()> {
    refuse_single_imu_flags(&a)?;
    let b = a.sim.builder("ideal", "csv")?;
    let out_dir = a
        .output
        .clone()
        .or(b.output_path().map(Path::to_path_buf))
        .unwrap_or_else(|| PathBuf::from("."));
    if out_dir == Path::new("-") {
        bail!("a rig writes one file per unit: give --output a directory, not `-`");
    }
    let rig = b.build_rig()?;
    for w in rig.warnings() {
        eprintln!("imu-emu: warning: {w}");
    }
    let out_dir = directory(&out_dir)?;
    let truth_dir = a.truth.as_deref().map(directory).transpose()?;
    let mut files = Vec::new();
    for u in rig.units() {
        let main = out_dir.join(u.path().map_or_else(
            || PathBuf::from(format!("{}.{}", u.name(), u.extension())),
            Path::to_path_buf,
        ));
        let side = truth_dir.as_ref().map(|d| {
            (
                d.join(format!("{}.csv", u.name())),
                d.join(format!("{}.failures.csv", u.name())),
            )
        });
        let side = match side {
            Some((t, f)) => Some((create(t)?, create(f)?)),
            None => None,
        };
        files.push((create(main)?, side));
        eprintln!(
            "imu-emu: unit `{}`: {} records at {} Hz, seed {}",
            u.name(),
            u.grid().count,
            u.grid().rate_hz,
            u.seed()
        );
    }
    let aiding_files = super::generate::write_aiding(&rig.aiding(), &a)?;
    let caught = imu_emu::realtime::signal::watch()?;
    let result = {
        let mut writers: Vec<_> = files
            .iter_mut()
            .map(|(m, s)| {
                let side = s
                    .as_mut()
                    .map(|(t, f)| (buffered(&mut t.0), buffered(&mut f.0)));
                (buffered(&mut m.0), side)
            })
            .collect();
        let mut outs: Vec<UnitOutputs<'_>> = writers
            .iter_mut()
            .map(|(m, s)| {
                let (truth, failures) = match s {
                    Some((t, f)) => (Some(t as &mut dyn Write), Some(f as &mut dyn Write)),
                    None => (None, None),
                };
                UnitOutputs {
                    main: m,
                    truth,
                    failures,
                }
            })
            .collect();
        rig.write(&mut outs, |_| match caught.load(Ordering::Relaxed) {
            0 => ControlFlow::Continue(()),
            _ => ControlFlow::Break(()),
        })
    };
    let sig = caught.load(Ordering::Relaxed);
    if sig != 0 {
        let e = Interrupted(sig);
        eprintln!("imu-emu: {e}: stopped before the end, unfinished output files removed");
        return Err(e.into());
    }
    result.context("writing the rig's outputs")?;
    let aiding = aiding_files.into_iter().map(|f| (f, None));
    for (m, s) in files.into_iter().chain(aiding) {
        let mut all = vec![m];
        if let Some((t, f)) = s {
            all.extend([t, f]);
        }
        for (f, p) in all {
            f.commit()
                .with_context(|| format!("finishing {}", p.display()))?;
        }
    }
    Ok(())
}
