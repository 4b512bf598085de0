//! The model of one axis: its components, their exact Allan-variance bases at the record's
//! Δt, a fitted model and what a fit of one axis reports.

use super::*;

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
            post_filter: 0.0,
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
pub(super) fn fixed_basis(k: Component, m: usize, dt: f64) -> f64 {
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
pub(super) fn flicker_basis(band: (f64, f64), m: usize, dt: f64) -> f64 {
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
    /// χ² the component gains over the best fit without it, the penalties of the other
    /// components each fit keeps counted (kept exactly when this exceeds its own penalty).
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
