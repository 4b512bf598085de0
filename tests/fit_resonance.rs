//! `fit` on broad resonances (issue 24): a band-pass bump of the PSD is a random vibration
//! whose table is the PSD's excess over the fitted floor, its Allan variance a known term of
//! the fit, and the closure's simulated record carries it. The Allan variance of a random
//! vibration against the generator; a unit with the ADIS164xx output stage and a bump on gyro
//! z and accel x, fitted and closed; the same unit without a bump gets no vibration term.

use std::f64::consts::PI;
use std::path::Path;

use imu_emu::errors::template::{self, ImuModel};
use imu_emu::errors::vibration::{Random, Sensor, VibrationSpec};
use imu_emu::fit::closure;
use imu_emu::fit::recording_fit::{Settings, fit};
use imu_emu::fit::resonance::{KnownVibration, gain2};

const DT: f64 = 0.01;

/// How far a checked row's band keeps from a table's ends and kinks (Hz): the generator
/// spreads an end over ±3·fs/N and rounds a kink over a few design bins, fs/N = 400/4095 Hz
/// for the gyro z bump (N ≥ 64·fs/width) and 400/8191 Hz for the accel x bump.
const MARGIN: f64 = 0.3;

/// A unit with the ADIS164xx output stage (4× internal rate, a Bartlett window: CIC order 2,
/// 4 taps), its LSBs (0.05 deg/s, 3.33 mg) and white noise only, as in `tests/fit_closure.rs`.
fn adis_like() -> ImuModel {
    let text = "name = \"adis-like\"\nrate_hz = 100\nquantization_mode = \"round\"\n\
         [gyro]\nnoise = \"2.5 deg/sqrt(h)\"\nquantization = \"0.05 deg/s\"\n\
         [accel]\nnoise = \"0.25 m/s/sqrt(h)\"\nquantization = \"3.33 mg\"\n\
         [output_filter]\ninternal_rate_hz = 400\nkind = \"cic\"\norder = 2\ntaps = 4\n";
    template::parse(text, Path::new("adis-like.toml")).unwrap()
}

/// The bumps of the fitted unit: on gyro z a peak at 20 Hz 10× the white floor
/// (2N² = 2·(2.5 deg/√h)² = 3.8e-9 (rad/s)²/Hz), falling to the floor at 15 and 25 Hz; on
/// accel x a peak at 10 Hz 2× its floor (2·(0.25 m/s/√h)² = 3.5e-5 (m/s²)²/Hz), falling to
/// half of it at 8 and 12 Hz. Log-log interpolated (a constant slope per side).
fn bumps() -> Vec<Random> {
    let g = 2.0 * (2.5 * PI / 180.0 / 60.0f64).powi(2);
    let a = 2.0 * (0.25 / 60.0f64).powi(2);
    vec![
        Random {
            sensor: Sensor::Gyro,
            axis: 2,
            psd: vec![(15.0, g), (20.0, 10.0 * g), (25.0, g)],
        },
        Random {
            sensor: Sensor::Accel,
            axis: 0,
            psd: vec![(8.0, 0.5 * a), (10.0, 2.0 * a), (12.0, 0.5 * a)],
        },
    ]
}

fn settings() -> Settings {
    Settings {
        name: "fitted".into(),
        source: "synthetic".into(),
        template_path: "fitted.toml".into(),
        closure: true,
        seed: 1234,
        segment: 1 << 12,
        plot: None,
    }
}

/// The Allan variance of a random vibration ([`KnownVibration`]) against (1) a brute-force
/// midpoint sum of the same integral, σ²(m) = ½∫Q(f) df with Q = P(f)·4 sin⁴(πfτ)/(m sin πfΔt)²
/// the PSD of the Allan difference d_k = ȳ_{k+m} − ȳ_k and P = S·sinc²(πfΔt) what the
/// generator makes of the table S (10⁻⁷), and (2) the generator: 2^20 samples of the gyro z
/// bump alone at 100 Hz, the octave Allan variance at every octave to n/8 within 4σ.
///
/// σ: the octave estimator ([`imu_emu::analysis::octave_adev`]) is the mean of M values
/// d_k²/2 at k a multiple of the stride s = max(1, m/16), so for Gaussian d
/// Var σ̂²/σ⁴ = (2/M)·Σ_{|j|<M}(1 − |j|/M)·ρ(js)², ρ(l) = R(l)/R(0) the autocorrelation of d,
/// R(l) = ∫Q(f) cos(2πf·lΔt) df (one-sided Q), summed over |js| ≤ 2m + 200 (d_k spans 2m
/// samples; the bump's envelope decays within 1/(10 Hz) = 10 samples, so beyond it ρ < 10⁻⁶).
/// The generator matches S·sinc² to 10⁻³ (`errors/vibration` module doc), below the smallest
/// 4σ here (1.5 % at m = 1).
#[test]
fn vibration_allan_variance_matches_the_generator() {
    let table = bumps()[0].psd.clone();
    let n = 1u64 << 20;
    let r = Random {
        sensor: Sensor::Gyro,
        axis: 2,
        psd: table.clone(),
    };
    let p = |f: f64| r.psd_at(f) * gain2(f, DT, None);
    let ms: Vec<usize> = (0..17).map(|j| 1usize << j).collect();
    let known = KnownVibration::new(table.clone(), DT, None, &ms);
    let none = template::parse("name = \"v\"\nrate_hz = 100\n", Path::new("v.toml")).unwrap();
    let spec = VibrationSpec {
        sines: Vec::new(),
        randoms: vec![r.clone()],
    };
    let rec = closure::simulate_with(none, spec, DT, n, 5, 1 << 12).unwrap();
    let (a, b) = (table[0].0, table[table.len() - 1].0);
    assert!(b < 0.5 / DT);
    let mut checked = 0;
    for pt in rec.channels[2]
        .adev
        .iter()
        .filter(|pt| pt.m as u64 <= n / 8)
    {
        let m = pt.m;
        let tau = m as f64 * DT;
        let lags = 2 * m + 200;
        // Midpoint grid: 64 points per period of the fastest oscillation, cos(2πf·lagsΔt).
        let steps = ((b - a) * lags as f64 * DT * 64.0).max(1e5) as usize;
        let h = (b - a) / steps as f64;
        let grid: Vec<(f64, f64)> = (0..steps)
            .map(|i| {
                let f = a + (i as f64 + 0.5) * h;
                let num = (PI * f * tau).sin().powi(2);
                let den = m as f64 * (PI * f * DT).sin();
                (f, p(f) * 4.0 * num * num / (den * den) * h)
            })
            .collect();
        let r0: f64 = grid.iter().map(|g| g.1).sum();
        let want = 0.5 * r0;
        let got = known.avar(m);
        assert!(
            (got / want - 1.0).abs() < 1e-7,
            "m {m}: {got:e} vs brute force {want:e}"
        );
        let stride = (m / 16).max(1);
        let terms = pt.terms as f64;
        let mut sum = 1.0;
        for j in 1..=lags / stride {
            let l = (j * stride) as f64;
            let rho = grid
                .iter()
                .map(|g| g.1 * (2.0 * PI * g.0 * l * DT).cos())
                .sum::<f64>()
                / r0;
            sum += 2.0 * (1.0 - j as f64 / terms) * rho * rho;
        }
        let sd = (2.0 / terms * sum).sqrt();
        let z = (pt.adev * pt.adev / want).ln() / sd;
        assert!(
            z.abs() < 4.0,
            "m {m}: z = {z}, σ̂² {:e}, σ² {want:e}, sd {sd}",
            pt.adev.powi(2)
        );
        checked += 1;
    }
    assert_eq!(checked, 18);
}

/// The ADIS-like unit with the bumps of [`bumps`] on gyro z and accel x, 2^19 samples at
/// 100 Hz, fitted end to end: a resonance on those two channels and on no other, the written
/// table (its recorded-sample PSD, S·sinc²(πf/400 Hz)·|H|²) matching the truth's, and the
/// closure inside at every octave and PSD band of every channel.
///
/// Table tolerance: at a band of the search the excess E = P̂ − c·M has the scatter of P̂,
/// √(2/ν)·P̂, plus the floor's, c·M·√(2/Σν) from the bands that set the level; |E − E_true| ≤ 4
/// of those. Checked at the rows whose band lies more than 1 Hz from the truth's ends (the
/// generator spreads an end over ±3·fs/N, fs/N ≤ width/64, so the rows at the ends see part of
/// the jump) and from its peak (a kink the generator rounds over a few design bins). The total
/// variance ∫E df within 4σ of the truth's, σ² = Σ(√(2/ν_b)·P̂_b·w_b)² over the bands.
#[test]
fn a_band_pass_resonance_is_found_and_closes() {
    let n = 1u64 << 19;
    let spec = VibrationSpec {
        sines: Vec::new(),
        randoms: bumps(),
    };
    let rec = closure::simulate_with(adis_like(), spec, DT, n, 21, 1 << 12).unwrap();
    let f = fit(&rec, &settings()).unwrap();
    let found: Vec<usize> = f.resonances.iter().map(Vec::len).collect();
    assert_eq!(found, vec![0, 0, 1, 1, 0, 0], "{}", f.report);
    let filter = imu_emu::errors::output_filter::FilterSpec {
        internal_rate_hz: 400.0,
        kind: imu_emu::errors::output_filter::FilterKind::Cic { order: 2, taps: 4 },
        accel: None,
    };
    for (ch, truth) in [(2usize, &bumps()[0]), (3, &bumps()[1])] {
        let r = &f.resonances[ch][0];
        let psd = &rec.channels[ch].psd;
        let df = psd.freq[1] - psd.freq[0];
        let edf =
            imu_emu::analysis::psd_band::WelchEdf::new(2 * (psd.freq.len() - 1), psd.segments);
        let recorded = |f: f64| truth.psd_at(f) * gain2(f, DT, Some(&filter));
        let (lo, hi) = (truth.psd[0].0, truth.psd[2].0);
        let peak = truth.psd[1].0;
        // The level is set by the top decade's bands outside the bump: fewer bins than the
        // whole decade, so its ν is at most that of the decade less the bump's width.
        let decade = ((0.45 / DT - (hi - lo)) / df) as usize;
        let nu_level = edf.edf(decade);
        let mut var_sd2 = 0.0;
        let mut checked = 0;
        for w in r.rows.windows(3) {
            let (prev, row, next) = (w[0], w[1], w[2]);
            // The band around this row: halfway to its neighbours.
            let (a, b) = (0.5 * (prev.0 + row.0), 0.5 * (row.0 + next.0));
            let bins = ((b - a) / df).round().max(1.0) as usize;
            let nu = edf.edf(bins);
            let floor = floor_psd(ch, row.0, &filter);
            let total = recorded(row.0) + floor;
            let sd = (2.0 / nu).sqrt() * total + floor * (2.0 / nu_level).sqrt();
            var_sd2 += (sd * (b - a)).powi(2);
            if a - lo > MARGIN && hi - b > MARGIN && (b < peak - MARGIN || a > peak + MARGIN) {
                let want = recorded(row.0);
                assert!(
                    (row.1 - want).abs() < 4.0 * sd,
                    "channel {ch} at {} Hz: {:e} vs {want:e} ± {:e}\n{:?}",
                    row.0,
                    row.1,
                    4.0 * sd,
                    r.rows
                );
                checked += 1;
            }
        }
        assert!(checked >= 4, "channel {ch}: {checked} rows checked");
        let steps = 100_000;
        let h = (hi - lo) / steps as f64;
        let want: f64 = (0..steps)
            .map(|i| recorded(lo + (i as f64 + 0.5) * h) * h)
            .sum();
        let got = r.variance();
        assert!(
            (got - want).abs() < 4.0 * var_sd2.sqrt(),
            "channel {ch}: variance {got:e} vs {want:e} ± {:e}",
            4.0 * var_sd2.sqrt()
        );
    }
    assert_eq!(f.failures, 0, "{}", f.report);
}

/// The floor under the bumps of the ADIS-like unit: filtered white noise and the rounding.
fn floor_psd(ch: usize, f: f64, filter: &imu_emu::errors::output_filter::FilterSpec) -> f64 {
    let white = imu_emu::errors::filter_allan::WhiteAllan::new(
        filter,
        imu_emu::timing::ReadRatio::integer(4),
    );
    let (n, q) = if ch < 3 {
        (2.5 * PI / 180.0 / 60.0, 0.05 * PI / 180.0)
    } else {
        (0.25 / 60.0, 3.33e-3 * imu_emu::units::G0)
    };
    2.0 * n * n * white.long_tau() * white.psd_ratio(f, DT) + 2.0 * q * q * DT / 12.0
}

/// The same unit without a bump: no channel gets a vibration term (at most one false bump in
/// 1000 records per channel, `resonance::FALSE_ALARM`), and the closure is inside everywhere.
#[test]
fn a_record_without_a_bump_gets_no_vibration() {
    let rec = closure::simulate(adis_like(), DT, 1 << 19, 21, 1 << 12).unwrap();
    let f = fit(&rec, &settings()).unwrap();
    assert!(f.resonances.iter().all(Vec::is_empty), "{}", f.report);
    assert!(!f.sines.contains("vibration.random"), "{}", f.sines);
    assert_eq!(f.failures, 0, "{}", f.report);
}
