//! The error chain: a list of stages (`stages/`, one type per stage) applied to each block of
//! records' interval-mean rates, then multiplied by Δt back into increments.
//!
//! The records are first rotated from the body into the case frame (the mounting, a change of
//! frame rather than an error); then come the stages on the true signal (vibration, size effect
//! and lever arm), then the error stages in the order the IMU model gives (default: the
//! paper's — scale factor, bias, misalignment, noise, quantization). Each stage belongs to a
//! [`StageKind`]; the injected error of each kind is what `--truth-errors` writes, one column
//! group per kind in [`StageKind::ALL`] order. A stage whose terms are all zero is not built.

pub use super::model::StageKind;
use super::model::{ImuModel, Sensor};
use super::stages::{
    Bias, Block, Misalignment, Noise, Quantization, ScaleFactor, SizeEffect, Stage, Temperature,
};
use super::temperature::TemperatureProfile;
use super::vibration::Vibration;
use crate::generator::RotationTerms;
use crate::math::{Mat3, QuatExt, Vec3};
use crate::record::Record;

pub use super::stages::{FLAG_ACCEL_SATURATED, FLAG_GYRO_SATURATED};

/// The error chain of an IMU.
#[derive(Clone, Debug)]
pub struct ErrorChain {
    /// The order of the template's stage kinds.
    order: Vec<StageKind>,
    /// The built stages, in application order (see [`ErrorChain::insert`]).
    stages: Vec<Box<dyn Stage>>,
    /// C_b^c: body to IMU case, when the IMU is not mounted along the body axes.
    mounting: Option<Mat3>,
    /// The temperature profile and the model's reference temperature, when any temperature
    /// coefficient is non-zero.
    temperature: Option<(TemperatureProfile, f64)>,
    dt: f64,
    /// Scratch: the block's error-free specific force and temperature offsets.
    f_true: Vec<Vec3>,
    dtemp: Vec<f64>,
    /// When capturing: each record's injected error per kind, and a scratch snapshot.
    capture: Option<Capture>,
}

/// Captured injected errors of a block and a scratch (gyro, accel) snapshot.
type Capture = (Vec<Components>, Vec<(Vec3, Vec3)>);

/// Names of the groups of injected errors, in [`Components`] order: the names of
/// [`StageKind::ALL`].
pub const COMPONENT_GROUPS: [&str; StageKind::ALL.len()] = {
    let mut names = [""; StageKind::ALL.len()];
    let mut i = 0;
    while i < names.len() {
        names[i] = StageKind::ALL[i].name();
        i += 1;
    }
    names
};

/// The error each kind of stage injected into one record, in output units (rad/s for the
/// gyro, m/s² for the accelerometer): `0[kind as usize][0]` gyro, `[1]` accelerometer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Components(pub [[Vec3; 2]; StageKind::ALL.len()]);

impl ErrorChain {
    /// Builds the chain of `model` for records at `rate_hz`, drawing every random constant
    /// and seeding every process from `seed` and the term's name.
    pub fn new(model: &ImuModel, rate_hz: f64, seed: u64) -> ErrorChain {
        let dt = 1.0 / rate_hz;
        let mut chain = ErrorChain {
            order: model.order.clone(),
            stages: Vec::new(),
            mounting: None,
            temperature: None,
            dt,
            f_true: Vec::new(),
            dtemp: Vec::new(),
            capture: None,
        };
        if let Some(s) = SizeEffect::build(model.accel.size_effect) {
            chain.insert(Box::new(s));
        }
        for s in Sensor::BOTH {
            let m = match s {
                Sensor::Gyro => &model.gyro,
                Sensor::Accel => &model.accel,
            };
            let built: [Option<Box<dyn Stage>>; 5] = [
                ScaleFactor::build(m, s, dt, seed).map(|x| Box::new(x) as _),
                Bias::build(m, s, dt, seed).map(|x| Box::new(x) as _),
                Misalignment::build(m, s, seed).map(|x| Box::new(x) as _),
                Noise::build(m, s, dt, seed).map(|x| Box::new(x) as _),
                Quantization::build(m, s, model.quantization_mode).map(|x| Box::new(x) as _),
            ];
            for stage in built.into_iter().flatten() {
                chain.insert(stage);
            }
        }
        chain
    }

    /// Adds a stage at its place: the kinds on the true signal first, then the template's
    /// order, by rank within a kind, after the stages already there of the same kind and rank.
    /// A stage of a kind the order leaves out is dropped (templates list all five; a model
    /// built in code may not).
    fn insert(&mut self, stage: Box<dyn Stage>) {
        let order = &self.order;
        let place = |s: &dyn Stage| {
            let k = s.kind();
            let slot = if k.is_on_true_signal() {
                Some(k as usize)
            } else {
                order.iter().position(|o| *o == k).map(|p| 2 + p)
            };
            slot.map(|p| (p, s.rank()))
        };
        if place(stage.as_ref()).is_none() {
            return;
        }
        let at = self
            .stages
            .partition_point(|s| place(s.as_ref()) <= place(stage.as_ref()));
        self.stages.insert(at, stage);
    }

    /// The first built stage of type `T`.
    fn stage_mut<T: 'static>(&mut self) -> Option<&mut T> {
        self.stages
            .iter_mut()
            .find_map(|s| s.as_any_mut().downcast_mut::<T>())
    }

    /// The kinds of the built stages, in application order (one per triad and kind; for tests
    /// and diagnostics).
    pub fn stage_kinds(&self) -> Vec<StageKind> {
        self.stages.iter().map(|s| s.kind()).collect()
    }

    /// Sets the IMU temperature over the run (default: the model's reference temperature, so
    /// the temperature terms vanish). Ignored when the model has no temperature coefficients.
    pub fn with_temperature(mut self, profile: TemperatureProfile, model: &ImuModel) -> ErrorChain {
        self.stages
            .retain_mut(|s| s.as_any_mut().downcast_mut::<Temperature>().is_none());
        self.temperature = None;
        for s in Sensor::BOTH {
            let m = match s {
                Sensor::Gyro => &model.gyro,
                Sensor::Accel => &model.accel,
            };
            for (kind, c) in [
                (StageKind::ScaleFactor, m.scale_factor_temperature),
                (StageKind::Bias, m.bias_temperature),
            ] {
                if let Some(t) = Temperature::build(s, kind, c) {
                    self.insert(Box::new(t));
                    self.temperature = Some((profile.clone(), model.temperature_ref));
                }
            }
        }
        self
    }

    /// Mounts the IMU case rotated from the body by `q_b_c` (C_b^c): the sensors see
    /// ω^c = C_b^c ω^b and f^c = C_b^c f^b before any stage (lever arm not included).
    pub fn with_mounting(mut self, q_b_c: crate::math::Quat) -> ErrorChain {
        let m = q_b_c.to_mat();
        if m != Mat3::identity() {
            self.mounting = Some(m);
        }
        self
    }

    /// Adds a lever arm (case frame, m) from the trajectory's reference point to the IMU's, to
    /// every accelerometer's position.
    pub fn with_lever_arm(mut self, r: Vec3) -> ErrorChain {
        if r != Vec3::zeros() {
            match self.stage_mut::<SizeEffect>() {
                Some(s) => s.add_lever_arm(r),
                None => {
                    let mut s = SizeEffect::zero();
                    s.add_lever_arm(r);
                    self.insert(Box::new(s));
                }
            }
        }
        self
    }

    /// Vibrates the IMU case (sinusoids and random vibration in the case axes): added to the
    /// true signal after the mounting rotation and before every error stage, so scale factor,
    /// g-sensitivity, saturation and quantization act on it.
    pub fn with_vibration(mut self, v: Vibration) -> ErrorChain {
        if !v.is_empty() {
            self.stages
                .retain_mut(|s| s.as_any_mut().downcast_mut::<Vibration>().is_none());
            self.insert(Box::new(v));
        }
        self
    }

    /// A chain with no stage (an ideal IMU).
    pub fn ideal() -> ErrorChain {
        let model = super::template::parse("", std::path::Path::new("ideal"))
            .expect("empty template is valid");
        ErrorChain::new(&model, 1.0, 0)
    }

    /// Records, on each apply, the error every kind of stage injected into every record (see
    /// [`ErrorChain::components`]): what a navigator under test can be scored against.
    pub fn with_components(mut self) -> ErrorChain {
        self.capture = Some((Vec::new(), Vec::new()));
        self
    }

    /// The injected errors of the records of the last apply (empty unless capturing).
    pub fn components(&self) -> &[Components] {
        self.capture.as_ref().map_or(&[], |c| &c.0)
    }

    /// The injected errors of the last apply, to fold those of skipped samples into the next
    /// one taken ([`crate::timing::merge`]).
    pub fn components_mut(&mut self) -> &mut Vec<Components> {
        &mut self.capture.get_or_insert_with(Default::default).0
    }

    /// True when accelerometers sit away from the reference point: then the records must be
    /// corrupted with [`ErrorChain::apply_with`] and the generator's rotation terms.
    pub fn needs_rotation_terms(&self) -> bool {
        self.stages
            .iter()
            .any(|s| s.kind() == StageKind::SizeEffect)
    }

    /// True when no stage was built (an ideal IMU): records pass unchanged.
    pub fn is_empty(&self) -> bool {
        self.stages.is_empty() && self.temperature.is_none() && self.mounting.is_none()
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
    /// the size effect and lever arm need (see `stages/size_effect.rs`).
    pub fn apply_with(&mut self, records: &mut [Record], rotation: Option<&[RotationTerms]>) {
        self.apply_over(records, rotation, self.dt)
    }

    /// [`ErrorChain::apply_with`] for records whose interval is `dt` rather than the chain's
    /// nominal step — an externally triggered unit's sample since the previous edge: the
    /// records carry their interval-mean rates over `dt`, white noise has σ = N/√`dt`, the
    /// random processes step over `dt` and the increments are the rates times `dt`. The
    /// quantization step stays the same. Vibration keeps the nominal step (its filters are
    /// designed for one sample rate).
    pub fn apply_over(
        &mut self,
        records: &mut [Record],
        rotation: Option<&[RotationTerms]>,
        dt: f64,
    ) {
        if let Some((comps, _)) = self.capture.as_mut() {
            comps.clear();
            comps.resize(records.len(), Components::default());
        }
        if self.is_empty() {
            return;
        }
        if let Some(m) = &self.mounting {
            for r in records.iter_mut() {
                r.gyro = m * r.gyro;
                r.accel = m * r.accel;
            }
        }
        let on_true = self
            .stages
            .partition_point(|s| s.kind().is_on_true_signal());
        let (true_stages, error_stages) = self.stages.split_at_mut(on_true);
        let mut block = Block {
            records,
            rotation,
            mounting: self.mounting.as_ref(),
            f_true: &[],
            dtemp: &[],
            dt,
            exact: [false; 2],
        };
        run(true_stages, &mut block, &mut self.capture);
        // The error-free specific force, for the g-sensitivity; the temperature offsets.
        self.f_true.clear();
        if error_stages.iter().any(|s| s.needs_true_force()) {
            self.f_true.extend(block.records.iter().map(|r| r.accel));
        }
        self.dtemp.clear();
        if let Some((p, t_ref)) = &self.temperature {
            self.dtemp
                .extend(block.records.iter().map(|r| p.at(r.t) - t_ref));
        }
        for r in block.records.iter_mut() {
            r.flags = 0;
        }
        block.f_true = &self.f_true;
        block.dtemp = &self.dtemp;
        run(error_stages, &mut block, &mut self.capture);
        // The increments stay exactly on the LSB grid only when quantization came last.
        let exact = if self.order.last() == Some(&StageKind::Quantization) {
            block.exact
        } else {
            [false; 2]
        };
        for r in block.records.iter_mut() {
            if !exact[0] {
                r.dtheta = r.gyro * dt;
            }
            if !exact[1] {
                r.dv = r.accel * dt;
            }
        }
    }
}

/// Runs `stages` over the block; when capturing, records what each run of stages of one kind
/// injected into its kind's group.
fn run(stages: &mut [Box<dyn Stage>], block: &mut Block<'_>, capture: &mut Option<Capture>) {
    for i in 0..stages.len() {
        let kind = stages[i].kind();
        if let Some((_, snap)) = capture.as_mut()
            && (i == 0 || stages[i - 1].kind() != kind)
        {
            snap.clear();
            snap.extend(block.records.iter().map(|r| (r.gyro, r.accel)));
        }
        stages[i].apply(block);
        if let Some((comps, snap)) = capture.as_mut()
            && stages.get(i + 1).is_none_or(|s| s.kind() != kind)
        {
            for ((c, r), (g, a)) in comps.iter_mut().zip(block.records.iter()).zip(snap.iter()) {
                c.0[kind as usize] = [r.gyro - *g, r.accel - *a];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::errors::template::parse;
    use crate::errors::vibration::{Sine, VibrationSpec};
    use std::path::Path;

    fn model(text: &str) -> ImuModel {
        parse(text, Path::new("t.toml")).expect("test template")
    }

    /// Every error figure on both triads (no size effect).
    const FULL: &str =
        "order = [\"bias\", \"quantization\", \"misalignment\", \"scale_factor\", \"noise\"]
[gyro]
bias = \"1 deg/h\"
scale_factor = \"50 ppm\"
misalignment = \"0.1 mrad\"
noise = \"0.1 deg/sqrt(h)\"
g_sensitivity = \"1 deg/h/g\"
quantization = \"1e-6 rad\"
bias_temperature = [\"0.1 deg/h/degC\"]
scale_factor_temperature = [\"1 ppm/degC\"]
[accel]
bias = \"1 mg\"
scale_factor = \"50 ppm\"
misalignment = \"0.1 mrad\"
noise = \"50 ug/sqrt(Hz)\"
range = \"10 g\"
bias_temperature = [\"1 ug/degC\"]
scale_factor_temperature = [\"1 ppm/degC\"]
";

    fn vibration(dt: f64) -> Vibration {
        let spec = VibrationSpec {
            sines: vec![Sine {
                sensor: Sensor::Accel,
                axis: 2,
                amplitude: 1.0,
                freq_hz: 10.0,
                phase_rad: 0.0,
            }],
            randoms: Vec::new(),
        };
        Vibration::new(&spec, dt, 1).unwrap()
    }

    /// The injected-error columns are the stage kinds, in `StageKind::ALL` order, and the
    /// `Components` index of a kind is its place there: the header, the groups the stages
    /// record into and the encoded values all come from the one list.
    #[test]
    fn components_header_is_the_stage_kinds() {
        for (i, k) in StageKind::ALL.iter().enumerate() {
            assert_eq!(*k as usize, i);
            assert_eq!(COMPONENT_GROUPS[i], k.name());
        }
        let header = crate::output::components_header();
        let cols: Vec<&str> = header.trim_end().split(',').collect();
        assert_eq!(cols.len(), 1 + 6 * StageKind::ALL.len());
        for (i, k) in StageKind::ALL.iter().enumerate() {
            assert_eq!(cols[1 + 6 * i], format!("{}_gyro_x", k.name()));
            assert_eq!(cols[6 + 6 * i], format!("{}_accel_z", k.name()));
        }
        // A chain with every kind of stage builds only kinds that have a column group.
        let m = model(FULL);
        let chain = ErrorChain::new(&m, 100.0, 1)
            .with_temperature(TemperatureProfile::Constant(30.0), &m)
            .with_lever_arm(Vec3::new(0.1, 0.0, 0.0))
            .with_vibration(vibration(0.01));
        let mut kinds = chain.stage_kinds();
        kinds.dedup();
        let mut all = StageKind::ALL.to_vec();
        all.sort_by_key(|k| kinds.iter().position(|x| x == k));
        assert_eq!(kinds, all, "every kind is built once per run of stages");
    }

    /// A stage whose parameters are all zero is not built: an explicit zero is no term, and
    /// an ideal IMU, a zero lever arm, an empty vibration and zero temperature coefficients
    /// leave the chain empty.
    #[test]
    fn zero_parameters_build_no_stage() {
        let zeros = model(
            "[gyro]\nbias = \"0 deg/h\"\nnoise = \"0 deg/sqrt(h)\"\nscale_factor = \"0 ppm\"\n\
             misalignment = \"0 mrad\"\nbias_temperature = [\"0 deg/h/degC\"]\n\
             [accel]\nsize_effect = [\"0 mm\", \"0 mm\", \"0 mm\", \"0 mm\", \"0 mm\", \"0 mm\", \
             \"0 mm\", \"0 mm\", \"0 mm\"]\n",
        );
        let empty = Vibration::new(&VibrationSpec::default(), 0.01, 1).unwrap();
        let chain = ErrorChain::new(&zeros, 100.0, 1)
            .with_temperature(TemperatureProfile::Constant(80.0), &zeros)
            .with_lever_arm(Vec3::zeros())
            .with_vibration(empty);
        assert!(chain.stage_kinds().is_empty());
        assert!(chain.is_empty() && !chain.needs_rotation_terms());
        assert!(ErrorChain::ideal().is_empty());
        // One non-zero term builds exactly its stage, on its triad only.
        let noise = model("[accel]\nnoise = \"50 ug/sqrt(Hz)\"\n");
        assert_eq!(
            ErrorChain::new(&noise, 100.0, 1).stage_kinds(),
            [StageKind::Noise]
        );
    }

    /// Stages run on the true signal first, then in the template's order, the temperature
    /// terms joining their kind; a lever arm joins the template's size effect (one stage).
    #[test]
    fn stages_follow_the_order() {
        use StageKind::*;
        let m = model(&format!(
            "{FULL}size_effect = [\"1 mm\", \"0 mm\", \"0 mm\", \"0 mm\", \"1 mm\", \"0 mm\", \
             \"0 mm\", \"0 mm\", \"1 mm\"]\n"
        ));
        let chain = ErrorChain::new(&m, 100.0, 1)
            .with_temperature(TemperatureProfile::Constant(30.0), &m)
            .with_vibration(vibration(0.01))
            .with_lever_arm(Vec3::new(0.0, 0.2, 0.0));
        assert_eq!(
            chain.stage_kinds(),
            [
                Vibration,
                SizeEffect,
                Bias, // temperature, gyro
                Bias, // temperature, accel
                Bias,
                Bias,
                Quantization,
                Quantization,
                Misalignment,
                Misalignment,
                ScaleFactor, // temperature, gyro
                ScaleFactor, // temperature, accel
                ScaleFactor,
                ScaleFactor,
                Noise,
                Noise,
            ]
        );
        assert!(chain.needs_rotation_terms());
    }

    /// The captured groups add up to the whole injected error (each stage's delta is taken
    /// against the output of the stage before: the sums telescope), and a template with only
    /// one term puts everything into that term's group.
    #[test]
    fn components_add_up_and_land_in_their_group() {
        let rate = 100.0;
        let input = |k: usize| Record {
            t: (k + 1) as f64 / rate,
            gyro: Vec3::new(0.1, -0.2, 0.3),
            accel: Vec3::new(0.5, -0.4, -9.8),
            ..Record::default()
        };
        let m = model(FULL);
        let mut chain = ErrorChain::new(&m, rate, 3)
            .with_temperature(TemperatureProfile::Constant(30.0), &m)
            .with_vibration(vibration(1.0 / rate))
            .with_components();
        let mut recs: Vec<Record> = (0..500).map(input).collect();
        chain.apply(&mut recs);
        for (k, (r, c)) in recs.iter().zip(chain.components()).enumerate() {
            let sum =
                c.0.iter()
                    .fold([Vec3::zeros(); 2], |s, g| [s[0] + g[0], s[1] + g[1]]);
            let d = [r.gyro - input(k).gyro, r.accel - input(k).accel];
            for s in 0..2 {
                // A few roundings of values of order 10: 1e-12 is thousands of ulps.
                assert!((sum[s] - d[s]).norm() < 1e-12, "record {k}");
            }
            assert!(c.0[StageKind::Vibration as usize][1].norm() > 0.0);
        }
        let bias_only = model("[gyro]\nbias = \"10 deg/h\"\n");
        let mut chain = ErrorChain::new(&bias_only, rate, 3).with_components();
        let mut recs: Vec<Record> = (0..10).map(input).collect();
        chain.apply(&mut recs);
        for c in chain.components() {
            for k in StageKind::ALL {
                let g = c.0[k as usize][0].norm();
                assert_eq!(g > 0.0, k == StageKind::Bias, "{k:?}");
                assert_eq!(c.0[k as usize][1], Vec3::zeros());
            }
        }
    }
}
