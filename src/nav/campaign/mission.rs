//! A campaign's mission: the motion source (a scene file, a built-in scene, a trajectory or a
//! motion definition), resolved with the scene file's tables into the motion, the span, the
//! units to compare and the GNSS receiver. Every table of a scene file is used or refused
//! here with the reason: nothing in it is silently ignored.

use super::CampaignError;
use super::unit::Candidate;
use crate::aiding::GnssConfig;
use crate::config::SceneFile;
use crate::errors::template;
use crate::rig::UnitModel;
use crate::source::AnyMotion;

/// Where a mission's motion comes from (the `--scene-file`, `--scene`, `--trajectory` and
/// `--motion-def` of `compare`), as any command names a source: the scene file gives its
/// trajectory, span, `[imu]`/`[[imu]]` units and `[gnss]`; none given: the default scene.
pub type MissionSpec = crate::sim::SourceChoice;

/// What a mission's scene file gives the campaign.
pub(super) struct Resolved {
    pub motion: AnyMotion,
    /// `[output] start_s`, `duration_s`.
    pub start: Option<f64>,
    pub duration: Option<f64>,
    /// `[imu] rate_hz`, `seed`.
    pub rate: Option<f64>,
    pub seed: Option<u64>,
    /// `[imu] model` (a candidate when no template is given) and its placement.
    pub imu_model: Option<String>,
    pub mounting_deg: [f64; 3],
    pub lever_arm_m: [f64; 3],
    /// The rig's units (`[[imu]]`), with their own rates when given.
    pub rig: Vec<(Candidate, Option<f64>)>,
    /// `[gnss]`, checked.
    pub gnss: Option<GnssConfig>,
}

/// A refusal naming the scene file and key.
fn refuse(file: &str, key: &str, why: &str) -> CampaignError {
    CampaignError::Invalid(format!("{file}: `{key}`: {why}"))
}

const WRITES_NOTHING: &str = "compare writes no record stream (it navigates the records); remove it or use a scene file without it";

/// Resolves `spec`: the motion and every table of the scene file, used or refused.
pub(super) fn resolve(spec: &MissionSpec) -> Result<Resolved, CampaignError> {
    let b = spec.builder()?;
    let motion = b.motion()?;
    let f: &SceneFile = b.scene_contents();
    let file = spec
        .scene_file
        .as_ref()
        .map_or("<settings>".into(), |p| p.display().to_string());
    let file = file.as_str();
    let tables: [(&str, bool, &str); 9] = [
        ("output.format", f.output.format.is_some(), WRITES_NOTHING),
        ("output.path", f.output.path.is_some(), WRITES_NOTHING),
        ("imu.sink", f.imu.sink.is_some(), WRITES_NOTHING),
        ("run", f.run.is_some(), WRITES_NOTHING),
        (
            "faults",
            f.faults != Default::default(),
            "protocol faults act on frames, and compare navigates records",
        ),
        (
            "timing",
            f.timing.is_some(),
            "compare samples every unit on its nominal grid (no timing errors yet)",
        ),
        (
            "temperature",
            f.temperature != Default::default(),
            "compare runs each template's error chain without a temperature profile (not yet)",
        ),
        (
            "vibration",
            f.vibration != Default::default(),
            "compare runs each template's error chain without vibration (not yet)",
        ),
        (
            "engine.quadrature_nodes",
            f.engine.quadrature_nodes.is_some(),
            "compare integrates with the engine's default quadrature",
        ),
    ];
    if let Some((key, _, why)) = tables.iter().find(|t| t.1) {
        return Err(refuse(file, key, why));
    }
    let sensors = [
        ("odometer", f.odometer.is_some()),
        ("baro", f.baro.is_some()),
        ("magnetometer", f.magnetometer.is_some()),
    ];
    if let Some((key, _)) = sensors.iter().find(|s| s.1) {
        return Err(refuse(
            file,
            key,
            "the aided navigator fuses GNSS fixes only; remove the table to compare with GNSS aiding",
        ));
    }
    if f.gnss.as_ref().is_some_and(|g| g.seed.is_some()) {
        return Err(refuse(
            file,
            "gnss.seed",
            "compare draws each run's receiver errors from --seed and the run number; a fixed seed would repeat one realization in every run",
        ));
    }
    let gnss = match &f.gnss {
        Some(g) => {
            g.validate()
                .map_err(|e| CampaignError::Invalid(format!("{file}: `gnss`: {e}")))?;
            Some(g.clone())
        }
        None => None,
    };
    let mut rig = Vec::new();
    for (index, u) in b.unit_specs()? {
        let key = |k: &str| match index {
            Some(i) => format!("imu[{i}].{k}"),
            None => format!("unit `{}`: {k}", u.name),
        };
        let UnitModel::Template(name) = &u.model else {
            return Err(refuse(
                file,
                &key("gyro"),
                "a skew-redundant unit has no three-axis reading for the strapdown navigator",
            ));
        };
        let used = [
            (
                "seed",
                u.seed.is_some(),
                "compare draws each run's errors from --seed, the run number and the unit's name; a fixed seed would repeat one realization in every run",
            ),
            ("format", u.format.is_some(), WRITES_NOTHING),
            ("path", u.path.is_some(), WRITES_NOTHING),
            ("sink", !u.sinks.is_empty(), WRITES_NOTHING),
            (
                "failure",
                !u.failures.is_empty(),
                "compare scores the unit's error template; scheduled failures are not part of it",
            ),
        ];
        if let Some((k, _, why)) = used.iter().find(|x| x.1) {
            return Err(refuse(file, &key(k), why));
        }
        let model = template::load(name)
            .map_err(|e| CampaignError::Invalid(format!("{file}: `{}`: {e}", key("model"))))?;
        check_model(&model).map_err(|why| refuse(file, &key("model"), &why))?;
        rig.push((
            Candidate {
                name: u.name.clone(),
                model,
                rate_hz: 0.0,
                mounting_deg: u.mounting_deg,
                lever_arm_m: u.lever_arm_m,
                rig_unit: true,
            },
            u.rate_hz,
        ));
    }
    if !rig.is_empty() {
        let single = [
            ("imu.model", f.imu.model.is_some()),
            ("imu.rate_hz", f.imu.rate_hz.is_some()),
            ("imu.mounting_deg", f.imu.mounting_deg.is_some()),
            ("imu.lever_arm_m", f.imu.lever_arm_m.is_some()),
        ];
        if let Some((k, _)) = single.iter().find(|s| s.1) {
            return Err(refuse(
                file,
                k,
                "describes one IMU, and the file lists `[[imu]]` units",
            ));
        }
    }
    Ok(Resolved {
        motion,
        start: f.output.start_s,
        duration: f.output.duration_s,
        rate: f.imu.rate_hz,
        seed: f.imu.seed,
        imu_model: f.imu.model.clone(),
        mounting_deg: f.imu.mounting_deg.unwrap_or_default(),
        lever_arm_m: f.imu.lever_arm_m.unwrap_or_default(),
        rig,
        gnss,
    })
}

/// A template compare can run: timing errors (a sensor clock) are not modelled here, and a
/// placed unit with an output filter would need the filter at its point.
pub(super) fn check_model(m: &template::ImuModel) -> Result<(), String> {
    if !m.timing.is_zero() {
        return Err(format!(
            "template `{}` has [timing] errors: compare samples every unit on its nominal grid (not yet)",
            m.name
        ));
    }
    Ok(())
}
