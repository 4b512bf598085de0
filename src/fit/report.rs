//! The fit report: a Markdown summary (terms with intervals, lines, closure) and the plot
//! panels (per channel: the recording's ADEV with its band, the fitted model, the ADEV of a
//! record simulated from the fitted template). Pure: text and panels out.

use std::fmt::Write;

use super::closure::{ClosurePoint, PSD_BANDS_PER_DECADE, PSD_FROM_HZ, PsdPoint};
use super::gmwm::{AxisFit, COMPONENTS, Component};
use super::lines::Line;
use super::ramp::{GATE_CONFIDENCE, RampTest, normal_point};
use super::template::{Provenance, sig4};
use crate::analysis::analyzer::Dropped;
use crate::analysis::analyzer::{Analysis, CHANNELS};
use crate::analysis::report::adev_unit;
use crate::analysis::report::{dropped_summary, transients_summary};
use crate::analysis::transients::{MIN_Z, Transients};
use crate::plot::{Panel, Series};

/// The Markdown report; `plot` is the picture's file name as the report links it.
pub fn markdown(
    p: &Provenance,
    fits: &[Option<AxisFit>],
    lines: &[Vec<Line>],
    closure: &Closure,
    plot: Option<&str>,
    transients: Option<&Transients>,
    dropped: Option<&Dropped>,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Fit of {}\n\n{} samples at {} Hz ({} s). Method and statistics: docs/fit.md.\n",
        p.source,
        p.samples,
        sig4(1.0 / p.dt),
        sig4(p.samples as f64 * p.dt)
    );
    if let Some(plot) = plot {
        let _ = writeln!(
            s,
            "![Allan deviation: recording, fitted model, simulated from the template]({plot})\n"
        );
    }
    let _ = writeln!(
        s,
        "| channel | term | value | 99 % interval | read at τ (s) | share of σ² | Δχ² |\n| --- | --- | --- | --- | --- | --- | --- |"
    );
    for (ch, fit) in fits.iter().enumerate() {
        let Some(fit) = fit else {
            let why = if p.missing[ch] {
                "(not in the input)"
            } else {
                "(no usable Allan deviation)"
            };
            let _ = writeln!(s, "| {} | {why} | | | | | |", CHANNELS[ch]);
            continue;
        };
        let gyro = ch < 3;
        let ramp = fit.ramp_alternative.map(|e| (Component::Ramp, e));
        let kept = COMPONENTS
            .iter()
            .filter_map(|&k| fit.estimate(k).map(|e| (k, e)));
        for (k, e) in kept.chain(ramp) {
            let (u, f) = super::template::unit(gyro, k);
            let mut name = k.name().to_string();
            if k == Component::BiasInstability {
                let b = fit.model.band;
                name = format!("{name} (band {}–{} s)", sig4(b.0), sig4(b.1));
            }
            if k == Component::Ramp {
                name = format!(
                    "{name} (not in the template: the other figures are the fit without it)"
                );
            }
            if k == Component::GaussMarkov {
                let (lo, hi) = fit
                    .gm_tau_interval
                    .unwrap_or((fit.model.gm_tau, fit.model.gm_tau));
                name = format!(
                    "{name} (T = {} s, [{}, {}])",
                    sig4(fit.model.gm_tau),
                    sig4(lo),
                    sig4(hi)
                );
            }
            let _ = writeln!(
                s,
                "| {} | {name} | {} {u} | [{}, {}] | {} | {:.0} % | {} |",
                CHANNELS[ch],
                sig4(e.value * f),
                sig4(e.lo * f),
                sig4(e.hi * f),
                sig4(e.tau),
                100.0 * e.share,
                sig4(e.gain)
            );
        }
    }
    ramp_rows(&mut s, fits);
    let any_line = lines.iter().any(|l| !l.is_empty());
    let _ = writeln!(s, "\n## Spectral lines\n");
    if !any_line {
        let _ = writeln!(
            s,
            "None above the false-alarm threshold (1 in 1000 records of noise)."
        );
    }
    for (ch, ls) in lines.iter().enumerate() {
        for l in ls {
            let (u, f) = crate::units::report_unit(ch < 3);
            let _ = writeln!(
                s,
                "- {}: {} Hz, amplitude {} {u} ({}× the background)",
                CHANNELS[ch],
                sig4(l.freq),
                sig4(l.amplitude * f),
                sig4(l.ratio)
            );
        }
    }
    let _ = writeln!(s, "\n## Broad resonances\n");
    if p.resonances.iter().all(Vec::is_empty) {
        let _ = writeln!(
            s,
            "{}",
            if p.table {
                "None that gains χ²₃(99 %) in the Allan deviation (a table has no PSD)."
            } else {
                "None above the false-alarm threshold (1 in 1000 records whose PSD is the fitted floor)."
            }
        );
    }
    for (ch, rs) in p.resonances.iter().enumerate() {
        for r in rs {
            let _ = writeln!(
                s,
                "- {}: {}",
                CHANNELS[ch],
                super::template::describe_resonance(r, ch < 3)
            );
        }
    }
    if let Some(d) = dropped {
        let _ = writeln!(s, "\n## Dropped samples\n\n{}.", dropped_summary(d));
    }
    if !p.table {
        transients_section(&mut s, transients, p.dt);
    }
    closure_section(&mut s, closure, &p.missing);
    s
}

/// `## Transients`: what was found beyond the bar, where, and what was done with it.
fn transients_section(s: &mut String, t: Option<&Transients>, dt: f64) {
    let _ = writeln!(s, "\n## Transients\n");
    let Some(t) = t else {
        let _ = writeln!(
            s,
            "None: no step between samples beyond {} times its channel's step RMS (docs/fit.md).",
            sig4(MIN_Z)
        );
        return;
    };
    let _ = writeln!(s, "{}.\n", transients_summary(t, dt));
    let _ = writeln!(
        s,
        "| samples | t from the start (s) | largest step | on | × step RMS |\n| --- | --- | --- | --- | --- |"
    );
    for x in t.list.iter().take(MAX_ROWS) {
        let (u, k) = crate::units::report_unit(x.channel < 3);
        let _ = writeln!(
            s,
            "| {}–{} | {} … {} | {} {u} | {} | {:.0} |",
            x.first + 1,
            x.last + 1,
            sig4(x.first as f64 * dt),
            sig4(x.last as f64 * dt),
            sig4(x.step * k),
            CHANNELS[x.channel],
            x.z
        );
    }
    if t.list.len() > MAX_ROWS {
        let _ = writeln!(s, "\n({} more not listed.)", t.list.len() - MAX_ROWS);
    }
}

/// Transients listed in the report at most.
const MAX_ROWS: usize = 50;

/// The closure check of every channel: Allan deviation per octave and PSD per band.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Closure {
    /// Per channel, the octaves from Δt to T/8.
    pub adev: Vec<Vec<ClosurePoint>>,
    /// Per channel, the PSD bands from 0.01 Hz to the Nyquist frequency (empty for a table).
    pub psd: Vec<Vec<PsdPoint>>,
}

impl Closure {
    /// Octaves and bands outside their band, over all channels.
    pub fn failures(&self) -> usize {
        let a = self.adev.iter().flatten().filter(|p| !p.inside()).count();
        a + self.psd.iter().flatten().filter(|p| !p.inside()).count()
    }
}

fn verdict(inside: bool) -> &'static str {
    if inside { "inside" } else { "**OUTSIDE**" }
}

/// `## Closure`: a summary line per channel, then every octave and band with its verdict;
/// the channels the input does not have are named once.
fn closure_section(s: &mut String, c: &Closure, missing: &[bool; 6]) {
    let _ = writeln!(
        s,
        "\n## Closure\n\nA static record of the same length simulated from the fitted template (as written, loaded back):\nits Allan deviation at every octave from Δt to T/8, and its PSD over bands of 1/{} decade from {} Hz to\nthe Nyquist frequency, against the recording's bands (±4σ of the difference, docs/fit.md).\n",
        PSD_BANDS_PER_DECADE, PSD_FROM_HZ
    );
    if c.adev.iter().all(Vec::is_empty) {
        let _ = writeln!(s, "No closure check was run.");
        return;
    }
    let absent: Vec<&str> = (0..6)
        .filter(|&ch| missing[ch])
        .map(|ch| CHANNELS[ch])
        .collect();
    if !absent.is_empty() {
        let _ = writeln!(s, "Not in the input: {}.\n", absent.join(", "));
    }
    let present = |&(ch, _): &(usize, _)| !missing[ch];
    for (ch, (a, name)) in c.adev.iter().zip(CHANNELS).enumerate().filter(present) {
        let p = c.psd.get(ch).map_or(&[][..], Vec::as_slice);
        let _ = writeln!(
            s,
            "- {}: Allan deviation {} of {} octaves inside; PSD {} of {} bands inside",
            name,
            a.iter().filter(|x| x.inside()).count(),
            a.len(),
            p.iter().filter(|x| x.inside()).count(),
            p.len()
        );
    }
    for (ch, (adev, name)) in c.adev.iter().zip(CHANNELS).enumerate().filter(present) {
        let (unit, k) = adev_unit(ch < 3);
        let _ = writeln!(
            s,
            "\n### {name}\n\n| τ (s) | recording ({unit}) | simulated | band | verdict |\n| --- | --- | --- | --- | --- |"
        );
        for q in adev {
            let _ = writeln!(
                s,
                "| {} | {} | {} | [{}, {}] | {} |",
                sig4(q.tau),
                sig4(q.recorded * k),
                sig4(q.simulated * k),
                sig4(q.lo * k),
                sig4(q.hi * k),
                verdict(q.inside())
            );
        }
        let Some(p) = c.psd.get(ch).filter(|p| !p.is_empty()) else {
            continue;
        };
        let _ = writeln!(
            s,
            "\n| f (Hz) | bins | PSD recording (({unit})²/Hz) | simulated | band | verdict |\n| --- | --- | --- | --- | --- | --- |"
        );
        for q in p {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | [{}, {}] | {} |",
                sig4(q.freq),
                q.bins,
                sig4(q.recorded * k * k),
                sig4(q.simulated * k * k),
                sig4(q.lo * k * k),
                sig4(q.hi * k * k),
                verdict(q.inside())
            );
        }
    }
}

/// The time-domain ramp of each channel of a recording: kept ones with their interval, the
/// others with their z.
fn ramp_rows(s: &mut String, fits: &[Option<AxisFit>]) {
    let gate = normal_point(GATE_CONFIDENCE);
    let tests: Vec<(usize, RampTest)> = fits
        .iter()
        .enumerate()
        .filter_map(|(ch, f)| Some((ch, f.as_ref()?.ramp?)))
        .collect();
    if tests.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Rate ramp\n\nLeast-squares slope of each channel against its σ under the model fitted without a ramp;\nkept when |z| > {gate:.2} (99.9 % two-sided), then the other terms are fitted around the line.\n\n| channel | slope | z | kept | 99 % interval |\n| --- | --- | --- | --- | --- |"
    );
    for (ch, t) in tests {
        let (u, f) = super::template::unit(ch < 3, Component::Ramp);
        let iv = t.interval.map_or(String::new(), |(lo, hi)| {
            format!("[{}, {}] {u}", sig4(lo * f), sig4(hi * f))
        });
        let _ = writeln!(
            s,
            "| {} | {} {u} | {:.2} | {} | {iv} |",
            CHANNELS[ch],
            sig4(t.slope * f),
            t.z,
            if t.kept { "yes" } else { "no" }
        );
    }
}

/// How many of a sensor's axes (from channel `base`) have a PSD in `a`.
fn present(a: &Analysis, base: usize) -> usize {
    (0..3)
        .filter(|i| a.channels[base + i].psd.segments > 0)
        .count()
}

/// The fit's picture as a grid: a row per sensor the input has, its channels' ADEV panels
/// then its PSD panel; returns the panels (blank ones pad a shorter row) and the columns.
pub fn grid(
    recorded: &Analysis,
    fits: &[Option<AxisFit>],
    simulated: Option<&Analysis>,
    title: &str,
) -> (Vec<Panel>, usize) {
    let mut adev = panels(recorded, fits, simulated, title).into_iter();
    let mut psd = psd_panels(recorded, simulated, title)
        .into_iter()
        .peekable();
    let mut rows: Vec<Vec<Panel>> = Vec::new();
    for base in [0, 3] {
        let mut row: Vec<Panel> = (0..3)
            .filter_map(|a| {
                Some(adev.next()?).filter(|_| !recorded.channels[base + a].adev.is_empty())
            })
            .collect();
        let sensor = if base == 0 { "gyro" } else { "accel" };
        if psd
            .peek()
            .is_some_and(|p| p.title.ends_with(&format!("{sensor} PSD")))
        {
            row.extend(psd.next());
        }
        if !row.is_empty() {
            rows.push(row);
        }
    }
    let columns = rows.iter().map(Vec::len).max().unwrap_or(1);
    let mut out = Vec::new();
    for mut row in rows {
        row.resize_with(columns, Panel::default);
        out.extend(row);
    }
    (out, columns)
}

/// One PSD panel per sensor: the recording's three axes with their 68 % bands (solid) and
/// the simulated record's (dashed).
pub fn psd_panels(recorded: &Analysis, simulated: Option<&Analysis>, title: &str) -> Vec<Panel> {
    [0, 3]
        .map(|base| {
            let (unit, k) = adev_unit(base == 0);
            let mut series = Vec::new();
            let axes: Vec<&str> = (0..3)
                .filter(|a| recorded.channels[base + a].psd.segments > 0)
                .map(|a| ["x", "y", "z"][a])
                .collect();
            for (i, a) in std::iter::once(recorded).chain(simulated).enumerate() {
                // The axes the recording has (the simulation has all six).
                for axis in (0..3).filter(|a| recorded.channels[base + a].psd.segments > 0) {
                    let p = &a.channels[base + axis].psd;
                    if p.segments == 0 {
                        continue;
                    }
                    let b = crate::analysis::report::banded_psd(p, k);
                    series.push(Series {
                        label: match (i, series.len()) {
                            (0, 0) => format!("recording {} (68 % band)", axes.join(" ")),
                            (_, n) if n == present(recorded, base) => {
                                "simulated from the template".into()
                            }
                            _ => String::new(),
                        },
                        x: b.freq,
                        y: b.density,
                        band: (i == 0).then_some((b.lo, b.hi)),
                        color: if i == 0 { 0 } else { 2 },
                        dashed: i > 0,
                    });
                }
            }
            Panel {
                title: format!("{title}: {} PSD", if base == 0 { "gyro" } else { "accel" }),
                x_label: "f (Hz)".into(),
                y_label: format!("PSD ({unit})²/Hz"),
                log_x: true,
                log_y: true,
                series,
            }
        })
        .into_iter()
        .filter(|p| !p.series.is_empty())
        .collect()
}

/// One ADEV panel per channel (gyro x y z, accel x y z): the recording with its 68 % band,
/// the fitted model (dashed) and the simulated record.
pub fn panels(
    recorded: &Analysis,
    fits: &[Option<AxisFit>],
    simulated: Option<&Analysis>,
    title: &str,
) -> Vec<Panel> {
    (0..6)
        .map(|ch| {
            let (unit, k) = adev_unit(ch < 3);
            let c = &recorded.channels[ch];
            let mut series = vec![Series {
                label: "recording (68 % band)".into(),
                x: c.adev.iter().map(|p| p.tau).collect(),
                y: c.adev.iter().map(|p| p.adev * k).collect(),
                band: Some((
                    c.adev.iter().map(|p| p.lo * k).collect(),
                    c.adev.iter().map(|p| p.hi * k).collect(),
                )),
                color: 0,
                dashed: false,
            }];
            if let Some(fit) = &fits[ch] {
                series.push(Series {
                    label: "fitted model".into(),
                    x: c.adev.iter().map(|p| p.tau).collect(),
                    y: c.adev
                        .iter()
                        .map(|p| fit.model.avar(p.m).sqrt() * k)
                        .collect(),
                    band: None,
                    color: 1,
                    dashed: true,
                });
            }
            if let Some(sim) = simulated {
                let a = &sim.channels[ch].adev;
                series.push(Series {
                    label: "simulated from the template".into(),
                    x: a.iter().map(|p| p.tau).collect(),
                    y: a.iter().map(|p| p.adev * k).collect(),
                    band: None,
                    color: 2,
                    dashed: false,
                });
            }
            Panel {
                title: format!("{title}: {}", CHANNELS[ch]),
                x_label: "τ (s)".into(),
                y_label: format!("σ(τ) ({unit})"),
                log_x: true,
                log_y: true,
                series,
            }
        })
        .collect()
}
