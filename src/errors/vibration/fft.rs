//! The radix-2 FFT of the random-vibration filter.
//!
//! Not rustfft (a dependency, used by the PSD analysis): its planner picks the algorithm and
//! the SIMD kernel (AVX, SSE, NEON or scalar) from the CPU at run time and may change them
//! between releases, and each choice rounds differently. This transform sits inside the
//! seeded random vibration, whose samples must be the same bits on every machine and every
//! build for a given seed; its rounding depends only on the code below. Speed is not the
//! issue: the transforms are amortised over the block's outputs (30–50 ns per record and axis,
//! module doc of `errors/vibration`).

use std::f64::consts::PI;

/// In-place iterative radix-2 complex FFT of a power-of-two size (forward, e^{−2πijk/n},
/// unnormalised); the inverse is the forward transform with re and im swapped.
#[derive(Clone)]
pub(crate) struct Fft {
    /// Twiddles e^{−iπj/h} of the stage of half-length h at [h, 2h).
    tw_re: Vec<f64>,
    tw_im: Vec<f64>,
    rev: Vec<u32>,
}

impl Fft {
    pub(crate) fn new(n: usize) -> Fft {
        assert!(n.is_power_of_two() && (2..=1 << 31).contains(&n));
        let bits = n.trailing_zeros();
        let (mut tw_re, mut tw_im) = (vec![0.0; n], vec![0.0; n]);
        let mut h = 1;
        while h < n {
            for j in 0..h {
                let (s, c) = (-PI * j as f64 / h as f64).sin_cos();
                tw_re[h + j] = c;
                tw_im[h + j] = s;
            }
            h *= 2;
        }
        let rev = (0..n)
            .map(|i| (i.reverse_bits() >> (usize::BITS - bits)) as u32)
            .collect();
        Fft { tw_re, tw_im, rev }
    }

    pub(crate) fn len(&self) -> usize {
        self.rev.len()
    }

    pub(crate) fn forward(&self, re: &mut [f64], im: &mut [f64]) {
        let n = self.rev.len();
        assert!(re.len() == n && im.len() == n);
        for (i, &j) in self.rev.iter().enumerate() {
            let j = j as usize;
            if j > i {
                re.swap(i, j);
                im.swap(i, j);
            }
        }
        let mut h = 1;
        while h < n {
            let (wr, wi) = (&self.tw_re[h..2 * h], &self.tw_im[h..2 * h]);
            for (cr, ci) in re.chunks_exact_mut(2 * h).zip(im.chunks_exact_mut(2 * h)) {
                let (ar, br) = cr.split_at_mut(h);
                let (ai, bi) = ci.split_at_mut(h);
                for j in 0..h {
                    let tr = br[j] * wr[j] - bi[j] * wi[j];
                    let ti = br[j] * wi[j] + bi[j] * wr[j];
                    br[j] = ar[j] - tr;
                    bi[j] = ai[j] - ti;
                    ar[j] += tr;
                    ai[j] += ti;
                }
            }
            h *= 2;
        }
    }
}
