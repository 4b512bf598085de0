//! The error chain: stages applied to each record's interval-mean rates in the order the IMU
//! model says (default: the paper's — scale factor, bias, misalignment, noise, quantization),
//! then multiplied by Δt back into increments. A stage whose terms are all zero is not built.

use super::process::{Flicker, GaussMarkov, QuantMode, Quantizer, RandomWalk};
use super::temperature::TemperatureProfile;
use super::template::{ImuModel, TriadModel};
use super::vibration::Vibration;
use crate::generator::RotationTerms;
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

/// The record's status flags live with the record; re-exported for the error chain's users.
pub use crate::record::{FLAG_ACCEL_SATURATED, FLAG_GYRO_SATURATED};

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
    /// Lower Cholesky factor of the noise correlation across axes, when not the identity.
    noise_chol: Option<[[f64; 3]; 3]>,
    quant: Option<(Lsb, [Quantizer; 3])>,
    range: Option<f64>,
    /// Temperature polynomials (bias, scale factor), set by `ErrorChain::with_temperature`.
    temp: Option<([f64; 3], [f64; 3])>,
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
    /// Position of each accelerometer (row i) from the reference point, case frame (m).
    size_effect: Option<[[f64; 3]; 3]>,
    /// Scratch: the block's error-free specific force and temperature offsets.
    f_true: Vec<Vec3>,
    dtemp: Vec<f64>,
    /// Vibration of the case, added to the true signal before every error stage.
    vibration: Option<Vibration>,
    /// When capturing: each record's injected error per group, and a scratch snapshot.
    capture: Option<Capture>,
}

/// Captured injected errors of a block and a scratch (gyro, accel) snapshot.
type Capture = (Vec<Components>, Vec<(Vec3, Vec3)>);

/// Names of the groups of injected errors, in [`Components`] order.
pub const COMPONENT_GROUPS: [&str; 7] = [
    "vibration",
    "size_effect",
    "scale_factor",
    "bias",
    "misalignment",
    "noise",
    "quantization",
];

/// The error each group injected into one record, in output units (rad/s for the gyro,
/// m/s² for the accelerometer): `0[group][0]` gyro, `0[group][1]` accelerometer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Components(pub [[Vec3; 2]; 7]);

/// Selects one sensor's vector in a record.
type Sel = fn(&mut Record) -> &mut Vec3;

fn gyro_of(r: &mut Record) -> &mut Vec3 {
    &mut r.gyro
}

fn accel_of(r: &mut Record) -> &mut Vec3 {
    &mut r.accel
}

fn dtheta_of(r: &mut Record) -> &mut Vec3 {
    &mut r.dtheta
}

fn dv_of(r: &mut Record) -> &mut Vec3 {
    &mut r.dv
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
            size_effect: model
                .accel
                .size_effect
                .iter()
                .flatten()
                .any(|v| *v != 0.0)
                .then_some(model.accel.size_effect),
            f_true: Vec::new(),
            dtemp: Vec::new(),
            capture: None,
            vibration: None,
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

    /// Adds a lever arm (case frame, m) from the trajectory's reference point to the IMU's, to
    /// every accelerometer's position.
    pub fn with_lever_arm(mut self, r: Vec3) -> ErrorChain {
        if r != Vec3::ZERO {
            let mut p = self.size_effect.unwrap_or([[0.0; 3]; 3]);
            for row in p.iter_mut() {
                for (c, v) in row.iter_mut().zip(r.0) {
                    *c += v;
                }
            }
            self.size_effect = Some(p);
        }
        self
    }

    /// Vibrates the IMU case (sinusoids and random vibration in the case axes): added to the
    /// true signal after the mounting rotation and before every error stage, so scale factor,
    /// g-sensitivity, saturation and quantization act on it.
    pub fn with_vibration(mut self, v: Vibration) -> ErrorChain {
        if !v.is_empty() {
            self.vibration = Some(v);
        }
        self
    }

    /// A chain with no stage (an ideal IMU).
    pub fn ideal() -> ErrorChain {
        let model = super::template::parse("", std::path::Path::new("ideal"))
            .expect("empty template is valid");
        ErrorChain::new(&model, 1.0, 0)
    }

    /// Records, on each apply, the error every group injected into every record (see
    /// [`ErrorChain::components`]): what a navigator under test can be scored against.
    pub fn with_components(mut self) -> ErrorChain {
        self.capture = Some((Vec::new(), Vec::new()));
        self
    }

    /// The injected errors of the records of the last apply (empty unless capturing).
    pub fn components(&self) -> &[Components] {
        self.capture.as_ref().map_or(&[], |c| &c.0)
    }

    fn snapshot(&mut self, records: &[Record]) {
        if let Some((_, snap)) = self.capture.as_mut() {
            snap.clear();
            snap.extend(records.iter().map(|r| (r.gyro, r.accel)));
        }
    }

    fn record_delta(&mut self, group: usize, records: &[Record]) {
        if let Some((comps, snap)) = self.capture.as_mut() {
            for ((c, r), (g, a)) in comps.iter_mut().zip(records).zip(snap.iter()) {
                c.0[group] = [r.gyro - *g, r.accel - *a];
            }
        }
    }

    /// True when accelerometers sit away from the reference point: then the records must be
    /// corrupted with [`ErrorChain::apply_with`] and the generator's rotation terms.
    pub fn needs_rotation_terms(&self) -> bool {
        self.size_effect.is_some()
    }

    /// True when no stage was built (an ideal IMU): records pass unchanged.
    pub fn is_empty(&self) -> bool {
        self.gyro.is_empty()
            && self.accel.is_empty()
            && self.g_sens.is_none()
            && self.temperature.is_none()
            && self.mounting.is_none()
            && self.size_effect.is_none()
            && self.vibration.is_none()
    }

    /// Corrupts records in place. Stage by stage over the whole block (each random process
    /// still steps once per record, in record order, on its own stream — so the result is
    /// bit-identical to a record-by-record pass and independent of the block size).
    ///
    /// Ignores the size effect and lever arm (see [`ErrorChain::apply_with`]).
    pub fn apply(&mut self, records: &mut [Record]) {
        self.apply_with(records, None)
    }

    /// [`ErrorChain::apply`] with the generator's rotation terms of the same records, which
    /// the size effect and lever arm need: accelerometer i at r_i senses
    /// f + ω̇ × r_i + ω × (ω × r_i), whose interval mean is f̄ + (Δω/Δt) × r_i + (W − tr W·I) r_i
    /// with W the mean of ω ωᵀ — exact, with no differentiation of ω.
    pub fn apply_with(&mut self, records: &mut [Record], rotation: Option<&[RotationTerms]>) {
        if let Some((comps, _)) = self.capture.as_mut() {
            comps.clear();
            comps.resize(records.len(), Components::default());
        }
        if self.is_empty() {
            return;
        }
        if let Some(m) = &self.mounting {
            for r in records.iter_mut() {
                r.gyro = m.mul_vec(r.gyro);
                r.accel = m.mul_vec(r.accel);
            }
        }
        self.snapshot(records);
        if let Some(v) = self.vibration.as_mut() {
            for r in records.iter_mut() {
                let (g, a) = v.next();
                r.gyro += g;
                r.accel += a;
            }
        }
        self.record_delta(0, records);
        self.snapshot(records);
        if let (Some(pos), Some(rot)) = (&self.size_effect, rotation) {
            let inv_dt = 1.0 / self.dt;
            for (r, t) in records.iter_mut().zip(rot) {
                let (mut dw, mut w) = (t.d_omega, Mat3(t.omega_outer));
                if let Some(m) = &self.mounting {
                    dw = m.mul_vec(dw);
                    w = m.mul_mat(&w).mul_mat(&m.transpose());
                }
                let tr = w.0[0][0] + w.0[1][1] + w.0[2][2];
                for (i, p) in pos.iter().enumerate() {
                    let p = Vec3(*p);
                    let add = (dw * inv_dt).cross(p) + w.mul_vec(p) - p * tr;
                    r.accel.0[i] += add.0[i];
                }
            }
        }
        self.record_delta(1, records);
        // The error-free specific force, for the g-sensitivity; the temperature offsets.
        self.f_true.clear();
        if self.g_sens.is_some() {
            self.f_true.extend(records.iter().map(|r| r.accel));
        }
        self.dtemp.clear();
        if let Some((p, t_ref)) = &self.temperature {
            self.dtemp.extend(records.iter().map(|r| p.at(r.t) - t_ref));
        }
        for r in records.iter_mut() {
            r.flags = 0;
        }
        let (gyro, accel): (Sel, Sel) = (gyro_of, accel_of);
        // Whether the last stage left the increments on the LSB grid (then kept exactly).
        let (mut exact_g, mut exact_a) = (false, false);
        for i in 0..self.order.len() {
            let stage = self.order[i];
            self.snapshot(records);
            match stage {
                StageKind::ScaleFactor => {
                    self.gyro.scale(records, gyro, &self.dtemp);
                    self.accel.scale(records, accel, &self.dtemp);
                }
                StageKind::Bias => {
                    self.gyro.bias(records, gyro, &self.dtemp);
                    if let Some(m) = &self.g_sens {
                        for (r, f) in records.iter_mut().zip(&self.f_true) {
                            r.gyro +=
                                Vec3(m.map(|row| {
                                    row[0] * f.0[0] + row[1] * f.0[1] + row[2] * f.0[2]
                                }));
                        }
                    }
                    self.accel.bias(records, accel, &self.dtemp);
                }
                StageKind::Misalignment => {
                    Triad::misalign(&self.gyro.misalign, records, gyro);
                    Triad::misalign(&self.accel.misalign, records, accel);
                }
                StageKind::Noise => {
                    self.gyro.noise(records, gyro);
                    self.accel.noise(records, accel);
                }
                StageKind::Quantization => {
                    exact_g =
                        self.gyro
                            .quantize(records, gyro, dtheta_of, FLAG_GYRO_SATURATED, self.dt);
                    exact_a =
                        self.accel
                            .quantize(records, accel, dv_of, FLAG_ACCEL_SATURATED, self.dt);
                }
            }
            if stage != StageKind::Quantization {
                (exact_g, exact_a) = (false, false);
            }
            let group = match stage {
                StageKind::ScaleFactor => 2,
                StageKind::Bias => 3,
                StageKind::Misalignment => 4,
                StageKind::Noise => 5,
                StageKind::Quantization => 6,
            };
            self.record_delta(group, records);
        }
        for r in records.iter_mut() {
            if !exact_g {
                r.dtheta = r.gyro * self.dt;
            }
            if !exact_a {
                r.dv = r.accel * self.dt;
            }
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
        let noise_chol = m.noise_correlation.map(cholesky3);
        let quant = m.quantization.map(|lsb| {
            let q = match lsb {
                Lsb::Increment(q) | Lsb::Rate(q) => q,
            };
            (lsb, std::array::from_fn(|_| Quantizer::new(q, mode)))
        });
        Triad {
            temp: None,
            scale,
            bias,
            misalign,
            noise,
            noise_chol,
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

    // Each stage runs over the block axis by axis: the per-axis options are tested once per
    // block, and each process's draws stay in record order.
    fn scale(&mut self, recs: &mut [Record], sel: Sel, dtemp: &[f64]) {
        if let Some((_, c)) = self.temp {
            for (r, d) in recs.iter_mut().zip(dtemp) {
                let k = d * (c[0] + d * (c[1] + d * c[2]));
                *sel(r) = *sel(r) * (1.0 + k);
            }
        }
        let Some(s) = self.scale.as_mut() else { return };
        for (i, a) in s.iter_mut().enumerate() {
            for r in recs.iter_mut() {
                let v = &mut sel(r).0[i];
                let mut k = a.fixed + if *v >= 0.0 { a.asym_half } else { -a.asym_half };
                if let Some(gm) = a.gm.as_mut() {
                    k += gm.step();
                }
                if let Some(rw) = a.rw.as_mut() {
                    k += rw.step();
                }
                *v = *v * (1.0 + k) + a.quad * *v * *v;
            }
        }
    }

    fn bias(&mut self, recs: &mut [Record], sel: Sel, dtemp: &[f64]) {
        if let Some((c, _)) = self.temp {
            for (r, d) in recs.iter_mut().zip(dtemp) {
                let b = d * (c[0] + d * (c[1] + d * c[2]));
                *sel(r) += Vec3::new(b, b, b);
            }
        }
        let Some(b) = self.bias.as_mut() else { return };
        for (i, a) in b.iter_mut().enumerate() {
            for r in recs.iter_mut() {
                let v = &mut sel(r).0[i];
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
        }
    }

    fn misalign(m: &Option<[[f64; 3]; 3]>, recs: &mut [Record], sel: Sel) {
        let Some(m) = m else { return };
        for r in recs.iter_mut() {
            let x = *sel(r);
            *sel(r) = Vec3(m.map(|row| row[0] * x.0[0] + row[1] * x.0[1] + row[2] * x.0[2]));
        }
    }

    fn noise(&mut self, recs: &mut [Record], sel: Sel) {
        let Some((sigma, rng)) = self.noise.as_mut() else {
            return;
        };
        if let Some(l) = &self.noise_chol {
            // Correlated across axes: n = diag(σ)·L·z with z the three axes' own draws.
            for r in recs.iter_mut() {
                let z = [rng[0].draw(), rng[1].draw(), rng[2].draw()];
                let v = sel(r);
                for i in 0..3 {
                    v.0[i] += sigma[i] * (l[i][0] * z[0] + l[i][1] * z[1] + l[i][2] * z[2]);
                }
            }
            return;
        }
        for (i, (s, g)) in sigma.iter().zip(rng.iter_mut()).enumerate() {
            for r in recs.iter_mut() {
                sel(r).0[i] += s * g.draw();
            }
        }
    }

    /// Saturates at ±range (setting `flag`), then quantizes. With an increment LSB the exact
    /// quantized increments go to `inc` and the function returns true.
    fn quantize(&mut self, recs: &mut [Record], sel: Sel, inc: Sel, flag: u8, dt: f64) -> bool {
        if let Some(lim) = self.range {
            for r in recs.iter_mut() {
                let mut hit = false;
                for v in sel(r).0.iter_mut() {
                    if v.abs() > lim {
                        *v = v.clamp(-lim, lim);
                        hit = true;
                    }
                }
                if hit {
                    r.flags |= flag;
                }
            }
        }
        let Some((lsb, q)) = self.quant.as_mut() else {
            return false;
        };
        match lsb {
            Lsb::Increment(_) => {
                for (i, q) in q.iter_mut().enumerate() {
                    for r in recs.iter_mut() {
                        let d = q.apply(sel(r).0[i] * dt);
                        inc(r).0[i] = d;
                        sel(r).0[i] = d / dt;
                    }
                }
                true
            }
            Lsb::Rate(_) => {
                for (i, q) in q.iter_mut().enumerate() {
                    for r in recs.iter_mut() {
                        let v = &mut sel(r).0[i];
                        *v = q.apply(*v);
                    }
                }
                false
            }
        }
    }
}

fn any(v: &[f64]) -> bool {
    v.iter().any(|x| *x != 0.0)
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
