//! `imu-emu fit`: a template fitted to a static recording (any input `analyze` reads), with a
//! report and the closure check against a record simulated from the template.

use std::path::PathBuf;

use anyhow::{Context, Result};

use imu_emu::analysis::analyzer::DEFAULT_SEGMENT;
use imu_emu::fit::closure;
use imu_emu::fit::compare;
use imu_emu::fit::report::Closure;
use imu_emu::fit::template::{Provenance, sines_scene, template_toml};
use imu_emu::fit::{checks, lines, report};

use super::analyze::write_file;
use super::input::InputArgs;

#[derive(clap::Args)]
pub struct FitArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Write the fitted template here (TOML, loadable by --imu) [default: stdout]
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Name of the fitted template [default: the output file's stem, else "fitted"]
    #[arg(long)]
    pub name: Option<String>,
    /// Write the Markdown report here (with the closure check against a simulated record)
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write the ADEV plot here (.png or .svg): recording, fitted model, simulated record
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the spectral lines found as [[vibration.sine]] entries of a scene file here
    #[arg(long)]
    pub sines: Option<PathBuf>,
    /// Seed of the closure simulation
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Welch segment length in samples (a power of two)
    #[arg(long, default_value_t = DEFAULT_SEGMENT)]
    pub segment: usize,
}

/// `imu-emu fit`.
pub fn fit(a: FitArgs) -> Result<()> {
    super::input::check_plot_path(a.plot.as_deref())?;
    let (rec, _) = a.input.analyze(a.segment, "fit")?;
    // Refused before anything is fitted or written: too short, not uniform, not static.
    checks::check(&rec).map_err(|e| anyhow::anyhow!("{}: {e}", a.input.input.display()))?;
    let samples = rec.samples as usize;
    let fitted = compare::fit_all_with_filter(&rec);
    let fits = fitted.fits;
    let found: Vec<Vec<lines::Line>> = rec.channels.iter().map(|c| lines::find(&c.psd)).collect();
    let name = a.name.clone().unwrap_or_else(|| {
        a.output
            .as_ref()
            .and_then(|p| p.file_stem())
            .map_or("fitted".into(), |s| s.to_string_lossy().into_owned())
    });
    let prov = Provenance {
        name,
        source: a.input.input.display().to_string(),
        samples: rec.samples,
        dt: rec.dt,
        lsb: compare::triad_lsbs(&rec),
        filter: fitted.filter,
        carry: fitted.carry,
    };
    let toml = template_toml(&prov, &fits, &found);
    // The template must load as written: what `--imu` will read is what was fitted.
    let model = imu_emu::errors::template::parse(
        &toml,
        a.output.as_deref().unwrap_or("fitted.toml".as_ref()),
    )
    .context("the fitted template does not load (a bug: please report it)")?;
    // The closure check is part of every report (stdout with -o, --report) and of the plot.
    let closing = a.report.is_some() || a.plot.is_some() || a.output.is_some();
    let table = rec.channels.iter().all(|c| c.trend.is_none());
    // A table's τ are its own: the simulated record is kept as series, to take its Allan
    // deviation at each of them (and analysed once more for the plot).
    let series = if closing && table {
        Some(closure::simulate_series(
            model.clone(),
            rec.dt,
            rec.samples,
            a.seed,
        )?)
    } else {
        None
    };
    let simulated = if let Some(series) = &series {
        let mut an = imu_emu::analysis::analyzer::Analyzer::new(a.segment);
        (0..series[0].len())
            .for_each(|k| an.push(f64::NAN, &std::array::from_fn(|i| series[i][k])));
        Some(an.finish(rec.dt))
    } else if closing {
        let filter = prov.filter.as_ref().map(|f| &f.spec);
        Some(closure::simulate_with(
            model,
            closure::vibration(&found, rec.dt, filter),
            rec.dt,
            rec.samples,
            a.seed,
            a.segment,
        )?)
    } else {
        None
    };
    let check = match &simulated {
        Some(_) if let Some(series) = &series => Closure {
            adev: (0..6)
                .map(|ch| match &fits[ch] {
                    Some(f) => {
                        let pts = &rec.channels[ch].adev;
                        let sim = closure::adev_at(&series[ch], rec.dt, pts);
                        closure::compare(pts, &sim, &f.model, samples)
                    }
                    None => Vec::new(),
                })
                .collect(),
            psd: vec![Vec::new(); 6],
        },
        Some(sim) => Closure {
            adev: (0..6)
                .map(|ch| match &fits[ch] {
                    Some(f) => closure::compare(
                        &rec.channels[ch].adev,
                        &sim.channels[ch].adev,
                        &f.model,
                        samples,
                    ),
                    None => Vec::new(),
                })
                .collect(),
            psd: (0..6)
                .map(|ch| closure::compare_psd(&rec.channels[ch].psd, &sim.channels[ch].psd))
                .collect(),
        },
        None => Closure::default(),
    };
    let plot_name = a
        .plot
        .as_ref()
        .and_then(|p| p.file_name())
        .map(|n| n.to_string_lossy().into_owned());
    let text = report::markdown(&prov, &fits, &found, &check, plot_name.as_deref());
    if let Some(p) = &a.plot {
        let title = a
            .input
            .input
            .file_name()
            .map_or("input".into(), |n| n.to_string_lossy().into_owned());
        let adev = report::panels(&rec, &fits, simulated.as_ref(), &title);
        let psd = report::psd_panels(&rec, simulated.as_ref(), &title);
        // Rows: gyro x y z (and the gyro PSD), accel x y z (and the accel PSD).
        let columns = if psd.len() == 2 { 4 } else { 3 };
        let mut panels = Vec::new();
        let mut psd = psd.into_iter();
        for (i, p) in adev.into_iter().enumerate() {
            panels.push(p);
            if i % 3 == 2 && columns == 4 {
                panels.extend(psd.next());
            }
        }
        imu_emu::plot::render(p, &panels, columns, (600 * columns as u32, 1000))?;
        eprintln!("imu-emu fit: plot written to {}", p.display());
    }
    if let Some(p) = &a.report {
        write_file(p, text.as_bytes())?;
        eprintln!("imu-emu fit: report written to {}", p.display());
    }
    if let Some(p) = &a.sines {
        write_file(p, sines_scene(&prov, &found).as_bytes())?;
        eprintln!("imu-emu fit: spectral lines written to {}", p.display());
    }
    match &a.output {
        Some(p) => {
            write_file(p, toml.as_bytes())?;
            eprintln!("imu-emu fit: template written to {}", p.display());
            std::io::Write::write_all(&mut std::io::stdout().lock(), text.as_bytes())?;
        }
        None => std::io::Write::write_all(&mut std::io::stdout().lock(), toml.as_bytes())?,
    }
    let fails = check.failures();
    if fails > 0 {
        eprintln!(
            "imu-emu fit: closure: {fails} octaves or PSD bands of the simulated record fall outside the recording's band (see the report)"
        );
    }
    Ok(())
}
