//! Presenting an [`Analysis`]: text tables in datasheet units, the plot panels (ADEV and PSD,
//! gyro and accelerometer, theory overlaid) and a CSV of the curves. Pure: strings and
//! [`Panel`]s out, the caller writes them.

use std::f64::consts::PI;
use std::fmt::Write;

use super::analyzer::Dropped;
use super::analyzer::{Analysis, CHANNELS};
use super::conformance::{TermRow, filtered_avar, filtered_psd};
use super::fit::{TERMS, Term};
use super::octave_adev::CONFIDENCE;
use super::psd_band::{BandedPsd, banded};
use super::theory::AxisTheory;
use super::transients::{Handling, Transients};
use crate::errors::filter_allan::SensorAllan;
use crate::plot::{Panel, Series};
use crate::units::G0;

const DEG: f64 = 180.0 / PI;

/// Datasheet unit and factor (SI × factor = shown value) of a term for gyro or accel.
pub fn term_unit(gyro: bool, t: Term) -> (&'static str, f64) {
    match (gyro, t) {
        (true, Term::Quantization) => ("urad", 1e6),
        (true, Term::WhiteNoise) => ("deg/sqrt(h)", DEG * 60.0),
        (true, Term::BiasInstability) => ("deg/h", DEG * 3600.0),
        (true, Term::RandomWalk) => ("deg/h/sqrt(h)", DEG * 3600.0 * 60.0),
        (true, Term::Ramp) => ("deg/h^2", DEG * 3600.0 * 3600.0),
        (false, Term::Quantization) => ("mm/s", 1e3),
        (false, Term::WhiteNoise) => ("m/s/sqrt(h)", 60.0),
        (false, Term::BiasInstability) => ("ug", 1.0 / (G0 * 1e-6)),
        (false, Term::RandomWalk) => ("m/s/h/sqrt(h)", 3600.0 * 60.0),
        (false, Term::Ramp) => ("m/s/h^2", 3600.0 * 3600.0),
    }
}

/// Unit and factor of ADEV curves: deg/h for gyros, µg for accelerometers.
pub fn adev_unit(gyro: bool) -> (&'static str, f64) {
    if gyro {
        ("deg/h", DEG * 3600.0)
    } else {
        ("ug", 1.0 / (G0 * 1e-6))
    }
}

/// Per-channel mean, std, min, max (gyro deg/s, accel m/s²).
pub fn stats_table(a: &Analysis) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<8} {:>14} {:>14} {:>14} {:>14}  unit",
        "channel", "mean", "std", "min", "max"
    );
    for (i, c) in a.channels.iter().enumerate() {
        let (unit, f) = if i < 3 {
            ("deg/s", DEG)
        } else {
            ("m/s^2", 1.0)
        };
        let st = &c.stats;
        if st.n == 0 {
            let _ = writeln!(s, "{:<8} (not in the input)", CHANNELS[i]);
            continue;
        }
        let _ = writeln!(
            s,
            "{:<8} {:>14.6e} {:>14.6e} {:>14.6e} {:>14.6e}  {unit}",
            CHANNELS[i],
            st.mean * f,
            st.std() * f,
            st.min * f,
            st.max * f
        );
    }
    s
}

/// The fitted terms per channel; with `rows` (from [`super::conformance::term_rows`]) also the
/// template's value, the ratio, the band and the verdict. Terms neither fitted nor specified
/// are left out.
pub fn term_table(a: &Analysis, rows: Option<&[TermRow]>) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "{:<8} {:<3} {:>11} {:<14} {:>10} {:>6}",
        "channel", "", "fitted", "unit", "τ read (s)", "share"
    );
    if rows.is_some() {
        let _ = write!(
            s,
            " {:>11} {:>7} {:>25}  verdict",
            "template", "ratio", "99 % band"
        );
    }
    s.push('\n');
    // A channel the input does not have has no row (not even a template's figure to miss).
    for (ch, c) in a
        .channels
        .iter()
        .enumerate()
        .filter(|(_, c)| !c.adev.is_empty())
    {
        for t in TERMS {
            let row = rows.and_then(|r| {
                r.iter()
                    .find(|r| r.term == t && r.axis == ch % 3 && (r.sensor == "gyro") == (ch < 3))
            });
            // Against a template, the template-aware refit (see `conformance`).
            let mut f = c.fit.term(t);
            if let Some(r) = row {
                (f.value, f.tau, f.share) = (r.fitted, r.tau, r.share);
            }
            let specified = row.map_or(0.0, |r| r.specified);
            if f.value == 0.0 && specified == 0.0 {
                continue;
            }
            let (unit, k) = term_unit(ch < 3, t);
            let _ = write!(
                s,
                "{:<8} {:<3} {:>11.4} {:<14} {:>10} {:>6.2}",
                CHANNELS[ch],
                t.symbol(),
                f.value * k,
                unit,
                f.tau.map_or("-".into(), |t| format!("{t:.3}")),
                f.share
            );
            if let Some(r) = row {
                let band = r.band.map_or("-".to_string(), |(lo, hi)| {
                    format!("[{:.4}, {:.4}]", lo * k, hi * k)
                });
                let verdict = match (r.pass, r.resolved) {
                    (Some(true), _) => "pass",
                    (Some(false), _) => "FAIL",
                    (None, false) => "not resolved (hidden by other terms or record too short)",
                    (None, true) => "not specified",
                };
                let ratio = if r.specified > 0.0 {
                    format!("{:.3}", r.ratio())
                } else {
                    "-".into()
                };
                let _ = write!(
                    s,
                    " {:>11.4} {:>7} {:>25}  {verdict}",
                    r.specified * k,
                    ratio,
                    band
                );
            }
            s.push('\n');
        }
    }
    s
}

/// Four panels: ADEV gyro, ADEV accel, PSD gyro, PSD accel, three axes each with 68 % bands,
/// the template's exact theory dashed (and its nominal IEEE curve dotted when it sets B).
pub fn panels(a: &Analysis, theory: Option<&[AxisTheory]>, title: &str) -> Vec<Panel> {
    panels_filtered(a, theory, None, title)
}

/// [`panels`] for a template with an output filter: its theory ADEV and PSD are the filtered
/// ones ([`filtered_avar`], [`filtered_psd`]).
pub fn panels_filtered(
    a: &Analysis,
    theory: Option<&[AxisTheory]>,
    filter: Option<&SensorAllan>,
    title: &str,
) -> Vec<Panel> {
    let mut out = Vec::new();
    // The axes the input has (a CSV of some axes, a table of one sensor): the others get no
    // curve, and a sensor with none gets no panel.
    let adev_axes = |base: usize| -> Vec<usize> {
        (0..3)
            .filter(|i| !a.channels[base + i].adev.is_empty())
            .collect()
    };
    let psd_axes = |base: usize| -> Vec<usize> {
        (0..3)
            .filter(|i| a.channels[base + i].psd.segments > 0)
            .collect()
    };
    for gyro in [true, false] {
        let (unit, k) = adev_unit(gyro);
        let base = if gyro { 0 } else { 3 };
        let sensor = if gyro { "gyro" } else { "accel" };
        let axes = adev_axes(base);
        if axes.is_empty() {
            continue;
        }
        let mut series = Vec::new();
        for axis in axes {
            let c = &a.channels[base + axis];
            series.push(Series {
                label: ["x", "y", "z"][axis].into(),
                x: c.adev.iter().map(|p| p.tau).collect(),
                y: c.adev.iter().map(|p| p.adev * k).collect(),
                band: Some((
                    c.adev.iter().map(|p| p.lo * k).collect(),
                    c.adev.iter().map(|p| p.hi * k).collect(),
                )),
                color: axis,
                dashed: false,
            });
        }
        if let Some(th) = theory {
            let ms: Vec<usize> = a.channels[base + adev_axes(base)[0]]
                .adev
                .iter()
                .map(|p| p.m)
                .collect();
            theory_series(&th[base..base + 3], &mut series, |t| {
                ms.iter()
                    .map(|&m| {
                        let avar = filtered_avar(t, filter.map(|f| f.sensor(!gyro)), m, a.dt);
                        (m as f64 * a.dt, avar.sqrt() * k)
                    })
                    .unzip()
            });
            let t0 = &th[base];
            if t0.bias_instability > 0.0 {
                series.push(Series {
                    label: "IEEE nominal (0.664 B floor)".into(),
                    x: ms.iter().map(|&m| m as f64 * a.dt).collect(),
                    y: ms
                        .iter()
                        .map(|&m| t0.nominal_avar(m as f64 * a.dt).sqrt() * k)
                        .collect(),
                    band: None,
                    color: 4,
                    dashed: true,
                });
            }
        }
        out.push(Panel {
            title: format!("{title}: {sensor} Allan deviation"),
            x_label: "τ (s)".into(),
            y_label: format!("σ(τ) ({unit})"),
            log_x: true,
            log_y: true,
            series,
        });
    }
    for gyro in [true, false] {
        let (unit, k) = adev_unit(gyro);
        let base = if gyro { 0 } else { 3 };
        let sensor = if gyro { "gyro" } else { "accel" };
        let axes = psd_axes(base);
        if axes.is_empty() {
            continue;
        }
        let mut series = Vec::new();
        for &axis in &axes {
            let p = banded_psd(&a.channels[base + axis].psd, k);
            series.push(Series {
                label: ["x", "y", "z"][axis].into(),
                x: p.freq,
                y: p.density,
                band: Some((p.lo, p.hi)),
                color: axis,
                dashed: false,
            });
        }
        if let Some(th) = theory {
            let p = &a.channels[base + axes[0]].psd;
            let (freq, _) = log_bins(plotted(&p.freq), &p.density, PSD_BINS_PER_DECADE);
            theory_series(&th[base..base + 3], &mut series, |t| {
                (
                    freq.clone(),
                    freq.iter()
                        .map(|&f| filtered_psd(t, filter.map(|w| w.sensor(!gyro)), f, a.dt) * k * k)
                        .collect(),
                )
            });
        }
        out.push(Panel {
            title: format!("{title}: {sensor} PSD (Welch, Hann)"),
            x_label: "f (Hz)".into(),
            y_label: format!("PSD ({unit})²/Hz"),
            log_x: true,
            log_y: true,
            series,
        });
    }
    out
}

/// The frequencies plotted: all but the Nyquist bin, whose one-sided density carries half
/// the level by construction (it has no mirror image) and would look like a roll-off.
fn plotted(freq: &[f64]) -> &[f64] {
    &freq[..freq.len().saturating_sub(1)]
}

/// A PSD as plotted: log bands with their 68 % χ² interval, densities scaled by `k²`.
pub fn banded_psd(p: &super::psd::Psd, k: f64) -> BandedPsd {
    let mut b = banded(p, PSD_BINS_PER_DECADE, CONFIDENCE);
    for v in [&mut b.density, &mut b.lo, &mut b.hi] {
        v.iter_mut().for_each(|d| *d *= k * k);
    }
    b
}

/// Plotted PSDs are averaged over log-spaced frequency bands (the CSV keeps every bin).
pub const PSD_BINS_PER_DECADE: f64 = 25.0;

/// Averages (f, P) over bands of 1/`per_decade` decade (f = 0 left out): a readable log-log
/// curve whose scatter shrinks with frequency as more Welch bins fall in each band.
pub fn log_bins(freq: &[f64], density: &[f64], per_decade: f64) -> (Vec<f64>, Vec<f64>) {
    super::psd_band::log_groups(freq, density, per_decade)
        .into_iter()
        .map(|(f, p, _)| (f, p))
        .unzip()
}

/// Adds the theory curves: one black dashed curve when the three axes share the same model,
/// else one dashed curve per axis in its colour.
fn theory_series(
    th: &[AxisTheory],
    series: &mut Vec<Series>,
    curve: impl Fn(&AxisTheory) -> (Vec<f64>, Vec<f64>),
) {
    let same = th.iter().all(|t| *t == th[0]);
    let axes: Vec<usize> = if same { vec![0] } else { vec![0, 1, 2] };
    for i in axes {
        let (x, y) = curve(&th[i]);
        if y.iter().all(|v| *v == 0.0) {
            continue;
        }
        series.push(Series {
            label: if same {
                "template (exact)".into()
            } else {
                format!("template {}", ["x", "y", "z"][i])
            },
            x,
            y,
            band: None,
            color: if same { 5 } else { i },
            dashed: true,
        });
    }
}

/// The curves as CSV rows `kind,channel,x,y,lo,hi` in SI (x = τ in s or f in Hz): kinds
/// `adev` (with its 68 % interval), `psd`, and with a template `theory_adev`,
/// `nominal_adev`, `theory_psd`.
pub fn curves_csv(a: &Analysis, theory: Option<&[AxisTheory]>) -> String {
    let mut s = String::from("kind,channel,x,y,lo,hi\n");
    let name = |i: usize| CHANNELS[i].replace(' ', "_");
    for (i, c) in a.channels.iter().enumerate() {
        for p in &c.adev {
            let _ = writeln!(s, "adev,{},{},{},{},{}", name(i), p.tau, p.adev, p.lo, p.hi);
        }
        for (f, d) in c.psd.freq.iter().zip(&c.psd.density) {
            let _ = writeln!(s, "psd,{},{f},{d},,", name(i));
        }
        if let Some(th) = theory {
            let t = &th[i];
            for p in &c.adev {
                let _ = writeln!(
                    s,
                    "theory_adev,{},{},{},,",
                    name(i),
                    p.tau,
                    t.avar(p.m, a.dt).sqrt()
                );
                let _ = writeln!(
                    s,
                    "nominal_adev,{},{},{},,",
                    name(i),
                    p.tau,
                    t.nominal_avar(p.tau).sqrt()
                );
            }
            for f in c.psd.freq.iter().skip(1) {
                let _ = writeln!(s, "theory_psd,{},{f},{},,", name(i), t.psd(*f, a.dt));
            }
        }
    }
    s
}

/// One sentence on the samples a record dropped: how many, where the longest gap is, and what
/// was done with them.
pub fn dropped_summary(d: &Dropped) -> String {
    let (_, t, most) =
        d.at.iter()
            .copied()
            .max_by_key(|a| (a.2, std::cmp::Reverse(a.0)))
            .expect("a record's drops are not empty");
    let gaps = d.at.len();
    format!(
        "{} sample{} dropped in {gaps} gap{} (the longest {most} at t = {:.2} s from the start): put back on the time grid at Δt = {} s and left out of every statistic as transients are",
        d.samples(),
        if d.samples() == 1 { "" } else { "s" },
        if gaps == 1 { "" } else { "s" },
        t,
        d.dt
    )
}

/// One sentence on a record's transients: how many, where the largest is, what was done.
pub fn transients_summary(t: &Transients, dt: f64) -> String {
    let big = t
        .list
        .iter()
        .max_by(|a, b| a.z.total_cmp(&b.z))
        .expect("a record's transients are not empty");
    let (unit, k) = crate::units::report_unit(big.channel < 3);
    let n = t.list.len();
    let what = if n == 1 {
        "1 transient (a knock or a spike)".to_string()
    } else {
        format!("{n} transients (knocks or spikes)")
    };
    let largest = format!(
        "the largest a step of {:.4} {unit} on {} at t = {:.2} s from the start ({:.0}× its channel's step RMS; the bar is {:.0}×)",
        big.step * k,
        CHANNELS[big.channel],
        big.first as f64 * dt,
        big.z,
        t.z
    );
    match t.handling {
        Handling::LeftOut => format!(
            "{what}, {largest}: left out of the statistics with {:.3} s on each side ({} samples); --keep-transients keeps them",
            t.pad as f64 * dt,
            t.left_out()
        ),
        Handling::Kept => format!("{what}, {largest}: kept (--keep-transients)"),
        Handling::HeavyTailed => format!(
            "{what}, {largest}: too many to leave out (more than {:.0} % of the record would go): the noise is heavy-tailed; kept, and a Gaussian model reproduces their variance, not their tails",
            100.0 * super::transients::MAX_LEFT_OUT
        ),
    }
}
