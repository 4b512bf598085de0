//! Which internal sample an output sample is. A unit that decimates puts out every D-th
//! filtered sample; a host that polls a unit's output register at its own rate reads the
//! newest complete one, which for an internal rate that is not a multiple of the output rate
//! (the ADIS164xx family samples at 819.2 Hz and is commonly read at 100 Hz) is internal sample
//! ⌊k·f_in/f_out⌋ at output k: 8 or 9 internal samples apart at 8.192. Both are the same
//! rule, n_k = ⌊k·p/q⌋ with f_in/f_out = p/q in lowest terms (q = 1 for decimation), computed
//! in integers so that output k reads the same sample however the run is cut into blocks.

/// The read rule n_k = ⌊k·p/q⌋ of one unit at one output rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadRatio {
    p: u64,
    q: u64,
}

/// Largest denominator accepted for f_in/f_out: a polled read repeats its pattern every q
/// outputs, and the filtered white noise's Allan variance averages over them.
pub const MAX_PERIOD: u64 = 10_000;

impl ReadRatio {
    /// Decimation by `d` (≥ 1): every d-th internal sample.
    pub fn integer(d: u64) -> ReadRatio {
        ReadRatio { p: d.max(1), q: 1 }
    }

    /// The ratio of `internal_hz` to `output_hz`: the first convergent p/q of its continued
    /// fraction within 1e-9 (relative) of it ([`ReadRatio::approximating`]). Refuses an
    /// internal rate below the output rate and a ratio with no such fraction of
    /// q ≤ [`MAX_PERIOD`].
    pub fn from_rates(internal_hz: f64, output_hz: f64) -> Result<ReadRatio, String> {
        let x = internal_hz / output_hz;
        if !(x.is_finite() && x >= 1.0 - 1e-9) {
            return Err(format!(
                "internal rate {internal_hz} Hz is below the output rate {output_hz} Hz"
            ));
        }
        ReadRatio::approximating(x, 1e-9).ok_or_else(|| {
            format!(
                "internal rate {internal_hz} Hz over the output rate {output_hz} Hz is not a ratio of whole numbers with a denominator up to {MAX_PERIOD}"
            )
        })
    }

    /// The first convergent p/q (q ≤ [`MAX_PERIOD`]) of the continued fraction of `x` ≥ 1
    /// within `tolerance` (relative) of it; None when there is none.
    pub fn approximating(x: f64, tolerance: f64) -> Option<ReadRatio> {
        if !(x.is_finite() && x >= 1.0 - tolerance) {
            return None;
        }
        // Convergents h/k: h_n = a_n h_{n−1} + h_{n−2}, likewise k.
        let (mut h0, mut h1, mut k0, mut k1) = (0u64, 1u64, 1u64, 0u64);
        let mut rest = x;
        loop {
            let a = rest.floor();
            if a > 1e12 {
                return None;
            }
            let a = a as u64;
            let (h, k) = (a * h1 + h0, a * k1 + k0);
            if k > MAX_PERIOD {
                return None;
            }
            (h0, h1, k0, k1) = (h1, h, k1, k);
            if (h as f64 / k as f64 - x).abs() <= tolerance * x {
                return Some(ReadRatio { p: h.max(1), q: k });
            }
            let frac = rest - a as f64;
            if frac <= 0.0 {
                return None;
            }
            rest = 1.0 / frac;
        }
    }

    /// n_k: the internal sample (1-based; 0 before the first) output k reads.
    pub fn index(&self, k: u64) -> u64 {
        if self.q == 1 {
            // A decimation: no 128-bit division per output.
            return k * self.p;
        }
        (u128::from(k) * u128::from(self.p) / u128::from(self.q)) as u64
    }

    /// The decimation D when the internal rate is D times the output rate.
    pub fn as_integer(&self) -> Option<u64> {
        (self.q == 1).then_some(self.p)
    }

    /// f_in/f_out as a number.
    pub fn value(&self) -> f64 {
        self.p as f64 / self.q as f64
    }

    /// q: the read pattern repeats every q outputs (p internal samples).
    pub fn period(&self) -> u64 {
        self.q
    }

    /// p: the internal samples in one period.
    pub fn internal_per_period(&self) -> u64 {
        self.p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 819.2 Hz read at 100 Hz is 1024/125: 125 outputs read 1024 internal samples, 8 or 9
    /// apart (9 in 24 of them: 1024 − 8·125 = 24); integer ratios are decimations.
    #[test]
    fn polled_ratio_of_the_adis_family() {
        let r = ReadRatio::from_rates(819.2, 100.0).unwrap();
        assert_eq!((r.internal_per_period(), r.period()), (1024, 125));
        assert_eq!(r.index(125), 1024);
        assert_eq!(r.index(1), 8);
        let steps: Vec<u64> = (1..=125).map(|k| r.index(k) - r.index(k - 1)).collect();
        assert_eq!(steps.iter().filter(|&&s| s == 9).count(), 24);
        assert!(steps.iter().all(|&s| s == 8 || s == 9));
        // Far into a long run the integer rule still holds exactly.
        let k = 1_000_000_007u64;
        assert_eq!(r.index(k), k * 1024 / 125);
        let d = ReadRatio::from_rates(800.0, 200.0).unwrap();
        assert_eq!(d.as_integer(), Some(4));
        assert_eq!(d, ReadRatio::integer(4));
        assert_eq!(r.as_integer(), None);
        assert_eq!(
            ReadRatio::from_rates(785.6, 196.4).unwrap(),
            ReadRatio::integer(4)
        );
    }

    /// A table's rate read from its τ column (the ADIS16448 of imu_utils at 199.999861 Hz,
    /// 0.7 ppm from 200) is 512/125 of 819.2 Hz within a clock's few ppm; 213/52, the
    /// convergent before, is 37 ppm off and not taken at 2 ppm.
    #[test]
    fn a_clock_tolerant_ratio() {
        let r = ReadRatio::approximating(819.2 / 199.999861, 2e-6).unwrap();
        assert_eq!((r.internal_per_period(), r.period()), (512, 125));
        assert!(ReadRatio::from_rates(819.2, 199.999861).is_err());
        // At 5e-5 the earlier convergent 213/52 would pass for it.
        let loose = ReadRatio::approximating(819.2 / 199.999861, 5e-5).unwrap();
        assert_eq!((loose.internal_per_period(), loose.period()), (213, 52));
    }

    /// Below the output rate, and ratios with no small denominator, are refused.
    #[test]
    fn refusals() {
        let e = ReadRatio::from_rates(50.0, 100.0).unwrap_err();
        assert!(e.contains("below the output rate"), "{e}");
        let e = ReadRatio::from_rates(std::f64::consts::PI * 100.0, 100.0).unwrap_err();
        assert!(e.contains("denominator up to 10000"), "{e}");
    }
}
