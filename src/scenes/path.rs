//! Analytic path pieces in a local "map" plane (x north, y east, metres) and height profiles:
//! polynomials in time and circular arcs, each with exact derivatives up to third order.

use nalgebra::{Matrix4, Vector4};

/// Value and first three time derivatives of a scalar.
pub type Jet = [f64; 4];

/// A polynomial Σ c_k τ^k of degree ≤ 7 in the piece-local time τ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Poly {
    c: [f64; 8],
    /// Index of the highest non-zero coefficient: lines and constants skip the rest.
    top: usize,
}

impl Poly {
    /// The polynomial with coefficients `c` (c[k] multiplies τ^k).
    pub fn new(c: [f64; 8]) -> Poly {
        let top = c.iter().rposition(|v| *v != 0.0).unwrap_or(0);
        Poly { c, top }
    }
    /// The constant c.
    pub fn constant(c: f64) -> Poly {
        let mut p = [0.0; 8];
        p[0] = c;
        Poly::new(p)
    }
    /// c0 + c1 τ.
    pub fn linear(c0: f64, c1: f64) -> Poly {
        let mut p = [0.0; 8];
        p[0] = c0;
        p[1] = c1;
        Poly::new(p)
    }
    /// Value and derivatives up to order 3 at τ.
    #[inline]
    pub fn jet(&self, tau: f64) -> Jet {
        let c = &self.c;
        let (mut p0, mut p1, mut p2, mut p3) = (0.0, 0.0, 0.0, 0.0);
        for k in (0..=self.top.min(7)).rev() {
            p3 = p3 * tau + p2;
            p2 = p2 * tau + p1;
            p1 = p1 * tau + p0;
            p0 = p0 * tau + c[k];
        }
        // Repeated synthetic division leaves f''/2! in p2 and f'''/3! in p3.
        [p0, p1, 2.0 * p2, 6.0 * p3]
    }
    /// The degree-7 polynomial on τ ∈ [0, T] whose value and first three derivatives equal
    /// `start` at τ = 0 and `end` at τ = T (two-point Hermite interpolation).
    pub fn hermite7(start: Jet, end: Jet, duration: f64) -> Poly {
        let t = duration;
        // In s = τ/T the derivative data scale by T^k.
        let a = [
            start[0],
            start[1] * t,
            start[2] * t * t / 2.0,
            start[3] * t * t * t / 6.0,
        ];
        let e = [end[0], end[1] * t, end[2] * t * t, end[3] * t * t * t];
        // Conditions at s = 1 for q(s) = Σ_{k<4} a_k s^k + Σ_{k=4..7} b_k s^k.
        let known = |d: usize| -> f64 { (0..4).map(|k| a[k] * falling(k, d)).sum::<f64>() };
        let m = Matrix4::from_fn(|d, k| falling(k + 4, d));
        let rhs = Vector4::from_fn(|d, _| e[d] - known(d));
        let b = m
            .lu()
            .solve(&rhs)
            .expect("the Hermite conditions at s = 1 are independent");
        let mut c = [0.0; 8];
        for k in 0..8 {
            let coef = if k < 4 { a[k] } else { b[k - 4] };
            c[k] = coef / t.powi(k as i32);
        }
        Poly::new(c)
    }
}

/// k·(k−1)·…·(k−d+1): the d-th derivative of s^k at s = 1.
fn falling(k: usize, d: usize) -> f64 {
    if d > k {
        return 0.0;
    }
    ((k - d + 1)..=k).map(|v| v as f64).product()
}

/// A horizontal path piece in the map plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Planar {
    /// x(τ), y(τ) polynomials.
    Poly(Poly, Poly),
    /// Uniform circular motion: position c + R(sin ψ, −cos ψ)·σ with heading ψ = ψ₀ + Ωτ,
    /// where σ = sign(Ω) (+1 turning right, clockwise seen from above).
    Arc {
        /// Centre (x, y).
        centre: [f64; 2],
        /// Radius (m).
        radius: f64,
        /// Heading at τ = 0 (rad).
        psi0: f64,
        /// Heading rate Ω (rad/s), positive to the right.
        rate: f64,
    },
}

impl Planar {
    /// Jets of x and y at τ.
    #[inline]
    pub fn jets(&self, tau: f64) -> (Jet, Jet) {
        match *self {
            Planar::Poly(ref x, ref y) => (x.jet(tau), y.jet(tau)),
            Planar::Arc {
                centre,
                radius,
                psi0,
                rate,
            } => {
                let (s, c) = (psi0 + rate * tau).sin_cos();
                let sg = rate.signum();
                let r = radius * sg;
                let (w, w2, w3) = (rate, rate * rate, rate * rate * rate);
                (
                    [centre[0] + r * s, r * w * c, -r * w2 * s, -r * w3 * c],
                    [centre[1] - r * c, r * w * s, r * w2 * c, -r * w3 * s],
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hermite7_matches_end_jets() {
        let s = [1.0, 2.0, -0.5, 0.25];
        let e = [7.0, -1.0, 0.3, -0.2];
        let p = Poly::hermite7(s, e, 3.5);
        let j0 = p.jet(0.0);
        let j1 = p.jet(3.5);
        for d in 0..4 {
            assert!((j0[d] - s[d]).abs() < 1e-12, "start d{d}");
            assert!(
                (j1[d] - e[d]).abs() < 1e-11,
                "end d{d}: {} vs {}",
                j1[d],
                e[d]
            );
        }
    }

    #[test]
    fn poly_jet_derivatives() {
        let p = Poly::new([1.0, -2.0, 0.5, 3.0, 0.0, 0.0, 0.0, 0.1]);
        let t: f64 = 0.7;
        let j = p.jet(t);
        let f = 1.0 - 2.0 * t + 0.5 * t * t + 3.0 * t.powi(3) + 0.1 * t.powi(7);
        let d1 = -2.0 + t + 9.0 * t * t + 0.7 * t.powi(6);
        let d2 = 1.0 + 18.0 * t + 4.2 * t.powi(5);
        let d3 = 18.0 + 21.0 * t.powi(4);
        assert!((j[0] - f).abs() < 1e-14);
        assert!((j[1] - d1).abs() < 1e-14);
        assert!((j[2] - d2).abs() < 1e-13);
        assert!((j[3] - d3).abs() < 1e-13);
    }
}
