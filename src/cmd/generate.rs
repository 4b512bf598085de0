//! `imu-emu generate`: records or frames offline, as fast as the machine allows.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};

use imu_emu::job;
use imu_emu::output::AtomicFile;

use super::setup::{GenerateArgs, resolve};

pub fn generate(a: GenerateArgs) -> Result<()> {
    let r = resolve(a)?;
    let motion = job::build_motion(&r.source, r.model).map_err(|e| r.locate(e))?;
    let grid = job::plan(&motion, r.rate, r.start, r.duration).map_err(|e| r.locate(e))?;
    let chain = r.chain(&grid)?;
    let show = std::io::stderr().is_terminal() && grid.count >= 500_000;
    let bar = if show {
        indicatif::ProgressBar::new(grid.count)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let started = Instant::now();
    // Side files (error-free truth, injected errors): written beside the output, committed
    // only when the whole run succeeded.
    let side = |p: &Option<PathBuf>| -> Result<Option<(AtomicFile, PathBuf)>> {
        p.as_ref()
            .map(|p| {
                Ok((
                    AtomicFile::create(p).with_context(|| format!("creating {}", p.display()))?,
                    p.clone(),
                ))
            })
            .transpose()
    };
    let mut truth_file = side(&r.truth)?;
    let mut errors_file = side(&r.truth_errors)?;
    {
        let mut truth_out = truth_file
            .as_mut()
            .map(|(f, _)| std::io::BufWriter::with_capacity(1 << 20, f));
        let mut errors_out = errors_file
            .as_mut()
            .map(|(f, _)| std::io::BufWriter::with_capacity(1 << 20, f));
        let truth_w = truth_out.as_mut().map(|w| w as &mut dyn Write);
        let errors_w = errors_out.as_mut().map(|w| w as &mut dyn Write);
        let to_stdout = r.output.as_deref().is_none_or(|p| p == Path::new("-"));
        let mut file = match (&r.output, to_stdout) {
            (Some(path), false) => Some((
                AtomicFile::create(path).with_context(|| format!("creating {}", path.display()))?,
                path.clone(),
            )),
            _ => None,
        };
        let label = file
            .as_ref()
            .map_or("stdout".to_string(), |(_, p)| p.display().to_string());
        {
            let mut out: Box<dyn Write + '_> = match file.as_mut() {
                Some((f, _)) => Box::new(std::io::BufWriter::with_capacity(1 << 20, f)),
                None => Box::new(std::io::BufWriter::with_capacity(
                    1 << 20,
                    std::io::stdout().lock(),
                )),
            };
            job::run(
                motion,
                grid,
                r.nodes,
                r.encoding(),
                chain,
                &mut out,
                truth_w,
                errors_w,
                |k| bar.set_position(k),
            )
            .with_context(|| format!("writing {label}"))?;
            out.flush()?;
        }
        if let Some((f, path)) = file {
            f.commit()
                .with_context(|| format!("finishing {}", path.display()))?;
        }
        for w in [truth_out.as_mut(), errors_out.as_mut()]
            .into_iter()
            .flatten()
        {
            w.flush()?;
        }
    }
    for (f, p) in [truth_file, errors_file].into_iter().flatten() {
        f.commit()
            .with_context(|| format!("finishing {}", p.display()))?;
    }
    bar.finish_and_clear();
    if let Some(f) = &r.faults {
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
