//! Fitting the IEEE Std 952 terms to a measured Allan deviation curve.
//!
//! Model (IEEE 952-1997 Annex C; the five terms are independent, so variances add):
//!
//! σ²(τ) = 3Q²/τ² + N²/τ + (2 ln 2/π)·B² + K²τ/3 + R²τ²/2,
//!
//! Q angle (velocity) quantization, N angle (velocity) random walk, B bias instability,
//! K rate random walk, R rate ramp. The model is linear in c = (Q², N², B², K², R²).
//!
//! Method: non-negative weighted least squares on σ² over all octave points, iterated
//! (IRLS). The variance of an Allan variance estimate is 2σ⁴/edf, so point j is weighted by
//! edf_j/model_j², where model_j is the current fit (not the measured σ̂²_j: weighting by the
//! data would favour points that came out low and bias every term down) and edf_j is the
//! edf of the noise type that dominates the current fit at τ_j. Since σ̂² is an unbiased
//! estimate of σ² and the weights do not depend on the data point itself, the fitted c are
//! unbiased up to the non-negativity constraint (which only acts on terms that are absent).
//! The non-negative solution is the best feasible unconstrained solution over the 31 subsets of
//! terms (exact NNLS for five unknowns); each term kept must lower the residual χ² by more
//! than its 99 % point for one degree of freedom (6.63), so terms the record does not show are
//! reported as 0 rather than fitted to noise.
//!
//! "Where it was read": the octave τ that carries most information on the term — the largest
//! edf·ρ², ρ the term's share of the fitted σ² there (one point's χ² information on the term's
//! coefficient when the rest of σ² is known) — and that share. A term whose share is small
//! everywhere was not really observed; the share says how much to trust it.

use super::confidence::{NoiseType, edf};
use super::octave_adev::AdevPoint;
use nalgebra::{DMatrix, DVector};

/// The five IEEE 952 terms.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Term {
    /// Quantization Q (angle or velocity; σ = √3·Q/τ).
    Quantization,
    /// Angle / velocity random walk N (σ = N/√τ).
    WhiteNoise,
    /// Bias instability B (flat σ = 0.664·B).
    BiasInstability,
    /// Rate random walk K (σ = K√(τ/3)).
    RandomWalk,
    /// Rate ramp R (σ = Rτ/√2).
    Ramp,
}

/// The terms in model order.
pub const TERMS: [Term; 5] = [
    Term::Quantization,
    Term::WhiteNoise,
    Term::BiasInstability,
    Term::RandomWalk,
    Term::Ramp,
];

/// 2 ln 2 / π: σ² of the flicker floor per B² (σ = 0.664·B).
pub const FLICKER_FLOOR: f64 = 2.0 * std::f64::consts::LN_2 / std::f64::consts::PI;

impl Term {
    /// The term's σ²(τ) per unit coefficient c (the c multiplying it).
    pub fn basis(self, tau: f64) -> f64 {
        match self {
            Term::Quantization => 3.0 / (tau * tau),
            Term::WhiteNoise => 1.0 / tau,
            Term::BiasInstability => FLICKER_FLOOR,
            Term::RandomWalk => tau / 3.0,
            Term::Ramp => tau * tau / 2.0,
        }
    }
    /// The noise type of the term (sets the edf where it dominates).
    pub fn noise_type(self) -> NoiseType {
        match self {
            Term::Quantization => NoiseType::WhitePhase,
            Term::WhiteNoise => NoiseType::WhiteRate,
            Term::BiasInstability => NoiseType::FlickerRate,
            Term::RandomWalk | Term::Ramp => NoiseType::RandomWalkRate,
        }
    }
    /// One-letter IEEE symbol.
    pub fn symbol(self) -> &'static str {
        ["Q", "N", "B", "K", "R"][self as usize]
    }
    /// Short name.
    pub fn name(self) -> &'static str {
        [
            "quantization",
            "random walk (ARW/VRW)",
            "bias instability",
            "rate random walk",
            "rate ramp",
        ][self as usize]
    }
}

/// One fitted term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TermFit {
    /// Which term.
    pub term: Term,
    /// Its value (SI: Q rad or m/s, N rad/√s or m/s/√s, B rad/s or m/s², K rad/s/√s or
    /// m/s²/√s, R rad/s² or m/s³); 0 when the fit leaves it out.
    pub value: f64,
    /// τ where its share of the fitted σ² is largest (None when absent).
    pub tau: Option<f64>,
    /// That share (0–1).
    pub share: f64,
}

/// A fitted curve.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// Coefficients c = (Q², N², B², K², R²).
    pub coeffs: [f64; 5],
    /// The terms with where they were read.
    pub terms: [TermFit; 5],
}

impl Fit {
    /// σ²(τ) of the fitted model.
    pub fn avar(&self, tau: f64) -> f64 {
        avar(&self.coeffs, tau)
    }
    /// The noise type of the largest term at τ (white rate when the fit is empty).
    pub fn dominant(&self, tau: f64) -> NoiseType {
        dominant(&self.coeffs, tau)
    }
    /// The fitted term `t`.
    pub fn term(&self, t: Term) -> TermFit {
        self.terms[t as usize]
    }
}

/// σ²(τ) of coefficients c.
pub fn avar(c: &[f64; 5], tau: f64) -> f64 {
    TERMS.iter().zip(c).map(|(t, c)| c * t.basis(tau)).sum()
}

fn dominant(c: &[f64; 5], tau: f64) -> NoiseType {
    dominant_with(c, tau, &|_| FLICKER_FLOOR)
}

/// The basis of term t with the bias-instability shape `floor`.
fn basis(t: Term, tau: f64, floor: &dyn Fn(f64) -> f64) -> f64 {
    if t == Term::BiasInstability {
        floor(tau)
    } else {
        t.basis(tau)
    }
}

fn avar_with(c: &[f64; 5], tau: f64, floor: &dyn Fn(f64) -> f64) -> f64 {
    TERMS
        .iter()
        .zip(c)
        .map(|(t, c)| c * basis(*t, tau, floor))
        .sum()
}

fn dominant_with(c: &[f64; 5], tau: f64, floor: &dyn Fn(f64) -> f64) -> NoiseType {
    TERMS
        .iter()
        .zip(c)
        .map(|(t, c)| (t, c * basis(*t, tau, floor)))
        .filter(|(_, v)| *v > 0.0)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(NoiseType::WhiteRate, |(t, _)| t.noise_type())
}

/// Fits the five terms to `points` measured from a record of `samples` rate samples.
pub fn fit(points: &[AdevPoint], samples: usize) -> Fit {
    fit_with_floor(points, samples, &|_| FLICKER_FLOOR)
}

/// As [`fit`], with the bias-instability basis σ²(τ)/B² given by `floor` instead of the
/// IEEE flat (2 ln 2/π): used against a template, whose generator's bank is flat only inside
/// its band (`theory::AxisTheory::flicker_shape`), so that B and N are read without the
/// model error of the flat floor outside it.
pub fn fit_with_floor(points: &[AdevPoint], samples: usize, floor: &dyn Fn(f64) -> f64) -> Fit {
    let pts: Vec<&AdevPoint> = points
        .iter()
        .filter(|p| p.adev > 0.0 && p.adev.is_finite())
        .collect();
    let mut c = [0.0; 5];
    if !pts.is_empty() {
        let measured: Vec<f64> = pts.iter().map(|p| p.adev * p.adev).collect();
        let mut model = measured.clone();
        let mut types = vec![NoiseType::WhiteRate; pts.len()];
        for _ in 0..8 {
            let w: Vec<f64> = pts
                .iter()
                .zip(&model)
                .zip(&types)
                .map(|((p, m), t)| edf(*t, samples + 1, p.m) / (m * m))
                .collect();
            c = nnls(&pts, &measured, &w, floor);
            for (j, p) in pts.iter().enumerate() {
                // A model that vanishes at a point would give it infinite weight.
                model[j] = avar_with(&c, p.tau, floor).max(1e-6 * measured[j]);
                types[j] = dominant_with(&c, p.tau, floor);
            }
        }
    }
    let terms = std::array::from_fn(|i| {
        let term = TERMS[i];
        // The point that says most about the term: largest edf·share² (the information of
        // one Allan variance point on the term's coefficient, the rest of σ² known).
        let best = pts
            .iter()
            .map(|p| {
                let share = c[i] * basis(term, p.tau, floor) / avar_with(&c, p.tau, floor);
                let info = edf(term.noise_type(), samples + 1, p.m) * share * share;
                (p.tau, share, info)
            })
            .filter(|(_, s, _)| *s > 0.0)
            .max_by(|a, b| a.2.total_cmp(&b.2));
        TermFit {
            term,
            value: c[i].sqrt(),
            tau: best.map(|b| b.0),
            share: best.map_or(0.0, |b| b.1),
        }
    });
    Fit { coeffs: c, terms }
}

/// The χ² reduction a term must bring to stay in the fit: χ²₁ at 99 %.
pub const TERM_PENALTY: f64 = 6.634_896_601_021_214;

/// Non-negative weighted least squares over the 31 subsets of terms, each term penalised by
/// [`TERM_PENALTY`] so that terms the data do not support are left out rather than fitted to
/// noise.
fn nnls(pts: &[&AdevPoint], y: &[f64], w: &[f64], floor: &dyn Fn(f64) -> f64) -> [f64; 5] {
    let mut best = ([0.0; 5], f64::INFINITY);
    for mask in 1u32..32 {
        let cols: Vec<usize> = (0..5).filter(|i| mask & (1 << i) != 0).collect();
        if cols.len() > pts.len() {
            continue;
        }
        let Some(sol) = weighted_ls(pts, y, w, &cols, floor) else {
            continue;
        };
        if sol.iter().any(|v| *v < 0.0) {
            continue;
        }
        let mut c = [0.0; 5];
        cols.iter().zip(&sol).for_each(|(&i, &v)| c[i] = v);
        // cost/2 is the χ² statistic of the residuals (Var σ̂² = 2σ⁴/edf); each term must
        // lower it by more than the 99 % point of χ²₁ to be kept.
        let cost: f64 = pts
            .iter()
            .zip(y)
            .zip(w)
            .map(|((p, y), w)| w * (y - avar_with(&c, p.tau, floor)).powi(2))
            .sum::<f64>()
            / 2.0
            + TERM_PENALTY * cols.len() as f64;
        if cost < best.1 {
            best = (c, cost);
        }
    }
    best.0
}

/// Unconstrained weighted least squares on the columns `cols`.
fn weighted_ls(
    pts: &[&AdevPoint],
    y: &[f64],
    w: &[f64],
    cols: &[usize],
    floor: &dyn Fn(f64) -> f64,
) -> Option<Vec<f64>> {
    let a: Vec<Vec<f64>> = cols
        .iter()
        .map(|&c| pts.iter().map(|p| basis(TERMS[c], p.tau, floor)).collect())
        .collect();
    let a: Vec<&[f64]> = a.iter().map(Vec::as_slice).collect();
    weighted_lstsq(&a, y, w)
}

/// Weighted least squares min Σ w_j (y_j − Σ_c x_c a_c[j])² over the columns `a`, by
/// Householder QR of the row-weighted, column-normalised design (the basis values of the
/// Allan-variance terms span many decades). None when a column vanishes or the design is
/// singular.
pub(crate) fn weighted_lstsq(cols: &[&[f64]], y: &[f64], w: &[f64]) -> Option<Vec<f64>> {
    let k = cols.len();
    let n = y.len();
    let mut a = DMatrix::from_fn(n, k, |i, c| w[i].sqrt() * cols[c][i]);
    let norms: Vec<f64> = a.column_iter().map(|col| col.norm()).collect();
    if norms.iter().any(|n| *n == 0.0 || !n.is_finite()) {
        return None;
    }
    for (mut col, n) in a.column_iter_mut().zip(&norms) {
        col /= *n;
    }
    let mut b = DVector::from_fn(n, |i, _| w[i].sqrt() * y[i]);
    let qr = a.qr();
    qr.q_tr_mul(&mut b);
    let r = qr.r();
    // Columns are unit-norm, so a tiny diagonal of R means the chosen terms are collinear.
    if r.diagonal().iter().any(|d| d.abs() < 1e-12) {
        return None;
    }
    let x = r.solve_upper_triangular(&b.rows(0, k))?;
    Some(x.iter().zip(&norms).map(|(x, n)| x / n).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact model curves (no noise) are recovered to round-off, whatever the mix.
    #[test]
    fn recovers_an_exact_curve() {
        let c = [1e-14, 4e-10, 2.5e-11, 1e-13, 0.0];
        let points: Vec<AdevPoint> = (0..20)
            .map(|j| {
                let m = 1usize << j;
                let tau = m as f64 * 0.01;
                let adev = avar(&c, tau).sqrt();
                AdevPoint {
                    m,
                    tau,
                    adev,
                    terms: 1,
                    edf: 1.0,
                    lo: adev,
                    hi: adev,
                }
            })
            .collect();
        let f = fit(&points, 1 << 22);
        for (i, (got, want)) in f.coeffs.iter().zip(&c).take(4).enumerate() {
            assert!((got / want - 1.0).abs() < 1e-6, "{i}: {got:e} vs {want:e}");
        }
        assert!(f.coeffs[4] < 1e-12 * c[3]);
        assert!(f.term(Term::Ramp).share < 1e-9);
        // Random walk is read where it dominates and the edf is still large (≈ 300 s here),
        // quantization at the shortest τ.
        let k = f.term(Term::RandomWalk);
        assert!(k.tau.unwrap() > 100.0 && k.share > 0.3, "{k:?}");
        assert!(f.term(Term::Quantization).tau.unwrap() < 0.02);
    }

    #[test]
    fn empty_and_zero_curves_fit_nothing() {
        assert_eq!(fit(&[], 100).coeffs, [0.0; 5]);
        let p = AdevPoint {
            m: 1,
            tau: 1.0,
            adev: 0.0,
            terms: 10,
            edf: 10.0,
            lo: 0.0,
            hi: 0.0,
        };
        assert_eq!(fit(&[p, p], 100).coeffs, [0.0; 5]);
    }
}
