//! The intervals of a fitted model: each figure read at its most informative octave (or pair
//! of octaves for a Gauss–Markov σ and T), as the module doc says.

use super::*;

/// Each kept component's value and 99 % interval for `model` (the `gain` left at 0), and
/// the interval of T.
pub(super) fn readings(
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
pub(super) fn refine(
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
pub(super) fn normal_quantile_two_sided(c: f64) -> f64 {
    crate::analysis::confidence::chi2_quantile(c, 1.0).sqrt()
}

/// The Gauss–Markov component read from a pair of octaves (σ² and T together: one reading
/// cannot tell a larger σ from a shifted T). With a_m = ∂ln σ²(m)/∂ln σ_GM² (its share) and
/// b_m = ∂ln σ²(m)/∂ln T, the readings ε_m (variance 2/edf_m) of octaves m < m' give
/// δln T = (a_m ε_m' − a_m' ε_m)/det and δln σ² = (b_m' ε_m − b_m ε_m')/det, det =
/// a_m b_m' − a_m' b_m, the octaves taken as independent and the other components as known
/// (as `analyze`'s two-octave rule for Q and N). Returns (ν of σ_GM² = 2/var, sd of ln T) of
/// the pair that knows each best (pairs one or two octaves apart); None without the component.
pub(super) fn gm_pair_dof(d: &Design, model: &Model, phases: usize) -> Option<(f64, f64)> {
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
pub(super) fn gm_joint_variances(d: &Design, model: &Model, phases: usize) -> Option<(f64, f64)> {
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
