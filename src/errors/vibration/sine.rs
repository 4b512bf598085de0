//! Sinusoidal vibration as the exact interval mean of each record, its phase formed from the
//! integer record index in double-double arithmetic (module doc of `errors/vibration`).

use super::{Sine, sinc, slot};
use crate::errors::process::round;
use std::f64::consts::{PI, TAU};

/// Dekker's split of a into a high half and the rest (a = hi + lo exactly).
#[inline]
fn split(a: f64) -> (f64, f64) {
    let t = 134_217_729.0 * a;
    let hi = t - (t - a);
    (hi, a - hi)
}

/// The rounding error of p = fl(a·b): a·b = p + err exactly (Dekker; b given split).
#[inline]
fn product_error(a: f64, (bh, bl): (f64, f64), p: f64) -> f64 {
    let (ah, al) = split(a);
    ((ah * bh - p) + ah * bl + al * bh) + al * bl
}

/// One sinusoid, as its interval mean.
#[derive(Clone, Debug)]
pub(super) struct SineTerm {
    pub(super) slot: usize,
    /// A·sinc(πfΔt).
    mean_amplitude: f64,
    /// Cycles per record f·Δt = c_hi + c_lo (double-double).
    c_hi: f64,
    c_hi_split: (f64, f64),
    c_lo: f64,
    phase: f64,
}

impl SineTerm {
    pub(super) fn new(s: &Sine, dt: f64) -> SineTerm {
        let c_hi = s.freq_hz * dt;
        let c_lo = product_error(s.freq_hz, split(dt), c_hi);
        SineTerm {
            slot: slot(s.sensor, s.axis),
            mean_amplitude: s.amplitude * sinc(PI * s.freq_hz * dt),
            c_hi,
            c_hi_split: split(c_hi),
            c_lo,
            phase: s.phase_rad,
        }
    }
    /// Record k's value: the mean over ((k − 1)Δt, kΔt] = A·sinc·sin(2πf(k − ½)Δt + φ).
    #[inline]
    pub(super) fn at(&self, k: u64) -> f64 {
        let m = k as f64 - 0.5; // exact for k < 2⁵²
        let p = m * self.c_hi;
        let tail = product_error(m, self.c_hi_split, p) + m * self.c_lo;
        let cycles = (p - round(p)) + tail;
        self.mean_amplitude * (TAU * cycles + self.phase).sin()
    }
}
