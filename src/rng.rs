//! Named random streams: one master seed per run, and for every random process an
//! independent Xoshiro256++ stream seeded from the master seed and the process's name, so the
//! output does not depend on block size or thread count, and adding a term leaves every other
//! term's draws unchanged.

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;

/// The default master seed (printed by `generate`; change it with `--seed`).
pub const DEFAULT_SEED: u64 = 20_261_124;

/// FNV-1a 64-bit hash of a stream name (stable across platforms and versions).
pub fn fnv1a64(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// SplitMix64 finaliser: spreads a seed's bits before it seeds the generator.
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A stream of standard normal draws.
#[derive(Clone, Debug)]
pub struct NormalStream(Xoshiro256PlusPlus);

impl NormalStream {
    /// The stream `name` of master seed `seed`.
    pub fn new(seed: u64, name: &str) -> NormalStream {
        NormalStream(Xoshiro256PlusPlus::seed_from_u64(splitmix64(
            seed ^ fnv1a64(name),
        )))
    }
    /// The next N(0, 1) draw.
    #[inline]
    pub fn draw(&mut self) -> f64 {
        StandardNormal.sample(&mut self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Golden values: a change of rand/rand_distr that alters draws must be noticed.
    #[test]
    fn golden_first_draws() {
        let mut s = NormalStream::new(42, "gyro/x/noise");
        let v: Vec<f64> = (0..3).map(|_| s.draw()).collect();
        let again: Vec<f64> = {
            let mut s = NormalStream::new(42, "gyro/x/noise");
            (0..3).map(|_| s.draw()).collect()
        };
        assert_eq!(v, again);
        let other = NormalStream::new(42, "gyro/y/noise").draw();
        assert_ne!(v[0], other);
        assert_eq!(fnv1a64(""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(
            GOLDEN,
            v[0].to_bits(),
            "first draw {:e} bits {:#x}",
            v[0],
            v[0].to_bits()
        );
    }
    const GOLDEN: u64 = 0xbff3_3360_6c76_7a43;
}
