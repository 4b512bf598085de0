//! Per-channel summary statistics in one pass (Welford's update for mean and variance).

/// Running mean, variance, minimum and maximum of one channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stats {
    /// Samples seen.
    pub n: u64,
    /// Mean.
    pub mean: f64,
    m2: f64,
    /// Smallest value (+∞ when empty).
    pub min: f64,
    /// Largest value (−∞ when empty).
    pub max: f64,
}

impl Default for Stats {
    fn default() -> Self {
        Stats {
            n: 0,
            mean: 0.0,
            m2: 0.0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
        }
    }
}

impl Stats {
    /// Adds one value.
    #[inline]
    pub fn push(&mut self, x: f64) {
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
        self.min = self.min.min(x);
        self.max = self.max.max(x);
    }
    /// Sample standard deviation (n − 1 in the denominator; 0 for fewer than two values).
    pub fn std(&self) -> f64 {
        if self.n < 2 {
            0.0
        } else {
            (self.m2 / (self.n - 1) as f64).sqrt()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        let mut s = Stats::default();
        [2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]
            .iter()
            .for_each(|&x| s.push(x));
        assert_eq!(s.mean, 5.0);
        assert!((s.std() - (32.0f64 / 7.0).sqrt()).abs() < 1e-15);
        assert_eq!((s.min, s.max, s.n), (2.0, 9.0, 8));
    }

    /// A large offset costs no digits (the naive Σx² − n·x̄² would lose them all).
    #[test]
    fn offset_does_not_cancel() {
        let mut s = Stats::default();
        (0..1000).for_each(|k| s.push(1e9 + (k % 2) as f64));
        assert!((s.std() - (250.0f64 / 999.0).sqrt()).abs() < 1e-9);
    }
}
