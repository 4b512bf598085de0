//! The fit report: a Markdown summary (terms with intervals, lines, closure) and the plot
//! panels (per channel: the recording's ADEV with its band, the fitted model, the ADEV of a
//! record simulated from the fitted template). Pure: text and panels out.

use std::fmt::Write;

use super::closure::ClosurePoint;
use super::gmwm::{AxisFit, COMPONENTS, Component};
use super::lines::Line;
use super::ramp::{GATE_CONFIDENCE, RampTest, normal_point};
use super::template::{Provenance, sig4};
use crate::analysis::analyzer::{Analysis, CHANNELS};
use crate::analysis::report::adev_unit;
use crate::plot::{Panel, Series};

/// The Markdown report; `plot` is the picture's file name as the report links it.
pub fn markdown(
    p: &Provenance,
    fits: &[Option<AxisFit>],
    lines: &[Vec<Line>],
    closure: &[Vec<ClosurePoint>],
    plot: Option<&str>,
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
            let _ = writeln!(
                s,
                "| {} | (no usable Allan deviation) | | | | | |",
                CHANNELS[ch]
            );
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
            let (u, f) = if ch < 3 {
                ("deg/s", 180.0 / std::f64::consts::PI)
            } else {
                ("g", 1.0 / crate::units::G0)
            };
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
    let _ = writeln!(
        s,
        "\n## Closure\n\nA static record of the same length simulated from the fitted template; its Allan deviation\nagainst the recording's band (±4σ of the difference, docs/fit.md) at every octave from Δt to T/8.\n"
    );
    for (ch, c) in closure.iter().enumerate() {
        let inside = c.iter().filter(|p| p.inside()).count();
        let worst = c
            .iter()
            .map(|p| (p.simulated / p.recorded).ln().abs() / (p.hi / p.recorded).ln())
            .fold(0.0, f64::max);
        let _ = writeln!(
            s,
            "- {}: {inside} of {} octaves inside; largest deviation {:.0} % of the band's half-width",
            CHANNELS[ch],
            c.len(),
            100.0 * worst
        );
    }
    s
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
