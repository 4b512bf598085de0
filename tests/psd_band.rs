//! The PSD confidence band of `analyze` (`imu_emu::analysis::psd_band`) against white noise,
//! whose density is known in closed form: P = 2σ²/f_s (one-sided).

use imu_emu::analysis::octave_adev::CONFIDENCE;
use imu_emu::analysis::psd::Welch;
use imu_emu::analysis::psd_band::banded;
use imu_emu::rng::NormalStream;

/// Runs `records` white-noise records of `n` samples (σ = 1, f_s = 1) through Welch segments
/// of `len` and counts, per chosen band (picked by a frequency it contains), how often the
/// band's interval holds the true density 2. Returns (bins per band, hits per band).
fn coverage(records: u64, n: usize, len: usize, at: &[f64]) -> (Vec<usize>, Vec<u64>) {
    let mut hits = vec![0u64; at.len()];
    let mut bins = vec![0usize; at.len()];
    for r in 0..records {
        let mut noise = NormalStream::new(20_261_202 + r, "psd band");
        let mut w = Welch::new(len);
        (0..n).for_each(|_| w.push(noise.draw()));
        let b = banded(&w.finish(1.0), 25.0, CONFIDENCE);
        for (j, &f) in at.iter().enumerate() {
            // The band whose mean frequency is nearest `f`.
            let i = (0..b.freq.len())
                .min_by(|&x, &y| (b.freq[x] - f).abs().total_cmp(&(b.freq[y] - f).abs()))
                .unwrap();
            bins[j] = b.bins[i];
            hits[j] += u64::from(b.lo[i] <= 2.0 && 2.0 <= b.hi[i]);
        }
    }
    (bins, hits)
}

/// Each chosen band's interval holds the true density in a fraction c = 68.27 % of
/// independent records. The count is binomial: over R = 2000 records its fraction scatters
/// by √(c(1 − c)/R) = 0.0104, so the tolerance is 4σ = 0.042. The bands are chosen far apart
/// in frequency (≥ 30 bins), away from DC (the segment mean removal lowers bins 1–2) and
/// from Nyquist, and hold 1, a few and about ten bins. Breaking the edf shows: counting the
/// M bins of a band as 2KM independent degrees of freedom (ignoring the Hann window's 4/9
/// correlation of neighbouring bins) narrows the ten-bin band's interval by √1.9 and its
/// coverage falls to about 0.53; a Gaussian interval instead of the χ² one misses the
/// skewed one-segment case below.
#[test]
fn welch_band_covers_white_noise_at_its_confidence() {
    let records = 2000;
    let tol = 4.0 * (CONFIDENCE * (1.0 - CONFIDENCE) / records as f64).sqrt();
    // 4096 samples in segments of 256: 31 segments; bins k/256 Hz.
    let (bins, hits) = coverage(records, 4096, 256, &[10.0 / 256.0, 40.0 / 256.0, 0.45]);
    assert_eq!(bins[0], 1, "{bins:?}");
    assert!(bins[1] >= 3 && bins[2] >= 8, "{bins:?}");
    // One segment (ν = 2 per bin: a χ² of two degrees of freedom, strongly skewed).
    let (bins1, hits1) = coverage(records, 256, 256, &[10.0 / 256.0, 0.45]);
    assert_eq!(bins1[0], 1, "{bins1:?}");
    for (m, h) in bins.iter().chain(&bins1).zip(hits.iter().chain(&hits1)) {
        let frac = *h as f64 / records as f64;
        println!("{m} bins: {frac:.4} inside (expected {CONFIDENCE:.4} ± {tol:.4})");
        assert!(
            (frac - CONFIDENCE).abs() < tol,
            "{m}-bin band: {frac} inside its {CONFIDENCE} interval"
        );
    }
}
