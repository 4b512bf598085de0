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

pub use super::output::{OutputStage, sine_avar};
use crate::analysis::confidence::{NoiseType, edf};
use crate::analysis::conformance::{band as chi2_band, model_allowance, term_edf};
use crate::analysis::fit::{TERM_PENALTY, Term, weighted_lstsq};
use crate::analysis::octave_adev::AdevPoint;
use crate::analysis::theory::{AxisTheory, gm_avar_sampled};
use crate::errors::process::{FLICKER_RATIO, flicker_bank};

/// χ²₂ at 99 % (= 2 ln 100): what a Gauss–Markov component (σ, T) must gain.
pub const GM_PENALTY: f64 = 9.210_340_371_976_184;

/// χ²₃ at 99 %: what bias instability with its band (B, τ_lo, τ_hi) must gain.
pub const FLICKER_PENALTY: f64 = 11.344_866_730_144_373;

/// Under an output filter, the shortest correlation time (in Δt) a fitted Gauss–Markov or
/// bank component may have ([`OutputStage`]).
pub const FILTERED_SLOWEST: f64 = 10.0;

/// Reweighting passes (the chosen model settles within three or four on every case tried).
const PASSES: usize = 6;

/// The components of the model, in coefficient order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Component {
    /// Angle (velocity) quantization Q.
    Quantization,
    /// White noise N (ARW / VRW).
    WhiteNoise,
    /// Bias instability B, as the flicker bank over its τ band.
    BiasInstability,
    /// Rate (acceleration) random walk K.
    RandomWalk,
    /// Rate ramp R.
    Ramp,
    /// First-order Gauss–Markov bias (σ, T).
    GaussMarkov,
}

/// All components, in coefficient order.
pub const COMPONENTS: [Component; 6] = [
    Component::Quantization,
    Component::WhiteNoise,
    Component::BiasInstability,
    Component::RandomWalk,
    Component::Ramp,
    Component::GaussMarkov,
];

impl Component {
    /// Short name.
    pub fn name(self) -> &'static str {
        [
            "quantization",
            "white noise",
            "bias instability",
            "random walk",
            "rate ramp",
            "Gauss-Markov",
        ][self as usize]
    }
    /// The χ² gain the component must bring to be kept.
    pub fn penalty(self) -> f64 {
        match self {
            Component::BiasInstability => FLICKER_PENALTY,
            Component::GaussMarkov => GM_PENALTY,
            _ => TERM_PENALTY,
        }
    }
    /// The noise type whose edf applies where the component dominates.
    pub fn noise_type(self) -> NoiseType {
        match self {
            Component::Quantization => NoiseType::WhitePhase,
            Component::WhiteNoise => NoiseType::WhiteRate,
            Component::BiasInstability | Component::GaussMarkov => NoiseType::FlickerRate,
            Component::RandomWalk | Component::Ramp => NoiseType::RandomWalkRate,
        }
    }
}

/// A fitted model of one axis: coefficients and shape parameters, SI.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// (Q², N², B², K², R², σ_GM²); 0 for a component left out.
    pub c: [f64; 6],
    /// τ band of the bias-instability bank (s).
    pub band: (f64, f64),
    /// Correlation time of the Gauss–Markov component (s).
    pub gm_tau: f64,
    /// Sampling interval (s).
    pub dt: f64,
    /// The output LSB's known part.
    pub output: OutputStage,
}

impl Model {
    /// The contribution of component `k` to σ² at cluster size m.
    pub fn part(&self, k: Component, m: usize) -> f64 {
        let i = k as usize;
        if self.c[i] == 0.0 {
            return 0.0;
        }
        self.c[i]
            * match k {
                Component::BiasInstability => flicker_basis(self.band, m, self.dt),
                Component::GaussMarkov => gm_avar_sampled(self.dt / self.gm_tau, m),
                Component::WhiteNoise => fixed_basis(k, m, self.dt) * self.output.white_ratio(m),
                _ => fixed_basis(k, m, self.dt),
            }
    }
    /// σ² at cluster size m, the output LSB's rounding noise included.
    pub fn avar(&self, m: usize) -> f64 {
        self.rounding(m) + COMPONENTS.iter().map(|&k| self.part(k, m)).sum::<f64>()
    }
    /// The known part of σ² at cluster size m: the rounding noise and the spectral lines.
    pub fn rounding(&self, m: usize) -> f64 {
        self.output.known(m, self.dt)
    }
    /// The component with the largest share at m (None when the model is empty).
    pub fn dominant(&self, m: usize) -> Option<Component> {
        COMPONENTS
            .iter()
            .map(|&k| (k, self.part(k, m)))
            .filter(|p| p.1 > 0.0)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|p| p.0)
    }
    /// The value of component k: √c (Q, N, B, K, R, σ_GM).
    pub fn value(&self, k: Component) -> f64 {
        self.c[k as usize].sqrt()
    }
    /// The same model as the error model's theory of one axis (carry-mode quantization).
    pub fn theory(&self) -> AxisTheory {
        let b = self.value(Component::BiasInstability);
        AxisTheory {
            white: self.value(Component::WhiteNoise),
            rounding_white: self.output.rounding.sqrt(),
            quantization: (self.c[Component::Quantization as usize] + self.output.carried).sqrt(),
            random_walk: self.value(Component::RandomWalk),
            gauss_markov: if self.c[5] > 0.0 {
                vec![(self.value(Component::GaussMarkov), self.gm_tau)]
            } else {
                Vec::new()
            },
            flicker: if b > 0.0 {
                flicker_bank(b, self.band, self.dt)
                    .iter()
                    .map(|c| (c.sigma, c.tau))
                    .collect()
            } else {
                Vec::new()
            },
            bias_instability: b,
        }
    }
}

/// σ² per unit coefficient of the components with no shape parameter.
fn fixed_basis(k: Component, m: usize, dt: f64) -> f64 {
    let tau = m as f64 * dt;
    let mf = m as f64;
    match k {
        Component::Quantization => 3.0 / (tau * tau),
        Component::WhiteNoise => 1.0 / tau,
        Component::RandomWalk => tau / 3.0 * (1.0 + 1.0 / (2.0 * mf * mf)),
        Component::Ramp => tau * tau / 2.0,
        _ => unreachable!("shaped components have their own basis"),
    }
}

/// σ² of the bias-instability bank per unit B² at cluster size m.
fn flicker_basis(band: (f64, f64), m: usize, dt: f64) -> f64 {
    flicker_bank(1.0, band, dt)
        .iter()
        .map(|c| c.sigma * c.sigma * gm_avar_sampled(dt / c.tau, m))
        .sum()
}

/// One fitted figure with its 99 % interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The value (SI).
    pub value: f64,
    /// Lower end of the 99 % interval.
    pub lo: f64,
    /// Upper end of the 99 % interval.
    pub hi: f64,
    /// τ of the most informative octave (s).
    pub tau: f64,
    /// The component's share of σ² there.
    pub share: f64,
    /// Degrees of freedom of the reading (ν).
    pub dof: f64,
    /// χ² the component gains over the best fit without it.
    pub gain: f64,
}

/// The fit of one axis.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisFit {
    /// The chosen model.
    pub model: Model,
    /// Estimates of the kept components, in [`COMPONENTS`] order (None: left out).
    pub estimates: [Option<Estimate>; 6],
    /// The Gauss–Markov correlation time's 99 % interval (s), when the component is kept.
    pub gm_tau_interval: Option<(f64, f64)>,
    /// χ² of the residuals of the chosen model.
    pub chi2: f64,
    /// χ² plus the penalties of the kept components (what the search minimises).
    pub cost: f64,
    /// When the ramp was left out ([`Options::ramp`] false) but a fit with it is better:
    /// the ramp that fit finds and its χ² gain.
    pub ramp_alternative: Option<Estimate>,
    /// The time-domain ramp test of a recording ([`super::ramp`]; None for a table).
    pub ramp: Option<RampTest>,
    /// Octave points used.
    pub points: usize,
}

/// The time-domain ramp test of one channel (SI: rate per second), part of its [`AxisFit`]:
/// defined here, run by [`super::ramp`], which builds on this module's fits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RampTest {
    /// Least-squares slope of the rate.
    pub slope: f64,
    /// Its standard deviation under the model fitted without a ramp.
    pub sigma_null: f64,
    /// slope / sigma_null.
    pub z: f64,
    /// Whether |z| passed the gate (the ramp is then in the template).
    pub kept: bool,
    /// The 99 % interval of R (σ from the model refitted around the line) when kept.
    pub interval: Option<(f64, f64)>,
}

impl AxisFit {
    /// The estimate of component k.
    pub fn estimate(&self, k: Component) -> Option<Estimate> {
        self.estimates[k as usize]
    }
}

/// Confidence of the stated intervals.
pub const INTERVAL_CONFIDENCE: f64 = crate::analysis::conformance::BAND_CONFIDENCE;

/// Precomputed basis columns over the measured octaves.
struct Design {
    ms: Vec<usize>,
    y: Vec<f64>,
    fixed: [Vec<f64>; 4],
    bands: Vec<((f64, f64), Vec<f64>)>,
    gms: Vec<(f64, Vec<f64>)>,
    /// The random walk must be in every model searched ([`Options::walk`]).
    walk: bool,
    /// The output LSB's known part, and `y` less its rounding noise (what the fitted
    /// components must explain).
    output: OutputStage,
    y_fit: Vec<f64>,
}

/// The fixed components in the order of `Design::fixed`.
const FIXED: [Component; 4] = [
    Component::Quantization,
    Component::WhiteNoise,
    Component::RandomWalk,
    Component::Ramp,
];

/// The best model found by a search, with its residual χ² and penalised cost.
#[derive(Clone, Debug)]
struct Found {
    model: Model,
    chi2: f64,
    cost: f64,
}

impl Design {
    fn new(points: &[AdevPoint], dt: f64, output: OutputStage) -> Design {
        let pts: Vec<&AdevPoint> = points
            .iter()
            .filter(|p| p.adev > 0.0 && p.adev.is_finite())
            .collect();
        let ms: Vec<usize> = pts.iter().map(|p| p.m).collect();
        let y: Vec<f64> = pts.iter().map(|p| p.adev * p.adev).collect();
        let y_fit = ms
            .iter()
            .zip(&y)
            .map(|(&m, y)| y - output.known(m, dt))
            .collect();
        let fixed = FIXED.map(|k| {
            ms.iter()
                .map(|&m| {
                    let shape = if k == Component::WhiteNoise {
                        output.white_ratio(m)
                    } else {
                        1.0
                    };
                    fixed_basis(k, m, dt) * shape
                })
                .collect()
        });
        let (tau_min, tau_max) = match (ms.first(), ms.last()) {
            (Some(&a), Some(&b)) => (a as f64 * dt, b as f64 * dt),
            _ => (dt, dt),
        };
        // Band edges on the bank's own half-decade spacing, from the shortest τ measured to
        // a decade beyond the longest (an edge beyond the record is "no upper edge seen");
        // at least a decade wide (narrower is what the Gauss–Markov component describes).
        // Widest first, so that among equal fits the band that claims least is kept.
        let grid = log_grid(tau_min, 10.0 * tau_max, 2.0);
        // Under an output filter the Gauss–Markov and bank components are taken unfiltered
        // (OutputStage): true to O(filter length/T), so only components slower than 10Δt are
        // candidates — a GM of T ≥ 10Δt, a band whose fastest component (τ_lo/(π·√10)) is.
        let (slow, gm_from) = if output.white.is_some() {
            (
                FILTERED_SLOWEST * dt * std::f64::consts::PI * FLICKER_RATIO,
                FILTERED_SLOWEST * dt,
            )
        } else {
            (0.0, 0.0)
        };
        let mut bands = Vec::new();
        for (i, &lo) in grid.iter().enumerate() {
            for &hi in &grid[i..] {
                if hi >= 9.99 * lo && lo <= tau_max && lo >= slow {
                    bands.push((lo, hi));
                }
            }
        }
        bands.sort_by(|a, b| (b.1 / b.0).total_cmp(&(a.1 / a.0)));
        let bands = bands
            .into_iter()
            .map(|b| (b, ms.iter().map(|&m| flicker_basis(b, m, dt)).collect()))
            .collect();
        let gms = log_grid(tau_min.max(gm_from), tau_max, 4.0)
            .into_iter()
            .map(|t| (t, gm_column(&ms, dt, t)))
            .collect();
        Design {
            ms,
            y,
            fixed,
            bands,
            gms,
            walk: false,
            output,
            y_fit,
        }
    }

    /// The best model under weights `w`, without component `exclude`, with the shape
    /// parameters restricted to `bands` and `gms` (indices; None entries mean "absent").
    fn search(
        &self,
        w: &[f64],
        dt: f64,
        exclude: &[Component],
        bands: &[Option<usize>],
        gms: &[Option<(f64, &[f64])>],
    ) -> Option<Found> {
        let mut best: Option<Found> = None;
        for &b in bands {
            if b.is_some() && exclude.contains(&Component::BiasInstability) {
                continue;
            }
            for &g in gms {
                if g.is_some() && exclude.contains(&Component::GaussMarkov) {
                    continue;
                }
                for mask in 0u32..16 {
                    let excluded = FIXED
                        .iter()
                        .enumerate()
                        .any(|(i, k)| mask & (1 << i) != 0 && exclude.contains(k));
                    // FIXED[2] is the random walk.
                    if excluded || (self.walk && mask & (1 << 2) == 0) {
                        continue;
                    }
                    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(6);
                    let mut which: Vec<Component> = Vec::with_capacity(6);
                    for (i, k) in FIXED.iter().enumerate() {
                        if mask & (1 << i) != 0 {
                            cols.push(self.fixed[i].clone());
                            which.push(*k);
                        }
                    }
                    if let Some(bi) = b {
                        cols.push(self.bands[bi].1.clone());
                        which.push(Component::BiasInstability);
                    }
                    if let Some((_, col)) = g {
                        cols.push(col.to_vec());
                        which.push(Component::GaussMarkov);
                    }
                    if cols.is_empty() || cols.len() > self.y.len() {
                        continue;
                    }
                    let Some(sol) = weighted_lstsq(cols, &self.y_fit, w) else {
                        continue;
                    };
                    if sol.iter().any(|v| *v <= 0.0) {
                        continue;
                    }
                    let mut model = Model {
                        c: [0.0; 6],
                        band: b.map_or((1.0, 1000.0), |bi| self.bands[bi].0),
                        gm_tau: g.map_or(1.0, |g| g.0),
                        dt,
                        output: self.output.clone(),
                    };
                    which
                        .iter()
                        .zip(&sol)
                        .for_each(|(k, v)| model.c[*k as usize] = *v);
                    let chi2 = self.chi2(&model, w);
                    let cost = chi2 + which.iter().map(|k| k.penalty()).sum::<f64>();
                    if best.as_ref().is_none_or(|f| cost < f.cost) {
                        best = Some(Found { model, chi2, cost });
                    }
                }
            }
        }
        best
    }

    /// Σ w (σ̂² − σ²)²/2: the χ² of the residuals (Var σ̂² = 2σ⁴/edf, w = edf/σ⁴).
    fn chi2(&self, model: &Model, w: &[f64]) -> f64 {
        self.ms
            .iter()
            .zip(&self.y)
            .zip(w)
            .map(|((&m, y), w)| w * (y - model.avar(m)).powi(2))
            .sum::<f64>()
            / 2.0
    }

    fn all_bands(&self) -> Vec<Option<usize>> {
        std::iter::once(None)
            .chain((0..self.bands.len()).map(Some))
            .collect()
    }

    fn all_gms(&self) -> Vec<Option<(f64, &[f64])>> {
        std::iter::once(None)
            .chain(self.gms.iter().map(|(t, c)| Some((*t, c.as_slice()))))
            .collect()
    }
}

fn gm_column(ms: &[usize], dt: f64, t: f64) -> Vec<f64> {
    ms.iter().map(|&m| gm_avar_sampled(dt / t, m)).collect()
}

/// ∂g/∂ln T of the Gauss–Markov basis at x = Δt/T (= −∂g/∂ln x), by a central difference in ln x.
fn gm_dlnt(x: f64, m: usize) -> f64 {
    let h = 1e-4f64;
    -(gm_avar_sampled(x * h.exp(), m) - gm_avar_sampled(x * (-h).exp(), m)) / (2.0 * h)
}

/// 10^(k/per_decade) for the k with lo ≤ value ≤ hi (a small tolerance at the ends).
fn log_grid(lo: f64, hi: f64, per_decade: f64) -> Vec<f64> {
    let k0 = (lo.log10() * per_decade - 1e-9).ceil() as i64;
    let k1 = (hi.log10() * per_decade + 1e-9).floor() as i64;
    (k0..=k1)
        .map(|k| 10f64.powf(k as f64 / per_decade))
        .collect()
}

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
        e.gain = without.map_or(f64::INFINITY, |f| f.chi2 - found.chi2);
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

/// Each kept component's value and 99 % interval for `model` (the `gain` left at 0), and
/// the interval of T.
fn readings(
    d: &Design,
    model: &Model,
    phases: usize,
) -> ([Option<Estimate>; 6], Option<(f64, f64)>) {
    let dt = model.dt;
    let th = model.theory();
    let nu_ieee = term_edf(&th, dt, &d.ms, phases);
    let gm_pair = gm_pair_dof(d, model, phases);
    let estimates = COMPONENTS.map(|k| {
        let value = model.value(k);
        if value == 0.0 {
            return None;
        }
        // The most informative single octave: largest edf·share²; bias instability only
        // inside its band, where its value does not depend on where the band ends.
        let inside = |m: usize| {
            let tau = m as f64 * dt;
            k != Component::BiasInstability || (tau >= model.band.0 && tau <= model.band.1)
        };
        let reading = |m: usize| {
            let share = model.part(k, m) / model.avar(m);
            let nu = edf(k.noise_type(), phases, m) * share * share;
            (m as f64 * dt, share, nu)
        };
        let best = |ok: &dyn Fn(usize) -> bool| {
            d.ms.iter()
                .filter(|&&m| ok(m))
                .map(|&m| reading(m))
                .max_by(|a, b| a.2.total_cmp(&b.2))
        };
        let (tau, share, single) = best(&inside).or_else(|| best(&|_| true))?;
        let (nu, allow) = match k {
            Component::Quantization => (nu_ieee[0], model_allowance(Term::Quantization, &th, dt)),
            Component::WhiteNoise => (nu_ieee[1], model_allowance(Term::WhiteNoise, &th, dt)),
            Component::RandomWalk => (nu_ieee[3], 0.0),
            Component::GaussMarkov => (gm_pair.map(|p| p.0), 0.0),
            _ => (None, 0.0),
        };
        let nu = nu.unwrap_or(single).max(0.5);
        let (lo_f, hi_f) = chi2_band(1.0, nu, allow);
        Some(Estimate {
            value,
            lo: value / hi_f,
            hi: value / lo_f,
            tau,
            share,
            dof: nu,
            gain: 0.0,
        })
    });
    let gm_tau_interval = gm_pair.map(|(_, sd)| {
        let z = normal_quantile_two_sided(INTERVAL_CONFIDENCE);
        (
            model.gm_tau * (-z * sd).exp(),
            model.gm_tau * (z * sd).exp(),
        )
    });
    (estimates, gm_tau_interval)
}

/// T off the search grid: golden-section search of the cost over ln T within a grid step
/// of the chosen T (band fixed), then the band searched again with that T, twice. Without it
/// T is off by up to half a grid step (±16 %) and σ_GM absorbs the difference.
fn refine(
    d: &Design,
    w: &[f64],
    dt: f64,
    exclude: &[Component],
    bands: &[Option<usize>],
    mut found: Found,
) -> Found {
    let step = 10f64.ln() / 4.0;
    for _ in 0..2 {
        let band = [(found.model.c[2] > 0.0)
            .then(|| d.bands.iter().position(|b| b.0 == found.model.band))
            .flatten()];
        let at = |ln_t: f64| {
            let t = ln_t.exp();
            let col = gm_column(&d.ms, dt, t);
            d.search(w, dt, exclude, &band, &[Some((t, &col))])
        };
        let cost = |ln_t: f64| at(ln_t).map_or(f64::INFINITY, |f| f.cost);
        let g = (5f64.sqrt() - 1.0) / 2.0;
        let centre = found.model.gm_tau.ln();
        let (mut a, mut b) = (centre - step, centre + step);
        let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
        let (mut f1, mut f2) = (cost(x1), cost(x2));
        for _ in 0..24 {
            if f1 < f2 {
                b = x2;
                (x2, f2) = (x1, f1);
                x1 = b - g * (b - a);
                f1 = cost(x1);
            } else {
                a = x1;
                (x1, f1) = (x2, f2);
                x2 = a + g * (b - a);
                f2 = cost(x2);
            }
        }
        if let Some(f) = at(0.5 * (a + b)).filter(|f| f.cost < found.cost && f.model.c[5] > 0.0) {
            found = f;
        }
        let t = found.model.gm_tau;
        let col = gm_column(&d.ms, dt, t);
        if let Some(f) = d
            .search(w, dt, exclude, bands, &[None, Some((t, &col))])
            .filter(|f| f.cost < found.cost)
        {
            found = f;
        }
        if found.model.c[5] == 0.0 {
            break;
        }
    }
    found
}

/// The two-sided standard normal quantile of confidence c, from the χ²₁ quantile.
fn normal_quantile_two_sided(c: f64) -> f64 {
    crate::analysis::confidence::chi2_quantile(c, 1.0).sqrt()
}

/// The Gauss–Markov component read from a pair of octaves (σ² and T together: one reading
/// cannot tell a larger σ from a shifted T). With a_m = ∂ln σ²(m)/∂ln σ_GM² (its share) and
/// b_m = ∂ln σ²(m)/∂ln T, the readings ε_m (variance 2/edf_m) of octaves m < m' give
/// δln T = (a_m ε_m' − a_m' ε_m)/det and δln σ² = (b_m' ε_m − b_m ε_m')/det, det =
/// a_m b_m' − a_m' b_m, the octaves taken as independent and the other components as known
/// (as `analyze`'s two-octave rule for Q and N). Returns (ν of σ_GM² = 2/var, sd of ln T) of
/// the pair that knows each best (pairs one or two octaves apart); None without the component.
fn gm_pair_dof(d: &Design, model: &Model, phases: usize) -> Option<(f64, f64)> {
    if model.c[5] <= 0.0 {
        return None;
    }
    let dt = model.dt;
    let nt = Component::GaussMarkov.noise_type();
    let ab = |m: usize| {
        let total = model.avar(m);
        let dg = gm_dlnt(dt / model.gm_tau, m);
        (
            model.part(Component::GaussMarkov, m) / total,
            model.c[5] * dg / total,
        )
    };
    let mut best_c = f64::INFINITY;
    let mut best_t = f64::INFINITY;
    for (j, &m) in d.ms.iter().enumerate() {
        for &m2 in d.ms.iter().skip(j + 1).take(2) {
            let ((a1, b1), (a2, b2)) = (ab(m), ab(m2));
            let det = a1 * b2 - a2 * b1;
            if det == 0.0 || !det.is_finite() {
                continue;
            }
            let (v1, v2) = (2.0 / edf(nt, phases, m), 2.0 / edf(nt, phases, m2));
            best_c = best_c.min((b2 * b2 * v1 + b1 * b1 * v2) / (det * det));
            best_t = best_t.min((a1 * a1 * v2 + a2 * a2 * v1) / (det * det));
        }
    }
    if !(best_c.is_finite() && best_t.is_finite()) {
        return None;
    }
    // The pair takes the other components as known; where σ_GM trades with them (white noise
    // below the bump, the bias-instability floor above it) their joint Fisher information
    // over all octaves knows less: take the larger variance of the two.
    let (joint_c, joint_t) = gm_joint_variances(d, model, phases).unwrap_or((0.0, 0.0));
    Some((2.0 / best_c.max(joint_c), best_t.max(joint_t).sqrt()))
}

/// Relative variances of σ_GM² and of ln T from the Fisher information of all the model's
/// parameters (each kept coefficient, and ln T) over the octaves, each octave's σ̂² with
/// variance 2σ⁴/edf, the octaves taken as independent.
fn gm_joint_variances(d: &Design, model: &Model, phases: usize) -> Option<(f64, f64)> {
    let dt = model.dt;
    let kept: Vec<Component> = COMPONENTS
        .into_iter()
        .filter(|&k| model.c[k as usize] > 0.0)
        .collect();
    let gm = kept.iter().position(|&k| k == Component::GaussMarkov)?;
    let p = kept.len() + 1;
    // Rows: ∂ln σ²(m)/∂ln c_k = share_k(m), and ∂ln σ²(m)/∂ln T; weight edf/2.
    let mut info = nalgebra::DMatrix::<f64>::zeros(p, p);
    for &m in &d.ms {
        let total = model.avar(m);
        let dg = gm_dlnt(dt / model.gm_tau, m);
        let mut row: Vec<f64> = kept.iter().map(|&k| model.part(k, m) / total).collect();
        row.push(model.c[5] * dg / total);
        let w = edf(model.dominant(m)?.noise_type(), phases, m) / 2.0;
        let r = nalgebra::DVector::from_vec(row);
        info += w * &r * r.transpose();
    }
    let cov = info.cholesky()?.inverse();
    Some((cov[(gm, gm)], cov[(p - 1, p - 1)]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact_points(model: &Model, octaves: usize) -> Vec<AdevPoint> {
        (0..octaves)
            .map(|j| {
                let m = 1usize << j;
                let adev = model.avar(m).sqrt();
                AdevPoint {
                    m,
                    tau: m as f64 * model.dt,
                    adev,
                    terms: 1,
                    edf: 1.0,
                    lo: adev,
                    hi: adev,
                }
            })
            .collect()
    }

    /// An exact model curve on the search grids is recovered to round-off, every component
    /// at once, and the intervals contain the values. Each component holds a good share of
    /// σ² somewhere (white noise below 1 s, the Gauss–Markov bump near 6 s, the floor from 10
    /// to 1000 s, the random walk beyond), so the exact answer is the only one of zero χ².
    #[test]
    fn recovers_an_exact_curve_with_every_component() {
        let dt = 0.01;
        let truth = Model {
            c: [1e-11, 1e-8, 1e-8, 4.4e-12, 0.0, 1e-8],
            band: (10.0, 1000.0),
            gm_tau: 10f64.powf(0.5),
            dt,
            output: OutputStage::default(),
        };
        let f = fit_axis(&exact_points(&truth, 22), 1 << 23, dt).unwrap();
        assert!(
            (f.model.band.0 / 10.0 - 1.0).abs() < 1e-12,
            "{:?}",
            f.model.band
        );
        assert!(
            (f.model.band.1 / 1000.0 - 1.0).abs() < 1e-12,
            "{:?}",
            f.model.band
        );
        assert!((f.model.gm_tau / truth.gm_tau - 1.0).abs() < 1e-12);
        for k in COMPONENTS {
            let (got, want) = (f.model.c[k as usize], truth.c[k as usize]);
            if want == 0.0 {
                assert!(f.estimate(k).is_none(), "{k:?}: {got:e}");
                continue;
            }
            assert!(
                (got / want - 1.0).abs() < 1e-6,
                "{k:?}: {got:e} vs {want:e}"
            );
            let e = f.estimate(k).unwrap();
            assert!(e.lo < e.value && e.value < e.hi, "{k:?} {e:?}");
        }
        assert!(f.chi2 < 1e-6, "{}", f.chi2);
    }
}
