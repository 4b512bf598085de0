//! The least-squares search: the basis columns over the measured octaves, every subset of
//! components solved and the best feasible model kept, band edges and T on their grids.

use super::*;

/// Precomputed basis columns over the measured octaves.
pub(super) struct Design {
    pub(super) ms: Vec<usize>,
    pub(super) y: Vec<f64>,
    pub(super) fixed: [Vec<f64>; 4],
    pub(super) bands: Vec<((f64, f64), Vec<f64>)>,
    pub(super) gms: Vec<(f64, Vec<f64>)>,
    /// The random walk must be in every model searched ([`Options::walk`]).
    pub(super) walk: bool,
    /// The output LSB's known part, and `y` less its rounding noise (what the fitted
    /// components must explain).
    pub(super) output: OutputStage,
    pub(super) y_fit: Vec<f64>,
}

/// The fixed components in the order of `Design::fixed`.
pub(super) const FIXED: [Component; 4] = [
    Component::Quantization,
    Component::WhiteNoise,
    Component::RandomWalk,
    Component::Ramp,
];

/// The best model found by a search, with its residual χ² and penalised cost.
#[derive(Clone, Debug)]
pub(super) struct Found {
    pub(super) model: Model,
    pub(super) chi2: f64,
    pub(super) cost: f64,
}

impl Design {
    pub(super) fn new(points: &[AdevPoint], dt: f64, output: OutputStage) -> Design {
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
    pub(super) fn search(
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
                    let mut cols: Vec<&[f64]> = Vec::with_capacity(6);
                    let mut which: Vec<Component> = Vec::with_capacity(6);
                    for (i, k) in FIXED.iter().enumerate() {
                        if mask & (1 << i) != 0 {
                            cols.push(&self.fixed[i]);
                            which.push(*k);
                        }
                    }
                    if let Some(bi) = b {
                        cols.push(&self.bands[bi].1);
                        which.push(Component::BiasInstability);
                    }
                    if let Some((_, col)) = g {
                        cols.push(col);
                        which.push(Component::GaussMarkov);
                    }
                    if cols.is_empty() || cols.len() > self.y.len() {
                        continue;
                    }
                    let Some(sol) = weighted_lstsq(&cols, &self.y_fit, w) else {
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
                    // χ² of the residuals, Σ w (σ̂² − σ²)²/2 (Var σ̂² = 2σ⁴/edf, w = edf/σ⁴),
                    // the model's σ² being the known part plus these columns times the solution
                    // ([`Model::avar`] term by term): from the columns, which spares rebuilding
                    // the bank's basis for every candidate.
                    let chi2 = (0..self.y_fit.len())
                        .map(|j| {
                            let fit: f64 = cols.iter().zip(&sol).map(|(c, x)| c[j] * x).sum();
                            w[j] * (self.y_fit[j] - fit).powi(2)
                        })
                        .sum::<f64>()
                        / 2.0;
                    let cost = chi2 + which.iter().map(|k| k.penalty()).sum::<f64>();
                    if best.as_ref().is_none_or(|f| cost < f.cost) {
                        best = Some(Found { model, chi2, cost });
                    }
                }
            }
        }
        best
    }

    pub(super) fn all_bands(&self) -> Vec<Option<usize>> {
        std::iter::once(None)
            .chain((0..self.bands.len()).map(Some))
            .collect()
    }

    pub(super) fn all_gms(&self) -> Vec<Option<(f64, &[f64])>> {
        std::iter::once(None)
            .chain(self.gms.iter().map(|(t, c)| Some((*t, c.as_slice()))))
            .collect()
    }
}

pub(super) fn gm_column(ms: &[usize], dt: f64, t: f64) -> Vec<f64> {
    ms.iter().map(|&m| gm_avar_sampled(dt / t, m)).collect()
}

/// ∂g/∂ln T of the Gauss–Markov basis at x = Δt/T (= −∂g/∂ln x), by a central difference in ln x.
pub(super) fn gm_dlnt(x: f64, m: usize) -> f64 {
    let h = 1e-4f64;
    -(gm_avar_sampled(x * h.exp(), m) - gm_avar_sampled(x * (-h).exp(), m)) / (2.0 * h)
}

/// 10^(k/per_decade) for the k with lo ≤ value ≤ hi (a small tolerance at the ends).
pub(super) fn log_grid(lo: f64, hi: f64, per_decade: f64) -> Vec<f64> {
    let k0 = (lo.log10() * per_decade - 1e-9).ceil() as i64;
    let k1 = (hi.log10() * per_decade + 1e-9).floor() as i64;
    (k0..=k1)
        .map(|k| 10f64.powf(k as f64 / per_decade))
        .collect()
}
