//! Causal reconstruction of a sensor signal from its increments, and the Gauss–Legendre
//! collocation tableau the navigator integrates with. Pure math.
//!
//! Reconstruction: inside the newest interval, ω_ib^b(t) (or f^b(t)) is taken as the
//! polynomial of degree n − 1 whose integrals over the last n intervals (the newest and the
//! n − 1 before it — causal, like a real-time navigator) equal the n recorded increments. It
//! is exact for signals that are polynomials of degree < n; the coning, sculling and scrolling
//! terms computed from it are therefore exact for such signals, which is what "an n-sample
//! algorithm" means (n = 2 reproduces the classic two-sample coning correction
//! Δθ_k + (1/12) Δθ_{k−1} × Δθ_k to third order).

use crate::math::Vec3;
use crate::quadrature::GaussLegendre;
use nalgebra::{DMatrix, DVector};

/// Largest reconstruction window (intervals).
pub const MAX_SAMPLES: usize = 8;

/// The inverse of a small square matrix (LU with partial pivoting), row by row.
///
/// The matrices here (moment and Vandermonde matrices of at most 8×8 on O(1) nodes) are
/// well conditioned and never singular; rows are returned as vectors so the per-record
/// reconstruction reads contiguous memory.
fn inverse_rows(m: DMatrix<f64>) -> Vec<Vec<f64>> {
    let inv = m
        .lu()
        .try_inverse()
        .expect("moment matrices of distinct unit intervals are invertible");
    inv.row_iter()
        .map(|r| r.iter().copied().collect())
        .collect()
}

/// Reconstruction weights for every window length 1..=n and every position of the target
/// interval in the window: `w[len − 1][o][m][i]` is the coefficient of τ^m (τ ∈ [0, 1] across
/// the target interval, number `o` of the window, oldest first) contributed by increment `i`.
#[derive(Clone, Debug)]
pub struct Reconstruction {
    weights: Vec<Vec<Vec<Vec<f64>>>>,
}

impl Reconstruction {
    /// Weights for windows of up to `n` intervals (1 ≤ n ≤ [`MAX_SAMPLES`]).
    pub fn new(n: usize) -> Reconstruction {
        let weights = (1..=n)
            .map(|len| {
                (0..len)
                    .map(|o| {
                        // Interval i of the window spans [i − o, i − o + 1] in units of Δt,
                        // so the target interval is [0, 1].
                        inverse_rows(DMatrix::from_fn(len, len, |i, m| {
                            let lo = i as f64 - o as f64;
                            let p = m as i32 + 1;
                            ((lo + 1.0).powi(p) - lo.powi(p)) / p as f64
                        }))
                    })
                    .collect()
            })
            .collect();
        Reconstruction { weights }
    }

    /// Polynomial coefficients (ascending powers of τ, in increment units) of interval
    /// `target` of `window` (oldest first, 1 ≤ len ≤ n). The constant term is set from the
    /// exact constraint ∫₀¹ p = that interval's increment, so each interval reproduces its
    /// own increment to round-off.
    pub fn coefficients(&self, window: &[Vec3], target: usize, out: &mut [Vec3; MAX_SAMPLES]) {
        let len = window.len();
        let w = &self.weights[len - 1][target];
        *out = [Vec3::zeros(); MAX_SAMPLES];
        let mut higher = Vec3::zeros();
        for m in 1..len {
            let c = window
                .iter()
                .zip(&w[m])
                .fold(Vec3::zeros(), |acc, (d, wi)| acc + *d * *wi);
            out[m] = c;
            higher += c * (1.0 / (m + 1) as f64);
        }
        out[0] = window[target] - higher;
    }
}

/// Horner evaluation of a vector polynomial of `len` coefficients at τ.
#[inline]
pub fn eval(c: &[Vec3; MAX_SAMPLES], len: usize, tau: f64) -> Vec3 {
    c[..len]
        .iter()
        .rev()
        .fold(Vec3::zeros(), |acc, cm| acc * tau + *cm)
}

/// Butcher tableau of the s-stage Gauss–Legendre collocation method on [0, 1] (order 2s).
#[derive(Clone, Debug)]
pub struct Tableau {
    /// Stage times c_i.
    pub c: Vec<f64>,
    /// a_ij = ∫₀^{c_i} ℓ_j.
    pub a: Vec<Vec<f64>>,
    /// b_j = ∫₀¹ ℓ_j (the Gauss weights).
    pub b: Vec<f64>,
}

impl Tableau {
    /// The s-stage tableau (1 ≤ s ≤ 16), from the library's Gauss–Legendre nodes: a_ij
    /// solves Σ_j a_ij c_j^m = c_i^{m+1}/(m+1), m < s.
    pub fn gauss(s: usize) -> Option<Tableau> {
        let rule = GaussLegendre::new(s)?;
        let c = rule.nodes.clone();
        // V a_i = rhs_i with V[m][j] = c_j^m, solved by LU (distinct nodes: V is invertible).
        let lu = DMatrix::from_fn(s, s, |m, j| c[j].powi(m as i32)).lu();
        let a = c
            .iter()
            .map(|ci| {
                let rhs = DVector::from_fn(s, |m, _| ci.powi(m as i32 + 1) / (m + 1) as f64);
                let a_i = lu.solve(&rhs).expect("Gauss nodes are distinct");
                a_i.iter().copied().collect()
            })
            .collect();
        Some(Tableau {
            c,
            a,
            b: rule.weights,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reconstruction is exact for polynomial signals of degree < window length.
    #[test]
    fn reconstruction_exact_for_polynomials() {
        for n in 1..=MAX_SAMPLES {
            let r = Reconstruction::new(n);
            let coef: Vec<f64> = (0..n).map(|m| (0.9 * m as f64 + 0.2).cos()).collect();
            let integral = |t: f64| -> f64 {
                (0..n)
                    .map(|m| coef[m] * t.powi(m as i32 + 1) / (m + 1) as f64)
                    .sum()
            };
            // Unit intervals starting at 0.3 − (n − 1), so nothing is centred; every
            // position of the target interval in the window.
            let start = 0.3 - (n - 1) as f64;
            let window: Vec<Vec3> = (0..n)
                .map(|i| {
                    let lo = start + i as f64;
                    let v = integral(lo + 1.0) - integral(lo);
                    Vec3::new(v, -2.0 * v, 0.5 * v)
                })
                .collect();
            for o in 0..n {
                let mut c = [Vec3::zeros(); MAX_SAMPLES];
                r.coefficients(&window, o, &mut c);
                for tau in [0.0, 0.3, 0.77, 1.0] {
                    let t = start + o as f64 + tau;
                    let want: f64 = (0..n).map(|m| coef[m] * t.powi(m as i32)).sum();
                    // Round-off scale: the window's terms reach |c_m|·n^m.
                    let scale: f64 = (0..n)
                        .map(|m| coef[m].abs() * (n as f64).powi(m as i32))
                        .sum();
                    let got = eval(&c, n, tau);
                    let tol = 1e-13 * scale;
                    let (ex, ey) = ((got.x - want).abs(), (got.y + 2.0 * want).abs());
                    assert!(ex < tol && ey < 2.0 * tol, "n {n}, o {o}, τ {tau}: {ex:e}");
                }
            }
        }
    }

    /// Order conditions of Gauss collocation: Σ b_j c_j^m = 1/(m+1) for m < 2s and
    /// Σ_j a_ij c_j^m = c_i^{m+1}/(m+1) for m < s.
    #[test]
    fn tableau_order_conditions() {
        for s in 1..=4 {
            let t = Tableau::gauss(s).unwrap();
            for m in 0..2 * s {
                let q: f64 = (0..s).map(|j| t.b[j] * t.c[j].powi(m as i32)).sum();
                assert!((q - 1.0 / (m + 1) as f64).abs() < 1e-15, "s {s} m {m}");
            }
            for i in 0..s {
                for m in 0..s {
                    let q: f64 = (0..s).map(|j| t.a[i][j] * t.c[j].powi(m as i32)).sum();
                    let want = t.c[i].powi(m as i32 + 1) / (m + 1) as f64;
                    // a_ij come from inverting a Vandermonde matrix (condition ≈ 1e3 at s = 4).
                    assert!(
                        (q - want).abs() < 1e-14,
                        "s {s} i {i} m {m}: {:e}",
                        q - want
                    );
                }
            }
        }
    }
}
