//! Broad resonances of a published Allan deviation table, which has no PSD to read them from
//! ([`super::resonance`] reads a recording's): a mechanical resonance's random vibration fitted
//! to the Allan variance beside the axis's other terms. Pure math.
//!
//! **Shape.** A resonance of centre f₀ and quality Q driven by white noise has the density
//! S·p(f), p = 1/((1 − r²)² + (r/Q)²) with r = f/f₀ scaled to a peak of 1 — three figures (S,
//! f₀, Q) for what the Allan kernel 2 sin⁴(πfτ)/(m sin πfΔt)² lets a table tell: a bump's
//! place, width and power (the kernel smooths its profile over ≈ 1/τ). It is taken as steps
//! on cells of [`CELLS_PER_DECADE`] per decade, from [`super::resonance::FROM_NYQUIST`] of the
//! Nyquist frequency up to it (where the white noise and the filter are the floor, as for a
//! recording's PSD), each cell at p of its geometric centre, the cells below
//! [`PROFILE_FLOOR`] of the peak left out; the error model's `[[vibration.random]]` table
//! holds those steps (rows at both ends of each cell), so what is simulated is what was
//! fitted. Its Allan variance through the interval mean and the output filter is S·Σ pᵢVᵢ(m),
//! Vᵢ each cell's ([`KnownVibration`], exact; past [`LONG_TAU_CYCLES`] kernel periods across a
//! cell, its long-τ limit, in the search only).
//!
//! **Search.** f₀ on [`CENTRES_PER_DECADE`] per decade over the same range, Q on
//! [`QUALITY`]. For each, S and the coefficients of the axis's components (those its model
//! holds, its bias-instability band and Gauss–Markov T kept, and the white noise whatever it
//! holds: the floor the bump sits on) are solved by the fit's weighted least squares (weights
//! edf/σ²_model², [`super::gmwm`]) on every subset of the components, each costing its
//! penalty as in the fit — a bump can make redundant a fast Gauss–Markov term or a carry
//! quantizer that took its rise. The (f₀, Q) of least cost is the bump. It is kept when it
//! lowers the least cost without it by more than [`FLICKER_PENALTY`] (χ²₃ at 99 %: S, f₀ and
//! Q on a grid, as the bias instability's B and band) and its peak stands at least
//! [`super::resonance::MIN_PEAK`] above the model's floor (below that it is the floor's shape,
//! as for a recording). One bump per axis: a table cannot part two. The fit is then run again
//! with the bump as a known term, and the bump read once more against that fit
//! (`super::recording_fit`), as a recording's are.
//!
//! **Significance.** A table's τ are often denser than octaves and their estimates
//! correlated, which the fit's weights do not know (they take the points as independent, as
//! for every other term of a table): its Δχ² then overstates the evidence by about the points
//! per octave.

use super::gmwm::{COMPONENTS, Component, FLICKER_PENALTY, Model};
use super::resonance::{FROM_NYQUIST, KnownVibration, MIN_PEAK, Resonance, gain2, model_psd};
use crate::analysis::confidence::{NoiseType, edf};
use crate::analysis::fit::weighted_lstsq;
use crate::analysis::octave_adev::AdevPoint;
use crate::errors::output_filter::FilterSpec;

/// Cells of the profile's steps per decade (3.7 % wide: far finer than the Allan kernel,
/// which smooths over ≈ 1/τ).
pub const CELLS_PER_DECADE: usize = 64;

/// Centre frequencies searched per decade.
pub const CENTRES_PER_DECADE: f64 = 32.0;

/// Quality factors searched (a factor √2 apart).
pub const QUALITY: [f64; 13] = [
    0.5, 0.707, 1.0, 1.414, 2.0, 2.828, 4.0, 5.657, 8.0, 11.31, 16.0, 22.63, 32.0,
];

/// A cell below this share of the profile's peak is left out of the table.
pub const PROFILE_FLOOR: f64 = 0.01;

/// Kernel periods across a cell beyond which its σ² is taken at the long-τ limit
/// ([`KnownVibration::avar_long`]: off by less than 3/(2π·50) ≈ 1 % of the cell's share,
/// itself falling as 1/τ² against the white noise's 1/τ), in the search only.
pub const LONG_TAU_CYCLES: f64 = 50.0;

/// The relative gap between one step of the table and the next.
pub const STEP: f64 = 1e-7;

/// The bump of one axis's Allan deviation `points` (measured from `samples` samples at the
/// model's Δt) beyond `model` (its own vibration left out), shaped by the output `filter`; at
/// most one.
pub fn find(
    points: &[AdevPoint],
    model: &Model,
    samples: usize,
    filter: Option<&FilterSpec>,
) -> Vec<Resonance> {
    let dt = model.dt;
    let pts: Vec<&AdevPoint> = points
        .iter()
        .filter(|p| p.adev > 0.0 && p.adev.is_finite())
        .collect();
    let ms: Vec<usize> = pts.iter().map(|p| p.m).collect();
    let mut base = model.clone();
    base.output.vibration = None;
    // The model's components, and the white noise whatever it holds: the floor a bump sits on
    // (a fit without the bump may have taken the white slope with a fast Gauss–Markov term).
    let white = Component::WhiteNoise as usize;
    let active: Vec<usize> = (0..COMPONENTS.len())
        .filter(|&i| base.c[i] > 0.0 || i == white)
        .collect();
    let mut unit = base.clone();
    unit.c = [1.0; 6];
    if pts.len() <= active.len() + 3 {
        return Vec::new();
    }
    let y: Vec<f64> = pts
        .iter()
        .map(|p| p.adev * p.adev - base.output.known(p.m, dt))
        .collect();
    // The weights of the model as fitted (its vibration included), as the fit's last pass.
    let w: Vec<f64> = pts
        .iter()
        .map(|p| {
            let a = model.avar(p.m).max(1e-6 * p.adev * p.adev);
            let t = model
                .dominant(p.m)
                .map_or(NoiseType::WhiteRate, |k| k.noise_type());
            edf(t, samples + 1, p.m) / (a * a)
        })
        .collect();
    let cols: Vec<Vec<f64>> = active
        .iter()
        .map(|&i| ms.iter().map(|&m| unit.part(COMPONENTS[i], m)).collect())
        .collect();
    // The least cost (χ² plus the kept components' penalties, as the fit's search) over
    // the subsets of the model's components, with the bump column `extra` when given; and
    // the bump's level there. A bump can make a component the model needed without it
    // redundant (a fast Gauss–Markov term or a carry quantizer that took its rise).
    let penalty: Vec<f64> = active.iter().map(|&i| COMPONENTS[i].penalty()).collect();
    let cost = |extra: Option<&[f64]>| -> Option<(f64, f64)> {
        let mut best: Option<(f64, f64)> = None;
        for mask in 0u32..1 << cols.len() {
            let mut c: Vec<&[f64]> = Vec::with_capacity(cols.len() + 1);
            let mut pen = 0.0;
            for (k, col) in cols
                .iter()
                .enumerate()
                .filter(|(k, _)| mask & (1 << k) != 0)
            {
                c.push(col);
                pen += penalty[k];
            }
            c.extend(extra);
            // No column (an axis whose model holds nothing but known parts, no bump): the
            // residuals are y itself.
            let sol = if c.is_empty() {
                Vec::new()
            } else {
                match weighted_lstsq(&c, &y, &w) {
                    Some(s) => s,
                    None => continue,
                }
            };
            if sol.iter().any(|v| *v <= 0.0) {
                continue;
            }
            let x2 = (0..y.len())
                .map(|j| {
                    let fit: f64 = c.iter().zip(&sol).map(|(c, x)| c[j] * x).sum();
                    w[j] * (y[j] - fit).powi(2)
                })
                .sum::<f64>()
                / 2.0;
            let level = if extra.is_some() {
                *sol.last().expect("the bump's column")
            } else {
                0.0
            };
            if best.is_none_or(|b| x2 + pen < b.0) {
                best = Some((x2 + pen, level));
            }
        }
        best
    };
    // Without a bump (the empty subset is always feasible).
    let without = cost(None).map_or(f64::INFINITY, |c| c.0);
    let edges = edges(dt);
    let cells: Vec<Vec<f64>> = edges
        .windows(2)
        .map(|e| {
            let v = KnownVibration::new(vec![(e[0], 1.0), (e[1], 1.0)], dt, filter, &[]);
            ms.iter()
                .map(|&m| {
                    if m as f64 * dt * (e[1] - e[0]) > LONG_TAU_CYCLES {
                        v.avar_long(m)
                    } else {
                        v.avar(m)
                    }
                })
                .collect()
        })
        .collect();
    let mut best: Option<(f64, Vec<f64>, f64)> = None;
    let mut col = vec![0.0; ms.len()];
    for f0 in centres(dt) {
        for q in QUALITY {
            let a = profile(&edges, f0, q);
            col.iter_mut().for_each(|c| *c = 0.0);
            for (cell, &ai) in cells.iter().zip(&a) {
                if ai > 0.0 {
                    col.iter_mut().zip(cell).for_each(|(c, v)| *c += ai * v);
                }
            }
            if let Some((c, s)) = cost(Some(&col))
                && best.as_ref().is_none_or(|b| c < b.0)
            {
                best = Some((c, a, s));
            }
        }
    }
    let Some((with, a, s)) = best else {
        return Vec::new();
    };
    let gain = without - with;
    // The recorded samples' excess density: each cell's level S·a at its two edges (the next
    // cell starts a hair above, so that the log-log table holds the steps the fit took).
    let mut rows: Vec<(f64, f64)> = Vec::new();
    for (e, &ai) in edges.windows(2).zip(&a).filter(|(_, ai)| **ai > 0.0) {
        let lo = if rows.is_empty() {
            e[0]
        } else {
            e[0] * (1.0 + STEP)
        };
        for f in [lo, e[1]] {
            rows.push((f, s * ai * gain2(f, dt, filter)));
        }
    }
    let peak = rows
        .iter()
        .map(|&(f, e)| e / model_psd(&base, f))
        .fold(0.0, f64::max);
    // A row the generator could not take (a filter's null under it) is no bump to write.
    let writable = rows.iter().all(|r| r.1 > 0.0 && r.1.is_finite());
    if gain <= FLICKER_PENALTY || peak < MIN_PEAK || !writable {
        return Vec::new();
    }
    vec![Resonance {
        rows,
        z: gain.sqrt(),
        z_gate: FLICKER_PENALTY.sqrt(),
        peak,
        level: 1.0,
        from_adev: true,
    }]
}

/// The resonance's relative level over each cell of `edges` (at its geometric centre),
/// 1/((1 − r²)² + (r/Q)²) with r = f/f₀ scaled to a peak of 1; 0 for the cells below
/// [`PROFILE_FLOOR`] of the peak.
fn profile(edges: &[f64], f0: f64, q: f64) -> Vec<f64> {
    let p: Vec<f64> = edges
        .windows(2)
        .map(|e| {
            let r = (e[0] * e[1]).sqrt() / f0;
            1.0 / ((1.0 - r * r).powi(2) + (r / q).powi(2))
        })
        .collect();
    let top = p.iter().cloned().fold(0.0, f64::max);
    p.iter()
        .map(|v| v / top)
        .map(|v| if v >= PROFILE_FLOOR { v } else { 0.0 })
        .collect()
}

/// The centre frequencies searched: [`CENTRES_PER_DECADE`] per decade over the grid.
fn centres(dt: f64) -> Vec<f64> {
    let nyquist = 0.5 / dt;
    let n = (CENTRES_PER_DECADE * (1.0 / FROM_NYQUIST).log10()).round() as usize;
    (0..=n)
        .map(|k| nyquist * 10f64.powf(-(k as f64) / CENTRES_PER_DECADE))
        .collect()
}

/// The grid's edges from [`FROM_NYQUIST`] of the Nyquist frequency 1/(2Δt) up to it,
/// ascending; the top one a hair below it, where a filter at the output rate (a Butterworth's
/// bilinear zero) has no gain and a table row would be 0/0.
fn edges(dt: f64) -> Vec<f64> {
    let nyquist = 0.5 / dt;
    let n = (CELLS_PER_DECADE as f64 * (1.0 / FROM_NYQUIST).log10()).round() as usize;
    (0..=n)
        .rev()
        .map(|k| nyquist * 10f64.powf(-(k as f64) / CELLS_PER_DECADE as f64))
        .map(|f| f.min(nyquist * (1.0 - 1e-6)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::gmwm::OutputStage;

    /// White noise of density 2N² (N² = 1e-6 rad²/s at Δt = 10 ms, under a CIC of order 2 and
    /// 4 taps at 400 Hz) and the exact Allan variance of a resonance from the search's own
    /// family (f₀ the 11th centre below the Nyquist frequency, Q = 2, peak 4e-6 rad²/s²/Hz:
    /// about 2× the floor there), at octaves to m = 4096 (τ·w ≤ 8 on every cell: no long-τ
    /// limit). `find` gives back its table to 1e-9 (the least-squares solve of two columns)
    /// and no bump without it. With the profile halved in the column the fit takes, the table
    /// comes back at twice its level; with the filter left out of the cells, its lowest row
    /// 11 % low.
    #[test]
    fn an_exact_resonance_is_read_back() {
        let filter = FilterSpec {
            internal_rate_hz: 400.0,
            kind: crate::errors::output_filter::FilterKind::Cic { order: 2, taps: 4 },
            accel: None,
        };
        read_back(filter, 4, 10);
    }

    /// The same at the Nyquist frequency (f₀ the top centre) under a Butterworth of order 4
    /// at the output rate, whose bilinear zero there has no gain: the table's top row sits a
    /// hair below it and is written (at the Nyquist frequency itself the row was 0/0, and the
    /// fitted template held NaN: the NavChip table).
    #[test]
    fn a_resonance_at_the_nyquist_frequency_is_written() {
        let filter = FilterSpec {
            internal_rate_hz: 100.0,
            kind: crate::errors::output_filter::FilterKind::Butterworth {
                order: 4,
                cutoff_hz: 40.0,
            },
            accel: None,
        };
        read_back(filter, 1, 0);
    }

    /// White noise under `filter` read at 1/`ratio` of its rate, and the resonance of the
    /// `centre`-th centre from the top, Q = 2: read back to 1e-9, none without it.
    fn read_back(filter: FilterSpec, ratio: u64, centre: usize) {
        let dt = 0.01;
        let white = crate::fit::filter::FittedFilter::known(
            filter.clone(),
            crate::timing::ReadRatio::integer(ratio),
        )
        .white()
        .sensor(false)
        .clone();
        let model = Model {
            c: [0.0, 1e-6, 0.0, 0.0, 0.0, 0.0],
            band: (1.0, 1000.0),
            gm_tau: 1.0,
            dt,
            output: OutputStage {
                white: Some(white),
                ..OutputStage::default()
            },
        };
        let edges = edges(dt);
        let (f0, q, s) = (centres(dt)[centre], 2.0, 4e-6);
        let a = profile(&edges, f0, q);
        let ms: Vec<usize> = (0..13).map(|j| 1 << j).collect();
        let bump: Vec<f64> = ms
            .iter()
            .map(|&m| {
                edges
                    .windows(2)
                    .zip(&a)
                    .map(|(e, ai)| {
                        let v = KnownVibration::new(
                            vec![(e[0], 1.0), (e[1], 1.0)],
                            dt,
                            Some(&filter),
                            &[],
                        );
                        s * ai * v.avar(m)
                    })
                    .sum()
            })
            .collect();
        let points = |with: bool| -> Vec<AdevPoint> {
            ms.iter()
                .zip(&bump)
                .map(|(&m, b)| {
                    let adev = (model.avar(m) + if with { *b } else { 0.0 }).sqrt();
                    AdevPoint {
                        m,
                        tau: m as f64 * dt,
                        adev,
                        terms: 0,
                        edf: 0.0,
                        lo: adev,
                        hi: adev,
                    }
                })
                .collect()
        };
        let samples = 1 << 16;
        let got = find(&points(true), &model, samples, Some(&filter));
        assert_eq!(got.len(), 1);
        let r = &got[0];
        assert!(r.from_adev && r.z * r.z > FLICKER_PENALTY, "{r:?}");
        let want: Vec<(f64, f64)> = edges
            .windows(2)
            .zip(&a)
            .filter(|(_, ai)| **ai > 0.0)
            .flat_map(|(e, ai)| [(e[0], *ai), (e[1], *ai)])
            .collect();
        assert_eq!(r.rows.len(), want.len());
        for (k, (&(f, e), &(wf, wa))) in r.rows.iter().zip(&want).enumerate() {
            let step = if k > 0 && k % 2 == 0 { STEP } else { 0.0 };
            assert!(
                (f / (wf * (1.0 + step)) - 1.0).abs() < 1e-15,
                "{k}: {f} vs {wf}"
            );
            let wanted = s * wa * gain2(f, dt, Some(&filter));
            assert!((e / wanted - 1.0).abs() < 1e-9, "{k}: {e:e} vs {wanted:e}");
        }
        assert!(find(&points(false), &model, samples, Some(&filter)).is_empty());
    }
}
