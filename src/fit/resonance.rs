//! Broad resonances: band-pass bumps of a recording's PSD above the fitted model's, taken as a
//! random vibration whose PSD table is the excess (the error model's `[[vibration.random]]`,
//! [`crate::errors::vibration`]), with its exact Allan variance a known term of the fit. Pure
//! math.
//!
//! **The floor.** Each fitted component has a closed-form one-sided PSD for the samples the
//! generator puts out ([`model_psd`]). A bump the first fit did not know about is laid on the
//! white noise, which lifts the whole floor; so the floor is the model's PSD times a level c
//! fitted over the searched bands outside the bumps (the weighted mean of ln(P̂/M), each band
//! weighted by ν/2 since Var ln P̂ = 2/ν, plus 1/ν for the bias of E ln χ²_ν/ν), iterated with
//! the bumps it leaves out.
//!
//! **Detection.** The Welch PSD from a tenth of the Nyquist frequency to the bin below it is
//! averaged over bands of 1/[`BANDS_PER_DECADE`] decade (the bins of the spectral lines'
//! main lobes left out: [`super::lines`] takes those). Under the floor each band's relative
//! excess x_b = P̂_b/(c·M_b) − 1 has mean 0 and standard deviation √(2/ν_b)
//! ([`crate::analysis::psd_band::WelchEdf`]). A bump is a maximal run of bands with x_b > 0
//! whose weighted mean excess stands z = Σ(x_b·ν_b/2)/√(Σν_b/2) standard errors above 0, z
//! beyond the normal quantile of [`FALSE_ALARM`] divided by the number of runs of consecutive
//! bands there are (n(n+1)/2 for n bands: Bonferroni over every run a search could pick, so
//! at most one false bump in 1000 records whose PSD is the floor), and whose highest band is
//! at least [`MIN_PEAK`] above the floor (below that an excess is the floor's shape, not a
//! bump: the output filter's candidates miss the ADIS164xx shape by 2–6 % of the PSD near the
//! Nyquist frequency).
//!
//! **The table.** The excess E_b = P̂_b − c·M_b at each band's mean frequency, and at the run's
//! outer edges the end bands' values: the PSD the recorded samples show. The generator makes
//! a table S into samples of PSD S(f)·sinc²(πfΔt_in)·|H(f)|² (interval means at its internal
//! step, then the output filter), so the written table is S = E/(sinc²·|H|²) at each row
//! ([`source_table`]); several bumps on one axis go into one table, separated by rows at
//! 10⁻⁹ of their levels (the table is interpolated log-log: zero is not a row).
//!
//! **Allan variance** ([`super::vibration_avar::KnownVibration`]): samples of one-sided PSD P(f) have
//! σ²(m) = ∫₀^{1/(2Δt)} P(f)·2 sin⁴(πfmΔt)/(m sin πfΔt)² df — adjacent m-sample means differ by
//! the filter 2i·sin(πfmΔt)·sin(πfmΔt)/(m sin πfΔt), and σ² is half the variance of that
//! difference (for one sine of samples' amplitude B this is [`super::gmwm::sine_avar`]; for a
//! continuous record, m sin πfΔt → πfτ, the IEEE Std 952-1997 form 2∫S sin⁴(πfτ)/(πfτ)² df).
//! P = S·sinc²(πfΔt_in)·|H|² is integrated by 8-point Gauss–Legendre on pieces of at most
//! 1/(8τ) (sin⁴(πfτ) has period 1/τ), exact to round-off for the table as written.

use super::gmwm::{Component, Model};
use super::lines::{LOBE, Line};
pub use super::vibration_avar::{KnownVibration, gain2};
use crate::analysis::confidence::chi2_quantile;
use crate::analysis::psd::Psd;
use crate::analysis::psd_band::WelchEdf;
use crate::errors::output_filter::FilterSpec;
use crate::errors::process::flicker_bank;
use std::f64::consts::PI;

/// Bands per decade of the search (1/100 decade: 0.47 Hz at 20 Hz, a fifth of the narrowest
/// bump seen, so that the table interpolated through the bands keeps the bump's power).
pub const BANDS_PER_DECADE: f64 = 100.0;

/// Lowest frequency searched, as a fraction of the Nyquist frequency (where the floor is the
/// white noise and the filter, whose shapes the fit knows best).
pub const FROM_NYQUIST: f64 = 0.1;

/// Probability of one or more false bumps on a channel whose PSD is the floor.
pub const FALSE_ALARM: f64 = 1e-3;

/// The least relative excess of a bump's highest band over the floor.
pub const MIN_PEAK: f64 = 0.1;

/// Rows separating two bumps in one table, relative to their levels.
const GAP_LEVEL: f64 = 1e-9;

/// A bump of a channel's PSD above the fitted floor.
#[derive(Clone, Debug, PartialEq)]
pub struct Resonance {
    /// (f in Hz, excess one-sided density of the recorded samples in unit²/Hz): the run's
    /// lower edge, each band's mean frequency, its upper edge.
    pub rows: Vec<(f64, f64)>,
    /// Standard errors the run's mean excess stands above the floor.
    pub z: f64,
    /// The threshold z had to pass.
    pub z_gate: f64,
    /// The highest band's P̂/floor − 1.
    pub peak: f64,
    /// The floor's level c (model PSD × c).
    pub level: f64,
    /// Read from a table's Allan deviation ([`super::resonance_adev`]): `z` is then √Δχ² and
    /// `z_gate` the penalty's root.
    pub from_adev: bool,
}

impl Resonance {
    /// The bump's variance in the recorded samples, ∫E df over its rows (trapezoid rule on
    /// the band values; unit²).
    pub fn variance(&self) -> f64 {
        self.rows
            .windows(2)
            .map(|w| 0.5 * (w[0].1 + w[1].1) * (w[1].0 - w[0].0))
            .sum()
    }
    /// The frequencies it spans (Hz).
    pub fn range(&self) -> (f64, f64) {
        (self.rows[0].0, self.rows[self.rows.len() - 1].0)
    }
    /// The power-weighted mean frequency (Hz).
    pub fn centre(&self) -> f64 {
        let v = self.variance();
        self.rows
            .windows(2)
            .map(|w| 0.25 * (w[0].1 + w[1].1) * (w[1].0 * w[1].0 - w[0].0 * w[0].0))
            .sum::<f64>()
            / v
    }
}

/// One-sided PSD at f (0 < f < 1/(2Δt)) of the samples the generator makes from `model`
/// (spectral lines and vibration left out): white noise 2N²·r_∞·ratio(f) through the output
/// filter (`WhiteAllan::psd_ratio`) plus the post-filter noise's flat 2P², rounding noise 2q²Δt/12, a carried quantizer's
/// differenced angle error 8Q² sin²(πfΔt)/Δt, each Gauss–Markov sequence (the bias-instability
/// bank's components too) 2Δtσ²(1 − φ²)/(1 − 2φ cos 2πfΔt + φ²) with φ = e^{−Δt/T}, the
/// random walk K²/(2π²f²). Their Allan variances are the fit's bases.
pub fn model_psd(model: &Model, f: f64) -> f64 {
    let dt = model.dt;
    let o = &model.output;
    let white = 2.0 * model.c[Component::WhiteNoise as usize] * o.white_psd(f, dt);
    let s = (PI * f * dt).sin();
    // The LSB known from the lattice, and a fitted carry term Q² of the same form.
    let quant =
        o.quantization_psd(f, dt) + 8.0 * model.c[Component::Quantization as usize] * s * s / dt;
    let gm = |sigma2: f64, t: f64| {
        let phi = (-dt / t).exp();
        2.0 * dt * sigma2 * (1.0 - phi * phi)
            / (1.0 - 2.0 * phi * (2.0 * PI * f * dt).cos() + phi * phi)
    };
    let mut slow = 0.0;
    if model.c[Component::GaussMarkov as usize] > 0.0 {
        slow += gm(model.c[Component::GaussMarkov as usize], model.gm_tau);
    }
    let b = model.value(Component::BiasInstability);
    if b > 0.0 {
        slow += flicker_bank(b, model.band, dt)
            .iter()
            .map(|c| gm(c.sigma * c.sigma, c.tau))
            .sum::<f64>();
    }
    let walk = model.c[Component::RandomWalk as usize] / (2.0 * PI * PI * f * f);
    white + quant + slow + walk
}

/// A band of the search.
struct Band {
    freq: f64,
    lo: f64,
    hi: f64,
    psd: f64,
    floor: f64,
    nu: f64,
}

/// The bumps of `psd` (interval Δt) above the PSD of `model`, leaving out the main lobes of
/// `lines`; strongest (largest z) first.
pub fn find(psd: &Psd, model: &Model, lines: &[Line], dt: f64) -> Vec<Resonance> {
    let n = psd.freq.len();
    if psd.segments == 0 || n < 3 {
        return Vec::new();
    }
    let end = n - 1;
    let df = psd.freq[1] - psd.freq[0];
    let from = FROM_NYQUIST * 0.5 / dt;
    let near_line = |k: usize| {
        lines
            .iter()
            .any(|l| (l.freq / df - k as f64).abs() <= (LOBE + 1) as f64)
    };
    let edf = WelchEdf::new(2 * end, psd.segments);
    let mut bands: Vec<Band> = Vec::new();
    let mut current: Option<(i64, Vec<usize>)> = None;
    let close = |bins: Vec<usize>, bands: &mut Vec<Band>| {
        if bins.is_empty() {
            return;
        }
        let count = bins.len() as f64;
        let mean = |v: &dyn Fn(usize) -> f64| bins.iter().map(|&k| v(k)).sum::<f64>() / count;
        bands.push(Band {
            freq: mean(&|k| psd.freq[k]),
            lo: psd.freq[bins[0]] - 0.5 * df,
            hi: psd.freq[bins[bins.len() - 1]] + 0.5 * df,
            psd: mean(&|k| psd.density[k]),
            floor: mean(&|k| model_psd(model, psd.freq[k])),
            nu: edf.edf(bins.len()),
        });
    };
    for k in 1..end {
        let f = psd.freq[k];
        if f < from || near_line(k) {
            continue;
        }
        let key = (f.log10() * BANDS_PER_DECADE).floor() as i64;
        match &mut current {
            Some((b, bins)) if *b == key && bins.last() == Some(&(k - 1)) => bins.push(k),
            _ => {
                if let Some((_, bins)) = current.take() {
                    close(bins, &mut bands);
                }
                current = Some((key, vec![k]));
            }
        }
    }
    if let Some((_, bins)) = current.take() {
        close(bins, &mut bands);
    }
    bands.retain(|b| b.psd > 0.0 && b.floor > 0.0);
    let nb = bands.len();
    if nb < 2 {
        return Vec::new();
    }
    let runs_possible = (nb * (nb + 1) / 2) as f64;
    let z_gate = chi2_quantile(1.0 - 2.0 * FALSE_ALARM / runs_possible, 1.0).sqrt();
    let mut inside = vec![false; nb];
    let mut found: Vec<(usize, usize, f64, f64)> = Vec::new();
    let mut level = 1.0;
    for _ in 0..10 {
        let (mut sw, mut swy) = (0.0, 0.0);
        for (b, _) in bands.iter().zip(&inside).filter(|(_, i)| !**i) {
            let w = b.nu / 2.0;
            sw += w;
            swy += w * ((b.psd / b.floor).ln() + 1.0 / b.nu);
        }
        if sw == 0.0 {
            break;
        }
        level = (swy / sw).exp();
        found.clear();
        let x = |b: &Band| b.psd / (level * b.floor) - 1.0;
        let mut i = 0;
        while i < nb {
            if x(&bands[i]) <= 0.0 {
                i += 1;
                continue;
            }
            let mut j = i;
            while j + 1 < nb && x(&bands[j + 1]) > 0.0 {
                j += 1;
            }
            let run = &bands[i..=j];
            let w: f64 = run.iter().map(|b| b.nu / 2.0).sum();
            let z = run.iter().map(|b| x(b) * b.nu / 2.0).sum::<f64>() / w.sqrt();
            let peak = run.iter().map(x).fold(0.0, f64::max);
            if z > z_gate && peak >= MIN_PEAK {
                found.push((i, j, z, peak));
            }
            i = j + 1;
        }
        let mut now = vec![false; nb];
        for &(i, j, _, _) in &found {
            now[i..=j].iter_mut().for_each(|v| *v = true);
        }
        if now == inside {
            break;
        }
        inside = now;
    }
    let mut out: Vec<Resonance> = found
        .iter()
        .map(|&(i, j, z, peak)| {
            let run = &bands[i..=j];
            let excess = |b: &Band| b.psd - level * b.floor;
            let mut rows = vec![(run[0].lo, excess(&run[0]))];
            rows.extend(run.iter().map(|b| (b.freq, excess(b))));
            rows.push((run[run.len() - 1].hi, excess(&run[run.len() - 1])));
            keep_band_power(&mut rows, run, level);
            Resonance {
                rows,
                z,
                z_gate,
                peak,
                level,
                from_adev: false,
            }
        })
        .collect();
    out.sort_by(|a, b| b.z.total_cmp(&a.z));
    out
}

/// Rescales `rows` (edges, then one row per band of `run`) so that the table's mean over each
/// band, interpolated log-log as the generator does, is the band's excess: through the band
/// means alone a peaked bump's table loses power (measured: 2 % of the ADIS16405's gyro z bump
/// at 1/100 decade, 7 % at 1/40). Multiplicative fixed-point steps, as the means are positive.
fn keep_band_power(rows: &mut [(f64, f64)], run: &[Band], level: f64) {
    let n = run.len();
    for _ in 0..20 {
        let table = crate::errors::vibration::Random {
            sensor: crate::errors::vibration::Sensor::Gyro,
            axis: 0,
            psd: rows.to_vec(),
        };
        let mut worst: f64 = 0.0;
        for (i, b) in run.iter().enumerate() {
            let mean = (table.variance_up_to(b.hi) - table.variance_up_to(b.lo)) / (b.hi - b.lo);
            let ratio = (b.psd - level * b.floor) / mean;
            if !(ratio.is_finite() && ratio > 0.0) {
                return;
            }
            worst = worst.max((ratio - 1.0).abs());
            rows[i + 1].1 *= ratio;
        }
        rows[0].1 = rows[1].1;
        rows[n + 1].1 = rows[n].1;
        if worst < 1e-6 {
            break;
        }
    }
}

/// The vibration table S (f in Hz, unit²/Hz) that puts the bumps `res` of one channel into
/// the recorded samples: each row E/[`gain2`], bumps in frequency order, separated by rows at
/// [`GAP_LEVEL`] of their levels. Empty when there is no bump.
pub fn source_table(res: &[Resonance], dt: f64, filter: Option<&FilterSpec>) -> Vec<(f64, f64)> {
    let mut sorted: Vec<&Resonance> = res.iter().collect();
    sorted.sort_by(|a, b| a.rows[0].0.total_cmp(&b.rows[0].0));
    let mut rows: Vec<(f64, f64)> = Vec::new();
    for r in sorted {
        let scaled: Vec<(f64, f64)> = r
            .rows
            .iter()
            .map(|&(f, e)| (f, e / gain2(f, dt, filter)))
            .collect();
        if let (Some(&last), Some(&first)) = (rows.last(), scaled.first()) {
            // Two bumps: drop to nothing between them (no overlap: runs are disjoint).
            let gap = (first.0 - last.0) * 1e-3;
            rows.push((last.0 + gap, last.1 * GAP_LEVEL));
            rows.push((first.0 - gap, first.1 * GAP_LEVEL));
        }
        rows.extend(scaled);
    }
    rows
}
