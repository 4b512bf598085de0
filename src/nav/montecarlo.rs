//! The statistics of a Monte Carlo comparison of IMUs (see [`crate::nav::campaign`], which
//! runs it): the seed of each run, the type-7 quantile, and the median and 95th percentile of
//! each error quantity along an outage.

use serde::{Deserialize, Serialize};

use crate::rng::{fnv1a64, splitmix64};

/// Median and 95th percentile of one error quantity.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 95th percentile.
    pub p95: f64,
}

/// Error statistics at one time since the outage start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// Time since the (re)start (s).
    pub t: f64,
    /// 3-D position error (m).
    pub position: Spread,
    /// 3-D velocity error (m/s).
    pub velocity: Spread,
    /// Attitude error angle (rad).
    pub attitude: Spread,
}

/// The seed of run `r` derived from the master seed (the same for every template: the
/// templates are compared on common random numbers where they share terms).
pub fn run_seed(seed: u64, r: usize) -> u64 {
    splitmix64(seed ^ fnv1a64(&format!("compare/run/{r}")))
}

/// q-quantile of sorted values with linear interpolation between order statistics
/// (Hyndman–Fan type 7, the default of R and NumPy).
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = q * (sorted.len() - 1) as f64;
    let i = pos.floor() as usize;
    let frac = pos - i as f64;
    match sorted.get(i + 1) {
        Some(next) => sorted[i] + frac * (next - sorted[i]),
        None => sorted[i],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_type7() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(quantile(&v, 0.5), 3.0);
        assert_eq!(quantile(&v, 0.95), 4.8);
        assert_eq!(quantile(&[7.0], 0.95), 7.0);
        assert!(quantile(&[], 0.5).is_nan());
    }
}
