//! Lateness statistics of frame writes: a fixed-size histogram (1 µs bins up to 100 ms), so
//! percentiles cost the same memory for any run length.

/// Bins of 1 µs; the last one collects everything later than 100 ms.
const BINS: usize = 100_001;

/// Histogram of lateness (write time − deadline) in microseconds.
#[derive(Clone, Debug)]
pub struct Lateness {
    bins: Vec<u64>,
    count: u64,
    max_ns: i128,
}

impl Default for Lateness {
    fn default() -> Self {
        Lateness {
            bins: vec![0; BINS],
            count: 0,
            max_ns: 0,
        }
    }
}

impl Lateness {
    /// Adds one lateness (ns; early counts as 0).
    pub fn add(&mut self, late_ns: i128) {
        let late = late_ns.max(0);
        let us = ((late / 1000) as usize).min(BINS - 1);
        self.bins[us] += 1;
        self.count += 1;
        self.max_ns = self.max_ns.max(late);
    }

    /// Adds every sample of `other`.
    pub fn merge(&mut self, other: &Lateness) {
        for (a, b) in self.bins.iter_mut().zip(&other.bins) {
            *a += b;
        }
        self.count += other.count;
        self.max_ns = self.max_ns.max(other.max_ns);
    }

    /// Samples so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// The q-quantile (0..=1) in µs, to the bin's 1 µs resolution (`None` when empty).
    pub fn quantile_us(&self, q: f64) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let rank = ((q * self.count as f64).ceil() as u64).clamp(1, self.count);
        let mut seen = 0;
        for (us, n) in self.bins.iter().enumerate() {
            seen += n;
            if seen >= rank {
                return Some(us as f64);
            }
        }
        Some(self.max_us())
    }

    /// Largest lateness seen (µs).
    pub fn max_us(&self) -> f64 {
        self.max_ns as f64 / 1000.0
    }

    /// `p50/p99/max` in µs, for status lines and tables.
    pub fn summary(&self) -> String {
        match (self.quantile_us(0.5), self.quantile_us(0.99)) {
            (Some(a), Some(b)) => {
                format!("p50 {a:.0} µs, p99 {b:.0} µs, max {:.0} µs", self.max_us())
            }
            _ => "no frames yet".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1..=100 µs once each: the median is 50 µs, p99 99 µs, max exact; overflow is kept.
    #[test]
    fn quantiles() {
        let mut h = Lateness::default();
        assert_eq!(h.quantile_us(0.5), None);
        for us in 1..=100 {
            h.add(us * 1000 + 500);
        }
        assert_eq!(h.quantile_us(0.5), Some(50.0));
        assert_eq!(h.quantile_us(0.99), Some(99.0));
        assert_eq!(h.max_us(), 100.5);
        h.add(5_000_000_000);
        h.add(-7);
        assert_eq!(h.count(), 102);
        assert_eq!(h.quantile_us(1.0), Some(100_000.0));
        assert_eq!(h.max_us(), 5_000_000.0);
    }
}
