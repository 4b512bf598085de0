//! Measured IEEE terms against an IMU template: one row per (sensor, axis, term) with a
//! pass/fail band justified by the record length — the perturbed half of `validate`.
//!
//! Band rule. For a term the template sets (value s), let ρ(m) be its share of the template's
//! theoretical σ² ([`super::theory`]) at octave m, and take the octave m* with the largest
//! edf(m)·ρ(m)² among those the record measured (edf of the term's own noise type for the
//! record's length, NIST SP 1065 Table 5): the most informative single reading. Read there,
//! the coefficient c = s² is estimated with the relative variance of one Allan variance point
//! divided by ρ² (the rest of σ² known), i.e. like c·χ²_ν/ν with ν = edf(m*)·ρ(m*)². The band
//! on the value is
//!
//! [s·√(χ²_{0.005}(ν)/ν), s·√(χ²_{0.995}(ν)/ν)] widened by the model allowance,
//!
//! a 99 % band. Why one point and not the least-squares covariance over all octaves: the
//! octave estimates come from the same samples and are strongly correlated at short τ, so
//! treating them as independent overstates the information (see docs/analysis.md, "analyze"
//! section for the seed sweep). A wrong term (e.g. white noise off by a √Δt factor) lands far
//! outside it. Model allowances (relative, where the fit model is not
//! exactly what is generated):
//! * bias instability: none — the refit uses the bank's exact shape (its ±10 % ripple about
//!   the nominal 0.664·B floor is in the basis, not in the band);
//! * quantization, and white noise which the fit can trade against it: the carried residual
//!   is an independent uniform error only when the per-sample noise σ of the increment spans
//!   several LSBs q. By the sawtooth's Fourier series its correlation at lag m is at most
//!   ρ_m = exp(−2π²mσ²/q²) of its variance, so the quantization part of the m = 1 Allan
//!   variance moves by at most (8ρ₁ + 2ρ₂)/6 of itself: Q by at most a = (8ρ₁ + 2ρ₂)/12
//!   ([`quantization_allowance`]), N (if the fit lays it all on N) by a·ρ_Q/ρ_N with the two
//!   terms' shares of σ² at m = 1;
//! * the other terms are exact in the fit model (0).
//!
//! The fitted values are those of a refit in which the bias-instability basis is the exact
//! Allan variance of the template's Gauss–Markov bank (flat only inside its band) rather than
//! the IEEE flat floor, so that the generator is checked against what it is meant to make.
//!
//! Terms the template leaves at zero get no band and no verdict (`pass = None`): the fit may
//! still report a small value, which the caller can show. A term the record is too short to
//! resolve (its band reaches below a tenth of the specified value) and that the fit left out
//! gets no verdict either (`resolved = false`): "not seen" is not "wrong".
//!
//! A template with an output filter. The filter low-passes the internal-rate noise, so at
//! τ ≈ Δt its white noise is not N²/τ ([`crate::errors::filter_allan`]: at τ = Δt the ratio
//! is D·Σ h_i(h_i − h_{i+D}), 17/32 for a Bartlett window of 4 + 4 taps at D = 4), and read
//! there the fit would lay the difference on Q, N and B. The check therefore uses only the
//! octaves from the first one where the filtered white-noise Allan variance is within
//! [`FILTER_TOLERANCE`] of its long-τ limit (and stays so), and the expected white noise is
//! N·√r_∞, the density the output carries after the filter's aliasing (r_∞ = 1 for a moving
//! average or CIC whose length is the decimation). Quantization, read at the shortest τ, then
//! usually shows as not resolved; every slower term is read where the filter no longer
//! matters.

use super::analyzer::Analysis;
#[cfg(test)]
use super::confidence::NoiseType;
use super::confidence::{chi2_quantile, edf};
use super::fit::{TERMS, Term, fit_with_floor};
use super::octave_adev::AdevPoint;
use super::theory::{AxisTheory, triad};
use crate::errors::filter_allan::{SensorAllan, WhiteAllan};
use crate::errors::template::ImuModel;

/// Relative departure of the filtered white-noise Allan variance from its long-τ limit
/// below which an octave is used against a filtered template: 1 % of σ² is 0.5 % of N, a
/// fraction of the N band at any record length `validate` runs.
pub const FILTER_TOLERANCE: f64 = 0.01;

/// Confidence of the pass/fail bands.
pub const BAND_CONFIDENCE: f64 = 0.99;

/// One term of one axis checked against the template.
#[derive(Clone, Debug, PartialEq)]
pub struct TermRow {
    /// "gyro" or "accel".
    pub sensor: &'static str,
    /// Axis 0, 1, 2.
    pub axis: usize,
    /// The term.
    pub term: Term,
    /// The template's value (SI; 0 when not set).
    pub specified: f64,
    /// The fitted value (SI).
    pub fitted: f64,
    /// τ where the fit read it.
    pub tau: Option<f64>,
    /// The term's share of the fitted σ² there.
    pub share: f64,
    /// Band of acceptable fitted values (None when the template does not set the term).
    pub band: Option<(f64, f64)>,
    /// Whether the fitted value lies in the band (None without a band, or when the term is
    /// not resolved).
    pub pass: Option<bool>,
    /// False when the record is too short to see the term: its band reaches below
    /// [`RESOLVED_FRACTION`] of the specified value (whatever the fit reported).
    pub resolved: bool,
}

/// A band whose lower edge is below this fraction of the specified value cannot tell the
/// term from its absence.
pub const RESOLVED_FRACTION: f64 = 0.1;

impl TermRow {
    /// fitted / specified (NaN when not specified).
    pub fn ratio(&self) -> f64 {
        if self.specified > 0.0 {
            self.fitted / self.specified
        } else {
            f64::NAN
        }
    }
}

/// The template's theory of the six channels at the analysis's rate; with an output filter
/// the white noise is the density the output carries at long τ, √(N²·r_∞ + P²) (P the
/// noise added after the filter).
pub fn channel_theory(model: &ImuModel, dt: f64) -> Vec<AxisTheory> {
    let mut v = triad(&model.gyro, model.quantization_mode, dt).to_vec();
    v.extend(triad(&model.accel, model.quantization_mode, dt));
    if let Some(w) = white_allan(model, dt) {
        for (ch, a) in v.iter_mut().enumerate() {
            let p2 = a.post_filter.powi(2);
            a.white = ((a.white.powi(2) - p2) * w.channel(ch).long_tau() + p2).sqrt();
        }
    }
    v
}

/// N²·r_∞: the filtered part of a channel's white density squared (its post-filter noise
/// taken out).
fn filtered_white2(t: &AxisTheory) -> f64 {
    (t.white.powi(2) - t.post_filter.powi(2)).max(0.0)
}

/// Allan variance at cluster size m of a channel whose theory is `t` (from
/// [`channel_theory`]), through the output filter when there is one: the white term
/// N²r_∞/τ becomes N²·r(m)/τ, the filtered white noise of [`WhiteAllan`]; the noise added
/// after the filter stays P²/τ; the slower terms are left as they are (the filter's mark on
/// them at τ ≈ Δt is below the white noise's).
pub fn filtered_avar(t: &AxisTheory, filter: Option<&WhiteAllan>, m: usize, dt: f64) -> f64 {
    let avar = t.avar(m, dt);
    filter.map_or(avar, |w| {
        avar + filtered_white2(t) / (m as f64 * dt) * (w.ratio(m) / w.long_tau() - 1.0)
    })
}

/// One-sided PSD at frequency f of a channel whose theory is `t`, through the output filter
/// when there is one: the white term 2N²r_∞ takes the filter's folded shape
/// ([`WhiteAllan::psd_ratio`]); the post-filter noise stays flat, 2P²; the slower terms are
/// left as they are, as in [`filtered_avar`].
pub fn filtered_psd(t: &AxisTheory, filter: Option<&WhiteAllan>, f: f64, dt: f64) -> f64 {
    let psd = t.psd(f, dt);
    filter.map_or(psd, |w| {
        psd + 2.0 * filtered_white2(t) * (w.psd_ratio(f, dt) - 1.0)
    })
}

/// The filtered white-noise Allan variance of each sensor of a template with an output
/// filter, at the output interval `dt`.
pub fn white_allan(model: &ImuModel, dt: f64) -> Option<SensorAllan> {
    model.output_filter.as_ref().and_then(|f| {
        let read = f.check(1.0 / dt).ok()?;
        Some(SensorAllan::new(f, read))
    })
}

/// The octave points a template is checked on: all of them, or with an output filter those
/// from the first octave where the filter no longer marks white noise ([`FILTER_TOLERANCE`]).
pub fn checked_points<'a>(points: &'a [AdevPoint], filter: Option<&WhiteAllan>) -> &'a [AdevPoint] {
    let Some(w) = filter else {
        return points;
    };
    let ms: Vec<usize> = points.iter().map(|p| p.m).collect();
    let first = w
        .settled_from(&ms, FILTER_TOLERANCE)
        .and_then(|m| ms.iter().position(|&x| x == m))
        .unwrap_or(points.len());
    &points[first..]
}

/// The rows for every sensor, axis and term (30 rows), in channel then term order.
pub fn term_rows(model: &ImuModel, analysis: &Analysis) -> Vec<TermRow> {
    let theory = channel_theory(model, analysis.dt);
    let filters = white_allan(model, analysis.dt);
    let phases = analysis.samples as usize + 1;
    let mut rows = Vec::with_capacity(30);
    for (ch, (c, th)) in analysis.channels.iter().zip(&theory).enumerate() {
        let filter = filters.as_ref().map(|f| f.channel(ch));
        let points = checked_points(&c.adev, filter);
        let ms: Vec<usize> = points.iter().map(|p| p.m).collect();
        let mut nu = term_edf(th, analysis.dt, &ms, phases);
        if filter.is_some() && nu[1].is_some() {
            nu[1] = joint_white_edf(th, analysis.dt, &ms, phases);
        }
        // Refit with the bank's exact shape for B when the template sets it.
        let fit = match th.flicker_shape(1.0) {
            Some(_) => fit_with_floor(points, analysis.samples as usize, &|tau| {
                th.flicker_shape(tau).unwrap_or(0.0)
            }),
            None if filter.is_some() => super::fit::fit(points, analysis.samples as usize),
            None => c.fit.clone(),
        };
        for (i, term) in TERMS.into_iter().enumerate() {
            let specified = th.specified(term);
            let fitted = fit.term(term);
            let band = nu[i].map(|nu| {
                let allow = model_allowance(term, th, analysis.dt);
                band(specified, nu, allow)
            });
            // Whether the fit happened to include the term does not make it resolvable: at
            // the shortest τ the fit can trade a few percent of σ² between Q and N, which for
            // a quantization far below the noise (STIM300) is a "Q" hundreds of times the LSB.
            let resolved = match band {
                Some((lo, _)) => lo >= RESOLVED_FRACTION * specified,
                None => true,
            };
            rows.push(TermRow {
                sensor: if ch < 3 { "gyro" } else { "accel" },
                axis: ch % 3,
                term,
                specified,
                fitted: fitted.value,
                tau: fitted.tau,
                share: fitted.share,
                band,
                pass: band
                    .filter(|_| resolved)
                    .map(|(lo, hi)| fitted.value >= lo && fitted.value <= hi),
                resolved,
            });
        }
    }
    rows
}

/// Degrees of freedom of each specified term read at its most informative octave (None for
/// terms the template does not set). At octave m the term T is read from the Allan variance
/// σ²(m) with relative error ε_m, var ε_m = 2/edf(m). Quantization Q and white noise N are
/// both read at the shortest τ, where the fit trades one against the other; when the partner
/// O of the pair holds a share of σ²(m) (≥ [`PARTNER_SHARE`]), it must be read too, from the
/// next octave m' — the two-point solve s_T(m)δ_T + s_O(m)δ_O = ε_m, s_T(m')δ_T + s_O(m')δ_O = ε_m'
/// gives var δ_T = (s_O(m')²·2/ν_m + s_O(m)²·2/ν_m')/det² (the octaves taken as independent,
/// which overstates the variance of a difference of positively correlated readings: the band
/// errs wide). Otherwise δ_T = ε_m/s_T(m) (the rest of σ² known). ν = 2/var δ_T, maximised
/// over m. Measured: the single-point rule made Q's band about half as wide as the seed
/// scatter of the fitted Q (7 of 120 LN-200 Q checks outside a 99 % band at 100 Hz, seeds
/// 1–10); the slower terms (B, K), read over many octaves of distinct slope, keep it.
pub fn term_edf(th: &AxisTheory, dt: f64, ms: &[usize], phases: usize) -> [Option<f64>; 5] {
    std::array::from_fn(|i| {
        let term = TERMS[i];
        if th.specified(term) <= 0.0 {
            return None;
        }
        let nu_at = |m: usize| edf(term.noise_type(), phases, m);
        ms.iter()
            .enumerate()
            .map(|(j, &m)| {
                let st = th.share(term, m, dt);
                let partner = match term {
                    Term::Quantization => Some(Term::WhiteNoise),
                    Term::WhiteNoise => Some(Term::Quantization),
                    _ => None,
                }
                .filter(|&o| th.specified(o) > 0.0)
                .map(|o| (o, th.share(o, m, dt)))
                .filter(|p| p.1 >= PARTNER_SHARE);
                match (partner, ms.get(j + 1)) {
                    (Some((o, so)), Some(&m2)) => {
                        let (st2, so2) = (th.share(term, m2, dt), th.share(o, m2, dt));
                        let det = st * so2 - st2 * so;
                        let var =
                            (so2 * so2 * 2.0 / nu_at(m) + so * so * 2.0 / nu_at(m2)) / (det * det);
                        if var.is_finite() { 2.0 / var } else { 0.0 }
                    }
                    // The last octave, or a term alone enough at m: the single reading.
                    _ => nu_at(m) * st * st,
                }
            })
            .max_by(f64::total_cmp)
            .filter(|nu| *nu > 0.0)
            .map(|nu| nu.max(0.5))
    })
}

/// ν of the white noise N of a filtered template, read jointly with the terms the fit can
/// trade it against on the few octaves the filter leaves (Q, B, K). The octave readings'
/// relative errors ε_m (var 2/edf_m, edf of the noise type dominating octave m, the octaves
/// taken as independent) enter the generalised least squares for the coefficients' changes
/// x_t, ε_m = Σ_t x_t·b_t(τ_m)/σ²(τ_m), whose covariance is (GᵀWG)⁻¹ with W = diag(edf_m/2);
/// then var(ΔN²/N²) = [(GᵀWG)⁻¹]_NN/N⁴ and ν = 2/var. Q, B and K are in G whether or not the
/// template sets them, because the fit may keep any of them; B with the bank's exact shape
/// when the template sets it (as the refit uses), else the flat floor. Fewer octaves than
/// terms leave N undetermined (None).
pub fn joint_white_edf(th: &AxisTheory, dt: f64, ms: &[usize], phases: usize) -> Option<f64> {
    const JOINT: [Term; 4] = [
        Term::Quantization,
        Term::WhiteNoise,
        Term::BiasInstability,
        Term::RandomWalk,
    ];
    let c_n = th.specified(Term::WhiteNoise).powi(2);
    if c_n <= 0.0 || ms.len() < JOINT.len() {
        return None;
    }
    let basis = |t: Term, tau: f64| match t {
        Term::BiasInstability => th.flicker_shape(tau).unwrap_or(super::fit::FLICKER_FLOOR),
        _ => t.basis(tau),
    };
    let mut g = nalgebra::DMatrix::<f64>::zeros(ms.len(), JOINT.len());
    let mut w = nalgebra::DVector::<f64>::zeros(ms.len());
    for (i, &m) in ms.iter().enumerate() {
        let tau = m as f64 * dt;
        let total = th.avar(m, dt);
        for (j, &t) in JOINT.iter().enumerate() {
            g[(i, j)] = basis(t, tau) / total;
        }
        let dominant = TERMS
            .into_iter()
            .max_by(|a, b| th.share(*a, m, dt).total_cmp(&th.share(*b, m, dt)))
            .unwrap_or(Term::WhiteNoise);
        w[i] = edf(dominant.noise_type(), phases, m) / 2.0;
    }
    // Columns scaled to unit norm so the normal matrix is well conditioned.
    let scale: Vec<f64> = g.column_iter().map(|c| c.norm()).collect();
    for (j, s) in scale.iter().enumerate() {
        g.column_mut(j).scale_mut(1.0 / s);
    }
    let f = g.transpose() * nalgebra::DMatrix::from_diagonal(&w) * &g;
    let cov = f.try_inverse()?;
    let var_n = cov[(1, 1)] / (scale[1] * scale[1]) / (c_n * c_n);
    (var_n.is_finite() && var_n > 0.0).then(|| (2.0 / var_n).max(0.5))
}

/// Share of σ² above which a second term must be read along with the one being checked.
pub const PARTNER_SHARE: f64 = 0.05;

/// The relative model allowance of the module documentation for `term` at sampling
/// interval Δt (0 for the terms the fit model describes exactly).
pub fn model_allowance(term: Term, th: &AxisTheory, dt: f64) -> f64 {
    let a = quantization_allowance(th.white * dt.sqrt(), th.quantization * 12f64.sqrt());
    match term {
        Term::Quantization => a,
        Term::WhiteNoise => {
            let n = th.share(Term::WhiteNoise, 1, dt);
            if n > 0.0 {
                a * th.share(Term::Quantization, 1, dt) / n
            } else {
                0.0
            }
        }
        _ => 0.0,
    }
}

/// Bound on the relative change of Q read at m = 1 when the per-sample increment noise
/// `sigma` does not span the LSB `q`: (8ρ₁ + 2ρ₂)/12, ρ_m = exp(−2π²mσ²/q²).
pub fn quantization_allowance(sigma: f64, q: f64) -> f64 {
    if q <= 0.0 {
        return 0.0;
    }
    let rho = |m: f64| (-2.0 * std::f64::consts::PI.powi(2) * m * (sigma / q).powi(2)).exp();
    (8.0 * rho(1.0) + 2.0 * rho(2.0)) / 12.0
}

/// The 99 % band on a term's value: ĉ ~ c·χ²_ν/ν, widened by the relative allowance.
pub fn band(specified: f64, nu: f64, allow: f64) -> (f64, f64) {
    let alpha = 1.0 - BAND_CONFIDENCE;
    let lo = (chi2_quantile(alpha / 2.0, nu) / nu).sqrt();
    let hi = (chi2_quantile(1.0 - alpha / 2.0, nu) / nu).sqrt();
    (
        specified * lo * (1.0 - allow),
        specified * hi * (1.0 + allow),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The band is the χ² interval of ν degrees of freedom: ±2.576/√(2ν) for large ν.
    #[test]
    fn band_is_the_chi2_interval() {
        let (lo, hi) = band(1.0, 1e6, 0.0);
        let half = 2.576 / (2.0f64 * 1e6).sqrt();
        assert!(((hi - 1.0) / half - 1.0).abs() < 0.01 && ((1.0 - lo) / half - 1.0).abs() < 0.01);
        let (lo2, hi2) = band(1.0, 1e6, 0.1);
        assert!((lo2 / lo - 0.9).abs() < 1e-12 && (hi2 / hi - 1.1).abs() < 1e-12);
    }

    /// White noise alone: the most informative octave is m = 1 with its full edf; a term
    /// the template does not set gets no ν.
    #[test]
    fn term_edf_reads_the_best_octave() {
        let th = AxisTheory {
            white: 1e-3,
            ..AxisTheory::default()
        };
        let ms: Vec<usize> = (0..12).map(|j| 1 << j).collect();
        let nu = term_edf(&th, 0.01, &ms, 100_001);
        assert_eq!(nu[1], Some(edf(NoiseType::WhiteRate, 100_001, 1)));
        assert!(nu[0].is_none() && nu[2].is_none());
    }

    /// Post-filter noise P (`post_filter_noise`) on examples/filtered.toml stays white in the
    /// theory: each channel's long-τ density squared gains P², its filtered Allan variance
    /// exactly P²/τ at every m and its PSD a flat 2P²; the filtered part is unchanged.
    #[test]
    fn post_filter_noise_stays_white_in_the_theory() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/filtered.toml");
        let m0 = crate::errors::template::load(path).unwrap();
        let mut m1 = m0.clone();
        let (pg, pa) = (m0.gyro.noise[0], m0.accel.noise[0]);
        m1.gyro.post_filter_noise = [pg; 3];
        m1.accel.post_filter_noise = [pa; 3];
        let dt = 1.0 / 204.8;
        let (t0, t1) = (channel_theory(&m0, dt), channel_theory(&m1, dt));
        let w = white_allan(&m0, dt).unwrap();
        let close = |a: f64, b: f64, what: &str| {
            assert!((a / b - 1.0).abs() < 1e-9, "{what}: {a:e} vs {b:e}")
        };
        for ch in 0..6 {
            let p2 = if ch < 3 { pg * pg } else { pa * pa };
            let w = Some(w.channel(ch));
            close(
                t1[ch].white.powi(2) - t0[ch].white.powi(2),
                p2,
                "long-τ density",
            );
            for m in [1, 2, 3, 64, 1000] {
                let d = filtered_avar(&t1[ch], w, m, dt) - filtered_avar(&t0[ch], w, m, dt);
                close(
                    d,
                    p2 / (m as f64 * dt),
                    &format!("Allan variance at m = {m}"),
                );
            }
            for f in [0.1, 51.2, 102.4] {
                let d = filtered_psd(&t1[ch], w, f, dt) - filtered_psd(&t0[ch], w, f, dt);
                close(d, 2.0 * p2, &format!("PSD at {f} Hz"));
            }
        }
    }

    /// examples/filtered.toml (Bartlett window of 4 + 4 taps, 819.2 → 204.8 Hz, r_∞ = 1):
    /// the plotted theory's white term at τ = Δt is 17/32 of N²/τ, the slower terms unchanged,
    /// and beyond the filter's lag it is N²/τ·(1 − 15/(32m)); without a filter nothing changes.
    #[test]
    fn filtered_theory_follows_the_closed_form() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/filtered.toml");
        let m = crate::errors::template::load(path).unwrap();
        let dt = 1.0 / 204.8;
        let th = channel_theory(&m, dt);
        let w = white_allan(&m, dt).unwrap();
        let w = w.channel(0);
        for t in &th {
            let n2 = t.white.powi(2);
            assert!(n2 > 0.0);
            for (k, r) in [(1usize, 17.0 / 32.0), (64, 1.0 - 15.0 / 2048.0)] {
                let tau = k as f64 * dt;
                let want = t.avar(k, dt) - n2 / tau + n2 * r / tau;
                let got = filtered_avar(t, Some(w), k, dt);
                assert!(
                    (got / want - 1.0).abs() < 1e-12,
                    "m = {k}: {got:e} vs {want:e}"
                );
            }
            assert_eq!(filtered_avar(t, None, 1, dt), t.avar(1, dt));
            // PSD: (44 + 20 cos 2πfΔt)/64 on the white term (filter_allan's closed form).
            for f in [0.1, 51.2, 102.4] {
                let shape = (44.0 + 20.0 * (2.0 * std::f64::consts::PI * f * dt).cos()) / 64.0;
                let want = t.psd(f, dt) + 2.0 * n2 * (shape - 1.0);
                let got = filtered_psd(t, Some(w), f, dt);
                assert!(
                    (got / want - 1.0).abs() < 1e-12,
                    "{f} Hz: {got:e} vs {want:e}"
                );
            }
            assert_eq!(filtered_psd(t, None, 1.0, dt), t.psd(1.0, dt));
        }
    }

    /// The quantization allowance vanishes once the noise spans the LSB and is large below it.
    #[test]
    fn quantization_allowance_depends_on_noise_over_lsb() {
        assert!(quantization_allowance(2.0, 1.0) < 1e-30);
        // σ = 0.4 q: ρ₁ = e^{−0.32π²} = 0.042, ρ₂ = 0.0018 → 2.9 %.
        let a = quantization_allowance(0.4, 1.0);
        assert!((a - 0.0286).abs() < 0.0005, "{a}");
        assert!(quantization_allowance(0.05, 1.0) > 0.3);
    }
}
