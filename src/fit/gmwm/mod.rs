//! The stochastic model of one axis fitted to its measured Allan variance, GMWM-style
//! (generalized method of wavelet moments: Guerrier et al., "Wavelet-variance-based estimation
//! for composite stochastic processes", JASA 108 (2013); the Haar wavelet variance is half the
//! Allan variance, so matching either is the same fit).
//!
//! Model: the sum of independent components, so the theoretical Allan variances add,
//!
//! σ²(τ) = Q²·3/τ² + N²/τ + B²·F_band(τ) + K²·τ/3·(1 + 1/(2m²)) + R²·τ²/2 + σ_GM²·g(τ/T),
//!
//! each basis being the exact Allan variance of what the error model generates at the
//! record's Δt (see [`crate::analysis::theory`]): F_band is the curve of the bias-instability
//! bank of [`crate::errors::process::flicker_bank`] per unit B² (flat 2 ln 2/π inside its τ
//! band, falling outside), g the Gauss–Markov sequence's exact curve at the record's Δt
//! ([`gm_avar_sampled`]: white noise when T ≪ Δt, the continuous g(τ/T) when T ≫ Δt). The model is linear in
//! the six coefficients (Q², N², B², K², R², σ_GM²) for a fixed band and T; the band edges
//! (half-decade grid) and T (quarter-decade grid) are searched.
//!
//! Estimator: weighted least squares of the model against the measured octave Allan variances
//! σ̂²_j, weights edf_j/model_j² (Var σ̂² = 2σ⁴/edf, NIST SP 1065 §5.3; the edf of the noise
//! type that dominates the current model at τ_j), iterated so that the weights come from the
//! model and not from the data point (weighting by σ̂² would favour points that came out low).
//! Non-negativity: every subset of components is solved unconstrained and the best feasible
//! one kept. A component earns its place by lowering the χ² of the residuals by more than its
//! 99 % point for the parameters it adds: χ²₁ for Q, N, K, R ([`TERM_PENALTY`]), χ²₂ for a
//! Gauss–Markov component (σ and T), χ²₃ for bias instability (B and the two band edges).
//!
//! Intervals (record length, not the fit's χ²): the octave Allan variances come from the
//! same samples and are correlated, so the least-squares covariance overstates what they
//! know. Each figure's interval is that of its most informative single reading, as `analyze`
//! uses for its pass bands ([`crate::analysis::conformance`]): at octave m the component
//! holds a share ρ(m) of σ², so its coefficient is read with ν = edf(m)·ρ(m)² degrees of
//! freedom (Q and N, which trade against each other at the shortest τ, with the two-octave
//! rule of [`term_edf`]); ν is maximised over the octaves and the value v̂ = √ĉ, distributed
//! as v·√(χ²_ν/ν), gives the 99 % interval v ∈ [v̂/√(χ²_{0.995}/ν), v̂/√(χ²_{0.005}/ν)].
//! Bias instability is read only inside its band (there its value does not depend on where
//! the band ends). The Gauss–Markov σ and T are read together from a pair of octaves
//! ([`gm_pair_dof`]), since one reading cannot tell a larger σ from a shifted T, or from the
//! joint Fisher information of every parameter where that is wider. The band edges trade
//! with their neighbours: each interval is the union over the bands whose fit is within
//! χ²₃(99 %) of the best.
//!
//! What a template can hold ([`fit_triad`]): one band per triad, and no ramp from the Allan
//! variance — its χ² cannot tell a ramp from a random walk's last octaves, so a better fit
//! with one is only reported beside the template's; a recording's ramp is tested on its time
//! series instead ([`super::ramp`]).

mod design;
mod intervals;
mod model;
#[cfg(test)]
mod tests;

pub use super::output::{OutputStage, sine_avar};
use crate::analysis::confidence::{NoiseType, edf};
use crate::analysis::conformance::{band as chi2_band, model_allowance, term_edf};
use crate::analysis::fit::{TERM_PENALTY, Term, weighted_lstsq};
use crate::analysis::octave_adev::AdevPoint;
use crate::analysis::theory::{AxisTheory, gm_avar_sampled};
use crate::errors::process::{FLICKER_RATIO, flicker_bank};

use design::*;
use intervals::*;
pub use model::*;

/// χ²₂ at 99 % (= 2 ln 100): what a Gauss–Markov component (σ, T) must gain.
pub const GM_PENALTY: f64 = 9.210_340_371_976_184;

/// χ²₃ at 99 %: what bias instability with its band (B, τ_lo, τ_hi) must gain.
pub const FLICKER_PENALTY: f64 = 11.344_866_730_144_373;

/// Under an output filter, the shortest correlation time (in Δt) a fitted Gauss–Markov or
/// bank component may have ([`OutputStage`]).
pub const FILTERED_SLOWEST: f64 = 10.0;

/// Reweighting passes (the chosen model settles within three or four on every case tried).
const PASSES: usize = 6;
/// What the search may use.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// Whether a rate ramp may be fitted (the template has no key for it).
    pub ramp: bool,
    /// The bias-instability band, when fixed (it must lie on the search grid).
    pub band: Option<(f64, f64)>,
    /// Whether the random walk must be in the model (the least favourable null of the
    /// time-domain ramp test, [`super::ramp`]).
    pub walk: bool,
    /// What the output LSB fixes.
    pub output: OutputStage,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            ramp: true,
            band: None,
            walk: false,
            output: OutputStage::default(),
        }
    }
}

/// Fits one axis to its octave Allan deviation `points`, measured from `samples` rate samples
/// at interval `dt`, every component allowed. None when no point is usable.
pub fn fit_axis(points: &[AdevPoint], samples: usize, dt: f64) -> Option<AxisFit> {
    fit_axis_with(points, samples, dt, &Options::default())
}

/// The three axes of a triad as the template can hold them: no ramp (reported as an
/// alternative where a fit with it is better) and one bias-instability band for the triad —
/// of the bands the axes choose alone, the one with the least total cost.
pub fn fit_triad(points: [&[AdevPoint]; 3], samples: usize, dt: f64) -> [Option<AxisFit>; 3] {
    fit_triad_with(points, samples, dt, true, Default::default())
}

/// [`fit_triad`], the Allan-variance ramp alternative sought only when `alternative` (a
/// recording's ramp is tested on its time series instead, [`super::ramp`]).
pub fn fit_triad_with(
    points: [&[AdevPoint]; 3],
    samples: usize,
    dt: f64,
    alternative: bool,
    outputs: [OutputStage; 3],
) -> [Option<AxisFit>; 3] {
    let axes = |band: Option<(f64, f64)>| -> [Option<AxisFit>; 3] {
        std::array::from_fn(|i| {
            let o = Options {
                ramp: false,
                band,
                walk: false,
                output: outputs[i].clone(),
            };
            fit_axis_with(points[i], samples, dt, &o)
        })
    };
    let alone = axes(None);
    let mut bands: Vec<(f64, f64)> = alone
        .iter()
        .flatten()
        .filter(|f| f.model.c[2] > 0.0)
        .map(|f| f.model.band)
        .collect();
    bands.dedup();
    let mut fits = if bands.len() <= 1 {
        alone
    } else {
        bands
            .iter()
            .map(|&b| axes(Some(b)))
            .min_by(|a, b| total_cost(a).total_cmp(&total_cost(b)))
            .expect("two or more bands")
    };
    for ((f, p), output) in fits.iter_mut().zip(points).zip(&outputs) {
        let Some(f) = f.as_mut().filter(|_| alternative) else {
            continue;
        };
        let with = Options {
            ramp: true,
            band: (f.model.c[2] > 0.0).then_some(f.model.band),
            walk: false,
            output: output.clone(),
        };
        if let Some(r) = fit_axis_with(p, samples, dt, &with)
            && r.cost < f.cost
        {
            f.ramp_alternative = r.estimate(Component::Ramp);
        }
    }
    fits
}

fn total_cost(fits: &[Option<AxisFit>; 3]) -> f64 {
    fits.iter().flatten().map(|f| f.cost).sum()
}

/// [`fit_axis`] with restrictions.
pub fn fit_axis_with(
    points: &[AdevPoint],
    samples: usize,
    dt: f64,
    opts: &Options,
) -> Option<AxisFit> {
    let mut d = Design::new(points, dt, opts.output.clone());
    d.walk = opts.walk;
    if d.y.is_empty() {
        return None;
    }
    let phases = samples + 1;
    let bands = match opts.band {
        None => d.all_bands(),
        Some(b) => vec![None, d.bands.iter().position(|c| c.0 == b)],
    };
    let gms = d.all_gms();
    let mut base_exclude: Vec<Component> = Vec::new();
    if !opts.ramp {
        base_exclude.push(Component::Ramp);
    }
    if !opts.output.carry {
        base_exclude.push(Component::Quantization);
    }
    let base_exclude = base_exclude.as_slice();
    // First pass weighted by the data, then by the model.
    let mut model_avar = d.y.clone();
    let mut types = vec![NoiseType::WhiteRate; d.y.len()];
    let mut found: Option<Found> = None;
    let mut w = Vec::new();
    for _ in 0..PASSES {
        w =
            d.ms.iter()
                .zip(&model_avar)
                .zip(&types)
                .map(|((&m, a), t)| edf(*t, phases, m) / (a * a))
                .collect();
        let f = d.search(&w, dt, base_exclude, &bands, &gms)?;
        for (j, &m) in d.ms.iter().enumerate() {
            // A model that vanishes at a point would give it infinite weight.
            model_avar[j] = f.model.avar(m).max(1e-6 * d.y[j]);
            types[j] = f
                .model
                .dominant(m)
                .map_or(NoiseType::WhiteRate, |k| k.noise_type());
        }
        let settled = found.as_ref().is_some_and(|p| p.model == f.model);
        found = Some(f);
        if settled {
            break;
        }
    }
    let mut found = found?;
    if found.model.c[5] > 0.0 {
        found = refine(&d, &w, dt, base_exclude, &bands, found);
    }
    let model = found.model.clone();
    let (mut intervals, mut gm_tau_interval) = readings(&d, &model, phases);
    // The band edges trade with their neighbours (the low edge with σ_GM, the high edge with
    // K): each figure's interval is the union of its intervals over the bands whose fit is
    // within χ²₃(99 %) of the best.
    if model.c[2] > 0.0 {
        let t = model.gm_tau;
        let col = gm_column(&d.ms, dt, t);
        let mut gms_t = gms.clone();
        gms_t.push(Some((t, col.as_slice())));
        for bi in 0..d.bands.len() {
            let Some(alt) = d
                .search(&w, dt, base_exclude, &[Some(bi)], &gms_t)
                .filter(|f| f.cost <= found.cost + FLICKER_PENALTY)
            else {
                continue;
            };
            let alt = if alt.model.c[5] > 0.0 {
                refine(&d, &w, dt, base_exclude, &[Some(bi)], alt)
            } else {
                alt
            };
            let (alt_iv, alt_t) = readings(&d, &alt.model, phases);
            for (iv, a) in intervals.iter_mut().zip(alt_iv) {
                if let (Some(iv), Some(a)) = (iv.as_mut(), a) {
                    iv.lo = iv.lo.min(a.lo);
                    iv.hi = iv.hi.max(a.hi);
                }
            }
            if let (Some(t), Some(a)) = (gm_tau_interval.as_mut(), alt_t) {
                *t = (t.0.min(a.0), t.1.max(a.1));
            }
        }
    }
    let estimates = std::array::from_fn(|i| {
        let mut e = intervals[i]?;
        let mut exclude = base_exclude.to_vec();
        exclude.push(COMPONENTS[i]);
        let without = d.search(&w, dt, &exclude, &bands, &gms);
        // The gain against the best fit without it is counted as the search chose: in
        // penalised cost, plus its own penalty. So it exceeds the penalty exactly when the
        // component was kept; a plain χ² difference can even be negative, when the best fit
        // without it takes two other components whose penalties it does not pay.
        e.gain = without.map_or(f64::INFINITY, |f| {
            f.cost - found.cost + COMPONENTS[i].penalty()
        });
        Some(e)
    });
    Some(AxisFit {
        model,
        estimates,
        gm_tau_interval,
        chi2: found.chi2,
        cost: found.cost,
        ramp_alternative: None,
        ramp: None,
        points: d.y.len(),
    })
}
