//! The magnetometer in IMU frames: KVH 1750 Format C's multiplexed magnetic word and MAVLink
//! HIL_SENSOR / HIGHRES_IMU's xmag, ymag, zmag carry the scene's `[magnetometer]` (in gauss),
//! checked against the closed form of a level vehicle at a known heading; the frames carry the
//! very samples `generate --magnetometer` writes; without a magnetometer they carry 0 as before.

use std::path::Path;
use std::process::Command;

use imu_emu::protocol::spec::Source;
use imu_emu::protocol::{self, Decoded, StreamDecoder};
use imu_emu::sim::Simulation;

/// WGS-84 equatorial radius and the IGRF reference radius (m).
const A_WGS84: f64 = 6_378_137.0;
const A_IGRF: f64 = 6_371_200.0;

/// Every frame of `bytes` in `protocol`, decoded.
fn decode(protocol: &str, bytes: &[u8]) -> Vec<Decoded> {
    let (_, plan) = protocol::load(protocol).unwrap();
    let mut dec = StreamDecoder::new(plan);
    let mut frames = Vec::new();
    dec.feed(bytes, |d| frames.push(d.clone()));
    dec.finish();
    let s = dec.stats();
    assert_eq!(
        (s.check_failures, s.status_flagged, s.skipped_bytes),
        (0, 0, 0)
    );
    frames
}

/// The frames of the scene file `text` (written into `dir`) in `protocol` over `seconds`.
fn frames(dir: &Path, text: &str, protocol: &str, seconds: f64) -> Vec<Decoded> {
    let path = dir.join(format!("{protocol}.toml"));
    std::fs::write(&path, text).unwrap();
    let sim = Simulation::from_scene_file(&path)
        .unwrap()
        .format(protocol)
        .duration(seconds)
        .build()
        .unwrap();
    let mut bytes = Vec::new();
    sim.write(&mut bytes).unwrap();
    decode(protocol, &bytes)
}

/// `x` T on the wire in gauss as IEEE single: what a field with lsb = 1e-4 T holds.
fn gauss_f32(x: f64) -> f32 {
    (x * 1e4) as f32
}

/// A decoded field (T) equals the expected value `x` (T) to the wire's resolution: the same
/// single-precision gauss value, give or take one unit in its last place (the expected value
/// is computed here by another route, which may round the last f64 bit the other way).
fn assert_lsb(decoded: f64, x: f64, what: &str) {
    let got = (decoded * 1e4) as f32;
    let want = gauss_f32(x);
    let ulps = (got.to_bits() as i64 - want.to_bits() as i64).abs();
    assert!(ulps <= 1, "{what}: {got} G on the wire, expected {want} G");
}

/// An axial dipole (g₁⁰ = −30 000 nT) on the equator at height h points north with
/// B_N = 30 000 nT·(a/r)³, r = a_WGS84 + h. Facing ψ = 30° with level attitude, the body reads
/// B^b = (B_N cos ψ, −B_N sin ψ, 0); through soft iron S and hard iron b, m = S B^b + b.
const EQUATOR: &str = "[trajectory]\nscene = \"static\"\n[trajectory.params]\nlat_deg = 0.0\n\
lon_deg = 30.0\nh_m = 100.0\nyaw_deg = 30.0\n[magnetometer]\nrate_hz = 50\n\
dipole_nt = [-30000.0, 0.0, 0.0]\nhard_iron_t = [2e-6, -1e-6, 3e-6]\n\
soft_iron = [[1.05, 0.02, 0.0], [0.02, 0.97, 0.01], [0.0, 0.01, 1.0]]\n";

fn equator_measurement() -> [f64; 3] {
    let b_n = 30_000e-9 * (A_IGRF / (A_WGS84 + 100.0)).powi(3);
    let (s, c) = 30f64.to_radians().sin_cos();
    let b = [b_n * c, -b_n * s, 0.0];
    let soft = [[1.05, 0.02, 0.0], [0.02, 0.97, 0.01], [0.0, 0.01, 1.0]];
    let hard = [2e-6, -1e-6, 3e-6];
    std::array::from_fn(|i| (0..3).map(|j| soft[i][j] * b[j]).sum::<f64>() + hard[i])
}

/// MAVLink HIL_SENSOR and HIGHRES_IMU at 250 Hz with a 50 Hz magnetometer: every frame's
/// xmag, ymag, zmag is the closed form to the LSB, and `fields_updated` adds the mag bits
/// (0x1C0) exactly on the frames that bring a new sample (the first, then every fifth).
#[test]
fn mavlink_frames_carry_the_closed_form_field() {
    let dir = tempfile::tempdir().unwrap();
    let m = equator_measurement();
    for protocol in ["mavlink-hil-sensor", "mavlink-highres-imu"] {
        let frames = frames(dir.path(), EQUATOR, protocol, 0.2);
        assert_eq!(frames.len(), 50);
        for (k, f) in (1..).zip(&frames) {
            for (i, want) in m.iter().enumerate() {
                assert_lsb(f.get(Source::Mag(i)).unwrap(), *want, protocol);
            }
            let fresh = k == 1 || k % 5 == 0;
            let updated = if fresh { 0x103F | 0x1C0 } else { 0x103F };
            assert_eq!(f.get(Source::Status), Some(updated as f64), "frame {k}");
            assert!(!f.flagged, "a new sample is not a failure");
        }
    }
}

/// KVH Format C at 1000 Hz: the word of sequence number c mod 4 = 1, 2, 3 carries mag X, Y, Z
/// (gauss) of the closed form; c mod 4 = 0 the temperature. With the case yawed 90° in the
/// body (`imu.mounting_deg`) the case axes read (m_y, −m_x, m_z).
#[test]
fn kvh_format_c_carries_the_closed_form_field_in_the_case_axes() {
    let dir = tempfile::tempdir().unwrap();
    let m = equator_measurement();
    let mounted = format!("{EQUATOR}[imu]\nmounting_deg = [0.0, 0.0, 90.0]\n");
    for (text, want) in [(EQUATOR.to_string(), m), (mounted, [m[1], -m[0], m[2]])] {
        let frames = frames(dir.path(), &text, "kvh1750-c", 0.02);
        assert_eq!(frames.len(), 20);
        for f in &frames {
            let slot = f.get(Source::Counter).unwrap() as usize % 4;
            match slot {
                0 => assert_eq!(f.get(Source::Temperature), Some(25.0)),
                i => assert_lsb(f.get(Source::Mag(i - 1)).unwrap(), want[i - 1], "kvh"),
            }
        }
    }
}

/// A tabulated field with every node (N, E, D) = (20 000, −3 000, 40 000) nT gives that field
/// anywhere in the grid; level at heading 120° the body reads
/// (N cos ψ + E sin ψ, −N sin ψ + E cos ψ, D).
#[test]
fn tabulated_field_in_the_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut table = String::from("lat_deg,lon_deg,north_nt,east_nt,down_nt\n");
    for (lat, lon) in [(40, -1), (40, 1), (42, -1), (42, 1)] {
        table += &format!("{lat},{lon},20000,-3000,40000\n");
    }
    std::fs::write(d.join("field.csv"), table).unwrap();
    let text = "[trajectory]\nscene = \"static\"\n[trajectory.params]\nyaw_deg = 120.0\n\
[magnetometer]\nfield_table = \"field.csv\"\n";
    let (s, c) = 120f64.to_radians().sin_cos();
    let (n, e, dn) = (20_000e-9, -3_000e-9, 40_000e-9);
    let want = [n * c + e * s, -n * s + e * c, dn];
    let frames = frames(d, text, "mavlink-hil-sensor", 0.1);
    assert_eq!(frames.len(), 25);
    for f in &frames {
        for (i, w) in want.iter().enumerate() {
            assert_lsb(f.get(Source::Mag(i)).unwrap(), *w, "table");
        }
    }
}

/// Without `[magnetometer]` the fields hold 0 and `fields_updated` 0x103F, as before.
#[test]
fn without_a_magnetometer_the_fields_hold_zero() {
    let dir = tempfile::tempdir().unwrap();
    let text = "[trajectory]\nscene = \"circle\"\n";
    for f in frames(dir.path(), text, "mavlink-hil-sensor", 0.1) {
        for i in 0..3 {
            assert_eq!(f.get(Source::Mag(i)), Some(0.0));
        }
        assert_eq!(f.get(Source::Status), Some(0x103F as f64));
    }
    for f in frames(dir.path(), text, "kvh1750-c", 0.01) {
        if let Some(v) = (0..3).find_map(|i| f.get(Source::Mag(i))) {
            assert_eq!(v, 0.0);
        }
    }
}

/// `generate --magnetometer` and the frames of one command carry the same samples: on the
/// circle with noise, hard iron and a 40 Hz magnetometer, each KVH frame's magnetic word is
/// the latest CSV row at or before the frame's time (the record time k/1000), to the LSB.
#[test]
fn frames_carry_the_samples_of_the_magnetometer_stream() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("s.toml"),
        "[trajectory]\nscene = \"circle\"\n[magnetometer]\nrate_hz = 40\nnoise_t = 2e-7\n\
hard_iron_t = [1e-6, 0.0, -2e-6]\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(d)
        .args([
            "generate",
            "s.toml",
            "--duration",
            "0.5",
            "--format",
            "kvh1750-c",
        ])
        .args(["-o", "imu.kvh", "--magnetometer", "mag.csv"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(d.join("mag.csv")).unwrap();
    let rows: Vec<[f64; 4]> = csv
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    assert_eq!(rows.len(), 21);
    // Noise of 0.2 µT makes every sample distinct: a frame holding the wrong one shows.
    assert!(rows.windows(2).all(|w| w[0][1] != w[1][1]));
    let frames = decode("kvh1750-c", &std::fs::read(d.join("imu.kvh")).unwrap());
    assert_eq!(frames.len(), 500);
    let mut seen = 0;
    for (k, f) in (1..).zip(&frames) {
        let t = k as f64 / 1000.0;
        let row = rows.iter().rev().find(|r| r[0] <= t).unwrap();
        if let Some(i) = (0..3).find(|&i| f.get(Source::Mag(i)).is_some()) {
            assert_lsb(
                f.get(Source::Mag(i)).unwrap(),
                row[1 + i],
                "frame vs stream",
            );
            seen += 1;
        }
    }
    assert_eq!(seen, 375);
}
