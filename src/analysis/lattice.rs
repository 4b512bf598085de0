//! The value lattice of a recorded channel: a real unit puts out integer counts times its
//! LSB, so a static recording's values sit on a grid v₀ + k·q. Streaming: the distinct values
//! of the first [`MAX_SCANNED`] samples are kept until there are too many to be a lattice worth
//! finding (a float record, or counts far finer than the noise), then the channel is given up.

use std::collections::HashSet;

/// Distinct values kept per channel before it is taken as continuous.
pub const MAX_DISTINCT: usize = 1 << 14;

/// Fewest distinct values a lattice is read from (fewer cannot tell a grid from chance).
pub const MIN_DISTINCT: usize = 8;

/// Samples scanned per channel: a grid shows itself long before (its distinct values are
/// those of the noise's span), and the scan costs a hash insert per sample, so a day-long
/// record is read at the speed of the rest of the analysis.
pub const MAX_SCANNED: u64 = 1 << 20;

/// Largest misfit of a value from the grid, in LSBs: values printed with fewer digits than
/// the LSB has (3.33 mg as 0.00333 g) are off by up to half a unit of the last digit.
pub const TOLERANCE: f64 = 0.02;

/// A lattice found: the LSB and where the grid sits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    /// The step q (unit of the channel).
    pub lsb: f64,
    /// The grid's offset v₀ mod q, in [0, q).
    pub offset: f64,
    /// Distinct values seen.
    pub distinct: usize,
    /// Largest misfit of a value from the grid (LSBs).
    pub misfit: f64,
}

/// Streaming collector of one channel's distinct values.
#[derive(Clone, Debug, Default)]
pub struct LatticeScan {
    values: HashSet<u64>,
    overflow: bool,
    scanned: u64,
}

impl LatticeScan {
    /// Adds a value.
    #[inline]
    pub fn push(&mut self, x: f64) {
        if self.overflow || self.scanned >= MAX_SCANNED {
            return;
        }
        self.scanned += 1;
        // +0.0 and −0.0 are one value.
        self.values.insert((x + 0.0).to_bits());
        if self.values.len() > MAX_DISTINCT {
            self.overflow = true;
            self.values = HashSet::new();
        }
    }

    /// The lattice of the values seen, if they lie on one.
    pub fn finish(&self) -> Option<Lattice> {
        if self.overflow {
            return None;
        }
        let mut v: Vec<f64> = self.values.iter().map(|b| f64::from_bits(*b)).collect();
        v.sort_by(f64::total_cmp);
        find(&v)
    }
}

/// The lattice of sorted distinct values: the smallest gap is the first guess of q; every
/// value's count k_i = round((v_i − v₀)/q) then gives the least-squares q = Σk_i(v_i − v₀)/Σk_i²,
/// kept when every value lies within [`TOLERANCE`] LSB of its grid point.
pub fn find(v: &[f64]) -> Option<Lattice> {
    if v.len() < MIN_DISTINCT || v.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let q0 = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    if q0.is_nan() || q0 <= 0.0 {
        return None;
    }
    let v0 = v[0];
    let k: Vec<f64> = v.iter().map(|x| ((x - v0) / q0).round()).collect();
    let (num, den) = k
        .iter()
        .zip(v)
        .fold((0.0, 0.0), |(n, d), (k, x)| (n + k * (x - v0), d + k * k));
    let q = num / den;
    let misfit = k
        .iter()
        .zip(v)
        .map(|(k, x)| ((x - v0 - k * q) / q).abs())
        .fold(0.0, f64::max);
    (q > 0.0 && misfit <= TOLERANCE).then(|| Lattice {
        lsb: q,
        offset: v0.rem_euclid(q),
        distinct: v.len(),
        misfit,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::NormalStream;

    /// Counts of a noisy signal times an LSB that is no short decimal (1/131 deg/s, an
    /// MPU-6050 gyro's) give the LSB back to 1e-12; the same values printed to 5 decimals
    /// (as a CSV would) within the bound their rounding allows; unquantized values give none.
    #[test]
    fn finds_the_lsb_of_counts_and_nothing_in_floats() {
        let q = 1.0 / 131.0;
        let mut s = NormalStream::new(3, "lattice");
        let mut scan = LatticeScan::default();
        let mut printed = LatticeScan::default();
        let mut float = LatticeScan::default();
        for _ in 0..10_000 {
            let x = 4.5 + 0.1 * s.draw();
            let c = (x / q).round() * q;
            scan.push(c);
            printed.push(format!("{c:.5}").parse().unwrap());
            float.push(x);
        }
        let l = scan.finish().unwrap();
        assert!((l.lsb / q - 1.0).abs() < 1e-12, "{l:?}");
        assert!(l.offset < 1e-9 * q || (q - l.offset) < 1e-9 * q, "{l:?}");
        // Printed to 5 decimals each value is off its grid point by ≤ 5e-6; the least-squares
        // slope over a span of s = (k_max − k_min)·q is then off by at most 2·5e-6/s, 3.3e-5
        // relative for the ±4σ span (≥ 80 LSB) of this record.
        let p = printed.finish().unwrap();
        let span = (p.distinct - 1) as f64 * q;
        assert!((p.lsb / q - 1.0).abs() < 2.0 * 5e-6 / span, "{p:?}");
        assert!(float.finish().is_none());
    }

    /// Too few distinct values say nothing; a grid with an offset is found with its offset;
    /// one value off the grid by a third of an LSB breaks it.
    #[test]
    fn offsets_few_values_and_outliers() {
        let grid: Vec<f64> = (0..20).map(|k| 0.3 + 0.05 * k as f64).collect();
        let l = find(&grid).unwrap();
        assert!((l.lsb - 0.05).abs() < 1e-12, "{l:?}");
        assert!(l.offset.min(l.lsb - l.offset) < 1e-9, "{l:?}");
        assert!(find(&grid[..MIN_DISTINCT - 1]).is_none());
        let shifted: Vec<f64> = (0..20).map(|k| 0.013 + 0.05 * k as f64).collect();
        assert!((find(&shifted).unwrap().offset - 0.013).abs() < 1e-12);
        let mut bad = grid.clone();
        bad[7] += 0.05 / 3.0;
        assert!(find(&bad).is_none());
    }
}
