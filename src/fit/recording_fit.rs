//! A template fitted to a static recording end to end (`imu-emu fit`): refused when the
//! recording is too short, not uniform or not static; the IEEE terms (with an output filter
//! and quantization where the recording shows them) and spectral lines fitted; the template
//! written as TOML and loaded back; a record simulated from it to check the fit closes (its
//! Allan deviation and PSD within the recording's bands); the report and the plot's panels.

use std::path::PathBuf;

use super::closure;
use super::compare;
use super::report::Closure;
use super::template::{Provenance, sines_scene, template_toml};
use super::{checks, lines, report, resonance, resonance_adev};
use crate::analysis::analyzer::{Analysis, Analyzer};
use crate::plot::Panel;

/// How to fit and what to make.
#[derive(Clone, Debug)]
pub struct Settings {
    /// The fitted template's name.
    pub name: String,
    /// How the template and report name the recording.
    pub source: String,
    /// The template's file name, for messages about it.
    pub template_path: PathBuf,
    /// Simulate a record from the template and check the fit closes.
    pub closure: bool,
    /// Seed of the closure simulation.
    pub seed: u64,
    /// Welch segment length (samples).
    pub segment: usize,
    /// The plot's file name (the report links it) and title, when one is wanted.
    pub plot: Option<(String, String)>,
}

/// What a fit made.
pub struct Fitted {
    /// The template (TOML, loadable by `--imu`).
    pub toml: String,
    /// The Markdown report (with the closure check when it ran).
    pub report: String,
    /// The spectral lines found, as `[[vibration.sine]]` entries of a scene file.
    pub sines: String,
    /// The plot's panels and columns, when one was wanted.
    pub plot: Option<(Vec<Panel>, usize)>,
    /// Octaves or PSD bands of the simulated record outside the recording's band.
    pub failures: usize,
    /// The broad resonances found on each channel (gyro x y z, accel x y z).
    pub resonances: Vec<Vec<resonance::Resonance>>,
}

/// Why a recording cannot be fitted.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// The recording is too short, not uniform or not static.
    #[error("{0}")]
    Refused(String),
    /// The fitted template does not load (a bug).
    #[error("the fitted template does not load (a bug: please report it)")]
    Template(#[source] crate::errors::TemplateError),
    /// The closure simulation failed.
    #[error(transparent)]
    Simulation(#[from] crate::sim::SimError),
}

/// The fits of `rec` with its broad resonances ([`resonance`]) as known random vibrations:
/// found against the fit without them, whose white noise took their power (the floor's level
/// is fitted around them), then once more against the fit with them, which has the floor
/// right; each time the channels refitted with what was found. Empty where none is found.
fn fit_resonances(
    rec: &Analysis,
    lines: &[Vec<lines::Line>],
) -> (compare::Fitted, Vec<Vec<resonance::Resonance>>) {
    let table = rec.channels.iter().all(|c| c.trend.is_none());
    let mut fitted = compare::fit_all_with_filter(rec);
    let mut res: Vec<Vec<resonance::Resonance>> = vec![Vec::new(); rec.channels.len()];
    for _ in 0..2 {
        let next: Vec<Vec<resonance::Resonance>> = rec
            .channels
            .iter()
            .zip(&fitted.fits)
            .zip(lines)
            .enumerate()
            .map(|(ch, ((c, f), l))| match f {
                // A table has no PSD: its bump is read from the Allan deviation.
                Some(f) if table => {
                    let spec = fitted.filter.as_ref().map(|x| x.spec.channel(ch));
                    resonance_adev::find(&c.adev, &f.model, rec.samples as usize, spec.as_ref())
                }
                Some(f) => resonance::find(&c.psd, &f.model, l, rec.dt),
                None => Vec::new(),
            })
            .collect();
        if next.iter().all(Vec::is_empty) && res.iter().all(Vec::is_empty) {
            // None: the filter is read once more knowing that no channel has a bump.
            fitted = compare::fit_all_with_resonances(rec, &next);
            break;
        }
        res = next;
        fitted = compare::fit_all_with_resonances(rec, &res);
    }
    (fitted, res)
}

/// Fits a template to `rec`.
pub fn fit(rec: &Analysis, s: &Settings) -> Result<Fitted, FitError> {
    // Refused before anything is fitted or written: too short, not uniform, not static.
    checks::check(rec).map_err(|e| FitError::Refused(format!("{}: {e}", s.source)))?;
    let samples = rec.samples as usize;
    let found: Vec<Vec<lines::Line>> = rec.channels.iter().map(|c| lines::find(&c.psd)).collect();
    let (fitted, resonances) = fit_resonances(rec, &found);
    let fits = fitted.fits;
    let prov = Provenance {
        name: s.name.clone(),
        source: s.source.clone(),
        samples: rec.samples,
        dt: rec.dt,
        lsb: compare::triad_lsbs(rec),
        filter: fitted.filter,
        carry: fitted.carry,
        resonances,
        table: rec.channels.iter().all(|c| c.trend.is_none()),
        missing: std::array::from_fn(|ch| rec.channels[ch].adev.is_empty()),
    };
    let toml = template_toml(&prov, &fits, &found);
    // The template must load as written: what `--imu` will read is what was fitted.
    let model =
        crate::errors::template::parse(&toml, &s.template_path).map_err(FitError::Template)?;
    // The closure check is part of every report (stdout with -o, --report) and of the plot.
    let closing = s.closure;
    let table = prov.table;
    // A table's τ are its own: the simulated record is kept as series, to take its Allan
    // deviation at each of them (and analysed once more for the plot).
    let series = if closing && table {
        let filter = prov.filter.as_ref().map(|f| &f.spec);
        Some(closure::simulate_series(
            model.clone(),
            closure::vibration_with(&found, &prov.resonances, rec.dt, filter),
            rec.dt,
            rec.samples,
            s.seed,
        )?)
    } else {
        None
    };
    let simulated = if let Some(series) = &series {
        let mut an = Analyzer::new(s.segment);
        (0..series[0].len())
            .for_each(|k| an.push(f64::NAN, &std::array::from_fn(|i| series[i][k])));
        Some(an.finish(rec.dt))
    } else if closing {
        let filter = prov.filter.as_ref().map(|f| &f.spec);
        Some(closure::simulate_with(
            model,
            closure::vibration_with(&found, &prov.resonances, rec.dt, filter),
            rec.dt,
            rec.samples,
            s.seed,
            s.segment,
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
    let text = report::markdown(
        &prov,
        &fits,
        &found,
        &check,
        s.plot.as_ref().map(|p| p.0.as_str()),
        rec.transients.as_ref(),
        rec.dropped.as_ref(),
    );
    let plot = s
        .plot
        .as_ref()
        .map(|(_, title)| report::grid(rec, &fits, simulated.as_ref(), title));
    Ok(Fitted {
        sines: sines_scene(&prov, &found),
        toml,
        report: text,
        plot,
        failures: check.failures(),
        resonances: prov.resonances.clone(),
    })
}
