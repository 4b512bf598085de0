//! Gauss–Legendre quadrature on [0, 1]: n nodes integrate polynomials of degree 2n − 1 exactly
//! (order 2n). Nodes and weights are computed once by Newton iteration on P_n to f64 precision.

/// Nodes and weights of an n-point Gauss–Legendre rule on [0, 1] (weights sum to 1).
#[derive(Clone, Debug, PartialEq)]
pub struct GaussLegendre {
    /// Node positions in (0, 1), ascending.
    pub nodes: Vec<f64>,
    /// Weights, summing to 1.
    pub weights: Vec<f64>,
}

/// Largest supported number of nodes.
pub const MAX_NODES: usize = 16;

impl GaussLegendre {
    /// The n-point rule, 1 ≤ n ≤ [`MAX_NODES`].
    pub fn new(n: usize) -> Option<GaussLegendre> {
        if n == 0 || n > MAX_NODES {
            return None;
        }
        let mut nodes = vec![0.0; n];
        let mut weights = vec![0.0; n];
        for i in 0..n {
            // Chebyshev-like first guess of the i-th root of P_n on [−1, 1], then Newton.
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (p, d) = legendre(n, x);
                dp = d;
                let dx = p / d;
                x -= dx;
                if dx.abs() < 1e-17 {
                    break;
                }
            }
            let (_, d) = legendre(n, x);
            if d != 0.0 {
                dp = d;
            }
            // Map [−1, 1] → [0, 1]; the standard weight 2/((1−x²)P'ₙ²) halves.
            nodes[n - 1 - i] = 0.5 * (1.0 + x);
            weights[n - 1 - i] = 1.0 / ((1.0 - x * x) * dp * dp);
        }
        // Renormalise so a constant integrand is reproduced to the last bit.
        let sum: f64 = weights.iter().sum();
        weights.iter_mut().for_each(|w| *w /= sum);
        Some(GaussLegendre { nodes, weights })
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Always false: a rule has at least one node.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }
}

/// P_n(x) and P_n'(x) by the three-term recurrence.
fn legendre(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    for k in 2..=n {
        let k = k as f64;
        let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    let p = if n == 0 { 1.0 } else { p1 };
    let d = n as f64 * (x * p - p0) / (x * x - 1.0);
    (p, d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_for_polynomials_up_to_degree_2n_minus_1() {
        for n in 1..=MAX_NODES {
            let r = GaussLegendre::new(n).unwrap();
            // Each moment is a sum of n rounded products: n·ε bounds its rounding.
            let tol = n as f64 * f64::EPSILON;
            assert!((r.weights.iter().sum::<f64>() - 1.0).abs() <= tol);
            for deg in 0..(2 * n) {
                let q: f64 = r
                    .nodes
                    .iter()
                    .zip(&r.weights)
                    .map(|(x, w)| w * x.powi(deg as i32))
                    .sum();
                let exact = 1.0 / (deg as f64 + 1.0);
                assert!((q - exact).abs() <= tol, "n {n} deg {deg}: {q} vs {exact}");
            }
        }
    }
}
