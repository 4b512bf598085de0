//! Tests of the vibration generator: the FFT, the PSD table, sinusoids, the FIR design and the
//! statistics of random vibration.

use super::design::{band_variance, design};
use super::fft::Fft;
use super::sine::SineTerm;
use super::*;
use crate::rng::NormalStream;
use std::f64::consts::{PI, TAU};

const G0: f64 = 9.806_65;

fn random(sensor: Sensor, axis: usize, psd: &[(f64, f64)]) -> Random {
    Random {
        sensor,
        axis,
        psd: psd.to_vec(),
    }
}

fn spec_of(randoms: Vec<Random>) -> VibrationSpec {
    VibrationSpec {
        sines: Vec::new(),
        randoms,
    }
}

/// n records of the slot's component.
fn run(v: &mut Vibration, slot: usize, n: usize) -> Vec<f64> {
    (0..n)
        .map(|_| {
            let (g, a) = v.next();
            if slot < 3 { g[slot] } else { a[slot - 3] }
        })
        .collect()
}

/// Welch one-sided PSD estimate: Hann segments of m samples, 50 % overlap;
/// P_j = 2Δt/Σw² · mean |Σ w x e^{−2πijn/m}|² at f_j = j/(mΔt).
fn welch(x: &[f64], dt: f64, m: usize) -> Vec<f64> {
    let fft = Fft::new(m);
    let w: Vec<f64> = (0..m)
        .map(|n| 0.5 - 0.5 * (TAU * n as f64 / m as f64).cos())
        .collect();
    let w2: f64 = w.iter().map(|v| v * v).sum();
    let mut acc = vec![0.0; m / 2 + 1];
    let mut segments = 0;
    let mut start = 0;
    while start + m <= x.len() {
        let mut re: Vec<f64> = (0..m).map(|n| x[start + n] * w[n]).collect();
        let mut im = vec![0.0; m];
        fft.forward(&mut re, &mut im);
        for (j, a) in acc.iter_mut().enumerate() {
            *a += re[j] * re[j] + im[j] * im[j];
        }
        segments += 1;
        start += m / 2;
    }
    acc.iter()
        .map(|a| 2.0 * dt / w2 * a / segments as f64)
        .collect()
}

/// Two-sided Σ_l ρ(l)² of the process with FIR h: the variance factor of sample
/// correlations (sd of a sample correlation over n samples ≈ √(Σρ²/n)).
fn sum_rho2(h: &[f64]) -> f64 {
    let var: f64 = h.iter().map(|v| v * v).sum();
    let n = h.len();
    let mut s = 1.0;
    for lag in 1..n {
        let c: f64 = (0..n - lag).map(|i| h[i] * h[i + lag]).sum::<f64>() / var;
        s += 2.0 * c * c;
    }
    s
}

/// Normalised sample correlation of x[i] and y[i + lag] (zero-mean processes).
fn corr(x: &[f64], y: &[f64], lag: usize) -> f64 {
    let n = x.len().min(y.len() - lag);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        sxy += x[i] * y[i + lag];
        sxx += x[i] * x[i];
        syy += y[i + lag] * y[i + lag];
    }
    sxy / (sxx * syy).sqrt()
}

#[test]
fn fft_matches_the_direct_dft() {
    for n in [2usize, 8, 64, 512] {
        let mut s = NormalStream::new(1, "vibration/test/fft");
        let x: Vec<(f64, f64)> = (0..n).map(|_| (s.draw(), s.draw())).collect();
        let (mut re, mut im): (Vec<f64>, Vec<f64>) = x.iter().copied().unzip();
        Fft::new(n).forward(&mut re, &mut im);
        for k in 0..n {
            let (mut dr, mut di) = (0.0, 0.0);
            for (j, &(a, b)) in x.iter().enumerate() {
                let (sn, cs) = (-TAU * ((j * k) % n) as f64 / n as f64).sin_cos();
                dr += a * cs - b * sn;
                di += a * sn + b * cs;
            }
            assert!((re[k] - dr).abs() < 1e-12 * n as f64, "n {n} k {k}");
            assert!((im[k] - di).abs() < 1e-12 * n as f64, "n {n} k {k}");
        }
        // Inverse by swapping parts, then 1/n.
        Fft::new(n).forward(&mut im, &mut re);
        for (k, &(a, b)) in x.iter().enumerate() {
            assert!((re[k] / n as f64 - a).abs() < 1e-13 && (im[k] / n as f64 - b).abs() < 1e-13);
        }
    }
}

#[test]
fn psd_table_interpolates_log_log() {
    // +3 dB/oct (PSD ∝ f) from 20 to 80 Hz, then flat to 400 Hz.
    let r = random(
        Sensor::Accel,
        2,
        &[(20.0, 1e-3), (80.0, 4e-3), (400.0, 4e-3)],
    );
    assert!((r.psd_at(40.0) / 2e-3 - 1.0).abs() < 1e-14);
    assert_eq!(r.psd_at(20.0), 1e-3);
    assert_eq!(r.psd_at(400.0), 4e-3);
    assert_eq!(r.psd_at(200.0), 4e-3);
    assert_eq!(r.psd_at(19.999), 0.0);
    assert_eq!(r.psd_at(400.001), 0.0);
    // ∫ 1e-3 f/20 df over [20, 80] = 0.15, then 4e-3 × 320 = 1.28.
    assert!((r.variance_up_to(f64::INFINITY) - 1.43).abs() < 1e-13);
    assert!((r.variance_up_to(200.0) - 0.63).abs() < 1e-13);
    assert_eq!(r.variance_up_to(10.0), 0.0);
    // The numerical band variance (with sinc² → 1 for a tiny step) agrees.
    assert!((band_variance(&r, 1e-9, f64::INFINITY) / 1.43 - 1.0).abs() < 1e-9);
    // S ∝ 1/f uses the logarithmic form: ∫ = S_a f_a ln(f_b/f_a).
    let s = random(Sensor::Gyro, 0, &[(10.0, 1e-2), (100.0, 1e-3)]);
    assert!((s.variance_up_to(f64::INFINITY) - 0.1 * 10f64.ln()).abs() < 1e-15);
}

/// The closed form is the interval mean of A sin(ωt + φ) (checked against Simpson), and
/// each record equals A/(ωΔt)·[cos(ωt_{k−1} + φ) − cos(ωt_k + φ)]; other axes stay 0.
/// Tolerance 1e-12·A: the reference's arguments ωt ≤ 315 rad carry an ulp of 6e-14, which
/// the difference of cosines amplifies by 1/(ωΔt) = 6.4.
#[test]
fn sine_interval_mean_is_exact() {
    let (a, f, phi, dt) = (0.3, 25.0, 0.7, 1e-3);
    let spec = VibrationSpec {
        sines: vec![Sine {
            sensor: Sensor::Gyro,
            axis: 1,
            amplitude: a,
            freq_hz: f,
            phase_rad: phi,
        }],
        randoms: Vec::new(),
    };
    let mut v = Vibration::new(&spec, dt, 1).unwrap();
    let w = TAU * f;
    for k in 1..=2000u64 {
        let (g, acc) = v.next();
        assert_eq!((g[0], g[2], acc), (0.0, 0.0, Vec3::zeros()));
        let (t0, t1) = ((k - 1) as f64 * dt, k as f64 * dt);
        let closed = a / (w * dt) * ((w * t0 + phi).cos() - (w * t1 + phi).cos());
        assert!((g[1] - closed).abs() < 1e-12 * a, "k {k}");
        if k % 97 == 0 {
            let n = 200;
            let h = dt / n as f64;
            let y = |i: usize| a * (w * (t0 + i as f64 * h) + phi).sin();
            let inner: f64 = (1..n)
                .map(|i| y(i) * if i % 2 == 1 { 4.0 } else { 2.0 })
                .sum();
            let simpson = (y(0) + y(n) + inner) * h / 3.0 / dt;
            assert!((g[1] - simpson).abs() < 1e-12 * a, "k {k}");
        }
    }
}

/// 25 Hz at 1 kHz: 40 records per period. Over 50 whole periods the mean is 0 and the RMS
/// is A·sinc(π/40)/√2 exactly (Σ sin² over whole periods is n/2), up to rounding.
#[test]
fn sine_whole_periods_mean_zero_rms_amplitude_over_sqrt2() {
    let (a, dt) = (0.5 * G0, 1e-3);
    let spec = VibrationSpec {
        sines: vec![Sine {
            sensor: Sensor::Accel,
            axis: 0,
            amplitude: a,
            freq_hz: 25.0,
            phase_rad: -1.1,
        }],
        randoms: Vec::new(),
    };
    let mut v = Vibration::new(&spec, dt, 1).unwrap();
    let x = run(&mut v, 3, 2000);
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    let expect = a * sinc(PI * 0.025) / 2f64.sqrt();
    assert!(mean.abs() < 1e-13 * a, "mean {mean:e}");
    assert!(
        (rms / expect - 1.0).abs() < 1e-13,
        "rms {rms} expected {expect}"
    );
    // The interval mean's attenuation is visible: 0.1 % below A/√2.
    assert!((rms / (a / 2f64.sqrt()) - 1.0 + 1.028e-3).abs() < 1e-5);
}

/// Record 8.64e7 (24 h at 1 kHz) of a 25 Hz sinusoid against the integer-exact phase
/// 2π((2k − 1) mod 80)/80. The f64 inputs f·Δt differ from 1/40 by 5e-19, which after 2.16e6
/// cycles is 3e-10 rad; a plain f64 product k·f·Δt would add up to ulp(2.16e6)/2 cycles
/// = 1.5e-9 rad. 1e-9 of the amplitude therefore shows that no phase is lost.
#[test]
fn sine_phase_does_not_drift_over_24_h() {
    let s = Sine {
        sensor: Sensor::Gyro,
        axis: 0,
        amplitude: 1.0,
        freq_hz: 25.0,
        phase_rad: 0.3,
    };
    let term = SineTerm::new(&s, 1e-3);
    for k in [1u64, 12_345, 86_400_000 - 7, 86_400_000] {
        let cycles = ((2 * k - 1) % 80) as f64 / 80.0;
        let exact = sinc(PI * 0.025) * (TAU * cycles + 0.3).sin();
        assert!(
            (term.at(k) - exact).abs() < 1e-9,
            "k {k}: {:e}",
            term.at(k) - exact
        );
    }
}

/// Deterministic check of the designed filter: the PSD it imposes, 2Δt|H(f)|² (from the
/// zero-padded FFT of h), equals the table × sinc² within 1e-3 more than 4 design bins
/// from the table's ends and 8 from its breakpoints and Nyquist, within 1e-2 nearer to
/// those (the rounding of a kink: the slope of √S changes there, and at Nyquist the
/// periodic response is reflected), and leaks < 1e-5 of the end level more than 4 bins
/// outside; a table cut at Nyquist has no end to spread. Σh² equals ∫S·sinc² within 1e-5.
#[test]
fn filter_response_matches_the_table() {
    let dt = 1e-3;
    for table in [
        vec![(50.0, 1e-3), (250.0, 1e-3)],
        vec![(20.0, 1e-3), (80.0, 4e-3), (400.0, 4e-3)],
        vec![(100.0, 1e-3), (200.0, 1e-4), (800.0, 1e-4)],
    ] {
        let r = random(Sensor::Accel, 2, &table);
        let h = design(&r, dt).h;
        let res = 1.0 / (dt * h.len() as f64);
        let m = 16 * (h.len() + 1);
        let (mut re, mut im) = (vec![0.0; m], vec![0.0; m]);
        re[..h.len()].copy_from_slice(&h);
        Fft::new(m).forward(&mut re, &mut im);
        let (lo, hi) = (table[0].0, table[table.len() - 1].0);
        let kinks = &table[1..table.len() - 1];
        let (mut worst_in, mut worst_kink, mut worst_out) = (0.0f64, 0.0f64, 0.0f64);
        for j in 0..=m / 2 {
            let f = j as f64 / (m as f64 * dt);
            let p = 2.0 * dt * (re[j] * re[j] + im[j] * im[j]);
            if f > lo + 4.0 * res && (f < hi - 4.0 * res || hi > 0.5 / dt) {
                let err = (p / (r.psd_at(f) * sinc(PI * f * dt).powi(2)) - 1.0).abs();
                let near = |k: f64| (f - k).abs() < 8.0 * res;
                if kinks.iter().any(|k| near(k.0)) || near(0.5 / dt) {
                    worst_kink = worst_kink.max(err);
                } else {
                    worst_in = worst_in.max(err);
                }
            } else if f < lo - 4.0 * res || f > hi + 4.0 * res {
                worst_out = worst_out.max(p / r.psd_at(f.clamp(lo, hi)));
            }
        }
        let var: f64 = h.iter().map(|v| v * v).sum();
        let target = band_variance(&r, dt, 0.5 / dt);
        eprintln!(
            "{table:?}: N {} res {res:.3} Hz, max rel err: in band {worst_in:.1e}, near \
             breakpoints and Nyquist {worst_kink:.1e}; outside {worst_out:.1e} of the level; \
             Σh²/target − 1 = {:.1e}",
            h.len(),
            var / target - 1.0
        );
        assert!(worst_in < 1e-3, "in band {worst_in:e}");
        assert!(worst_kink < 1e-2, "at breakpoints {worst_kink:e}");
        assert!(worst_out < 1e-5, "out of band {worst_out:e}");
        assert!(
            (var / target - 1.0).abs() < 1e-5,
            "variance {var} vs {target}"
        );
    }
}

/// The overlap-save blocks are the linear convolution of the stream with h, across block
/// boundaries and refills, to rounding.
#[test]
fn blocks_equal_the_direct_convolution() {
    let r = random(Sensor::Accel, 2, &[(100.0, 1e-2), (400.0, 1e-2)]);
    let dt = 1e-3;
    let mut v = Vibration::new(&spec_of(vec![r.clone()]), dt, 9).unwrap();
    let h = design(&r, dt).h;
    let n_out = 5 * v.randoms[0].block + 17;
    let y = run(&mut v, 5, n_out);
    let mut s = NormalStream::new(9, "vibration/accel/z/random");
    let z: Vec<f64> = (0..h.len() - 1 + n_out).map(|_| s.draw()).collect();
    let rms = v.randoms[0].summary.rms;
    for (j, &yj) in y.iter().enumerate() {
        let direct: f64 = h
            .iter()
            .enumerate()
            .map(|(i, hi)| hi * z[h.len() - 1 + j - i])
            .sum();
        assert!((yj - direct).abs() < 1e-12 * rms, "sample {j}");
    }
}

/// Flat S = 0.01 g²/Hz over [50, 250] Hz at 1 kHz, 2¹⁹ records (524 s).
/// Variance: the estimate's relative sd is √(2Σρ²/n), Σρ² = fs/(2W) = 2.5 → 0.31 %
/// (calibrated: over 40 seeds the normalised errors had mean −0.04 and sd 1.06); checked
/// at 4 sd against Σh², which itself equals S·∫sinc² within 1e-5 (previous test), i.e.
/// against S·(f₂ − f₁) times the band's mean sinc² (0.919 here: the interval mean).
/// PSD: Welch with 1024-sample Hann segments, 50 % overlap (1023 segments): relative sd
/// per bin ≈ √(1.06/1023) = 3.2 %; bins are averaged in groups of 10 (adjacent Hann bins
/// correlate, ≈ 6 independent) → ≈ 1.4 %; each group must be within 6 % (> 4 sd).
/// Outside the table, more than 10 Hz from its ends, the estimate must be < 1e-4 of S
/// (Hann leakage at 10 bins and the FIR's sidelobes are both far below).
#[test]
fn flat_band_variance_and_psd() {
    let (s, f1, f2, dt) = (0.01 * G0 * G0, 50.0, 250.0, 1e-3);
    let r = random(Sensor::Accel, 2, &[(f1, s), (f2, s)]);
    let mut v = Vibration::new(&spec_of(vec![r.clone()]), dt, 3).unwrap();
    let n = 1 << 19;
    let x = run(&mut v, 5, n);
    let sum = v.random_summaries().next().copied().unwrap();
    assert_eq!(sum.truncated_at_hz, None);
    assert!((sum.rms_spec - (s * (f2 - f1)).sqrt()).abs() < 1e-12 * sum.rms_spec);
    let var = x.iter().map(|v| v * v).sum::<f64>() / n as f64;
    let mean = x.iter().sum::<f64>() / n as f64;
    let sd = (2.0 * 2.5 / n as f64).sqrt();
    let mean_sinc2 = band_variance(&r, dt, f64::INFINITY) / (s * (f2 - f1));
    eprintln!(
        "flat: var/Σh² − 1 = {:.2e} (sd {sd:.1e}), var/(S(f2−f1)·{mean_sinc2:.4}) − 1 = \
         {:.2e}, mean {mean:.1e} (rms {:.3})",
        var / (sum.rms * sum.rms) - 1.0,
        var / (s * (f2 - f1) * mean_sinc2) - 1.0,
        sum.rms
    );
    assert!((var / (sum.rms * sum.rms) - 1.0).abs() < 4.0 * sd);
    assert!((var / (s * (f2 - f1) * mean_sinc2) - 1.0).abs() < 4.0 * sd + 1e-5);
    // No power at 0 Hz: over T = 524 s the mean is of order rms/(2πf₁T) ≈ 6e-6 rms.
    assert!(mean.abs() < 1e-4 * sum.rms);

    let m = 1024;
    let p = welch(&x, dt, m);
    let df = 1.0 / (m as f64 * dt);
    let inside: Vec<usize> = (0..p.len())
        .filter(|&j| j as f64 * df > f1 + 8.0 && (j as f64 * df) < f2 - 8.0)
        .collect();
    let (mut worst, mut ss, mut groups) = (0.0f64, 0.0, 0);
    for g in inside.chunks_exact(10) {
        let est = g.iter().map(|&j| p[j]).sum::<f64>() / 10.0;
        let tgt = g
            .iter()
            .map(|&j| s * sinc(PI * j as f64 * df * dt).powi(2))
            .sum::<f64>()
            / 10.0;
        worst = worst.max((est / tgt - 1.0).abs());
        ss += (est / tgt - 1.0).powi(2);
        groups += 1;
    }
    let outside = (0..p.len())
        .filter(|&j| {
            let f = j as f64 * df;
            f < f1 - 10.0 || f > f2 + 10.0
        })
        .map(|j| p[j] / s)
        .fold(0.0f64, f64::max);
    let rms_dev = (ss / groups as f64).sqrt();
    eprintln!(
        "flat Welch: {groups} groups, rms {rms_dev:.2e}, worst {worst:.2e}; outside max \
         {outside:.2e} of S"
    );
    assert!(worst < 0.06, "in band {worst}");
    assert!(outside < 1e-4, "out of band {outside:e}");
}

/// +3 dB/oct from 20 to 80 Hz then flat to 400 Hz, on a gyro axis at 1 kHz, 2¹⁹ records.
/// Groups of 10 Welch bins within 6 % (≈ 4 sd, see above) of S·sinc² on both parts; the
/// fitted log-log slope over 25–75 Hz is 1 (3.01 dB/oct) within 0.1: over a 1.6-octave
/// span with ~50 bins of 3.2 % scatter each, the slope's sd is ≈ 0.02.
#[test]
fn two_level_table_has_its_shape() {
    let dt = 1e-3;
    let r = random(
        Sensor::Gyro,
        0,
        &[(20.0, 1e-8), (80.0, 4e-8), (400.0, 4e-8)],
    );
    let mut v = Vibration::new(&spec_of(vec![r.clone()]), dt, 4).unwrap();
    let x = run(&mut v, 0, 1 << 19);
    let m = 1024;
    let p = welch(&x, dt, m);
    let df = 1.0 / (m as f64 * dt);
    let mut worst = 0.0f64;
    for (lo, hi) in [(24.0, 76.0), (84.0, 392.0)] {
        let bins: Vec<usize> = (0..p.len())
            .filter(|&j| j as f64 * df > lo && (j as f64 * df) < hi)
            .collect();
        for g in bins.chunks_exact(10) {
            let est = g.iter().map(|&j| p[j]).sum::<f64>() / 10.0;
            let tgt = g
                .iter()
                .map(|&j| {
                    let f = j as f64 * df;
                    r.psd_at(f) * sinc(PI * f * dt).powi(2)
                })
                .sum::<f64>()
                / 10.0;
            worst = worst.max((est / tgt - 1.0).abs());
        }
    }
    // Least-squares slope of ln P against ln f (sinc² removed) over 25–75 Hz.
    let pts: Vec<(f64, f64)> = (0..p.len())
        .map(|j| (j as f64 * df, j))
        .filter(|&(f, _)| (25.0..=75.0).contains(&f))
        .map(|(f, j)| (f.ln(), (p[j] / sinc(PI * f * dt).powi(2)).ln()))
        .collect();
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>()
        / pts.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    eprintln!("two-level Welch: worst group {worst:.2e}, slope {slope:.3} (1 = +3 dB/oct)");
    assert!(worst < 0.06, "shape {worst}");
    assert!((slope - 1.0).abs() < 0.1, "slope {slope}");
}

/// No repetition: the sample autocorrelation at lags of one and two FFT blocks, the FFT
/// size, and 10 and 100 FIR lengths is 0 within 5 sd (sd = √(Σρ²/n), ≈ 0.002 here — a
/// repeating buffer would give ≈ 1 at its period); windows of 2¹⁵ records 2¹⁸ records
/// apart are uncorrelated within 5 sd (≈ 0.009) at a few relative shifts.
#[test]
fn no_repetition() {
    let (s, dt) = (1e-3, 1e-3);
    let r = random(Sensor::Accel, 0, &[(50.0, s), (250.0, s)]);
    let mut v = Vibration::new(&spec_of(vec![r.clone()]), dt, 5).unwrap();
    let n = 1 << 19;
    let x = run(&mut v, 3, n);
    let ch = &v.randoms[0];
    let (taps, b) = (ch.summary.taps, ch.block);
    let rho2 = sum_rho2(&design(&r, dt).h);
    let mut worst = 0.0f64;
    for lag in [b, 2 * b, 2 * (taps + 1), 10 * taps, 100 * taps] {
        let c = corr(&x, &x, lag);
        let sd = (rho2 / (n - lag) as f64).sqrt();
        worst = worst.max(c.abs() / sd);
        assert!(c.abs() < 5.0 * sd, "lag {lag}: {c}");
    }
    let w = 1 << 15;
    let sd = (rho2 / w as f64).sqrt();
    let (a, later) = (&x[..w], &x[1 << 18..]);
    for shift in [0, 1, 7, b] {
        let c = corr(a, later, shift);
        worst = worst.max(c.abs() / sd);
        assert!(c.abs() < 5.0 * sd, "shift {shift}: {c}");
    }
    eprintln!("no repetition: N {taps}, B {b}, Σρ² {rho2:.2}, worst |r|/sd {worst:.2}");
}

/// Two vibrated axes with overlapping bands are uncorrelated (5 sd, sd from
/// Cauchy–Schwarz ≤ (Σρ₁²Σρ₂²)^{1/4}/√n); adding another term or reordering leaves an
/// axis bit-identical (own stream); a seed reproduces exactly.
#[test]
fn streams_are_independent_and_deterministic() {
    let dt = 1e-3;
    let az = random(Sensor::Accel, 2, &[(50.0, 1e-3), (250.0, 1e-3)]);
    let gy = random(Sensor::Gyro, 1, &[(30.0, 1e-6), (300.0, 1e-6)]);
    let sine = Sine {
        sensor: Sensor::Accel,
        axis: 1,
        amplitude: 1.0,
        freq_hz: 13.0,
        phase_rad: 0.0,
    };
    let both = VibrationSpec {
        sines: vec![sine.clone()],
        randoms: vec![gy.clone(), az.clone()],
    };
    let n = 1 << 18;
    let mut v = Vibration::new(&both, dt, 11).unwrap();
    let recs: Vec<(Vec3, Vec3)> = (0..n).map(|_| v.next()).collect();
    let x: Vec<f64> = recs.iter().map(|r| r.1[2]).collect();
    let y: Vec<f64> = recs.iter().map(|r| r.0[1]).collect();
    let sd = (sum_rho2(&design(&az, dt).h) * sum_rho2(&design(&gy, dt).h))
        .sqrt()
        .sqrt()
        / (n as f64).sqrt();
    for lag in [0, 1, 5, 100] {
        assert!(corr(&x, &y, lag).abs() < 5.0 * sd, "lag {lag}");
        assert!(corr(&y, &x, lag).abs() < 5.0 * sd, "lag −{lag}");
    }
    // Alone, first in the list, or with other terms: the same accel z values.
    let mut alone = Vibration::new(&spec_of(vec![az.clone()]), dt, 11).unwrap();
    assert_eq!(run(&mut alone, 5, 5000), x[..5000]);
    let reordered = VibrationSpec {
        sines: vec![sine],
        randoms: vec![az.clone(), gy],
    };
    let mut again = Vibration::new(&reordered, dt, 11).unwrap();
    let recs2: Vec<(Vec3, Vec3)> = (0..5000).map(|_| again.next()).collect();
    assert_eq!(recs2, recs[..5000]);
    let mut other = Vibration::new(&spec_of(vec![az]), dt, 12).unwrap();
    assert_ne!(run(&mut other, 5, 10), x[..10]);
}

#[test]
fn table_past_nyquist_is_cut() {
    let s = 1e-3;
    let r = random(Sensor::Accel, 0, &[(100.0, s), (800.0, s)]);
    let v = Vibration::new(&spec_of(vec![r.clone()]), 1e-3, 1).unwrap();
    let sum = *v.random_summaries().next().unwrap();
    assert_eq!(sum.truncated_at_hz, Some(500.0));
    assert!((sum.rms_spec - (s * 700.0).sqrt()).abs() < 1e-12);
    let target = band_variance(&r, 1e-3, 500.0).sqrt();
    assert!(
        (sum.rms / target - 1.0).abs() < 1e-5,
        "{} vs {target}",
        sum.rms
    );
}

/// Tables finer than the largest FIR resolves (fs/N = 0.06 Hz at 1 kHz): starting at
/// 0.01 Hz, a 1 Hz band, a band across Nyquist. The shape is smoothed over a few bins, but
/// the filter is finite and keeps the target variance (measured within 6e-5).
#[test]
fn extreme_tables_keep_their_variance() {
    let dt = 1e-3;
    for table in [
        vec![(0.01, 1e-3), (10.0, 1e-3)],
        vec![(100.0, 1e-3), (101.0, 1e-3)],
        vec![(499.0, 1e-3), (501.0, 1e-3)],
    ] {
        let r = random(Sensor::Accel, 0, &table);
        let h = design(&r, dt).h;
        assert_eq!(h.len(), MAX_TAPS);
        assert!(h.iter().all(|v| v.is_finite()));
        let var: f64 = h.iter().map(|v| v * v).sum();
        let target = band_variance(&r, dt, 0.5 / dt);
        assert!(
            (var / target - 1.0).abs() < 2e-4,
            "{table:?}: {var} vs {target}"
        );
    }
}

#[test]
fn bad_specs_name_the_entry() {
    let dt = 1e-3;
    let ok = random(Sensor::Accel, 0, &[(10.0, 1e-3), (100.0, 1e-3)]);
    let with = |r: Random| spec_of(vec![ok.clone(), r]);
    let err = |spec: VibrationSpec| Vibration::new(&spec, dt, 1).unwrap_err();
    let e = err(with(random(Sensor::Gyro, 3, &[(1.0, 1.0), (2.0, 1.0)])));
    assert_eq!(
        e,
        VibrationError::Axis {
            entry: Entry::Random(1),
            axis: 3
        }
    );
    let e = err(with(random(Sensor::Gyro, 0, &[(1.0, 1.0), (2.0, 0.0)])));
    assert!(matches!(
        e,
        VibrationError::Psd {
            entry: Entry::Row(1, 1),
            ..
        }
    ));
    assert!(e.to_string().contains("random[1].psd[1]"), "{e}");
    let e = err(with(random(Sensor::Gyro, 0, &[(1.0, -1.0), (2.0, 1.0)])));
    assert!(matches!(
        e,
        VibrationError::Psd {
            entry: Entry::Row(1, 0),
            ..
        }
    ));
    let e = err(with(random(Sensor::Gyro, 0, &[(5.0, 1.0), (5.0, 1.0)])));
    assert!(matches!(
        e,
        VibrationError::NotIncreasing {
            entry: Entry::Row(1, 1),
            ..
        }
    ));
    let e = err(with(random(Sensor::Gyro, 0, &[(0.0, 1.0), (5.0, 1.0)])));
    assert!(matches!(
        e,
        VibrationError::Frequency {
            entry: Entry::Row(1, 0),
            ..
        }
    ));
    let e = err(with(random(
        Sensor::Gyro,
        0,
        &[(1.0, f64::NAN), (5.0, 1.0)],
    )));
    assert!(matches!(
        e,
        VibrationError::NotFinite {
            entry: Entry::Row(1, 0),
            what: "PSD",
            ..
        }
    ));
    let e = err(with(random(Sensor::Gyro, 0, &[(500.0, 1.0), (900.0, 1.0)])));
    assert!(matches!(
        e,
        VibrationError::AboveNyquist {
            entry: Entry::Random(1),
            ..
        }
    ));
    assert!(e.to_string().contains("Nyquist frequency 500 Hz"), "{e}");
    let e = err(with(random(Sensor::Gyro, 0, &[(5.0, 1.0)])));
    assert_eq!(
        e,
        VibrationError::TooFewRows {
            entry: Entry::Random(1),
            rows: 1
        }
    );
    let e = err(with(random(Sensor::Accel, 0, &[(5.0, 1.0), (9.0, 1.0)])));
    assert!(matches!(
        e,
        VibrationError::Duplicate {
            entry: Entry::Random(1),
            first: 0,
            ..
        }
    ));
    let sine = |amplitude: f64, freq_hz: f64, axis: usize| VibrationSpec {
        sines: vec![Sine {
            sensor: Sensor::Gyro,
            axis,
            amplitude,
            freq_hz,
            phase_rad: 0.0,
        }],
        randoms: Vec::new(),
    };
    assert!(matches!(
        err(sine(1.0, 501.0, 0)),
        VibrationError::AboveNyquist {
            entry: Entry::Sine(0),
            ..
        }
    ));
    assert!(matches!(
        err(sine(1.0, 0.0, 0)),
        VibrationError::Frequency {
            entry: Entry::Sine(0),
            ..
        }
    ));
    assert!(matches!(
        err(sine(-1.0, 5.0, 0)),
        VibrationError::Amplitude { .. }
    ));
    assert!(matches!(
        err(sine(f64::INFINITY, 5.0, 0)),
        VibrationError::NotFinite {
            what: "amplitude",
            ..
        }
    ));
    assert!(matches!(
        err(sine(1.0, 5.0, 7)),
        VibrationError::Axis {
            entry: Entry::Sine(0),
            axis: 7
        }
    ));
    assert!(Vibration::new(&sine(1.0, 500.0, 0), dt, 1).is_ok());
    assert!(matches!(
        Vibration::new(&sine(1.0, 5.0, 0), 0.0, 1),
        Err(VibrationError::Step { .. })
    ));
    let empty = Vibration::new(&VibrationSpec::default(), dt, 1).unwrap();
    assert!(empty.is_empty() && VibrationSpec::default().is_empty());
}
