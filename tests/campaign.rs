//! The campaign behind `compare` (`imu_emu::nav::campaign`): closed forms of the navigation
//! error, GNSS aiding with outages, rig scene files and their `[gnss]` receiver, and the
//! merge of task summaries that a distributed run relies on. Short spans keep these fast.

use std::path::{Path, PathBuf};

use imu_emu::nav::campaign::{Aiding, Campaign, CampaignSpec, MissionSpec, Row, Summary};

fn scene(name: &str) -> MissionSpec {
    MissionSpec {
        scene: Some(name.into()),
        ..MissionSpec::default()
    }
}

fn file(path: &Path) -> MissionSpec {
    MissionSpec {
        scene_file: Some(path.to_path_buf()),
        ..MissionSpec::default()
    }
}

fn spec(mission: MissionSpec, templates: &[&str]) -> CampaignSpec {
    CampaignSpec {
        missions: vec![mission],
        templates: templates.iter().map(|s| s.to_string()).collect(),
        rate_hz: Some(100.0),
        duration_s: Some(20.0),
        runs: 3,
        seed: Some(11),
        points: 10,
        ..CampaignSpec::default()
    }
}

fn run(s: CampaignSpec) -> Vec<Row> {
    Campaign::new(s).unwrap().run_local(2).unwrap()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// An error-free IMU navigates without error: the navigator's own algorithm error over 20 s
/// of straight flight is ~1e-11 m (tests/compare.rs measures it), so 1e-6 m, 1e-6 m/s and
/// 1e-8 rad are float tolerance for position, velocity and attitude.
#[test]
fn an_error_free_imu_has_no_navigation_error() {
    let r = run(spec(scene("straight"), &["ideal"]));
    for p in &r[0].growth {
        assert!(p.position.p95 < 1e-6, "{p:?}");
        assert!(p.velocity.p95 < 1e-6, "{p:?}");
        assert!(p.attitude.p95 < 1e-8, "{p:?}");
    }
}

/// A constant accelerometer bias b = 2 mg along x on the static (level) scene: the position
/// error over an outage from the truth is ½·b·t² less the Schuler feedback, which makes it
/// b/ω_s²·(1 − cos ω_s t) = ½·b·t²·(1 − ω_s² t²/12 + …) with ω_s² = g/R ≈ 1.54e-6 s⁻²: at
/// t = 10 s the relative deficit is 1.3e-5. Earth rate turns the velocity error by
/// 2Ω sinφ·t ≈ 1e-3 rad, which changes the norm by half its square (5e-7). So |error| =
/// ½·b·t² within 3e-5 relative (twice the Schuler term) plus 1e-6 m, at every sample of every
/// outage: the growth is exactly quadratic, as the physics says.
#[test]
fn an_accelerometer_bias_grows_half_b_t_squared() {
    let dir = tempfile::tempdir().unwrap();
    let t = write(
        dir.path(),
        "biased.toml",
        "name = \"biased\"\ndescription = \"x accelerometer bias only\"\ngrade = \"test\"\nsources = []\n[gyro]\n[accel]\nbias = [\"2 mg\", \"0 mg\", \"0 mg\"]\n",
    );
    let mut s = spec(scene("static"), &[t.to_str().unwrap()]);
    s.outages_s = vec![10.0];
    let r = run(s);
    assert_eq!(r[0].windows, 2);
    let b = 2e-3 * 9.80665;
    for p in &r[0].growth {
        let expect = 0.5 * b * p.t * p.t;
        let tol = 3e-5 * expect + 1e-6;
        assert!(
            (p.position.median - expect).abs() < tol,
            "t = {}: {} m, expected {expect} m",
            p.t,
            p.position.median
        );
        assert!(
            (p.velocity.median - b * p.t).abs() < 3e-5 * b * p.t + 1e-7,
            "{p:?}"
        );
    }
    assert_eq!(r[0].last().t, 10.0);
}

/// GNSS-aided throughout: the error stays at the fixes' level along the run, where the same
/// seeds navigated free-inertially grow. The default receiver reports σ = (1.1, 1.1, 2.2) m
/// per axis (white and Gauss–Markov parts together), 2.7 m in 3-D: a 95th percentile of the
/// 3-D error below 4 × 2.7 m is bounded by the fixes. Measured after 60 s of straight flight
/// (3 runs): LN-200 aided 1.8 m, free 3.4 m; MPU-6000 aided 1.6 m, free 10 km.
#[test]
fn aided_errors_are_bounded_and_below_free_inertial() {
    let mut s = spec(scene("straight"), &["ln200", "mpu6000"]);
    s.duration_s = Some(60.0);
    s.aiding = Aiding::Gnss;
    let aided = run(s.clone());
    s.aiding = Aiding::Free;
    let free = run(s);
    for (a, f) in aided.iter().zip(&free) {
        assert!(a.aided && !f.aided);
        for p in &a.growth {
            assert!(p.position.p95 < 4.0 * 2.7, "{}: {p:?}", a.unit);
        }
        println!(
            "{}: aided {:?} free {:?}",
            a.unit,
            a.last().position,
            f.last().position
        );
    }
    assert!(aided[0].last().position.median < free[0].last().position.median);
    assert!(aided[1].last().position.median < free[1].last().position.median / 100.0);
}

/// Outages after aiding: the first sample of each outage is the aided error (at the fixes'
/// level), the error grows along the outage, and a unit whose biases the filter learnt
/// before the outage ends it far closer to the truth than the same unit, same seeds, started
/// from a perfect state without that knowledge (free-inertial reset to the truth). ADIS16405,
/// 20 s outages after 40 s of fixes on the circle (a turning flight makes the biases and
/// heading observable).
#[test]
fn aiding_before_an_outage_beats_a_perfect_start() {
    let mut s = spec(scene("circle"), &["adis16405"]);
    s.duration_s = Some(120.0);
    s.outages_s = vec![20.0];
    s.aided_s = 40.0;
    s.aiding = Aiding::Gnss;
    let aided = run(s.clone());
    s.aiding = Aiding::Free;
    let free = run(s);
    let (a, f) = (&aided[0], &free[0]);
    assert_eq!(a.windows, 2);
    let start = a.at_start().unwrap();
    assert_eq!(start.t, 0.0);
    assert!(start.position.p95 < 4.0 * 2.7, "{start:?}");
    let g = &a.growth;
    assert!(
        g.windows(2)
            .all(|w| w[0].position.median < w[1].position.median * 1.5)
    );
    assert!(g[1].position.median < a.last().position.median);
    println!("aided end {:?}, free end {:?}", a.last(), f.last());
    assert!(a.last().position.median < f.last().position.median);
}

/// A rig scene file: every `[[imu]]` unit is compared at its place (lever arm and mounting),
/// each against the truth of its own point and axes. Error-free units at 1.5 m and
/// upside down navigate without error (their readings carry the gravity at their own point);
/// an hg1700
/// unit beside them does not. Its `[gnss]` table is used (aided rows), and a receiver 20 times
/// noisier gives a larger aided error.
#[test]
fn a_rig_scene_compares_each_unit_with_its_gnss() {
    let dir = tempfile::tempdir().unwrap();
    let rig = |gnss_noise: f64| {
        format!(
            "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 30.0\n\
             [[imu]]\nname = \"front\"\nmodel = \"ideal\"\nlever_arm_m = [1.5, 0.0, -0.4]\n\
             [[imu]]\nname = \"flipped\"\nmodel = \"ideal\"\nrate_hz = 50.0\nmounting_deg = [180.0, 0.0, 90.0]\nlever_arm_m = [-1.0, 0.5, 0.3]\n\
             [[imu]]\nname = \"tactical\"\nmodel = \"hg1700\"\n\
             [gnss]\nlever_arm_m = [-0.5, 0.0, -1.2]\npos_white_m = [{n}, {n}, {n}]\npos_gm_m = [0.0, 0.0, 0.0]\n",
            n = gnss_noise
        )
    };
    let mut s = spec(file(&write(dir.path(), "quiet.toml", &rig(0.1))), &[]);
    s.outages_s = vec![5.0];
    s.aided_s = 10.0;
    s.aiding = Aiding::Free;
    let free = run(s.clone());
    let names: Vec<&str> = free.iter().map(|r| r.unit.as_str()).collect();
    assert_eq!(names, ["front", "flipped", "tactical"]);
    assert_eq!((free[0].rate_hz, free[1].rate_hz), (100.0, 50.0));
    // The rig's lever-arm readings add the kinematic terms (ω̇ × l, ω × (ω × l)) and the
    // gravitation's gradient across the lever arm (−Γ l) to the reference point's specific
    // force: the gravity at the unit's point, which the navigator there applies. So the units
    // navigate as an error-free IMU at the reference point does (the bounds of
    // `an_error_free_imu_has_no_navigation_error`); without the gradient they missed by up to
    // (2g/R)·|l| ≈ 5e-6 m/s², ½·5e-6·t² = 2.2 mm of position at 30 s, 1.4e-4 m/s of velocity.
    for r in &free[..2] {
        for p in &r.growth {
            assert!(p.position.p95 < 1e-6, "{}: {p:?}", r.unit);
            assert!(p.velocity.p95 < 1e-6, "{}: {p:?}", r.unit);
            assert!(p.attitude.p95 < 1e-8, "{}: {p:?}", r.unit);
        }
    }
    assert!(free[2].last().position.median > 1e-3);
    s.aiding = Aiding::Auto;
    let quiet = run(s.clone());
    assert!(quiet.iter().all(|r| r.aided));
    s.missions = vec![file(&write(dir.path(), "noisy.toml", &rig(2.0)))];
    let noisy = run(s);
    for (q, n) in quiet.iter().zip(&noisy) {
        let (q0, n0) = (q.at_start().unwrap(), n.at_start().unwrap());
        println!(
            "{}: quiet {:?} noisy {:?}",
            q.unit, q0.position, n0.position
        );
        assert!(n0.position.median > 3.0 * q0.position.median, "{}", q.unit);
    }
}

/// Tables compare cannot use are refused, naming the file and the key and why.
#[test]
fn unused_scene_tables_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "[[imu]]\nname = \"a\"\nmodel = \"ln200\"\n[odometer]\nrate_hz = 10\n",
            "`odometer`",
            "GNSS fixes only",
        ),
        (
            "[[imu]]\nname = \"a\"\nmodel = \"ln200\"\nseed = 3\n",
            "`imu[0].seed`",
            "every run",
        ),
        (
            "[[imu]]\nname = \"a\"\nmodel = \"ln200\"\nformat = \"ln200\"\n",
            "`imu[0].format`",
            "no record stream",
        ),
        (
            "[[imu]]\nname = \"s\"\n[[imu.gyro]]\naxis = [1.0, 0.0, 0.0]\n",
            "`imu[0].gyro`",
            "skew-redundant",
        ),
        (
            "[imu]\nmodel = \"ln200\"\n[output]\npath = \"x.csv\"\n",
            "`output.path`",
            "no record stream",
        ),
        ("[gnss]\nseed = 4\n", "`gnss.seed`", "every run"),
        (
            "[temperature]\ncelsius = 40.0\n",
            "`temperature`",
            "temperature",
        ),
    ];
    for (i, (text, key, why)) in cases.iter().enumerate() {
        let p = write(
            dir.path(),
            &format!("s{i}.toml"),
            &format!("[trajectory]\nscene = \"straight\"\n{text}"),
        );
        let e = Campaign::new(spec(file(&p), &["ln200"]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&p.display().to_string()) && e.contains(key) && e.contains(why),
            "{e}"
        );
    }
}

/// The merge is a function of the set of summaries: computed in a shuffled order, and after
/// a round trip through a serialized form (TOML, as a worker would send it), it gives the
/// thread-run table exactly. A summary missing or given twice is refused.
#[test]
fn shuffled_summaries_merge_into_the_thread_run_table() {
    let mut s = spec(scene("circle"), &["ln200", "adis16405"]);
    s.outages_s = vec![5.0, 10.0];
    s.aided_s = 5.0;
    s.aiding = Aiding::Gnss;
    let c = Campaign::new(s).unwrap();
    let local = c.run_local(2).unwrap();
    assert_eq!(local.len(), 4);
    let mut tasks = c.tasks();
    // A fixed permutation: reverse, then interleave halves.
    tasks.reverse();
    let (a, b) = tasks.split_at(tasks.len() / 2);
    let shuffled: Vec<_> = b.iter().zip(a).flat_map(|(x, y)| [*x, *y]).collect();
    assert_ne!(shuffled, c.tasks());
    let sums: Vec<Summary> = shuffled
        .iter()
        .map(|t| {
            #[derive(serde::Serialize, serde::Deserialize)]
            struct Wire {
                s: Summary,
            }
            let text = toml::to_string(&Wire {
                s: c.run_task(t).unwrap(),
            })
            .unwrap();
            toml::from_str::<Wire>(&text).unwrap().s
        })
        .collect();
    assert_eq!(c.merge(sums.clone()).unwrap(), local);
    // The printed table names each row by unit and outage length.
    let table = imu_emu::nav::campaign::report::table(&local);
    for label in ["ln200 5s ", "ln200 10s ", "adis16405 5s ", "adis16405 10s "] {
        assert!(table.contains(label), "{label}: {table}");
    }
    let e = c.merge(sums[1..].to_vec()).unwrap_err().to_string();
    assert!(e.contains("no summary of task"), "{e}");
    let mut twice = sums.clone();
    twice[0] = twice[1].clone();
    assert!(c.merge(twice).is_err());
}
