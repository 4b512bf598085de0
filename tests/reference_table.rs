//! `analyze --reference TABLE` with a published Allan deviation table of few points: where the
//! table's fit has no more points than free parameters its terms are not determined, and the
//! comparison says "not enough points" instead of a verdict; a table that does determine a
//! term still gives `DIFFER` where the run is off.

use std::path::Path;
use std::process::Command;

fn imu_emu(dir: &Path, args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// (channel, term, verdict) of each row of a comparison CSV.
fn verdicts(csv: &str) -> Vec<(String, String, String)> {
    csv.lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (c[1].into(), c[2].into(), c[10].into())
        })
        .collect()
}

fn table(name: &str) -> String {
    format!("{}/docs/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// The KVH 1750 table has two τ values per channel: its fit (a Gauss–Markov σ and T through
/// both) is exact whatever the unit, so no row gets `agree` or `DIFFER` — before, gyro z's
/// σ_GM and T_GM read `DIFFER` against a run of the very profile the table describes.
#[test]
fn a_two_point_table_determines_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    imu_emu(
        d,
        &[
            "generate",
            "--scene",
            "static",
            "--imu",
            "kvh1750:typical",
            "--rate",
            "1000",
            "--duration",
            "300",
            "--format",
            "bin",
            "--seed",
            "1",
            "-o",
            "k.bin",
        ],
    );
    let out = imu_emu(
        d,
        &[
            "analyze",
            "k.bin",
            "--reference",
            &table("kvh1750-real-adev.csv"),
            "--compare-csv",
            "k.csv",
        ],
    );
    let rows = verdicts(&std::fs::read_to_string(d.join("k.csv")).unwrap());
    assert!(rows.len() >= 12, "{out}");
    assert!(rows.iter().all(|r| r.2 == "not enough points"), "{rows:?}");
    assert!(out.contains("not determined (not enough points)"), "{out}");
    assert!(!out.contains("DIFFER"), "{out}");
}

/// The LN-200 table has three τ values and its gyro fit keeps N alone (1 parameter, 3
/// points): determined, and the datasheet's 0.07 deg/√h against the real 0.0395 differs.
#[test]
fn a_table_that_determines_a_term_still_differs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    imu_emu(
        d,
        &[
            "generate",
            "--scene",
            "static",
            "--imu",
            "ln200",
            "--rate",
            "100",
            "--duration",
            "600",
            "--format",
            "bin",
            "--seed",
            "1",
            "-o",
            "l.bin",
        ],
    );
    imu_emu(
        d,
        &[
            "analyze",
            "l.bin",
            "--reference",
            &table("ln200-real-adev.csv"),
            "--compare-csv",
            "l.csv",
        ],
    );
    let rows = verdicts(&std::fs::read_to_string(d.join("l.csv")).unwrap());
    for axis in ["x", "y", "z"] {
        let n = rows
            .iter()
            .find(|r| r.0 == format!("gyro {axis}") && r.1 == "N")
            .unwrap_or_else(|| panic!("{rows:?}"));
        assert_eq!(n.2, "DIFFER", "{rows:?}");
    }
}
