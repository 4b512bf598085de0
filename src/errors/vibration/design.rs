//! Spectral synthesis of a random vibration's filter: frequency-sampling design of the
//! linear-phase FIR whose response matches a PSD table (module doc of `errors/vibration`).

use super::fft::Fft;
use super::{MAX_TAPS, MIN_TAPS, RESOLUTION_BINS, Random, sinc};
use std::f64::consts::{PI, TAU};

/// The FIR of a random vibration (N odd, linear phase) and where its table was cut.
pub(super) struct Design {
    pub(super) h: Vec<f64>,
    pub(super) truncated_at_hz: Option<f64>,
}

/// Frequency-sampling design of |H| = √(S/(2Δt))·sinc(πfΔt) (module doc), with the table's
/// ends moved out so that Σh² keeps the target variance.
pub(super) fn design(r: &Random, dt: f64) -> Design {
    let fs = 1.0 / dt;
    let nyquist = 0.5 * fs;
    let (f_first, f_last) = (r.psd[0].0, r.psd[r.psd.len() - 1].0);
    let top = f_last.min(nyquist);
    let feature = f_first.min(top - f_first);
    let wanted = RESOLUTION_BINS * fs / feature;
    let taps = if wanted >= MAX_TAPS as f64 {
        MAX_TAPS
    } else {
        ((wanted as usize) + 1).next_power_of_two() - 1
    }
    .max(MIN_TAPS);
    let fft = Fft::new(8 * (taps + 1));
    // A table's end at Nyquist is no edge: the two-sided target is continuous there.
    let cut_top = f_last < nyquist;
    let fir_with = |delta: f64| {
        let lo = (f_first - delta).max(0.0);
        let hi = (f_last + delta).min(nyquist);
        fir(r, dt, taps, &fft, lo, cut_top.then_some(hi))
    };
    // The window spreads each end (a jump of the amplitude to 0) symmetrically, which loses
    // power: ∫(a⊛K)² < ∫a² across the jump, half a design bin of the end's level per end
    // (0.46 % of a 200-bin band). Moving each end out by δ = lost power / Σ(end levels) gives
    // it back and changes only the spread-out zone itself; a second step takes up what the
    // levels' slopes near the ends and the rounding of kinks leave (measured: Σh² within 1e-5 of
    // the target, 6e-5 for tables finer than the FIR resolves).
    let target = band_variance(r, dt, top);
    let level = |f: f64| r.psd_at(f) * sinc(PI * f * dt).powi(2);
    let ends = level(f_first) + if cut_top { level(f_last) } else { 0.0 };
    let max_shift = 2.0 * fs / taps as f64;
    let mut delta = 0.0;
    let mut h = fir_with(delta);
    for _ in 0..2 {
        let lost = target - h.iter().map(|v| v * v).sum::<f64>();
        delta = (delta + lost / ends).clamp(-max_shift, max_shift);
        h = fir_with(delta);
    }
    Design {
        h,
        truncated_at_hz: (f_last > nyquist).then_some(nyquist),
    }
}

/// The windowed FIR for the table with its ends placed at lo and hi (None: up to Nyquist),
/// holding the end values beyond the table. The target is area-sampled (each grid cell
/// weighted by the part of it inside [lo, hi]) so the ends' positions act continuously.
fn fir(r: &Random, dt: f64, taps: usize, fft: &Fft, lo: f64, hi: Option<f64>) -> Vec<f64> {
    let g = fft.len();
    let fs = 1.0 / dt;
    let cell = fs / g as f64;
    let (f_first, f_last) = (r.psd[0].0, r.psd[r.psd.len() - 1].0);
    let (mut re, mut im) = (vec![0.0; g], vec![0.0; g]);
    // The part of a cell inside the band, counting its mirror images about 0 and fs, which
    // reach the cells at 0 Hz and at Nyquist. Up to Nyquist the band on the circle of period
    // fs is the single interval [lo, fs − lo], its own image about fs.
    let overlap = |f: f64, a: f64, b: f64| {
        ((f + 0.5 * cell).min(b) - (f - 0.5 * cell).max(a)).max(0.0) / cell
    };
    let band = |f: f64| match hi {
        Some(hi) => overlap(f, lo, hi) + overlap(f, -hi, -lo) + overlap(f, fs - hi, fs - lo),
        None => overlap(f, lo, fs - lo) + overlap(f, lo - fs, -lo),
    };
    for k in 0..=g / 2 {
        let f = k as f64 * cell;
        let inside = band(f);
        if inside > 0.0 {
            let s = r.psd_at(f.clamp(f_first, f_last));
            let d = inside * (0.5 * s * fs).sqrt() * sinc(PI * f * dt);
            re[k] = d;
            if k > 0 && k < g / 2 {
                re[g - k] = d;
            }
        }
    }
    // Real and even: the transform's direction does not matter.
    fft.forward(&mut re, &mut im);
    let mid = (taps - 1) / 2;
    let w = TAU / (taps - 1) as f64;
    (0..taps)
        .map(|n| {
            let blackman = 0.42 - 0.5 * (w * n as f64).cos() + 0.08 * (2.0 * w * n as f64).cos();
            re[(n + g - mid) % g] / g as f64 * blackman
        })
        .collect()
}

/// ∫ S(f)·sinc²(πfΔt) df from the table's start to `top` (Hz): the variance of the interval
/// means of the vibration as specified. Simpson on each segment, where S is a power law:
/// 256 intervals leave < 1e-9 relative error.
pub(super) fn band_variance(r: &Random, dt: f64, top: f64) -> f64 {
    let f = |x: f64| r.psd_at(x) * sinc(PI * x * dt).powi(2);
    r.psd
        .windows(2)
        .map(|w| {
            let (a, b) = (w[0].0, w[1].0.min(top));
            if b <= a {
                return 0.0;
            }
            let n = 256;
            let h = (b - a) / n as f64;
            let inner: f64 = (1..n)
                .map(|i| f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 })
                .sum();
            (f(a) + f(b) + inner) * h / 3.0
        })
        .sum()
}
