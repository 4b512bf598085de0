//! The error chain: stages applied to each record's interval-mean rates in the order the IMU
//! model says (default: the paper's — scale factor, bias, misalignment, noise, quantization),
//! then multiplied by Δt back into increments. A stage whose terms are all zero is not built.

use super::process::{Flicker, GaussMarkov, QuantMode, Quantizer, RandomWalk};
use super::temperature::TemperatureProfile;
use super::template::{ImuModel, TriadModel};
use crate::math::{Mat3, Vec3};
use crate::record::Record;
use crate::rng::NormalStream;
use crate::units::Lsb;

/// A stage of the chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StageKind {
    /// Scale factor (paper eq. 3–4).
    ScaleFactor,
    /// Bias (eq. 5–6).
    Bias,
    /// Misalignment (eq. 7–8).
    Misalignment,
    /// White noise.
    Noise,
    /// Saturation and quantization (eq. 9–10).
    Quantization,
}

impl StageKind {
    /// The paper's order.
    pub const PAPER_ORDER: [StageKind; 5] = [
        StageKind::ScaleFactor,
        StageKind::Bias,
        StageKind::Misalignment,
        StageKind::Noise,
        StageKind::Quantization,
    ];
    /// Parses a stage name.
    pub fn from_name(s: &str) -> Option<StageKind> {
        Some(match s {
            "scale_factor" => StageKind::ScaleFactor,
            "bias" => StageKind::Bias,
            "misalignment" => StageKind::Misalignment,
            "noise" => StageKind::Noise,
            "quantization" => StageKind::Quantization,
            _ => return None,
        })
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];
const PAIRS: [&str; 6] = ["xy", "xz", "yx", "yz", "zx", "zy"];

/// Record flag: a gyro axis was saturated.
pub const FLAG_GYRO_SATURATED: u8 = 1;
/// Record flag: an accelerometer axis was saturated.
pub const FLAG_ACCEL_SATURATED: u8 = 2;

/// Scale-factor error of one axis.
#[derive(Clone, Debug)]
struct AxisScale {
    fixed: f64,
    gm: Option<GaussMarkov>,
    rw: Option<RandomWalk>,
    asym_half: f64,
    quad: f64,
}

/// Bias of one axis.
#[derive(Clone, Debug)]
struct AxisBias {
    fixed: f64,
    gm: Option<GaussMarkov>,
    rw: Option<RandomWalk>,
    flicker: Option<Flicker>,
}

/// The stages of one triad.
#[derive(Clone, Debug)]
struct Triad {
    scale: Option<[AxisScale; 3]>,
    bias: Option<[AxisBias; 3]>,
    /// y = M x, with M = I + off-diagonal angles.
    misalign: Option<[[f64; 3]; 3]>,
    noise: Option<([f64; 3], [NormalStream; 3])>,
    quant: Option<(Lsb, [Quantizer; 3])>,
    range: Option<f64>,
    /// Temperature polynomials (bias, scale factor), set by `ErrorChain::with_temperature`.
    temp: Option<([f64; 3], [f64; 3])>,
    /// The increments of the last quantization on an increment LSB, while still exact.
    last_inc: Option<Vec3>,
}

/// The error chain of an IMU: gyro and accelerometer triads, and the gyro g-sensitivity.
#[derive(Clone, Debug)]
pub struct ErrorChain {
    order: Vec<StageKind>,
    /// The temperature profile and the model's reference temperature, when any temperature
    /// coefficient is non-zero.
    temperature: Option<(TemperatureProfile, f64)>,
    gyro: Triad,
    accel: Triad,
    g_sens: Option<[[f64; 3]; 3]>,
    /// C_b^c: body to IMU case, when the IMU is not mounted along the body axes.
    mounting: Option<Mat3>,
    dt: f64,
}

impl ErrorChain {
    /// Builds the chain of `model` for records at `rate_hz`, drawing every random constant
    /// and seeding every process from `seed` and the term's name.
    pub fn new(model: &ImuModel, rate_hz: f64, seed: u64) -> ErrorChain {
        let dt = 1.0 / rate_hz;
        let g = &model.gyro;
        let g_sens = g.g_sensitivity.iter().any(|v| *v != 0.0).then(|| {
            let s = &g.g_sensitivity;
            [[s[0], s[1], s[2]], [s[3], s[4], s[5]], [s[6], s[7], s[8]]]
        });
        ErrorChain {
            order: model.order.clone(),
            temperature: None,
            mounting: None,
            gyro: Triad::new(&model.gyro, "gyro", dt, seed, model.quantization_mode),
            accel: Triad::new(&model.accel, "accel", dt, seed, model.quantization_mode),
            g_sens,
            dt,
        }
    }

    /// Sets the IMU temperature over the run (default: the model's reference temperature, so
    /// the temperature terms vanish). Ignored when the model has no temperature coefficients.
    pub fn with_temperature(mut self, profile: TemperatureProfile, model: &ImuModel) -> ErrorChain {
        let any_coeff = [&model.gyro, &model.accel]
            .iter()
            .any(|t| any(&t.bias_temperature) || any(&t.scale_factor_temperature));
        if any_coeff {
            self.gyro.temp = Some((
                model.gyro.bias_temperature,
                model.gyro.scale_factor_temperature,
            ));
            self.accel.temp = Some((
                model.accel.bias_temperature,
                model.accel.scale_factor_temperature,
            ));
            self.temperature = Some((profile, model.temperature_ref));
        }
        self
    }

    /// Mounts the IMU case rotated from the body by `q_b_c` (C_b^c): the sensors see
    /// ω^c = C_b^c ω^b and f^c = C_b^c f^b before any error stage (lever arm not included).
    pub fn with_mounting(mut self, q_b_c: crate::math::Quat) -> ErrorChain {
        let m = q_b_c.to_mat();
        if m != Mat3::IDENTITY {
            self.mounting = Some(m);
        }
        self
    }

    /// True when no stage was built (an ideal IMU): records pass unchanged.
    pub fn is_empty(&self) -> bool {
        self.gyro.is_empty()
            && self.accel.is_empty()
            && self.g_sens.is_none()
            && self.temperature.is_none()
            && self.mounting.is_none()
    }

    /// Corrupts records in place, in record order.
    pub fn apply(&mut self, records: &mut [Record]) {
        if self.is_empty() {
            return;
        }
        for r in records.iter_mut() {
            if let Some(m) = &self.mounting {
                r.gyro = m.mul_vec(r.gyro);
                r.accel = m.mul_vec(r.accel);
            }
            let f_true = r.accel;
            let mut g = r.gyro;
            let mut a = r.accel;
            let mut flags = 0u8;
            let dtemp = self
                .temperature
                .as_ref()
                .map_or(0.0, |(p, t_ref)| p.at(r.t) - t_ref);
            for stage in &self.order {
                match stage {
                    StageKind::ScaleFactor => {
                        g = self.gyro.scale(g, dtemp);
                        a = self.accel.scale(a, dtemp);
                    }
                    StageKind::Bias => {
                        g = self.gyro.bias(g, dtemp);
                        if let Some(m) = &self.g_sens {
                            g += Vec3(m.map(|row| {
                                row[0] * f_true.0[0] + row[1] * f_true.0[1] + row[2] * f_true.0[2]
                            }));
                        }
                        a = self.accel.bias(a, dtemp);
                    }
                    StageKind::Misalignment => {
                        g = Triad::misalign(&self.gyro.misalign, g);
                        a = Triad::misalign(&self.accel.misalign, a);
                    }
                    StageKind::Noise => {
                        g = self.gyro.noise(g);
                        a = self.accel.noise(a);
                    }
                    StageKind::Quantization => {
                        let (gq, gs) = self.gyro.quantize(g, self.dt);
                        let (aq, as_) = self.accel.quantize(a, self.dt);
                        g = gq;
                        a = aq;
                        flags |= ((gs as u8) * FLAG_GYRO_SATURATED)
                            | ((as_ as u8) * FLAG_ACCEL_SATURATED);
                    }
                }
                // A stage after quantization moves the values off the LSB grid again.
                if *stage != StageKind::Quantization {
                    self.gyro.last_inc = None;
                    self.accel.last_inc = None;
                }
            }
            r.gyro = g;
            r.accel = a;
            // Quantized increments are kept exactly (whole LSBs), not recomputed as rate·Δt.
            r.dtheta = self.gyro.last_inc.take().unwrap_or(g * self.dt);
            r.dv = self.accel.last_inc.take().unwrap_or(a * self.dt);
            r.flags = flags;
        }
    }
}

impl Triad {
    fn new(m: &TriadModel, sensor: &str, dt: f64, seed: u64, mode: QuantMode) -> Triad {
        let stream =
            |axis: &str, term: &str| NormalStream::new(seed, &format!("{sensor}/{axis}/{term}"));
        // Random constants: one draw each from their own stream.
        let turn_on = |axis: usize, term: &str, sigma: f64| {
            if sigma == 0.0 {
                0.0
            } else {
                sigma * stream(AXES[axis], term).draw()
            }
        };
        let scale_needed = any(&m.scale_factor)
            || any(&m.scale_factor_turn_on)
            || m.scale_factor_gm.is_some()
            || any(&m.scale_factor_random_walk)
            || any(&m.scale_factor_asymmetry)
            || any(&m.scale_factor_quadratic);
        let scale = scale_needed.then(|| {
            std::array::from_fn(|i| AxisScale {
                fixed: m.scale_factor[i]
                    + turn_on(i, "scale_factor_turn_on", m.scale_factor_turn_on[i]),
                gm: m.scale_factor_gm.and_then(|(s, t)| {
                    (s[i] > 0.0).then(|| {
                        GaussMarkov::new(s[i], t[i], dt, stream(AXES[i], "scale_factor_gm"))
                    })
                }),
                rw: (m.scale_factor_random_walk[i] > 0.0).then(|| {
                    RandomWalk::new(
                        m.scale_factor_random_walk[i],
                        dt,
                        stream(AXES[i], "scale_factor_random_walk"),
                    )
                }),
                asym_half: 0.5 * m.scale_factor_asymmetry[i],
                quad: m.scale_factor_quadratic[i],
            })
        });
        let bias_needed = any(&m.bias)
            || any(&m.bias_turn_on)
            || any(&m.bias_instability)
            || m.bias_gm.is_some()
            || any(&m.random_walk);
        let bias = bias_needed.then(|| {
            std::array::from_fn(|i| AxisBias {
                fixed: m.bias[i] + turn_on(i, "bias_turn_on", m.bias_turn_on[i]),
                gm: m.bias_gm.and_then(|(s, t)| {
                    (s[i] > 0.0)
                        .then(|| GaussMarkov::new(s[i], t[i], dt, stream(AXES[i], "bias_gm")))
                }),
                rw: (m.random_walk[i] > 0.0)
                    .then(|| RandomWalk::new(m.random_walk[i], dt, stream(AXES[i], "random_walk"))),
                flicker: (m.bias_instability[i] > 0.0).then(|| {
                    Flicker::new(m.bias_instability[i], m.bias_instability_band, dt, |j| {
                        stream(AXES[i], &format!("bias_instability/{j}"))
                    })
                }),
            })
        });
        let mis_needed = any(&m.misalignment) || any(&m.misalignment_turn_on);
        let misalign = mis_needed.then(|| {
            let ang: [f64; 6] = std::array::from_fn(|j| {
                let s = m.misalignment_turn_on[j];
                m.misalignment[j]
                    + if s == 0.0 {
                        0.0
                    } else {
                        s * NormalStream::new(
                            seed,
                            &format!("{sensor}/{}/misalignment_turn_on", PAIRS[j]),
                        )
                        .draw()
                    }
            });
            // Paper eq. 7–8: [[1, −y_z, z_y], [x_z, 1, −z_x], [−x_y, y_x, 1]] with angles
            // ordered [xy, xz, yx, yz, zx, zy].
            let [xy, xz, yx, yz, zx, zy] = ang;
            [[1.0, -yz, zy], [xz, 1.0, -zx], [-xy, yx, 1.0]]
        });
        let noise = any(&m.noise).then(|| {
            (
                std::array::from_fn(|i| m.noise[i] / dt.sqrt()),
                std::array::from_fn(|i| stream(AXES[i], "noise")),
            )
        });
        let quant = m.quantization.map(|lsb| {
            let q = match lsb {
                Lsb::Increment(q) | Lsb::Rate(q) => q,
            };
            (lsb, std::array::from_fn(|_| Quantizer::new(q, mode)))
        });
        Triad {
            temp: None,
            last_inc: None,
            scale,
            bias,
            misalign,
            noise,
            quant,
            range: m.range,
        }
    }

    fn is_empty(&self) -> bool {
        self.temp.is_none()
            && self.scale.is_none()
            && self.bias.is_none()
            && self.misalign.is_none()
            && self.noise.is_none()
            && self.quant.is_none()
            && self.range.is_none()
    }

    // Plain loops rather than array::from_fn closures: the closures were not inlined here.
    #[inline]
    fn scale(&mut self, x: Vec3, dtemp: f64) -> Vec3 {
        let mut out = x;
        if let Some((_, c)) = self.temp {
            let k = dtemp * (c[0] + dtemp * (c[1] + dtemp * c[2]));
            out = out * (1.0 + k);
        }
        let Some(s) = self.scale.as_mut() else {
            return out;
        };
        for (a, v) in s.iter_mut().zip(out.0.iter_mut()) {
            let mut k = a.fixed + if *v >= 0.0 { a.asym_half } else { -a.asym_half };
            if let Some(gm) = a.gm.as_mut() {
                k += gm.step();
            }
            if let Some(rw) = a.rw.as_mut() {
                k += rw.step();
            }
            *v = *v * (1.0 + k) + a.quad * *v * *v;
        }
        out
    }

    #[inline]
    fn bias(&mut self, x: Vec3, dtemp: f64) -> Vec3 {
        let mut out = x;
        if let Some((c, _)) = self.temp {
            let b = dtemp * (c[0] + dtemp * (c[1] + dtemp * c[2]));
            out += Vec3::new(b, b, b);
        }
        let Some(b) = self.bias.as_mut() else {
            return out;
        };
        for (a, v) in b.iter_mut().zip(out.0.iter_mut()) {
            *v += a.fixed;
            if let Some(gm) = a.gm.as_mut() {
                *v += gm.step();
            }
            if let Some(rw) = a.rw.as_mut() {
                *v += rw.step();
            }
            if let Some(f) = a.flicker.as_mut() {
                *v += f.step();
            }
        }
        out
    }

    #[inline]
    fn misalign(m: &Option<[[f64; 3]; 3]>, x: Vec3) -> Vec3 {
        match m {
            None => x,
            Some(m) => Vec3(m.map(|row| row[0] * x.0[0] + row[1] * x.0[1] + row[2] * x.0[2])),
        }
    }

    #[inline]
    fn noise(&mut self, x: Vec3) -> Vec3 {
        let Some((sigma, rng)) = self.noise.as_mut() else {
            return x;
        };
        let mut out = x;
        for ((v, s), r) in out.0.iter_mut().zip(sigma.iter()).zip(rng.iter_mut()) {
            *v += s * r.draw();
        }
        out
    }

    /// Saturates at ±range, then quantizes; returns whether any axis saturated.
    #[inline]
    fn quantize(&mut self, x: Vec3, dt: f64) -> (Vec3, bool) {
        let mut sat = false;
        let mut x = x;
        if let Some(r) = self.range {
            for v in x.0.iter_mut() {
                if v.abs() > r {
                    *v = v.clamp(-r, r);
                    sat = true;
                }
            }
        }
        let Some((lsb, q)) = self.quant.as_mut() else {
            return (x, sat);
        };
        match lsb {
            Lsb::Increment(_) => {
                let mut inc = Vec3::ZERO;
                for ((v, q), i) in x.0.iter_mut().zip(q.iter_mut()).zip(inc.0.iter_mut()) {
                    *i = q.apply(*v * dt);
                    *v = *i / dt;
                }
                self.last_inc = Some(inc);
            }
            Lsb::Rate(_) => {
                for (v, q) in x.0.iter_mut().zip(q.iter_mut()) {
                    *v = q.apply(*v);
                }
            }
        }
        (x, sat)
    }
}

fn any(v: &[f64]) -> bool {
    v.iter().any(|x| *x != 0.0)
}
