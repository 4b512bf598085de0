//! Accelerometer size effect and lever arm: a sensor at r from the reference point senses
//! f + ω̇ × r + ω × (ω × r) − Γ r (ω = ω_ib^b, Γ the gravitation's gradient in body axes).
//! Checked against closed forms computed here.

use std::path::Path;

use imu_emu::errors::{ErrorChain, template};
use imu_emu::generator::{IdealImu, RotationTerms};
use imu_emu::math::Vec3;
use imu_emu::motion::Motion;
use imu_emu::record::Record;
use imu_emu::scenes::{self, SceneParams};
use imu_emu::source::AnyMotion;
use imu_emu::validation::reference_cases;

/// Records of `m` with and without accelerometers at `pos` (row i = accelerometer i, metres).
fn with_and_without(
    m: &AnyMotion,
    rate: f64,
    k0: u64,
    n: usize,
    pos: [[f64; 3]; 3],
) -> (Vec<Record>, Vec<Record>) {
    let p: Vec<String> = pos.iter().flatten().map(|v| format!("\"{v} m\"")).collect();
    let text = format!(
        "name = \"offsets\"\n[accel]\nsize_effect = [{}]\n",
        p.join(", ")
    );
    let model = template::parse(&text, Path::new("offsets.toml")).unwrap();
    let mut imu = IdealImu::new(m.clone(), rate, 0.0, k0 + n as u64, 3);
    let mut plain = vec![Record::default(); n];
    imu.fill(k0, &mut plain);
    let mut rot = vec![RotationTerms::default(); n];
    imu.rotation_terms(k0, &mut rot);
    let mut moved = plain.clone();
    let mut chain = ErrorChain::new(&model, rate, 1);
    assert!(chain.needs_rotation_terms());
    chain.apply_with(&mut moved, Some(&rot));
    (plain, moved)
}

/// At rest the body turns with the Earth only: ω̇ = 0 and the offset adds the centripetal
/// ω(ω·r) − r|ω|² (~5e-9 m/s² per metre) and −Γ r (~3e-6 m/s² per metre; Γ^b at rest is the
/// gradient at the scene's place turned into its fixed attitude), exact up to the rounding of
/// adding it to f (one ulp of |f| ≈ 9.8 m/s² is 1.8e-15). Without −Γ r it would miss by
/// 1.5e-6 m/s² on axis x.
#[test]
fn static_centripetal_closed_form() {
    let m = AnyMotion::Scene(
        scenes::build("static", &SceneParams::defaults_for("static"))
            .unwrap()
            .unwrap(),
    );
    let pos = [[1.0, 2.0, -3.0], [0.5, 0.0, 0.0], [0.0, -1.0, 0.25]];
    let (plain, moved) = with_and_without(&m, 100.0, 1, 10, pos);
    let w = plain[0].gyro;
    let gamma = imu_emu::generator::gravitation_gradient_b(&m.pose(0.0));
    for (a, b) in plain.iter().zip(&moved) {
        for (i, p) in pos.iter().enumerate() {
            let r = Vec3::from(*p);
            let want = (w * w.dot(&r) - r * w.dot(&w) - gamma * r)[i];
            let got = b.accel[i] - a.accel[i];
            let ulp = 2.0 * f64::EPSILON * a.accel[i].abs().max(1.0);
            assert!((got - want).abs() <= ulp, "axis {i}: {got:e} vs {want:e}");
        }
    }
}

/// The 10 g turn with a 1000 °/s roll oscillation: the interval mean of ω̇ × r + ω × (ω × r)
/// − Γ r (Γ^b of the pose at each node: the engine takes it at the interval's middle, within
/// (ωΔt)²/6·|Γ| ≈ 5e-5 · 3e-7 m/s² here),
/// integrated here by 16 Gauss–Legendre nodes on 8 sub-intervals with ω̇ from 4th-order
/// central differences of ω (step 1e-5 s: truncation ~1e-10, round-off ~1e-10 rad/s² on
/// ω̇ ~ 500 rad/s²), agrees within 1e-8 m/s² for offsets of 10 cm (added terms up to ~50 m/s²).
#[test]
fn fast_rotation_matches_the_definition() {
    let case = &reference_cases()[2];
    let m = AnyMotion::Scene(scenes::build(case.scene, &case.params).unwrap().unwrap());
    let pos = [[0.1, 0.0, 0.0], [0.0, 0.1, 0.05], [-0.03, 0.0, 0.1]];
    let rate = 1000.0;
    let (plain, moved) = with_and_without(&m, rate, 1001, 50, pos);
    let omega = |t: f64| m.sense(m.piece_at(t, 0), t).omega_ib_b;
    let rule = imu_emu::quadrature::GaussLegendre::new(16).unwrap();
    for (a, b) in plain.iter().zip(&moved) {
        let (lo, hi) = (a.t - 1.0 / rate, a.t);
        let mut want = [0.0; 3];
        for part in 0..8 {
            let (s0, len) = (lo + (hi - lo) * part as f64 / 8.0, (hi - lo) / 8.0);
            for (x, wt) in rule.nodes.iter().zip(&rule.weights) {
                let t = s0 + x * len;
                let h = 1e-5;
                let wdot = (omega(t - 2.0 * h) - omega(t + 2.0 * h)) * (1.0 / (12.0 * h))
                    + (omega(t + h) - omega(t - h)) * (8.0 / (12.0 * h));
                let w = omega(t);
                let gamma = imu_emu::generator::gravitation_gradient_b(&m.pose(t));
                for (i, p) in pos.iter().enumerate() {
                    let r = Vec3::from(*p);
                    let add = wdot.cross(&r) + w.cross(&w.cross(&r)) - gamma * r;
                    want[i] += add[i] * wt / 8.0;
                }
            }
        }
        for (i, want) in want.iter().enumerate() {
            let got = b.accel[i] - a.accel[i];
            assert!(
                (got - want).abs() < 1e-8,
                "t {} axis {i}: {got} vs {want}",
                a.t
            );
        }
        // The gyros do not move with the accelerometers.
        assert_eq!(a.gyro, b.gyro);
    }
}
