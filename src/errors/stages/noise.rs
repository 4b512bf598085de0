//! White-noise stage: σ = N/√Δt per record and axis, optionally correlated across the axes.
//! Δt is the block's own step, so an externally triggered record of interval T carries an
//! increment noise of variance N²·T.

use super::{AXES, Block, Stage, any, stream};
use crate::errors::model::{Sensor, StageKind, TriadModel};
use crate::math::{Mat3, Vec3};
use crate::rng::NormalStream;
use nalgebra::Cholesky;

/// The white noise of one triad.
#[derive(Clone, Debug)]
pub(crate) struct Noise {
    sensor: Sensor,
    sigma: [f64; 3],
    /// The step `sigma` is for, and the densities N to form σ for another step.
    dt: f64,
    density: [f64; 3],
    rng: [NormalStream; 3],
    /// Lower Cholesky factor of the noise correlation across axes, when not the identity.
    chol: Option<Mat3>,
}

impl Noise {
    /// The triad's white noise on its streams from `seed`; `None` when the density is zero.
    pub(crate) fn build(m: &TriadModel, sensor: Sensor, dt: f64, seed: u64) -> Option<Noise> {
        any(&m.noise).then(|| Noise {
            sensor,
            sigma: std::array::from_fn(|i| m.noise[i] / dt.sqrt()),
            dt,
            density: m.noise,
            rng: std::array::from_fn(|i| stream(seed, sensor, AXES[i], "noise")),
            // The template loader refuses matrices that are not positive definite
            // (errors::template); from code, one that is not yields NaN factors.
            chol: m
                .noise_correlation
                .map(|c| Cholesky::new_unchecked(Mat3::from_fn(|i, j| c[i][j])).l()),
        })
    }
}

impl Stage for Noise {
    fn kind(&self) -> StageKind {
        StageKind::Noise
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        let other: [f64; 3];
        let sigma = if b.dt == self.dt {
            &self.sigma
        } else {
            other = self.density.map(|n| n / b.dt.sqrt());
            &other
        };
        let (s, rng) = (self.sensor, &mut self.rng);
        if let Some(l) = &self.chol {
            // Correlated across axes: n = diag(σ)·L·z with z the three axes' own draws.
            for r in b.records.iter_mut() {
                let z = Vec3::new(rng[0].draw(), rng[1].draw(), rng[2].draw());
                let lz = l * z;
                let v = s.rate(r);
                for i in 0..3 {
                    v[i] += sigma[i] * lz[i];
                }
            }
            return;
        }
        for (i, (sg, g)) in sigma.iter().zip(rng.iter_mut()).enumerate() {
            for r in b.records.iter_mut() {
                s.rate(r)[i] += sg * g.draw();
            }
        }
    }
}
