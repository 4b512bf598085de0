//! A rig unit's further protocol (`--unit-sink NAME=SINK,protocol=P`, or `,protocol=P` in a
//! unit's `sink` key): the unit's records, after its errors and failures, also as P's frames
//! on a stream of their own. They are byte for byte the frames of the same rig whose unit
//! speaks P as its own `format`, for a unit that shares its grid's evaluation and one with a
//! producer of its own (an output filter); the unit's own stream does not change.

use std::path::Path;

#[path = "common/hil.rs"]
mod hil;
use hil::{failed, imu_emu, ok};

/// Two units on a circle: an LN-200 at the reference point (shared evaluation) and a unit
/// with an output filter 1.2 m aft (a producer of its own), CSV by default, or in `formats`.
fn scene(dir: &Path, name: &str, formats: [&str; 2], sinks: [&str; 2]) -> String {
    let filtered = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/filtered.toml");
    let text = format!(
        "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 2.0\n\
         [[imu]]\nname = \"nav\"\nmodel = \"ln200\"\nrate_hz = 400.0\nseed = 1\n{}\n{}\n\
         [[imu]]\nname = \"filt\"\nmodel = \"{}\"\nrate_hz = 204.8\nseed = 2\n\
         lever_arm_m = [-1.2, 0.0, 0.3]\n{}\n{}\n",
        formats[0],
        sinks[0],
        filtered.display(),
        formats[1],
        sinks[1],
    );
    std::fs::write(dir.join(name), text).unwrap();
    name.to_string()
}

fn read(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn a_further_protocol_is_the_units_own_frames_in_that_protocol() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let plain = scene(d, "plain.toml", ["", ""], ["", ""]);
    let own = scene(
        d,
        "own.toml",
        ["format = \"ln200\"", "format = \"kvh1750-b\""],
        ["", ""],
    );
    let unit_sinks = |pairs: &[(&str, &str)]| -> Vec<String> {
        (pairs.iter())
            .flat_map(|(u, s)| ["--unit-sink".to_string(), format!("{u}={s}")])
            .collect()
    };
    let run = |scene: &str, sinks: Vec<String>| {
        let mut args = vec!["run", scene, "--speed", "max"];
        args.extend(sinks.iter().map(String::as_str));
        ok(&imu_emu(d, &args))
    };
    let both = unit_sinks(&[
        ("nav", "file:a-nav.csv"),
        ("nav", "file:a-nav.ln200,protocol=ln200"),
        ("filt", "file:a-filt.csv"),
        ("filt", "file:a-filt.kvh,protocol=kvh1750-b"),
    ]);
    let summary = run(&plain, both);
    assert!(
        summary.contains("stream filt (kvh1750-b): 409 of 409 frames"),
        "{summary}"
    );
    run(
        &own,
        unit_sinks(&[("nav", "file:b-nav.ln200"), ("filt", "file:b-filt.kvh")]),
    );
    run(
        &plain,
        unit_sinks(&[("nav", "file:c-nav.csv"), ("filt", "file:c-filt.csv")]),
    );
    for (a, b) in [
        ("a-nav.ln200", "b-nav.ln200"),
        ("a-filt.kvh", "b-filt.kvh"),
        ("a-nav.csv", "c-nav.csv"),
        ("a-filt.csv", "c-filt.csv"),
    ] {
        let (x, y) = (read(d, a), read(d, b));
        assert!(!x.is_empty() && x == y, "{a} differs from {b}");
    }
    assert_eq!(
        read(d, "a-nav.ln200").len(),
        800 * 26,
        "800 LN-200 frames of 26 bytes"
    );
}

/// The scene file's `sink` key takes `,protocol=` as the flag does.
#[test]
fn a_units_sink_key_takes_a_protocol() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let keyed = scene(
        d,
        "keyed.toml",
        ["", ""],
        [
            "sink = [\"file:k-nav.csv\", \"file:k-nav.ln200,protocol=ln200\"]",
            "sink = \"file:k-filt.csv\"",
        ],
    );
    ok(&imu_emu(d, &["run", &keyed, "--speed", "max"]));
    let own = scene(
        d,
        "own.toml",
        ["format = \"ln200\"", ""],
        ["sink = \"file:o-nav.ln200\"", "sink = \"file:o-filt.csv\""],
    );
    ok(&imu_emu(d, &["run", &own, "--speed", "max"]));
    assert_eq!(read(d, "k-nav.ln200"), read(d, "o-nav.ln200"));
}

/// A skew-redundant unit's frames carry its own channels: a further protocol is refused
/// when the run is built, naming the flag; so is a protocol that does not exist.
#[test]
fn refused_protocols_name_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("skew.toml"),
        "[trajectory]\nscene = \"static\"\n[output]\nduration_s = 1.0\n\
         [[imu]]\nname = \"s\"\nrate_hz = 100.0\n\
         [[imu.gyro]]\naxis = [1.0, 0.0, 0.0]\n[[imu.accel]]\naxis = [0.0, 0.0, 1.0]\n",
    )
    .unwrap();
    let e = failed(&imu_emu(
        d,
        &[
            "run",
            "skew.toml",
            "--speed",
            "max",
            "--unit-sink",
            "s=file:s.bin,protocol=ln200",
        ],
    ));
    assert!(
        e.contains("--unit-sink s=file:s.bin,protocol=ln200: unit `s` is skew-redundant"),
        "{e}"
    );
    let plain = scene(d, "plain.toml", ["", ""], ["", ""]);
    let e = failed(&imu_emu(
        d,
        &[
            "run",
            &plain,
            "--speed",
            "max",
            "--unit-sink",
            "nav=file:n.bin,protocol=nope",
        ],
    ));
    assert!(
        e.contains("--unit-sink nav=file:n.bin,protocol=nope: sink protocol `nope`"),
        "{e}"
    );
    assert!(!d.join("n.bin").exists() && !d.join("s.bin").exists());
}
