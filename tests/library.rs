//! The library used without the command line: the `examples/simulate.rs` program run as it
//! is, and the `Simulation` builder's scene-file behaviour.

use std::path::Path;

use imu_emu::protocol::StreamDecoder;
use imu_emu::protocol::spec::Source;
use imu_emu::sim::{SimError, Simulation};

// The example's own code, compiled into this test (its `main` is not called).
#[allow(dead_code)]
#[path = "../examples/simulate.rs"]
mod simulate;

/// Every frame of a KVH 1750 stream, decoded with the library's decoder.
fn decode_kvh1750(bytes: &[u8]) -> (Vec<imu_emu::protocol::Decoded>, u64) {
    let (_, mut plan) = imu_emu::protocol::load("kvh1750").unwrap();
    plan.set_rate(1000.0).unwrap();
    let mut dec = StreamDecoder::new(plan);
    let mut frames = Vec::new();
    dec.feed(bytes, |d| frames.push(d.clone()));
    let bad = dec.stats().check_failures;
    (frames, bad)
}

// The example writes 10 s of 1 kHz frames that decode cleanly, whose temperature field follows
// the 2 °C/s ramp it sets (not a constant), and whose specific force carries the 90° roll
// mounting: gravity's reaction, along the body's down axis (with at most v²/r = 5 m/s² of the
// 50 m/s, 500 m circle along body y), appears on the case's y axis.
#[test]
fn example_simulate_writes_decodable_frames() {
    let dir = tempfile::TempDir::new().unwrap();
    let out = dir.path().join("circle.kvh");
    let n = simulate::simulate(&out).unwrap();
    assert_eq!(n, 10_000);
    let bytes = std::fs::read(&out).unwrap();
    let (frames, bad) = decode_kvh1750(&bytes);
    assert_eq!(bad, 0);
    assert_eq!(frames.len(), 10_000);
    for (k, f) in frames.iter().enumerate() {
        let t = (k + 1) as f64 / 1000.0;
        let want = 10.0 + 2.0 * t;
        let got = f.get(Source::Temperature).unwrap();
        // The field is whole degrees: within rounding of the profile at the record's time.
        assert!(
            (got - want).abs() <= 0.5 + 1e-9,
            "frame {k}: {got} °C, profile {want} °C"
        );
    }
    // Mean specific force over the run.
    let mean = |s: Source| frames.iter().map(|f| f.get(s).unwrap()).sum::<f64>() / 1e4;
    let fy = mean(Source::Accel(1)).abs();
    assert!(fy > 9.0, "case y {fy} m/s²: gravity not rotated onto it");
}

fn scene_file(dir: &Path, text: &str) -> std::path::PathBuf {
    let p = dir.join("scene.toml");
    std::fs::write(&p, text).unwrap();
    p
}

// A library user gets the scene file's temperature and mounting: the same scene file gives
// the same records through the builder as the settings given in code.
#[test]
fn scene_file_temperature_and_mounting_reach_the_library() {
    let dir = tempfile::TempDir::new().unwrap();
    let p = scene_file(
        dir.path(),
        "[trajectory]\nscene = \"circle\"\n[imu]\nmodel = \"ln200\"\nrate_hz = 100\n\
         mounting_deg = [0, 0, 90]\n[output]\nduration_s = 2\n\
         [temperature]\nprofile = \"ramp\"\nstart_celsius = -20\nrate_celsius_per_s = 30\n",
    );
    let records = |sim: Simulation| -> Vec<imu_emu::record::Record> {
        sim.records().unwrap().flat_map(|b| b.unwrap()).collect()
    };
    let from_file = records(Simulation::from_scene_file(&p).unwrap().build().unwrap());
    let in_code = Simulation::builder()
        .scene("circle")
        .imu("ln200")
        .rate(100.0)
        .duration(2.0)
        .mounting_deg([0.0, 0.0, 90.0])
        .temperature(imu_emu::errors::temperature::TemperatureProfile::Ramp {
            start: -20.0,
            rate: 30.0,
            limit: None,
        })
        .build()
        .unwrap();
    assert_eq!(from_file, records(in_code));
    // Without the temperature and the mounting the records differ.
    let plain = Simulation::builder()
        .scene("circle")
        .imu("ln200")
        .rate(100.0)
        .duration(2.0)
        .build()
        .unwrap();
    assert_ne!(from_file, records(plain));
    assert_eq!(from_file.len(), 200);
}

// A refused scene-file value is a typed error naming the file and the key; a setter
// overrides the file's value.
#[test]
fn scene_file_errors_name_the_key_and_setters_override() {
    let dir = tempfile::TempDir::new().unwrap();
    let p = scene_file(dir.path(), "[engine]\nstencil = 2\n");
    let e = match Simulation::from_scene_file(&p).unwrap().build() {
        Err(e) => e,
        Ok(_) => panic!("stencil 2 accepted"),
    };
    match &e {
        SimError::At { place, .. } => {
            assert_eq!(place, &format!("{}: `engine.stencil`", p.display()))
        }
        other => panic!("not located: {other:?}"),
    }
    assert!(e.root().to_string().contains("3 to 15"), "{}", e.root());
    let sim = Simulation::from_scene_file(&p).unwrap().stencil(5).build();
    assert!(sim.is_ok());
}
