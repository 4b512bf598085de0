//! White-noise stage: σ = N/√Δt per record and axis, optionally correlated across the axes.

use super::{AXES, Block, Stage, any, stream};
use crate::errors::model::{Sensor, StageKind, TriadModel};
use crate::rng::NormalStream;

/// The white noise of one triad.
#[derive(Clone, Debug)]
pub(crate) struct Noise {
    sensor: Sensor,
    sigma: [f64; 3],
    rng: [NormalStream; 3],
    /// Lower Cholesky factor of the noise correlation across axes, when not the identity.
    chol: Option<[[f64; 3]; 3]>,
}

impl Noise {
    /// The triad's white noise on its streams from `seed`; `None` when the density is zero.
    pub(crate) fn build(m: &TriadModel, sensor: Sensor, dt: f64, seed: u64) -> Option<Noise> {
        any(&m.noise).then(|| Noise {
            sensor,
            sigma: std::array::from_fn(|i| m.noise[i] / dt.sqrt()),
            rng: std::array::from_fn(|i| stream(seed, sensor, AXES[i], "noise")),
            chol: m.noise_correlation.map(cholesky3),
        })
    }
}

impl Stage for Noise {
    fn kind(&self) -> StageKind {
        StageKind::Noise
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        let (s, sigma, rng) = (self.sensor, &self.sigma, &mut self.rng);
        if let Some(l) = &self.chol {
            // Correlated across axes: n = diag(σ)·L·z with z the three axes' own draws.
            for r in b.records.iter_mut() {
                let z = [rng[0].draw(), rng[1].draw(), rng[2].draw()];
                let v = s.rate(r);
                for i in 0..3 {
                    v[i] += sigma[i] * (l[i][0] * z[0] + l[i][1] * z[1] + l[i][2] * z[2]);
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

/// Lower Cholesky factor of a symmetric positive-definite 3×3 matrix (validated on load).
fn cholesky3(c: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut l = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            l[i][j] = if i == j {
                (c[i][i] - s).max(0.0).sqrt()
            } else {
                (c[i][j] - s) / l[j][j]
            };
        }
    }
    l
}
