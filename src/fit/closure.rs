//! Closing the loop: simulate a static record from the fitted template and check its Allan
//! deviation against the recording's, octave by octave from Δt to T/8.
//!
//! Band. At octave m both deviations are estimates: σ̂² ~ σ²·χ²_ν/ν, so ln σ̂ scatters by
//! 1/√(2ν) (ν the edf of the noise type the fitted model says dominates there, NIST SP 1065
//! Table 5). The simulated record adds its own scatter of the same size, and the fitted curve
//! it is drawn from is itself read from the recording with at most that scatter at the
//! octave (the fit pools several octaves). The band for the simulated deviation is therefore
//! σ̂_rec·exp(±4·√(3/(2ν))): four standard deviations of the difference of logs. Octaves past
//! T/8 (fewer than eight independent spans) are not checked.

use super::gmwm::Model;
use super::lines::Line;
use super::resonance::Resonance;
use crate::analysis::analyzer::{Analysis, Analyzer};
use crate::analysis::confidence::{NoiseType, edf};
use crate::analysis::octave_adev::AdevPoint;
use crate::analysis::psd::Psd;
use crate::analysis::psd_band::banded;
use crate::errors::model::Sensor;
use crate::errors::output_filter::FilterSpec;
use crate::errors::template::ImuModel;
use crate::errors::vibration::{Random, Sine, VibrationSpec};
use crate::sim::{SimError, Simulation};

/// Standard deviations of the difference of log deviations the band allows.
pub const BAND_SIGMAS: f64 = 4.0;

/// One octave of the closure check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosurePoint {
    /// τ (s).
    pub tau: f64,
    /// The recording's Allan deviation.
    pub recorded: f64,
    /// The simulated record's.
    pub simulated: f64,
    /// Band for the simulated deviation.
    pub lo: f64,
    /// Upper end of the band.
    pub hi: f64,
}

impl ClosurePoint {
    /// Whether the simulated deviation lies in the band.
    pub fn inside(&self) -> bool {
        self.simulated >= self.lo && self.simulated <= self.hi
    }
}

/// The octaves m ≤ n/8 present in both curves, with their bands.
pub fn compare(
    recorded: &[AdevPoint],
    simulated: &[AdevPoint],
    model: &Model,
    samples: usize,
) -> Vec<ClosurePoint> {
    recorded
        .iter()
        .filter(|p| p.m <= samples / 8 && p.adev > 0.0)
        .filter_map(|p| {
            let s = simulated.iter().find(|s| s.m == p.m)?;
            let noise = model
                .dominant(p.m)
                .map_or(NoiseType::WhiteRate, |k| k.noise_type());
            let nu = edf(noise, samples + 1, p.m);
            let half = BAND_SIGMAS * (3.0 / (2.0 * nu)).sqrt();
            Some(ClosurePoint {
                tau: p.tau,
                recorded: p.adev,
                simulated: s.adev,
                lo: p.adev * (-half).exp(),
                hi: p.adev * half.exp(),
            })
        })
        .collect()
}

/// Lowest frequency of the PSD check (Hz).
pub const PSD_FROM_HZ: f64 = 0.01;

/// Bands per decade of the PSD check.
pub const PSD_BANDS_PER_DECADE: f64 = 5.0;

/// One frequency band of the PSD closure check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PsdPoint {
    /// Mean frequency of the band (Hz).
    pub freq: f64,
    /// Welch bins averaged.
    pub bins: usize,
    /// The recording's mean density over the band.
    pub recorded: f64,
    /// The simulated record's.
    pub simulated: f64,
    /// Band for the simulated density.
    pub lo: f64,
    /// Upper end of the band.
    pub hi: f64,
}

impl PsdPoint {
    /// Whether the simulated density lies in the band.
    pub fn inside(&self) -> bool {
        self.simulated >= self.lo && self.simulated <= self.hi
    }
}

/// The PSD check from [`PSD_FROM_HZ`] to the Nyquist frequency (its own bin left out), over
/// bands of 1/[`PSD_BANDS_PER_DECADE`] decade. Both estimates are Welch averages of the same
/// segment length over records of the same length, so each band's mean density is P·χ²_ν/ν
/// with the same ν ([`crate::analysis::psd_band::WelchEdf`], exact for a spectrum flat
/// across the band, conservative otherwise): ln P̂ scatters by √(2/ν), the difference of the
/// two by √(4/ν), and the fitted model, read from the recording, adds at most the
/// recording's own √(2/ν). The band is P̂_rec·exp(±4·√(6/ν)).
pub fn compare_psd(recorded: &Psd, simulated: &Psd) -> Vec<PsdPoint> {
    if recorded.freq != simulated.freq {
        return Vec::new();
    }
    let (r, s) = (
        banded(recorded, PSD_BANDS_PER_DECADE, 0.5),
        banded(simulated, PSD_BANDS_PER_DECADE, 0.5),
    );
    let end = recorded.freq.len().saturating_sub(1);
    let edf = crate::analysis::psd_band::WelchEdf::new(2 * end, recorded.segments);
    r.freq
        .iter()
        .zip(&r.density)
        .zip(&r.bins)
        .zip(&s.density)
        .filter(|(((f, _), _), _)| **f >= PSD_FROM_HZ)
        .map(|(((&freq, &rec), &bins), &sim)| {
            let half = BAND_SIGMAS * (6.0 / edf.edf(bins)).sqrt();
            PsdPoint {
                freq,
                bins,
                recorded: rec,
                simulated: sim,
                lo: rec * (-half).exp(),
                hi: rec * half.exp(),
            }
        })
        .collect()
}

/// The amplitude A of a vibration sine whose recorded samples have amplitude B at frequency
/// f: the generator puts out each sine's interval mean (gain sinc(πfΔt)) at the rate it runs
/// at — the filter's internal rate, then through the filter (gain |H(f)|) — so A = B/gain.
pub fn source_amplitude(b: f64, f: f64, dt: f64, filter: Option<&FilterSpec>) -> f64 {
    let sinc = |x: f64| if x == 0.0 { 1.0 } else { x.sin() / x };
    let gain = match filter {
        None => sinc(std::f64::consts::PI * f * dt),
        Some(s) => sinc(std::f64::consts::PI * f / s.internal_rate_hz) * s.magnitude(f),
    };
    b / gain
}

/// The spectral lines of the six channels (gyro x y z, accel x y z) as the vibration sines
/// that reproduce them (phase 0) through `filter` (each sensor's own).
pub fn vibration(lines: &[Vec<Line>], dt: f64, filter: Option<&FilterSpec>) -> VibrationSpec {
    let mut spec = VibrationSpec::default();
    for (ch, ls) in lines.iter().enumerate() {
        let filter = filter.map(|f| f.channel(ch));
        for l in ls {
            spec.sines.push(Sine {
                sensor: if ch < 3 { Sensor::Gyro } else { Sensor::Accel },
                axis: ch % 3,
                amplitude: source_amplitude(l.amplitude, l.freq, dt, filter.as_ref()),
                freq_hz: l.freq,
                phase_rad: 0.0,
            });
        }
    }
    spec
}

/// [`vibration`] with the broad resonances `res` of each channel as random vibrations
/// ([`super::resonance::source_table`]).
pub fn vibration_with(
    lines: &[Vec<Line>],
    res: &[Vec<Resonance>],
    dt: f64,
    filter: Option<&FilterSpec>,
) -> VibrationSpec {
    let mut spec = vibration(lines, dt, filter);
    for (ch, r) in res.iter().enumerate().filter(|(_, r)| !r.is_empty()) {
        spec.randoms.push(Random {
            sensor: if ch < 3 { Sensor::Gyro } else { Sensor::Accel },
            axis: ch % 3,
            psd: super::resonance::source_table(r, dt, filter.map(|f| f.channel(ch)).as_ref()),
        });
    }
    spec
}

/// A static record of `samples` samples at interval `dt` simulated from `model` with `seed`,
/// analysed with Welch segments of `segment` samples.
pub fn simulate(
    model: ImuModel,
    dt: f64,
    samples: u64,
    seed: u64,
    segment: usize,
) -> Result<Analysis, SimError> {
    simulate_with(model, VibrationSpec::default(), dt, samples, seed, segment)
}

/// [`simulate`] with the vibration `sines` on the static scene.
pub fn simulate_with(
    model: ImuModel,
    sines: VibrationSpec,
    dt: f64,
    samples: u64,
    seed: u64,
    segment: usize,
) -> Result<Analysis, SimError> {
    let mut b = Simulation::builder()
        .scene("static")
        .imu_model(model)
        .rate(1.0 / dt)
        .duration(samples as f64 * dt)
        .seed(seed);
    if !sines.is_empty() {
        b = b.vibration(sines);
    }
    let sim = b.build()?;
    let mut an = Analyzer::new(segment);
    for block in sim.records()? {
        block?.iter().for_each(|r| an.push_record(r));
    }
    Ok(an.finish(dt))
}

/// The six rate channels (gyro x y z, accel x y z) of a static record simulated as in
/// [`simulate_with`] (with `vibration`): a published table's τ are not octaves, so its closure needs the Allan
/// deviation at its own cluster sizes ([`adev_at`]).
pub fn simulate_series(
    model: ImuModel,
    vibration: VibrationSpec,
    dt: f64,
    samples: u64,
    seed: u64,
) -> Result<[Vec<f64>; 6], SimError> {
    let mut b = Simulation::builder()
        .scene("static")
        .imu_model(model)
        .rate(1.0 / dt)
        .duration(samples as f64 * dt)
        .seed(seed);
    if !vibration.is_empty() {
        b = b.vibration(vibration);
    }
    let sim = b.build()?;
    let mut out: [Vec<f64>; 6] = Default::default();
    for block in sim.records()? {
        for r in block?.iter() {
            for i in 0..3 {
                out[i].push(r.gyro[i]);
                out[3 + i].push(r.accel[i]);
            }
        }
    }
    Ok(out)
}

/// The overlapping Allan deviation of `series` (interval Δt) at the cluster sizes of `points`
/// (edf and interval left at the point's own: only m, τ and σ are compared).
pub fn adev_at(series: &[f64], dt: f64, points: &[AdevPoint]) -> Vec<AdevPoint> {
    let ms: Vec<usize> = points.iter().map(|p| p.m).collect();
    crate::analysis::allan::overlapping_at(series, dt, &ms)
        .into_iter()
        .map(|a| AdevPoint {
            m: a.m,
            tau: a.tau,
            adev: a.adev,
            terms: (series.len() + 1 - 2 * a.m) as u64,
            edf: 0.0,
            lo: a.adev,
            hi: a.adev,
        })
        .collect()
}
