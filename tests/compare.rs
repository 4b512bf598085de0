//! `compare` (Monte Carlo free-inertial error per template) and the `navigate` / `compare`
//! command lines. Short scenes and few runs keep these fast.

use std::path::Path;
use std::process::Command;

use imu_emu::nav::campaign::{Aiding, Campaign, CampaignSpec, MissionSpec, Row};

fn plan(scene: &str, seconds: f64, rate: f64, runs: usize, seed: u64) -> CampaignSpec {
    CampaignSpec {
        missions: vec![MissionSpec {
            scene: Some(scene.into()),
            ..MissionSpec::default()
        }],
        rate_hz: Some(rate),
        duration_s: Some(seconds),
        runs,
        seed: Some(seed),
        points: 10,
        aiding: Aiding::Free,
        ..CampaignSpec::default()
    }
}

fn run(plan: &CampaignSpec, names: &[&str], threads: usize) -> Vec<Row> {
    let spec = CampaignSpec {
        templates: names.iter().map(|s| s.to_string()).collect(),
        ..plan.clone()
    };
    Campaign::new(spec).unwrap().run_local(threads).unwrap()
}

/// Same seed → the same table, bit for bit, whatever the thread count; another seed → a
/// different one.
#[test]
fn reproducible_for_a_seed() {
    let names = ["ln200", "mpu6000"];
    let a = run(&plan("straight", 5.0, 100.0, 3, 7), &names, 1);
    let b = run(&plan("straight", 5.0, 100.0, 3, 7), &names, 3);
    assert_eq!(a, b);
    let c = run(&plan("straight", 5.0, 100.0, 3, 8), &names, 2);
    assert_ne!(a[0].last(), c[0].last());
}

/// Grades order as expected at every error quantity: ideal < tactical (LN-200) <
/// industrial (ADIS16405) < consumer (MPU-6000). 10 s straight flight, 8 runs; measured
/// medians of position error 1e-11 / 0.2 / 89 / 382 m — factors of 4 or more apart, far
/// beyond the spread of 8 runs (the 95 % points are within 1.5× of the medians).
#[test]
fn grades_order_as_expected() {
    let r = run(
        &plan("straight", 10.0, 100.0, 8, 20261124),
        &["ideal", "ln200", "adis16405", "mpu6000"],
        2,
    );
    for q in 0..3 {
        let med: Vec<f64> = r
            .iter()
            .map(|t| {
                let p = t.last();
                [p.position, p.velocity, p.attitude][q].median
            })
            .collect();
        println!("quantity {q}: medians {med:?}");
        assert!(med[0] < 1e-6, "ideal {med:?}");
        assert!(med.windows(2).all(|w| w[0] < w[1]), "quantity {q}: {med:?}");
    }
    // Errors grow along the run for a real IMU.
    let g = &r[1].growth;
    assert!(g.first().unwrap().position.median < g.last().unwrap().position.median);
    assert_eq!(g.last().unwrap().t, 10.0);
}

/// Outage mode: back-to-back outages, each scored at its end: runs × outages samples, the
/// growth curve spans one outage, and errors stay at the outage scale.
#[test]
fn outages_reset_to_truth() {
    let mut p = plan("straight", 12.0, 100.0, 2, 1);
    p.outages_s = vec![3.0];
    let r = run(&p, &["ln200"], 2);
    assert_eq!(r[0].windows, 4);
    assert_eq!(r[0].samples, 8);
    assert_eq!(r[0].growth.last().unwrap().t, 3.0);
    let free = run(&plan("straight", 12.0, 100.0, 2, 1), &["ln200"], 2);
    assert!(r[0].last().position.median < free[0].last().position.median);
}

fn imu_emu(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

/// The CLI: a table on stdout, identical for the same seed, the growth CSV and its plot.
#[test]
fn compare_cli_table_and_csv() {
    let dir = tempfile::TempDir::new().unwrap();
    let args = [
        "compare",
        "--imu",
        "ln200,mpu6000",
        "--scene",
        "straight",
        "--duration",
        "4",
        "--rate",
        "100",
        "--runs",
        "2",
        "--points",
        "4",
        "--csv",
        "g.csv",
        "--plot",
        "growth.svg",
    ];
    let a = imu_emu(dir.path(), &args);
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let b = imu_emu(dir.path(), &args);
    assert_eq!(a.stdout, b.stdout);
    let text = String::from_utf8(a.stdout).unwrap();
    assert!(text.contains("ln200") && text.contains("mpu6000") && text.contains("median"));
    let csv = std::fs::read_to_string(dir.path().join("g.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].starts_with("t_s,template,grade,position_median_m"));
    assert_eq!(lines.len(), 1 + 2 * 4);
    assert!(lines[4].starts_with("4.0,ln200,tactical,"), "{}", lines[4]);
    let svg = std::fs::read_to_string(dir.path().join("growth.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    for label in [
        "position error growth",
        "ln200 (tactical)",
        "mpu6000 (consumer)",
    ] {
        assert!(svg.contains(label), "{label} missing from the plot");
    }
    let bad = imu_emu(dir.path(), &["compare", "--imu", "nosuch"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("nosuch"));
}

/// `navigate` closes the generator's own output from the scene's initial state, writes
/// trajectory and error CSVs, and refuses a gap in the records naming the record.
#[test]
fn navigate_cli_closes_generated_records() {
    let dir = tempfile::TempDir::new().unwrap();
    let made = imu_emu(
        dir.path(),
        &[
            "generate",
            "--scene",
            "circle",
            "--duration",
            "20",
            "--format",
            "bin",
            "-o",
            "c.bin",
        ],
    );
    assert!(made.status.success());
    let nav = imu_emu(
        dir.path(),
        &[
            "navigate", "c.bin", "--scene", "circle", "-o", "t.csv", "--errors", "e.csv",
        ],
    );
    assert!(
        nav.status.success(),
        "{}",
        String::from_utf8_lossy(&nav.stderr)
    );
    let summary = String::from_utf8(nav.stdout).unwrap();
    assert!(
        summary.contains("navigated 8000 records at 400 Hz"),
        "{summary}"
    );
    let err = std::fs::read_to_string(dir.path().join("e.csv")).unwrap();
    let last: Vec<f64> = err
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(last[0], 20.0);
    assert!(last[10] < 1e-8, "final position error {}", last[10]);
    let traj = imu_emu_lib_read(&dir.path().join("t.csv"));
    assert_eq!(traj, 8001);
    // Drop record 100: the time check names it.
    let bytes = std::fs::read(dir.path().join("c.bin")).unwrap();
    let mut cut = bytes[..99 * 104].to_vec();
    cut.extend_from_slice(&bytes[100 * 104..]);
    std::fs::write(dir.path().join("gap.bin"), cut).unwrap();
    let bad = imu_emu(dir.path(), &["navigate", "gap.bin", "--scene", "circle"]);
    assert!(!bad.status.success());
    let msg = String::from_utf8_lossy(&bad.stderr);
    assert!(msg.contains("gap.bin: record 100"), "{msg}");
}

/// Rows of a trajectory CSV, read back by the library's own trajectory parser.
fn imu_emu_lib_read(path: &Path) -> usize {
    imu_emu::trajectory::read(path).unwrap().len()
}

/// The CLI on a rig scene file with `[gnss]`: each unit a row, aided before each outage (the
/// aided error column), `--no-gnss` says the receiver is not used; a scene table compare
/// cannot use (an odometer) is refused naming the file and the table.
#[test]
fn compare_cli_rig_scene_with_gnss() {
    let dir = tempfile::TempDir::new().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/compare_rig.toml");
    let args = [
        "compare",
        "--scene-file",
        scene,
        "--duration",
        "13",
        "--outage",
        "2",
        "--aided",
        "3",
        "--runs",
        "2",
        "--points",
        "3",
    ];
    let a = imu_emu(dir.path(), &args);
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let text = String::from_utf8(a.stdout).unwrap();
    println!("{text}");
    assert!(
        text.contains("GNSS-aided, outages of 2 × 2 s per run, each after 3 s of fixes"),
        "{text}"
    );
    assert!(text.contains("position at start m"), "{text}");
    for unit in ["ln200", "adis16405", "mpu6000"] {
        assert!(text.lines().any(|l| l.starts_with(unit)), "{unit}: {text}");
    }
    let free = imu_emu(dir.path(), &[&args[..], &["--no-gnss"]].concat());
    let text = String::from_utf8(free.stdout).unwrap();
    assert!(
        text.contains("note: ") && text.contains("[gnss] receiver is not used"),
        "{text}"
    );
    let rig = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/rig_aided.toml");
    let bad = imu_emu(dir.path(), &["compare", "--scene-file", rig]);
    assert!(!bad.status.success());
    let e = String::from_utf8_lossy(&bad.stderr);
    assert!(
        e.contains("rig_aided.toml") && e.contains("`odometer`"),
        "{e}"
    );
}
