//! This run against a reference (`analyze --reference`): the stochastic terms of both fitted
//! by [`super::gmwm`] with their 99 % intervals, compared term by term, and the overlay of
//! both Allan deviations (and PSDs) with their bands. Pure: no I/O.

use std::fmt::Write as _;

use super::filter::FittedFilter;
use super::gmwm::{AxisFit, COMPONENTS, Component, Estimate, OutputStage, fit_triad_with};
use super::resonance::{KnownVibration, Resonance, source_table};
use super::template::{sig4, unit};
use crate::analysis::analyzer::{Analysis, CHANNELS};
use crate::analysis::octave_adev::AdevPoint;
use crate::analysis::report::{adev_unit, banded_psd};
use crate::errors::output_filter::FilterSpec;
use crate::plot::{Panel, Series};

/// The fits of the six channels (gyro x y z, accel x y z; None where a channel has no
/// usable Allan deviation), one band per triad as a template holds it. A recording's ramp is
/// tested on its time series ([`super::ramp`]); a table's is sought as an Allan-variance
/// alternative.
pub fn fit_all(a: &Analysis) -> Vec<Option<AxisFit>> {
    fit_all_with_filter(a).fits
}

/// The fits of a recording with the output stage they took.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// The six channels' fits.
    pub fits: Vec<Option<AxisFit>>,
    /// The output filter kept.
    pub filter: Option<FittedFilter>,
    /// How an LSB found on the lattice quantizes: true for carry (pulse accumulation, error
    /// 3Q²/τ²), false for per-sample rounding (white q²/12).
    pub carry: bool,
}

/// [`fit_all`] and the output filter it took. Values on a lattice are quantized, but a rate
/// grid does not say how: a unit that rounds each sample adds white noise q²/12 per sample, one
/// that accumulates pulses and carries the residual (the generator's carry mode) an angle error
/// uniform over qΔt, 3Q²/τ². Under each quantizer the recording's PSD roll-off names the best
/// filter ([`super::filter::fit_excluding`]: one for both sensors, or the accelerometers' own
/// when it earns it; the quantizer's known density is part of the roll-off), and the
/// Allan-variance fit is run with it and, for a series, without it. The cheapest of these is
/// kept, its cost the fits' cost, plus the misfit of the PSD the fitted model draws in the top
/// decade ([`super::filter::psd_misfit`]: the Allan variance alone takes a carried LSB under a
/// steeper filter for a rounded one under the true filter), plus
/// [`super::filter::FILTER_PENALTY`] per filter kept (the top decade of a PSD also falls for a
/// Gauss–Markov term of T ≈ 10Δt, which the unfiltered fit models exactly). A table's filter is
/// read from its shortest τ ([`super::filter::fit_adev`]) and kept as read.
pub fn fit_all_with_filter(a: &Analysis) -> Fitted {
    fit_all_with_resonances(a, &[])
}

/// [`fit_all_with_filter`] with the broad resonances `res` of each channel (gyro x y z, accel
/// x y z; empty: none) as known random vibrations ([`super::resonance`]), each shaped by the
/// output filter of the variant fitted.
pub fn fit_all_with_resonances(a: &Analysis, res: &[Vec<Resonance>]) -> Fitted {
    let series = a.channels.iter().all(|c| c.trend.is_some());
    let lattice = triad_lsbs(a).iter().any(Option::is_some);
    let ranges: Vec<Vec<(f64, f64)>> = res
        .iter()
        .map(|r| r.iter().map(Resonance::range).collect())
        .collect();
    let roll = super::filter::roll_off(a, &ranges);
    let cost = |f: &[Option<AxisFit>]| f.iter().flatten().map(|f| f.cost).sum::<f64>();
    let mut best: Option<(f64, Fitted)> = None;
    // The variants share filters (the quantizers often read the same one, and the unfiltered
    // option recurs): each resonance's Allan variance is built once per filter.
    let built = Built::default();
    for carry in if lattice {
        vec![false, true]
    } else {
        vec![false]
    } {
        // The filter is read under each quantizer: the LSB's noise adds to the roll-off.
        let filter = super::filter::fit_roll_off(a, &roll, &ranges, &output_stages(a, carry));
        let mut options = vec![filter.clone()];
        if filter.is_some() && series {
            options.push(None);
        }
        for f in options {
            let fits = fit_with(a, f.as_ref(), carry, res, &built);
            // Each filter costs the penalty it must beat (the accelerometers' own a second
            // one), against the fits of either quantizer: a carry quantizer's noise rises
            // towards the Nyquist frequency, and a filter that takes it back must not come free.
            let filters = f
                .as_ref()
                .map_or(0, |f| 1 + usize::from(f.spec.accel.is_some()));
            // And each post-filter floor the one it had to beat.
            let floors = f
                .as_ref()
                .map_or(0, |f| f.floors.iter().filter(|x| x.ratio > 0.0).count());
            let penalty = filters as f64 * super::filter::FILTER_PENALTY
                + floors as f64 * super::filter::FLOOR_PENALTY;
            // The roll-off the fitted model draws weighs in: the Allan variance alone can take
            // a carried LSB under a steeper filter for a rounded one under the true filter.
            let psd = super::filter::psd_misfit(&roll, |ch, f| {
                fits[ch]
                    .as_ref()
                    .map(|x| super::resonance::model_psd(&x.model, f))
            });
            let c = cost(&fits) + psd + penalty;
            if best.as_ref().is_none_or(|b| c < b.0) {
                best = Some((
                    c,
                    Fitted {
                        fits,
                        filter: f,
                        carry,
                    },
                ));
            }
        }
    }
    best.expect("one variant at least").1
}

/// The resonances' Allan variances built so far: (channel, its filter, the term).
type Built = std::sync::Mutex<Vec<(usize, Option<FilterSpec>, KnownVibration)>>;

fn fit_with(
    a: &Analysis,
    filter: Option<&FittedFilter>,
    carry: bool,
    res: &[Vec<Resonance>],
    built: &Built,
) -> Vec<Option<AxisFit>> {
    let samples = a.samples as usize;
    let series = a.channels.iter().all(|c| c.trend.is_some());
    let white = filter.map(FittedFilter::white);
    let mut stages = output_stages(a, carry);
    for (i, s) in stages.iter_mut().enumerate() {
        s.white = white.as_ref().map(|w| w.sensor(i == 1).clone());
    }
    let triad = |base: usize| {
        let c = &a.channels;
        let outputs = std::array::from_fn(|i| OutputStage {
            post_filter: filter.map_or(0.0, |f| f.floors[base + i].ratio),
            sines: super::lines::find(&c[base + i].psd)
                .iter()
                .map(|l| (l.amplitude, l.freq))
                .collect(),
            vibration: res.get(base + i).filter(|r| !r.is_empty()).map(|r| {
                let ch = base + i;
                let spec = filter.map(|f| f.spec.channel(ch));
                let known = |b: &Vec<(usize, Option<FilterSpec>, KnownVibration)>| {
                    b.iter()
                        .find(|(c, s, _)| *c == ch && *s == spec)
                        .map(|x| x.2.clone())
                };
                if let Some(v) = known(&built.lock().expect("cache")) {
                    return v;
                }
                let ms: Vec<usize> = c[ch].adev.iter().map(|p| p.m).collect();
                let s = spec.as_ref();
                let v = KnownVibration::new(source_table(r, a.dt, s), a.dt, s, &ms);
                built.lock().expect("cache").push((ch, spec, v.clone()));
                v
            }),
            ..stages[base / 3].clone()
        });
        fit_triad_with(
            [&c[base].adev, &c[base + 1].adev, &c[base + 2].adev],
            samples,
            a.dt,
            !series,
            outputs,
        )
    };
    let mut fits = std::thread::scope(|s| {
        let accel = s.spawn(|| triad(3));
        let mut v = triad(0).to_vec();
        v.extend(accel.join().expect("fit thread"));
        v
    });
    if series {
        super::ramp::apply(a, &mut fits);
    }
    fits
}

/// The output LSB of each triad (gyro, accel) from its value lattice: q the median of the
/// axes' LSBs where all three axes sit on a lattice. A template has one quantization mode:
/// when either triad has an LSB, both are fitted for rounding (`quantization_mode = "round"`),
/// so neither fits the carry-mode term.
pub fn triad_lsbs(a: &Analysis) -> [Option<f64>; 2] {
    [0, 3].map(|base| {
        let mut q: Vec<f64> = (0..3)
            .map(|i| a.channels[base + i].lattice.map(|l| l.lsb))
            .collect::<Option<Vec<f64>>>()?;
        q.sort_by(f64::total_cmp);
        Some(q[1])
    })
}

/// What the fit of each triad takes as known from its LSB ([`triad_lsbs`]).
fn output_stages(a: &Analysis, carry: bool) -> [OutputStage; 2] {
    let q = triad_lsbs(a);
    let rounding = q.iter().any(Option::is_some) && !carry;
    q.map(|q| match q {
        Some(q) if carry => OutputStage::carried(q, a.dt),
        Some(q) => OutputStage::rounded(q, a.dt),
        None if rounding => OutputStage {
            carry: false,
            ..OutputStage::default()
        },
        None => OutputStage::default(),
    })
}

/// What the two intervals of a term say.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Both kept the term and the 99 % intervals overlap.
    Agree,
    /// Both kept it and the intervals are disjoint.
    Differ,
    /// Only this run's fit kept the term.
    OnlyThis,
    /// Only the reference's fit kept it.
    OnlyReference,
    /// One of the two fits is not determined by its points ([`determined`]): whatever it
    /// kept or left out says nothing about this figure (a published table of two or three
    /// τ values, say).
    NotEnoughPoints,
}

impl Verdict {
    /// Word printed in the table.
    pub fn word(self) -> &'static str {
        match self {
            Verdict::Agree => "agree",
            Verdict::Differ => "DIFFER",
            Verdict::OnlyThis => "only in this run",
            Verdict::OnlyReference => "only in the reference",
            Verdict::NotEnoughPoints => "not enough points",
        }
    }
}

/// A figure compared: the Gauss–Markov correlation time T is `component` GaussMarkov with
/// `time` set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// Channel index ([`CHANNELS`]).
    pub channel: usize,
    /// The component.
    pub component: Component,
    /// Whether the row is the Gauss–Markov correlation time rather than σ_GM.
    pub time: bool,
    /// (value, lo, hi) of this run, SI.
    pub this: Option<(f64, f64, f64)>,
    /// (value, lo, hi) of the reference, SI.
    pub reference: Option<(f64, f64, f64)>,
    /// Whether each fit (this run, the reference) is determined by its points ([`determined`]).
    pub determined: [bool; 2],
}

/// Free parameters of a fit: one per kept figure, and the Gauss–Markov time with σ_GM.
pub fn free_parameters(f: &AxisFit) -> usize {
    let kept = f.estimates.iter().flatten().count();
    kept + usize::from(f.estimate(Component::GaussMarkov).is_some())
}

/// Whether a fit is determined by its Allan deviation points: only with more points than
/// free parameters. With as many parameters as points a model of the right shape passes
/// through every point exactly — any two τ values are met by a Gauss–Markov term's σ and T,
/// or by N and B, alike — so neither its figures nor the terms it left out say anything,
/// and its χ² has no degree of freedom left to reject it.
pub fn determined(f: &AxisFit) -> bool {
    f.points > free_parameters(f)
}

impl Row {
    /// The verdict.
    pub fn verdict(&self) -> Verdict {
        if self.determined.contains(&false) {
            return Verdict::NotEnoughPoints;
        }
        match (self.this, self.reference) {
            (Some(a), Some(b)) if a.1 <= b.2 && b.1 <= a.2 => Verdict::Agree,
            (Some(_), Some(_)) => Verdict::Differ,
            (Some(_), None) => Verdict::OnlyThis,
            _ => Verdict::OnlyReference,
        }
    }
    /// Symbol of the figure (Q, N, B, K, R, σ_GM, T_GM).
    pub fn symbol(&self) -> &'static str {
        if self.time {
            return "T_GM";
        }
        ["Q", "N", "B", "K", "R", "σ_GM"][self.component as usize]
    }
    /// Unit and SI factor of the figure.
    pub fn unit(&self) -> (&'static str, f64) {
        if self.time {
            ("s", 1.0)
        } else {
            unit(self.channel < 3, self.component)
        }
    }
}

/// Every figure kept by either fit, channel by channel (channels fitted on one side only
/// included), in [`COMPONENTS`] order with T after σ_GM.
pub fn compare(this: &[Option<AxisFit>], reference: &[Option<AxisFit>]) -> Vec<Row> {
    let triple = |e: Estimate| (e.value, e.lo, e.hi);
    let mut rows = Vec::new();
    for ch in 0..this.len().min(reference.len()) {
        let (a, b) = (this[ch].as_ref(), reference[ch].as_ref());
        let determined = [a, b].map(|f| f.is_none_or(determined));
        for k in COMPONENTS {
            let get = |f: Option<&AxisFit>| f.and_then(|f| f.estimate(k)).map(triple);
            let row = Row {
                channel: ch,
                component: k,
                time: false,
                this: get(a),
                reference: get(b),
                determined,
            };
            if row.this.is_none() && row.reference.is_none() {
                continue;
            }
            rows.push(row);
            if k == Component::GaussMarkov {
                let t = |f: Option<&AxisFit>| {
                    let f = f?;
                    f.estimate(k)?;
                    f.gm_tau_interval.map(|(lo, hi)| (f.model.gm_tau, lo, hi))
                };
                rows.push(Row {
                    time: true,
                    this: t(a),
                    reference: t(b),
                    ..row
                });
            }
        }
    }
    rows
}

fn cell(v: Option<(f64, f64, f64)>, f: f64) -> String {
    v.map_or("—".into(), |(v, lo, hi)| {
        format!("{} [{}, {}]", sig4(v * f), sig4(lo * f), sig4(hi * f))
    })
}

/// The comparison as a Markdown table with a closing count.
pub fn markdown(rows: &[Row], reference: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Per-term comparison with {reference} (stochastic model fitted to each, docs/fit.md; 99 % intervals; \"agree\": the intervals overlap; \"not enough points\": a fit with no more Allan deviation points than free parameters, which determine nothing)\n"
    );
    let _ = writeln!(
        s,
        "| channel | term | unit | this run | reference | verdict |\n| --- | --- | --- | --- | --- | --- |"
    );
    for r in rows {
        let (u, f) = r.unit();
        let _ = writeln!(
            s,
            "| {} | {} | {u} | {} | {} | {} |",
            CHANNELS[r.channel],
            r.symbol(),
            cell(r.this, f),
            cell(r.reference, f),
            r.verdict().word()
        );
    }
    let count = |v: Verdict| rows.iter().filter(|r| r.verdict() == v).count();
    let _ = writeln!(
        s,
        "\n{} figures agree, {} differ, {} only in this run, {} only in the reference, {} not determined (not enough points)",
        count(Verdict::Agree),
        count(Verdict::Differ),
        count(Verdict::OnlyThis),
        count(Verdict::OnlyReference),
        count(Verdict::NotEnoughPoints)
    );
    s
}

/// The header of the comparison CSV.
pub fn csv_header() -> &'static str {
    "reference,channel,term,unit,this,this_lo,this_hi,reference,reference_lo,reference_hi,verdict\n"
}

/// The rows of one reference's comparison as CSV lines (after [`csv_header`]; values in the
/// units of the `unit` column; empty: not kept).
pub fn csv(rows: &[Row], reference: &str) -> String {
    let mut s = String::new();
    let cells = |v: Option<(f64, f64, f64)>, f: f64| {
        v.map_or(",,".into(), |(v, lo, hi)| {
            format!("{:e},{:e},{:e}", v * f, lo * f, hi * f)
        })
    };
    for r in rows {
        let (u, f) = r.unit();
        let _ = writeln!(
            s,
            "{},{},{},{u},{},{},{}",
            reference.replace(',', ";"),
            CHANNELS[r.channel],
            r.symbol(),
            cells(r.this, f),
            cells(r.reference, f),
            r.verdict().word()
        );
    }
    s
}

fn adev_series(pts: &[AdevPoint], k: f64, label: String, color: usize, dashed: bool) -> Series {
    Series {
        label,
        x: pts.iter().map(|p| p.tau).collect(),
        y: pts.iter().map(|p| p.adev * k).collect(),
        band: Some((
            pts.iter().map(|p| p.lo * k).collect(),
            pts.iter().map(|p| p.hi * k).collect(),
        )),
        color,
        dashed,
    }
}

/// The overlay: per channel every Allan deviation with its band (a recording's 68 % χ²
/// band; a table's stated range, else the band of its record length), and per sensor every
/// PSD that exists (three axes in one colour, each with its 68 % χ² band). `curves` is (analysis, label), this run
/// first (solid), then the references (dashed). Rows gyro then accel, the PSD last in each.
pub fn panels(curves: &[(&Analysis, String)]) -> Vec<Panel> {
    let psd = curves
        .iter()
        .any(|(a, _)| a.channels.iter().any(|c| c.psd.segments > 0));
    let mut out = Vec::new();
    for base in [0, 3] {
        let (unit, k) = adev_unit(base == 0);
        for (ch, name) in CHANNELS.iter().enumerate().skip(base).take(3) {
            let series = curves
                .iter()
                .enumerate()
                .map(|(i, (a, name))| {
                    adev_series(&a.channels[ch].adev, k, name.clone(), i % 6, i > 0)
                })
                .collect();
            out.push(Panel {
                title: format!("{name}: Allan deviation"),
                x_label: "τ (s)".into(),
                y_label: format!("σ(τ) ({unit})"),
                log_x: true,
                log_y: true,
                series,
            });
        }
        if psd {
            let mut series = Vec::new();
            for (i, (a, name)) in curves.iter().enumerate() {
                for axis in 0..3 {
                    let p = &a.channels[base + axis].psd;
                    if p.segments == 0 {
                        continue;
                    }
                    let b = banded_psd(p, k);
                    series.push(Series {
                        label: if axis == 0 {
                            format!("{name} (x y z)")
                        } else {
                            String::new()
                        },
                        x: b.freq,
                        y: b.density,
                        band: Some((b.lo, b.hi)),
                        color: i % 6,
                        dashed: i > 0,
                    });
                }
            }
            out.push(Panel {
                title: format!(
                    "{} PSD (Welch, Hann)",
                    if base == 0 { "gyro" } else { "accel" }
                ),
                x_label: "f (Hz)".into(),
                y_label: format!("PSD ({unit})²/Hz"),
                log_x: true,
                log_y: true,
                series,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(this: Option<(f64, f64, f64)>, reference: Option<(f64, f64, f64)>) -> Row {
        Row {
            channel: 0,
            component: Component::WhiteNoise,
            time: false,
            this,
            reference,
            determined: [true; 2],
        }
    }

    /// Overlap decides: touching intervals agree, disjoint ones differ, either side alone
    /// is named.
    #[test]
    fn verdicts() {
        let a = Some((1.0, 0.9, 1.1));
        assert_eq!(row(a, Some((1.2, 1.1, 1.3))).verdict(), Verdict::Agree);
        assert_eq!(row(a, Some((1.2, 1.11, 1.3))).verdict(), Verdict::Differ);
        assert_eq!(row(Some((1.2, 1.11, 1.3)), a).verdict(), Verdict::Differ);
        assert_eq!(row(a, None).verdict(), Verdict::OnlyThis);
        assert_eq!(row(None, a).verdict(), Verdict::OnlyReference);
        // Either fit undetermined: no verdict, whatever the intervals.
        for d in [[false, true], [true, false]] {
            let r = Row {
                determined: d,
                ..row(a, Some((1.2, 1.11, 1.3)))
            };
            assert_eq!(r.verdict(), Verdict::NotEnoughPoints);
            let r = Row {
                determined: d,
                ..row(a, None)
            };
            assert_eq!(r.verdict(), Verdict::NotEnoughPoints);
        }
    }
}
