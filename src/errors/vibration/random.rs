//! Random vibration: unit white noise from the axis's own stream, filtered without end by the
//! designed FIR as overlap-save FFT blocks (module doc of `errors/vibration`).

use super::design::{Design, design};
use super::fft::Fft;
use super::{Random, RandomSummary, slot};
use crate::rng::NormalStream;
use std::fmt;

/// Axis names in stream names.
const AXES: [&str; 3] = ["x", "y", "z"];

/// One random vibration: overlap-save FFT convolution of its white-noise stream with h.
#[derive(Clone)]
pub(super) struct RandomChannel {
    pub(super) slot: usize,
    /// N − 1: samples of history a block needs.
    keep: usize,
    /// B = L − N + 1: outputs per block.
    pub(super) block: usize,
    fft: Fft,
    /// Spectrum of h zero-padded to L, divided by L (the inverse transform's scale).
    h_re: Vec<f64>,
    h_im: Vec<f64>,
    /// N − 1 samples of history, then the 2B draws of the current block pair.
    seq: Vec<f64>,
    /// After a refill: block 1's outputs at re[keep..], block 2's at im[keep..].
    re: Vec<f64>,
    im: Vec<f64>,
    pos: usize,
    rng: NormalStream,
    pub(super) summary: RandomSummary,
}

impl fmt::Debug for RandomChannel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("RandomChannel")
            .field("summary", &self.summary)
            .field("pos", &self.pos)
            .finish_non_exhaustive()
    }
}

impl RandomChannel {
    fn stream_name(r: &Random) -> String {
        format!("vibration/{}/{}/random", r.sensor.name(), AXES[r.axis])
    }

    pub(super) fn new(r: &Random, dt: f64, seed: u64) -> RandomChannel {
        let Design { h, truncated_at_hz } = design(r, dt);
        let taps = h.len();
        let l = 2 * (taps + 1);
        let (keep, block) = (taps - 1, l - taps + 1);
        let fft = Fft::new(l);
        let (mut h_re, mut h_im) = (vec![0.0; l], vec![0.0; l]);
        let scale = 1.0 / l as f64;
        for (d, &v) in h_re.iter_mut().zip(&h) {
            *d = v * scale;
        }
        fft.forward(&mut h_re, &mut h_im);
        let mut rng = NormalStream::new(seed, &Self::stream_name(r));
        let mut seq = vec![0.0; keep + 2 * block];
        // The history before record 1, so the output is stationary from the start.
        for v in &mut seq[..keep] {
            *v = rng.draw();
        }
        let summary = RandomSummary {
            sensor: r.sensor,
            axis: r.axis,
            taps,
            resolution_hz: 1.0 / (dt * taps as f64),
            rms: h.iter().map(|v| v * v).sum::<f64>().sqrt(),
            rms_spec: r.variance_up_to(f64::INFINITY).sqrt(),
            truncated_at_hz,
        };
        RandomChannel {
            slot: slot(r.sensor, r.axis),
            keep,
            block,
            fft,
            h_re,
            h_im,
            seq,
            re: vec![0.0; l],
            im: vec![0.0; l],
            pos: 2 * block,
            rng,
            summary,
        }
    }

    /// Draws the next 2B samples and filters them: two blocks in one complex FFT pair (the
    /// filter is real, so the real and imaginary parts do not mix).
    #[cold]
    fn refill(&mut self) {
        let (keep, b, l) = (self.keep, self.block, self.re.len());
        for v in &mut self.seq[keep..] {
            *v = self.rng.draw();
        }
        self.re.copy_from_slice(&self.seq[..l]);
        self.im.copy_from_slice(&self.seq[b..b + l]);
        self.fft.forward(&mut self.re, &mut self.im);
        for (((r, i), hr), hi) in self
            .re
            .iter_mut()
            .zip(self.im.iter_mut())
            .zip(&self.h_re)
            .zip(&self.h_im)
        {
            let (a, c) = (*r, *i);
            *r = a * hr - c * hi;
            *i = a * hi + c * hr;
        }
        // Inverse transform as the forward one with real and imaginary parts swapped.
        self.fft.forward(&mut self.im, &mut self.re);
        self.seq.copy_within(2 * b.., 0);
        self.pos = 0;
    }

    #[inline]
    pub(super) fn sample(&mut self) -> f64 {
        if self.pos == 2 * self.block {
            self.refill();
        }
        let p = self.pos;
        self.pos += 1;
        if p < self.block {
            self.re[self.keep + p]
        } else {
            self.im[self.keep + p - self.block]
        }
    }
}
