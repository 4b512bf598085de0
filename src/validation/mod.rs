//! Measuring the error-free signal: sample an analytic scene into trajectory CSV, rebuild it
//! with the sampled motion model, and compare the IMU records of both. Used by the accuracy
//! benchmark (`cargo bench --bench accuracy`) and by the tests. It runs on the built-in cases
//! and on CSV text it wrote itself, so a failure here is a bug, and it panics rather than
//! returning errors.

#[cfg(feature = "plot")]
pub mod report;

use crate::generator::IdealImu;
use crate::motion::Motion;
use crate::motion::sampled::{ModelSettings, SampledMotion};
use crate::record::Record;
use crate::scenes::{self, SceneParams};
use crate::source::AnyMotion;
use crate::trajectory;

/// A reference case: a scene with parameters, sampled at an input rate.
#[derive(Clone, Debug)]
pub struct Case {
    /// Short name for tables.
    pub name: &'static str,
    /// Scene name.
    pub scene: &'static str,
    /// Scene parameters.
    pub params: SceneParams,
    /// Duration of the sampled trajectory (s).
    pub duration_s: f64,
}

/// The reference cases of the accuracy table (the motions the independent tool was
/// measured on): a level circle R = 500 m at 50 m/s; a 20° roll oscillation at 1 Hz in level
/// flight; a 10 g level turn at 200 m/s with a roll oscillation of 1000 °/s peak (31.83° at 5 Hz).
pub fn reference_cases() -> Vec<Case> {
    let circle = SceneParams {
        radius_m: 500.0,
        speed_m_s: 50.0,
        ..SceneParams::defaults_for("circle")
    };
    let roll = SceneParams {
        roll_osc_deg: 20.0,
        roll_osc_hz: 1.0,
        ..SceneParams::defaults_for("straight")
    };
    let v: f64 = 200.0;
    let g = 9.80665;
    let hard = SceneParams {
        speed_m_s: v,
        radius_m: v * v / (10.0 * g),
        roll_osc_deg: (1000.0f64 / (2.0 * std::f64::consts::PI * 5.0)),
        roll_osc_hz: 5.0,
        ..SceneParams::defaults_for("circle")
    };
    vec![
        Case {
            name: "circle R500 50m/s",
            scene: "circle",
            params: circle,
            duration_s: 20.0,
        },
        Case {
            name: "roll 20deg 1Hz",
            scene: "straight",
            params: roll,
            duration_s: 20.0,
        },
        Case {
            name: "10g turn + 1000deg/s roll",
            scene: "circle",
            params: hard,
            duration_s: 4.0,
        },
    ]
}

/// The analytic motion of a case.
pub fn analytic(case: &Case) -> AnyMotion {
    AnyMotion::Scene(
        scenes::build(case.scene, &case.params)
            .expect("known scene")
            .expect("valid parameters"),
    )
}

/// Trajectory CSV text of `motion` sampled at `rate_hz` over [0, duration] (as a file would
/// carry it: degrees, shortest round-trip decimal).
pub fn sample_csv(motion: &impl Motion, rate_hz: f64, duration_s: f64) -> String {
    let n = (duration_s * rate_hz + 1e-9).floor() as u64;
    trajectory::sample_motion(motion, 0.0, rate_hz, n, None)
}

/// The sampled motion rebuilt from `sample_csv` text.
pub fn rebuild(csv: &str, settings: ModelSettings) -> AnyMotion {
    let samples =
        trajectory::parse(csv, std::path::Path::new("<sampled>")).expect("well-formed CSV");
    AnyMotion::Sampled(SampledMotion::new(&samples, settings).expect("enough samples"))
}

/// Records k = 1..=count at `rate_hz` from t₀ = 0.
pub fn records(motion: AnyMotion, rate_hz: f64, count: u64, nodes: usize) -> Vec<Record> {
    let mut imu = IdealImu::new(motion, rate_hz, 0.0, count, nodes);
    let mut out = vec![Record::default(); count as usize];
    imu.fill(1, &mut out);
    out
}

/// Largest absolute differences of interval-mean rates.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Errors {
    /// max |Δ gyro| over the whole record (rad/s).
    pub gyro: f64,
    /// max |Δ accel| over the whole record (m/s²).
    pub accel: f64,
    /// The same away from the first and last second.
    pub gyro_interior: f64,
    /// The same away from the first and last second.
    pub accel_interior: f64,
}

/// Compares two record sequences on the same time grid.
pub fn compare(reference: &[Record], candidate: &[Record]) -> Errors {
    let t_end = reference.last().map_or(0.0, |r| r.t);
    let mut e = Errors::default();
    for (a, b) in reference.iter().zip(candidate) {
        let dg = (a.gyro - b.gyro).amax();
        let da = (a.accel - b.accel).amax();
        e.gyro = e.gyro.max(dg);
        e.accel = e.accel.max(da);
        if a.t > 1.0 && a.t < t_end - 1.0 {
            e.gyro_interior = e.gyro_interior.max(dg);
            e.accel_interior = e.accel_interior.max(da);
        }
    }
    e
}
