//! `imu-emu analyze`: statistics, Allan deviation with fitted IEEE terms, and PSD of a
//! recording (ours or anyone's), optionally against a template, with plots.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use imu_emu::analysis::analyzer::DEFAULT_SEGMENT;
use imu_emu::analysis::conformance::{channel_theory, term_rows, white_allan};
use imu_emu::analysis::report;
use imu_emu::fit::compare;

use super::input::InputArgs;

#[derive(clap::Args)]
pub struct AnalyzeArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// IMU template to compare with (name or file): theory curves and measured/specified per term
    #[arg(long)]
    pub imu: Option<String>,
    /// Write the plots here (.png or .svg)
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the ADEV / PSD curves here as CSV
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Welch segment length in samples (a power of two)
    #[arg(long, default_value_t = DEFAULT_SEGMENT)]
    pub segment: usize,
    /// A second recording or ADEV table to compare with: overlaid on the plot, terms compared (repeatable)
    #[arg(long)]
    pub reference: Vec<PathBuf>,
    /// Format of the reference (csv, bin or a protocol name) [default: bin for *.bin, else csv]
    #[arg(long, requires = "reference")]
    pub reference_format: Option<String>,
    /// Write the per-term comparison with the reference here as CSV
    #[arg(long, requires = "reference")]
    pub compare_csv: Option<PathBuf>,
}

/// `imu-emu analyze`.
pub fn analyze(a: AnalyzeArgs) -> Result<()> {
    super::input::check_plot_path(a.plot.as_deref())?;
    let model = a
        .imu
        .as_deref()
        .map(imu_emu::errors::template::load)
        .transpose()?;

    let (res, summary) = a.input.analyze(a.segment, "analyze")?;
    let references = a
        .reference
        .iter()
        .map(|p| {
            Ok(InputArgs::other(p.clone(), a.reference_format.clone())
                .analyze(a.segment, "analyze")
                .with_context(|| format!("--reference {}", p.display()))?
                .0)
        })
        .collect::<Result<Vec<_>>>()?;
    let dt = res.dt;
    // The report goes to stdout in one write at the end, so a reader that stops early
    // (`… | head`) ends the command quietly (main treats a broken pipe as success) instead of
    // a panic in println!.
    let mut text = String::new();
    if let Some(s) = summary.frames {
        writeln!(
            text,
            "frames: {} decoded, {} check failures, {} counter gaps, {} bytes skipped",
            s.frames, s.check_failures, s.counter_gaps, s.skipped_bytes
        )?;
    }
    writeln!(
        text,
        "{}: {} samples, Δt = {} s ({} Hz), {:.1} s",
        a.input.input.display(),
        res.samples,
        digits12(dt),
        digits12(1.0 / dt),
        res.samples as f64 * dt
    )?;
    writeln!(text)?;
    write!(text, "{}", report::stats_table(&res))?;
    writeln!(text)?;
    writeln!(
        text,
        "IEEE 952 terms, least squares on the octave Allan variance: σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)B² + K²τ/3 + R²τ²/2"
    )?;
    let rows = model.as_ref().map(|m| term_rows(m, &res));
    write!(text, "{}", report::term_table(&res, rows.as_deref()))?;
    // The verdict against the template: like `validate`, a FAIL makes the command fail, after
    // the report, plots and CSV are written.
    let mut verdict = None;
    if let Some(rows) = &rows {
        let failed = rows.iter().filter(|r| r.pass == Some(false)).count();
        let checked = rows.iter().filter(|r| r.pass.is_some()).count();
        let name = model.as_ref().map_or("", |m| m.name.as_str());
        writeln!(
            text,
            "template `{name}`: {} of {checked} specified terms within their bands",
            checked - failed
        )?;
        if failed > 0 {
            verdict = Some(format!(
                "template `{name}`: {failed} of {checked} specified terms FAIL (outside their 99 % bands)"
            ));
        }
    }
    let theory = model.as_ref().map(|m| channel_theory(m, dt));
    let title = a
        .input
        .input
        .file_name()
        .map_or("input".into(), |n| n.to_string_lossy().into_owned());
    let file_name = |p: &Path| {
        p.file_name()
            .map_or("input".into(), |n| n.to_string_lossy().into_owned())
    };
    if !references.is_empty() {
        let this = compare::fit_all(&res);
        let mut csv = String::from(compare::csv_header());
        for (r, path) in references.iter().zip(&a.reference) {
            let rows = compare::compare(&this, &compare::fit_all(r));
            writeln!(text)?;
            write!(text, "{}", compare::markdown(&rows, &file_name(path)))?;
            csv += &compare::csv(&rows, &file_name(path));
        }
        if let Some(p) = &a.compare_csv {
            write_file(p, csv.as_bytes())?;
        }
        if let Some(p) = &a.plot {
            let mut curves = vec![(&res, title.clone())];
            curves.extend(
                references
                    .iter()
                    .zip(&a.reference)
                    .map(|(r, p)| (r, file_name(p))),
            );
            let panels = compare::panels(&curves);
            let columns = if panels.len() == 8 { 4 } else { 3 };
            imu_emu::plot::render(p, &panels, columns, (500 * columns as u32, 1000))?;
            eprintln!("imu-emu analyze: plot written to {}", p.display());
        }
    } else if let Some(p) = &a.plot {
        let filter = model.as_ref().and_then(|m| white_allan(m, dt));
        let panels = report::panels_filtered(&res, theory.as_deref(), filter.as_ref(), &title);
        imu_emu::plot::render(p, &panels, 2, (1600, 1200))?;
        eprintln!("imu-emu analyze: plot written to {}", p.display());
    }
    if let Some(p) = &a.csv {
        write_file(p, report::curves_csv(&res, theory.as_deref()).as_bytes())?;
    }
    std::io::Write::write_all(&mut std::io::stdout().lock(), text.as_bytes())?;
    if let Some(v) = verdict {
        anyhow::bail!(v);
    }
    Ok(())
}

/// x rounded to 12 significant digits (a measured Δt prints as 0.0025, not 0.0024999999999999996).
fn digits12(x: f64) -> f64 {
    format!("{x:.11e}").parse().unwrap_or(x)
}

pub fn write_file(p: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let mut f = imu_emu::output::AtomicFile::create(p)
        .with_context(|| format!("{}: cannot create", p.display()))?;
    f.write_all(bytes)
        .with_context(|| format!("{}: write failed", p.display()))?;
    f.commit()
        .with_context(|| format!("{}: write failed", p.display()))?;
    Ok(())
}
