//! Skew-redundant units: N single-axis gyros and N′ single-axis accelerometers, each with its
//! own sense axis, position and error terms. Pure math, no I/O.
//!
//! Sensor i reads m_i = (1 + s_i) uᵢ·x + b_i + n_i, with x the unit's error-free angular rate
//! (gyros) or the specific force at the sensor's own position (accelerometers, see
//! `geometry.rs`), s_i a scale-factor error, b_i a constant bias and n_i white noise whose
//! interval mean has σ = N_i/√Δt for a noise density N_i (angle or velocity random walk,
//! IEEE Std 952-1997 Annex C: the rate noise density equals the random-walk coefficient).

use crate::math::Vec3;
use crate::rng::NormalStream;

/// Which kind of single-axis sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorKind {
    /// A gyro (rad/s).
    Gyro,
    /// An accelerometer (m/s²).
    Accel,
}

impl SensorKind {
    /// `gyro` or `accel`.
    pub fn name(self) -> &'static str {
        match self {
            SensorKind::Gyro => "gyro",
            SensorKind::Accel => "accel",
        }
    }
}

/// One single-axis sensor of a skew-redundant unit.
#[derive(Clone, Debug, PartialEq)]
pub struct SkewSensor {
    /// Sense axis in the unit's axes (unit length).
    pub axis: Vec3,
    /// Position in the unit's axes from the unit's reference point (m); only an
    /// accelerometer's matters (the angular rate is the same everywhere on a rigid body).
    pub position_m: Vec3,
    /// Constant bias (rad/s or m/s²).
    pub bias: f64,
    /// Scale-factor error (ratio).
    pub scale_factor: f64,
    /// White-noise density (rad/√s or m/s/√s).
    pub noise_density: f64,
}

impl SkewSensor {
    /// An error-free sensor along `axis` (normalised here) at the unit's reference point.
    pub fn along(axis: [f64; 3]) -> SkewSensor {
        let a = Vec3::from(axis);
        SkewSensor {
            axis: a * (1.0 / a.norm()),
            position_m: Vec3::zeros(),
            bias: 0.0,
            scale_factor: 0.0,
            noise_density: 0.0,
        }
    }
}

/// The sensors of a skew-redundant unit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkewLayout {
    /// Single-axis gyros.
    pub gyros: Vec<SkewSensor>,
    /// Single-axis accelerometers.
    pub accels: Vec<SkewSensor>,
}

impl SkewLayout {
    /// Number of channels: gyros, then accelerometers.
    pub fn channels(&self) -> usize {
        self.gyros.len() + self.accels.len()
    }

    /// Channel names: `gyro_0` … then `accel_0` ….
    pub fn channel_names(&self) -> Vec<String> {
        (0..self.gyros.len())
            .map(|i| format!("gyro_{i}"))
            .chain((0..self.accels.len()).map(|i| format!("accel_{i}")))
            .collect()
    }

    /// Whether an accelerometer sits away from the unit's reference point.
    pub fn has_offsets(&self) -> bool {
        self.accels.iter().any(|s| s.position_m != Vec3::zeros())
    }
}

/// The six sense axes of a dodecahedral skew-redundant unit: the normals of six faces of a
/// regular dodecahedron, one from each pair of opposite faces. They point at the vertices
/// (0, ±1, φ), (±1, φ, 0), (φ, 0, ±1) of a regular icosahedron (φ the golden ratio), every
/// two at the same angle, arccos(1/√5) ≈ 63.43° (Sturza, "Navigation system integrity
/// monitoring using redundant measurements", Navigation 35(4), 1988).
pub fn dodecahedron_axes() -> [[f64; 3]; 6] {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let n = (1.0 + phi * phi).sqrt();
    [
        [0.0, 1.0, phi],
        [0.0, -1.0, phi],
        [1.0, phi, 0.0],
        [-1.0, phi, 0.0],
        [phi, 0.0, 1.0],
        [phi, 0.0, -1.0],
    ]
    .map(|v| v.map(|x| x / n))
}

/// The error terms of one channel and its noise stream.
#[derive(Clone, Debug)]
pub(crate) struct ChannelErrors {
    gain: f64,
    bias: f64,
    /// σ of the white noise's interval mean at the unit's rate, and its density.
    sigma: f64,
    density: f64,
    noise: NormalStream,
}

impl ChannelErrors {
    /// The errors of every channel of `layout` (gyros, then accelerometers) at `rate_hz`,
    /// each noise on its own stream `gyro/I/noise` or `accel/I/noise` of `seed`.
    pub(crate) fn of(layout: &SkewLayout, rate_hz: f64, seed: u64) -> Vec<ChannelErrors> {
        let each = |kind: SensorKind, sensors: &[SkewSensor]| {
            sensors
                .iter()
                .enumerate()
                .map(|(i, s)| ChannelErrors {
                    gain: 1.0 + s.scale_factor,
                    bias: s.bias,
                    sigma: s.noise_density * rate_hz.sqrt(),
                    density: s.noise_density,
                    noise: NormalStream::new(seed, &format!("{}/{i}/noise", kind.name())),
                })
                .collect::<Vec<_>>()
        };
        let mut out = each(SensorKind::Gyro, &layout.gyros);
        out.extend(each(SensorKind::Accel, &layout.accels));
        out
    }

    /// The reading of an error-free value `x`.
    #[inline]
    pub(crate) fn read(&mut self, x: f64) -> f64 {
        let n = if self.sigma > 0.0 {
            self.sigma * self.noise.draw()
        } else {
            0.0
        };
        self.gain * x + self.bias + n
    }

    /// The reading of `x`, the error-free mean over an interval of `dt` s (an externally
    /// triggered sample): the white noise's mean over it has σ = N/√`dt`.
    #[inline]
    pub(crate) fn read_over(&mut self, x: f64, dt: f64) -> f64 {
        let n = if self.density > 0.0 {
            self.density / dt.sqrt() * self.noise.draw()
        } else {
            0.0
        };
        self.gain * x + self.bias + n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dodecahedral axes are unit vectors, pairwise at arccos(1/√5) (|cos| = 1/√5 to
    /// round-off), and span 3-D space (HᵀH = (6/3)·I for this equiangular set: the frame
    /// condition Σ uᵢuᵢᵀ = (N/3) I that makes the layout isotropic).
    #[test]
    fn dodecahedron_axes_are_equiangular_and_isotropic() {
        let a = dodecahedron_axes();
        for (i, u) in a.iter().enumerate() {
            let u = Vec3::from(*u);
            assert!((u.norm() - 1.0).abs() < 4.0 * f64::EPSILON);
            for v in &a[i + 1..] {
                let c = u.dot(&Vec3::from(*v)).abs();
                assert!((c - 1.0 / 5f64.sqrt()).abs() < 4.0 * f64::EPSILON, "{c}");
            }
        }
        for r in 0..3 {
            for c in 0..3 {
                let s: f64 = a.iter().map(|u| u[r] * u[c]).sum();
                let expect = if r == c { 2.0 } else { 0.0 };
                assert!(
                    (s - expect).abs() < 8.0 * f64::EPSILON,
                    "HᵀH[{r}][{c}] = {s}"
                );
            }
        }
    }

    /// The reading is (1 + s)·x + b exactly when there is no noise.
    #[test]
    fn reading_applies_scale_factor_and_bias() {
        let mut s = SkewSensor::along([0.0, 0.0, 2.0]);
        assert_eq!(s.axis, Vec3::new(0.0, 0.0, 1.0));
        s.bias = 0.25;
        s.scale_factor = 1e-3;
        let layout = SkewLayout {
            gyros: vec![s],
            accels: Vec::new(),
        };
        let mut e = ChannelErrors::of(&layout, 100.0, 1);
        assert_eq!(e[0].read(2.0), 1.001 * 2.0 + 0.25);
    }
}
