//! Finite-difference weights on arbitrary (non-uniform) grids, by Fornberg's algorithm
//! (B. Fornberg, "Generation of finite difference formulas on arbitrarily spaced grids",
//! Math. Comp. 51, 1988).

/// Weights `w[m][j]` such that f^(m)(z) ≈ Σ_j w[m][j] f(x_j), for m = 0..=max_order.
///
/// With n points the m-th derivative is exact for polynomials of degree n − 1.
pub fn fornberg(z: f64, x: &[f64], max_order: usize) -> Vec<Vec<f64>> {
    let n = x.len();
    let mut c = vec![vec![0.0; n]; max_order + 1];
    let mut c1 = 1.0;
    let mut c4 = x[0] - z;
    c[0][0] = 1.0;
    for i in 1..n {
        let mn = i.min(max_order);
        let mut c2 = 1.0;
        let c5 = c4;
        c4 = x[i] - z;
        for j in 0..i {
            let c3 = x[i] - x[j];
            c2 *= c3;
            if j == i - 1 {
                for k in (1..=mn).rev() {
                    c[k][i] = c1 * (k as f64 * c[k - 1][i - 1] - c5 * c[k][i - 1]) / c2;
                }
                c[0][i] = -c1 * c5 * c[0][i - 1] / c2;
            }
            for k in (1..=mn).rev() {
                c[k][j] = (c4 * c[k][j] - k as f64 * c[k - 1][j]) / c3;
            }
            c[0][j] = c4 * c[0][j] / c3;
        }
        c1 = c2;
    }
    c
}

/// The `n` sample indices nearest to sample `i` (centred when possible, shifted at the ends),
/// as a half-open range into a series of `len` samples.
pub fn stencil(i: usize, n: usize, len: usize) -> std::ops::Range<usize> {
    let n = n.min(len);
    let lo = i.saturating_sub(n / 2).min(len - n);
    lo..lo + n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_on_polynomials_non_uniform() {
        let x = [0.0, 0.09, 0.21, 0.3, 0.41, 0.5, 0.62];
        let f = |t: f64| 1.0 + 2.0 * t - 3.0 * t.powi(3) + 0.5 * t.powi(6);
        let df = |t: f64| 2.0 - 9.0 * t * t + 3.0 * t.powi(5);
        let d2f = |t: f64| -18.0 * t + 15.0 * t.powi(4);
        for &z in &[0.0, 0.3, 0.62] {
            let w = fornberg(z, &x, 2);
            let d1: f64 = x.iter().zip(&w[1]).map(|(xi, wi)| wi * f(*xi)).sum();
            let d2: f64 = x.iter().zip(&w[2]).map(|(xi, wi)| wi * f(*xi)).sum();
            assert!((d1 - df(z)).abs() < 1e-11, "{d1} {}", df(z));
            assert!((d2 - d2f(z)).abs() < 1e-9, "{d2} {}", d2f(z));
        }
    }

    #[test]
    fn stencil_is_centred_and_shifted_at_ends() {
        assert_eq!(stencil(0, 7, 100), 0..7);
        assert_eq!(stencil(50, 7, 100), 47..54);
        assert_eq!(stencil(99, 7, 100), 93..100);
        assert_eq!(stencil(2, 7, 5), 0..5);
    }
}
