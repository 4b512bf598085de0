//! What `imu-emu analyze` reports on a recording: the read tally, statistics, the IEEE 952
//! terms fitted to the octave Allan variance (against a template's, with a verdict, when one
//! is given), the per-term comparison with reference recordings, and the plot's panels and the
//! curves' CSV.

use std::fmt::Write as _;

use super::compare;
use crate::analysis::analyzer::Analysis;
use crate::analysis::conformance::{channel_theory, term_rows, white_allan};
use crate::analysis::reader::ReadSummary;
use crate::analysis::report;
use crate::errors::ImuModel;
use crate::plot::Panel;

/// A recording to report on, and what to hold it against.
pub struct Subject<'a> {
    /// Its analysis.
    pub analysis: &'a Analysis,
    /// What was read besides the samples.
    pub summary: &'a ReadSummary,
    /// How the report names it (its path).
    pub name: String,
    /// The plot's title (its file name).
    pub title: String,
    /// A template to compare with: theory curves and measured/specified per term.
    pub model: Option<&'a ImuModel>,
    /// Reference recordings, each with the name the tables give it.
    pub references: &'a [(Analysis, String)],
}

/// The report's parts.
pub struct AnalysisReport {
    /// The text (Markdown tables).
    pub text: String,
    /// The template's verdict when terms fall outside their bands: the command fails with it.
    pub verdict: Option<String>,
    /// The per-term comparison with the references, as CSV (when there are references).
    pub compare_csv: Option<String>,
    /// The plot's panels, its columns and its size in pixels.
    pub plot: (Vec<Panel>, usize, (u32, u32)),
    /// The ADEV and PSD curves (and the template's theory) as CSV.
    pub curves_csv: String,
}

/// `x` rounded to 12 significant digits (a measured Δt prints as 0.0025, not
/// 0.0024999999999999996).
fn digits12(x: f64) -> f64 {
    format!("{x:.11e}").parse().unwrap_or(x)
}

/// Reports on `s`; the plot's panels only when `plot`.
pub fn report_on(s: &Subject, plot: bool) -> AnalysisReport {
    let (res, model) = (s.analysis, s.model);
    let dt = res.dt;
    let mut text = String::new();
    if let Some(f) = s.summary.frames {
        let _ = writeln!(
            text,
            "frames: {} decoded, {} check failures, {} counter gaps, {} bytes skipped",
            f.frames, f.check_failures, f.counter_gaps, f.skipped_bytes
        );
    }
    let _ = writeln!(
        text,
        "{}: {} samples, Δt = {} s ({} Hz), {:.1} s\n",
        s.name,
        res.samples,
        digits12(dt),
        digits12(1.0 / dt),
        res.samples as f64 * dt
    );
    if let Some(d) = &res.dropped {
        let _ = writeln!(text, "dropped samples: {}\n", report::dropped_summary(d));
    }
    if let Some(t) = &res.transients {
        let _ = writeln!(text, "transients: {}\n", report::transients_summary(t, dt));
    }
    text += &report::stats_table(res);
    let _ = writeln!(
        text,
        "\nIEEE 952 terms, least squares on the octave Allan variance: σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)B² + K²τ/3 + R²τ²/2"
    );
    let rows = model.map(|m| term_rows(m, res));
    text += &report::term_table(res, rows.as_deref());
    // The verdict against the template: like `validate`, a FAIL makes the command fail, after
    // the report, plots and CSV are written.
    let mut verdict = None;
    if let Some(rows) = &rows {
        let failed = rows.iter().filter(|r| r.pass == Some(false)).count();
        let checked = rows.iter().filter(|r| r.pass.is_some()).count();
        let name = model.map_or("", |m| m.name.as_str());
        let _ = writeln!(
            text,
            "template `{name}`: {} of {checked} specified terms within their bands",
            checked - failed
        );
        if failed > 0 {
            verdict = Some(format!(
                "template `{name}`: {failed} of {checked} specified terms FAIL (outside their 99 % bands)"
            ));
        }
    }
    let theory = model.map(|m| channel_theory(m, dt));
    let mut compare_csv = None;
    let mut panels = (Vec::new(), 2, (1600, 1200));
    if !s.references.is_empty() {
        let this = compare::fit_all(res);
        let mut csv = String::from(compare::csv_header());
        for (r, name) in s.references {
            let rows = compare::compare(&this, &compare::fit_all(r));
            text.push('\n');
            text += &compare::markdown(&rows, name);
            csv += &compare::csv(&rows, name);
        }
        compare_csv = Some(csv);
        if plot {
            let mut curves = vec![(res, s.title.clone())];
            curves.extend(s.references.iter().map(|(r, n)| (r, n.clone())));
            let p = compare::panels(&curves);
            let columns = if p.len() == 8 { 4 } else { 3 };
            panels = (p, columns, (500 * columns as u32, 1000));
        }
    } else if plot {
        let filter = model.and_then(|m| white_allan(m, dt));
        panels.0 = report::panels_filtered(res, theory.as_deref(), filter.as_ref(), &s.title);
        // Two columns; a row per pair (one sensor, or a table's two ADEV panels).
        let rows = panels.0.len().div_ceil(2).max(1) as u32;
        panels.2 = (1600, 600 * rows);
    }
    AnalysisReport {
        text,
        verdict,
        compare_csv,
        plot: panels,
        curves_csv: report::curves_csv(res, theory.as_deref()),
    }
}
