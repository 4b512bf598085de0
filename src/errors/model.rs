//! The IMU model as data: the error figures of a template in SI, the stage kinds of the error
//! chain and the sensor triads. Loading (`template`) and applying (`chain`) both depend on this
//! module and not on each other.

use super::process::QuantMode;
use crate::units::Lsb;

/// The error terms of one sensor triad, in SI, per axis.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriadModel {
    /// Constant bias.
    pub bias: [f64; 3],
    /// Random-constant (turn-on) bias, 1σ.
    pub bias_turn_on: [f64; 3],
    /// Bias-instability coefficient B (ADEV floor 0.664·B).
    pub bias_instability: [f64; 3],
    /// τ band of the bias-instability floor (s).
    pub bias_instability_band: (f64, f64),
    /// Gauss–Markov bias: σ and τ per axis.
    pub bias_gm: Option<([f64; 3], [f64; 3])>,
    /// Random-walk density K of the bias.
    pub random_walk: [f64; 3],
    /// White-noise density N (ARW / VRW).
    pub noise: [f64; 3],
    /// White-noise density added after the output filter, at the output rate (same unit as
    /// `noise`; only with `[output_filter]`): a flat floor under the filtered noise, which
    /// makes the PSD roll off less towards the Nyquist frequency than the filter alone.
    pub post_filter_noise: [f64; 3],
    /// White angle (velocity) noise Q (rad or m/s): a rate error (w_k − w_{k−1})/Δt with w
    /// white of σ Q, whose Allan variance is 3Q²/τ² — an LSB's quantization noise as the IEEE
    /// model has it, without an LSB (what `fit` reads from a table, which shows no lattice).
    pub quantization_noise: [f64; 3],
    /// Rate ramp R (IEEE Std 952): a bias growing by R per second from the run's start
    /// (rad/s² or m/s³).
    pub ramp: [f64; 3],
    /// Constant scale-factor error.
    pub scale_factor: [f64; 3],
    /// Random-constant scale-factor error, 1σ.
    pub scale_factor_turn_on: [f64; 3],
    /// Gauss–Markov scale-factor error: σ and τ.
    pub scale_factor_gm: Option<([f64; 3], [f64; 3])>,
    /// Scale-factor random-walk density.
    pub scale_factor_random_walk: [f64; 3],
    /// Scale-factor asymmetry (positive minus negative input).
    pub scale_factor_asymmetry: [f64; 3],
    /// Quadratic scale factor (accelerometers), 1/(m/s²).
    pub scale_factor_quadratic: [f64; 3],
    /// Constant misalignment angles [xy, xz, yx, yz, zx, zy] (rad).
    pub misalignment: [f64; 6],
    /// Random-constant misalignment, 1σ per angle (rad).
    pub misalignment_turn_on: [f64; 6],
    /// Gyro g-sensitivity matrix, row-major, (rad/s)/(m/s²).
    pub g_sensitivity: [f64; 9],
    /// Output LSB.
    pub quantization: Option<Lsb>,
    /// Saturation limit (rad/s or m/s²).
    pub range: Option<f64>,
    /// Bias temperature polynomial: coefficients of (T − T_ref)^1, ^2, ^3 (SI per °C^k).
    pub bias_temperature: [f64; 3],
    /// Scale-factor temperature polynomial: coefficients of (T − T_ref)^1, ^2, ^3 (1/°C^k).
    pub scale_factor_temperature: [f64; 3],
    /// Correlation matrix of the white noise across the three axes (identity when absent).
    pub noise_correlation: Option<[[f64; 3]; 3]>,
    /// Accelerometers only: position of accelerometer i (row i) from the IMU's reference
    /// point, in the case frame (m) — the size effect.
    pub size_effect: [[f64; 3]; 3],
}

/// A loaded IMU model.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuModel {
    /// Template name.
    pub name: String,
    /// One-line description.
    pub description: String,
    /// Grade (navigation, tactical, industrial, consumer, ideal).
    pub grade: String,
    /// Nominal output rate (Hz), if the template gives one.
    pub rate_hz: Option<f64>,
    /// Gyro terms.
    pub gyro: TriadModel,
    /// Accelerometer terms.
    pub accel: TriadModel,
    /// Quantization mode.
    pub quantization_mode: QuantMode,
    /// Stage order.
    pub order: Vec<StageKind>,
    /// Reference temperature of the temperature polynomials (°C).
    pub temperature_ref: f64,
    /// The unit's timing errors (`[timing]`): its clock, jitter, skew, latency.
    pub timing: crate::timing::TimingModel,
    /// The unit's internal rate and output filter (`[output_filter]`), if it has one.
    pub output_filter: Option<super::output_filter::FilterSpec>,
}

impl ImuModel {
    /// True when the template sets any stochastic or deterministic error term (not just the
    /// interface's quantization and range).
    pub fn has_error_figures(&self) -> bool {
        [&self.gyro, &self.accel].iter().any(|t| {
            let any = |v: &[f64]| v.iter().any(|x| *x != 0.0);
            any(&t.bias)
                || any(&t.bias_turn_on)
                || any(&t.bias_instability)
                || t.bias_gm.is_some()
                || any(&t.random_walk)
                || any(&t.ramp)
                || any(&t.noise)
                || any(&t.post_filter_noise)
                || any(&t.quantization_noise)
                || any(&t.scale_factor)
                || any(&t.scale_factor_turn_on)
                || t.scale_factor_gm.is_some()
                || any(&t.scale_factor_random_walk)
                || any(&t.scale_factor_asymmetry)
                || any(&t.scale_factor_quadratic)
                || any(&t.misalignment)
                || any(&t.misalignment_turn_on)
                || any(&t.g_sensitivity)
                || any(&t.bias_temperature)
                || any(&t.scale_factor_temperature)
        })
    }
}

/// A kind of stage of the error chain. The two kinds on the true signal (vibration, size
/// effect) always come first; the template's `order` arranges the other five. The kinds in
/// [`StageKind::ALL`] order are the groups of the injected-error (`--truth-errors`) columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StageKind {
    /// Vibration of the case, added to the true signal.
    Vibration,
    /// Size effect and lever arm: the accelerometers' offsets from the reference point.
    SizeEffect,
    /// Scale factor (paper eq. 3–4), with its temperature polynomial.
    ScaleFactor,
    /// Bias (eq. 5–6), with its temperature polynomial and the gyro g-sensitivity.
    Bias,
    /// Misalignment (eq. 7–8).
    Misalignment,
    /// White noise.
    Noise,
    /// Saturation and quantization (eq. 9–10).
    Quantization,
}

impl StageKind {
    /// Every kind, in the order of the injected-error column groups (and of this enum).
    pub const ALL: [StageKind; 7] = [
        StageKind::Vibration,
        StageKind::SizeEffect,
        StageKind::ScaleFactor,
        StageKind::Bias,
        StageKind::Misalignment,
        StageKind::Noise,
        StageKind::Quantization,
    ];
    /// The paper's order of the kinds a template's `order` arranges.
    pub const PAPER_ORDER: [StageKind; 5] = [
        StageKind::ScaleFactor,
        StageKind::Bias,
        StageKind::Misalignment,
        StageKind::Noise,
        StageKind::Quantization,
    ];
    /// The name in templates' `order` and in the injected-error column names.
    pub const fn name(self) -> &'static str {
        match self {
            StageKind::Vibration => "vibration",
            StageKind::SizeEffect => "size_effect",
            StageKind::ScaleFactor => "scale_factor",
            StageKind::Bias => "bias",
            StageKind::Misalignment => "misalignment",
            StageKind::Noise => "noise",
            StageKind::Quantization => "quantization",
        }
    }
    /// Parses the name of a kind a template's `order` may arrange.
    pub fn from_name(s: &str) -> Option<StageKind> {
        StageKind::PAPER_ORDER.into_iter().find(|k| k.name() == s)
    }
    /// True for the kinds acting on the true signal, before every kind of `order`.
    pub fn is_on_true_signal(self) -> bool {
        matches!(self, StageKind::Vibration | StageKind::SizeEffect)
    }
}

/// One of the two triads of an IMU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sensor {
    /// Angular rate (rad/s).
    Gyro,
    /// Specific force (m/s²).
    Accel,
}

impl Sensor {
    /// Both, gyro first.
    pub const BOTH: [Sensor; 2] = [Sensor::Gyro, Sensor::Accel];
    /// The name used in keys and stream names: `gyro` or `accel`.
    pub fn name(self) -> &'static str {
        match self {
            Sensor::Gyro => "gyro",
            Sensor::Accel => "accel",
        }
    }
}
