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
use crate::analysis::analyzer::{Analysis, Analyzer};
use crate::analysis::confidence::{NoiseType, edf};
use crate::analysis::octave_adev::AdevPoint;
use crate::errors::template::ImuModel;
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

/// A static record of `samples` samples at interval `dt` simulated from `model` with `seed`,
/// analysed with Welch segments of `segment` samples.
pub fn simulate(
    model: ImuModel,
    dt: f64,
    samples: u64,
    seed: u64,
    segment: usize,
) -> Result<Analysis, SimError> {
    let sim = Simulation::builder()
        .scene("static")
        .imu_model(model)
        .rate(1.0 / dt)
        .duration(samples as f64 * dt)
        .seed(seed)
        .build()?;
    let mut an = Analyzer::new(segment);
    for block in sim.records()? {
        block?.iter().for_each(|r| an.push_record(r));
    }
    Ok(an.finish(dt))
}
