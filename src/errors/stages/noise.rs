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
    /// White angle (velocity) noise (`quantization_noise`), when set.
    angle: Option<Box<AngleNoise>>,
}

/// White angle noise of σ Q per axis: the rate error is its increment over the step,
/// (w_k − w_{k−1})/Δt, so adjacent m-sample means differ by (w_{2m} − 2w_m + w_0)/τ and the
/// Allan variance is 3Q²/τ² at every m (IEEE Std 952-1997, Annex C, quantization noise).
#[derive(Clone, Debug)]
struct AngleNoise {
    q: [f64; 3],
    rng: [NormalStream; 3],
    /// w_{k−1}: drawn at the start too, so the first record's error is like every other's.
    last: [f64; 3],
}

impl Noise {
    /// The triad's white noise on its streams from `seed`; `None` when the density is zero.
    pub(crate) fn build(m: &TriadModel, sensor: Sensor, dt: f64, seed: u64) -> Option<Noise> {
        let angle = any(&m.quantization_noise).then(|| {
            let mut rng: [NormalStream; 3] =
                std::array::from_fn(|i| stream(seed, sensor, AXES[i], "quantization_noise"));
            let q = m.quantization_noise;
            let last = std::array::from_fn(|i| q[i] * rng[i].draw());
            Box::new(AngleNoise { q, rng, last })
        });
        (any(&m.noise) || angle.is_some()).then(|| Noise {
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
            angle,
        })
    }
}

impl Stage for Noise {
    fn kind(&self) -> StageKind {
        StageKind::Noise
    }
    fn apply(&mut self, b: &mut Block<'_>) {
        if let Some(a) = self.angle.as_deref_mut() {
            let (sensor, step) = (self.sensor, b.dt);
            for i in 0..3 {
                for r in b.records.iter_mut() {
                    let w = a.q[i] * a.rng[i].draw();
                    sensor.rate(r)[i] += (w - a.last[i]) / step;
                    a.last[i] = w;
                }
            }
        }
        if self.density.iter().all(|n| *n == 0.0) {
            return;
        }
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

#[cfg(test)]
mod tests {
    use crate::errors::chain::ErrorChain;
    use crate::errors::template::parse;
    use crate::record::Record;

    /// `quantization_noise` Q is white angle noise: the rate error (w_k − w_{k−1})/Δt has
    /// variance 2Q²/Δt² and lag-one correlation −½ (so the Allan variance is 3Q²/τ² at every
    /// m), on each axis (applied in two blocks). 3·2^16 samples pooled over the axes: for
    /// this MA(1) sequence the variance estimate's relative sd is √((1 + 2ρ₁²)·2/n) = √(3/n)
    /// = 0.39 % and the correlation's √((1 − 3ρ₁² + 4ρ₁⁴)/n) = √(0.5/n) = 0.0016 (Bartlett);
    /// both are checked to 4σ.
    #[test]
    fn quantization_noise_is_white_angle_noise() {
        let model = parse(
            "name = \"q\"\n[gyro]\nquantization_noise = \"2 urad\"\n",
            std::path::Path::new("q.toml"),
        )
        .unwrap();
        let (n, dt) = (1usize << 16, 0.01);
        let mut rec: Vec<Record> = (0..n)
            .map(|k| Record {
                t: (k + 1) as f64 * dt,
                ..Record::default()
            })
            .collect();
        let mut chain = ErrorChain::new(&model, 1.0 / dt, 3);
        let (first, second) = rec.split_at_mut(n / 2);
        chain.apply(first);
        chain.apply(second);
        let q = 2e-6;
        let want = 2.0 * q * q / (dt * dt);
        let (mut var, mut lag) = (0.0, 0.0);
        for axis in 0..3 {
            let x: Vec<f64> = rec.iter().map(|r| r.gyro[axis]).collect();
            var += x.iter().map(|v| v * v).sum::<f64>();
            lag += x.windows(2).map(|w| w[0] * w[1]).sum::<f64>();
        }
        let total = (3 * n) as f64;
        let rho = lag / var;
        var /= total;
        assert!(
            (var / want - 1.0).abs() < 4.0 * (3.0 / total).sqrt(),
            "variance {var:e} vs {want:e}"
        );
        assert!(
            (rho + 0.5).abs() < 4.0 * (0.5 / total).sqrt(),
            "lag-one correlation {rho}"
        );
        assert!(rec.iter().all(|r| r.accel == crate::math::Vec3::zeros()));
    }
}
