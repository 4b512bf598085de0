//! What a rig unit senses besides the motion: the scene file's `[temperature]` (each unit's
//! thermal terms and frames), `[vibration]` (the body's, in each unit's axes),
//! `[magnetometer]` (each unit's frames, in its axes) and `--gps-time` (every unit's and the
//! GNSS stream's GPS time), checked against the single-IMU path and closed forms.

use std::ops::ControlFlow;
use std::path::Path;
use std::process::Command;

use imu_emu::aiding::mag_samples::MagSampler;
use imu_emu::aiding::magnetometer::MagConfig;
use imu_emu::math::{Mat3, QuatExt, Vec3, quat_from_euler};
use imu_emu::protocol::spec::Source;
use imu_emu::protocol::{self, Decoded, StreamDecoder};
use imu_emu::rig::{Rig, UnitOutputs};
use imu_emu::sim::Simulation;

/// Every unit's main output and truth (CSV, or frames for the main output).
fn write_all(rig: Rig) -> Vec<(Vec<u8>, String)> {
    let n = rig.units().len();
    let mut bufs: Vec<[Vec<u8>; 2]> = (0..n).map(|_| Default::default()).collect();
    {
        let mut outs: Vec<UnitOutputs<'_>> = bufs
            .iter_mut()
            .map(|[m, t]| UnitOutputs {
                main: m,
                truth: Some(t),
                failures: None,
            })
            .collect();
        rig.write(&mut outs, |_| ControlFlow::Continue(())).unwrap();
    }
    (bufs.into_iter())
        .map(|[m, t]| (m, String::from_utf8(t).unwrap()))
        .collect()
}

/// The numeric rows of a CSV text (header skipped).
fn rows(text: &str) -> Vec<Vec<f64>> {
    (text.lines().skip(1))
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// Every frame of `bytes` in `protocol`, decoded, with no check failure or skipped byte.
fn decode(protocol: &str, bytes: &[u8]) -> Vec<Decoded> {
    let (_, plan) = protocol::load(protocol).unwrap();
    let mut dec = StreamDecoder::new(plan);
    let mut frames = Vec::new();
    dec.feed(bytes, |d| frames.push(d.clone()));
    dec.finish();
    let s = dec.stats();
    assert_eq!((s.check_failures, s.skipped_bytes), (0, 0));
    frames
}

/// A template with thermal terms on both triads and white noise (so a wrong seed shows).
const WARM: &str = "name = \"warm\"\ntemperature_ref = \"25 degC\"\n\
[gyro]\nnoise = \"0.1 deg/sqrt(h)\"\nbias_temperature = [\"2 deg/h/degC\"]\n\
scale_factor_temperature = [\"100 ppm/degC\"]\n\
[accel]\nnoise = \"0.05 m/s/sqrt(h)\"\nbias_temperature = [\"0.1 mg/degC\"]\n";

/// Temperature ramp, sinusoidal and random vibration, a noisy 40 Hz magnetometer.
const ENVIRONMENT: &str = "[temperature]\nprofile = \"ramp\"\nstart_celsius = 10.0\n\
rate_celsius_per_s = 20.0\n\
[[vibration.sine]]\nsensor = \"accel\"\naxis = \"x\"\namplitude = \"0.5 g\"\nfrequency = \"25 Hz\"\n\
[[vibration.sine]]\nsensor = \"gyro\"\naxis = \"y\"\namplitude = \"2 deg/s\"\nfrequency = \"7 Hz\"\n\
phase = \"30 deg\"\n\
[[vibration.random]]\nsensor = \"gyro\"\naxis = \"z\"\n\
psd = [[\"5 Hz\", \"0.01 (deg/s)^2/Hz\"], [\"40 Hz\", \"0.01 (deg/s)^2/Hz\"]]\n\
[magnetometer]\nrate_hz = 40.0\nnoise_t = 2e-7\nhard_iron_t = [1e-6, 0.0, -2e-6]\n";

/// The bytes of the single IMU `[imu]` of `model` (seed 7) with `env`, and of the one-unit
/// rig (unit seed 7, master seed 7, identity mounting, no lever arm) with `env`, in `format`.
fn single_and_rig(d: &Path, model: &Path, env: &str, format: &str) -> (Vec<u8>, Vec<u8>) {
    let head = "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 1.0\n";
    let m = model.display();
    let single = d.join("single.toml");
    std::fs::write(&single, format!("{head}[imu]\nmodel = \"{m}\"\n{env}")).unwrap();
    let rig = d.join("rig.toml");
    let unit = format!("[[imu]]\nname = \"a\"\nmodel = \"{m}\"\nseed = 7\nformat = \"{format}\"\n");
    std::fs::write(&rig, format!("{head}{unit}{env}")).unwrap();
    let sim = (Simulation::from_scene_file(&single).unwrap())
        .seed(7)
        .format(format)
        .build()
        .unwrap();
    let mut one = Vec::new();
    sim.write(&mut one).unwrap();
    let rig = (Simulation::from_scene_file(&rig).unwrap().seed(7))
        .build_rig()
        .unwrap();
    (one, write_all(rig).remove(0).0)
}

/// A one-unit rig at the reference point in the body's axes is the single IMU: with the
/// temperature ramp (thermal bias and scale factor), sinusoidal and random vibration and the
/// magnetometer, its CSV records and its KVH 1750 Format C frames (which carry the
/// temperature and the magnetic field) are byte for byte the single IMU's. Without the
/// environment the rig's records differ, so the equality is not one of two runs that both
/// ignore it.
#[test]
fn one_unit_rig_is_the_single_imu_in_its_environment() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = d.join("warm.toml");
    std::fs::write(&model, WARM).unwrap();
    let (single, rig) = single_and_rig(d, &model, ENVIRONMENT, "csv");
    let data = |b: &[u8]| -> Vec<String> {
        (String::from_utf8(b.to_vec()).unwrap().lines())
            .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
            .map(str::to_string)
            .collect()
    };
    let (single_rows, rig_rows) = (data(&single), data(&rig));
    assert_eq!(rig_rows.len(), 400);
    assert_eq!(rig_rows, single_rows);
    let (_, bare) = single_and_rig(d, &model, "", "csv");
    assert_ne!(data(&bare), rig_rows);

    let (single, rig) = single_and_rig(d, &model, ENVIRONMENT, "kvh1750-c");
    assert_eq!(rig.len(), single.len());
    assert!(
        rig == single,
        "the rig's KVH frames differ from the single IMU's"
    );
    let frames = decode("kvh1750-c", &rig);
    assert_eq!(frames.len(), 1000);
    // The frames carry the ramp (10 °C + 20 °C/s · t) and a non-zero field.
    let (k, celsius) = (1..)
        .zip(&frames)
        .filter_map(|(k, f)| f.get(Source::Temperature).map(|c| (k, c)))
        .last()
        .unwrap();
    let want = 10.0 + 20.0 * k as f64 / 1000.0;
    assert!(
        (celsius - want).abs() < 0.5,
        "{celsius} °C at frame {k}, expected {want}"
    );
    assert!(
        frames
            .iter()
            .any(|f| f.get(Source::Mag(0)).is_some_and(|m| m != 0.0))
    );
}

/// C_b^c of a unit mounted at [roll, pitch, yaw] degrees (C_c^b from the angles).
fn c_b_c(deg: [f64; 3]) -> Mat3 {
    let [r, p, y] = deg.map(f64::to_radians);
    quat_from_euler(r, p, y).to_mat().transpose()
}

/// sinc x = sin x / x.
fn sinc(x: f64) -> f64 {
    x.sin() / x
}

/// The body's vibration reaches every unit as one realization turned into its axes: on an
/// error-free rig, a unit's output minus its truth is the vibration alone. At the reference
/// point in the body's axes it is the closed form A·sinc(πfΔt)·sin(2πf(k − ½)Δt + φ) of each
/// sinusoid (docs/error-model.md); a three-axis unit turned by C_b^c reads C_b^c times the
/// first unit's (random part included); a turned skew unit's sensor i reads uᵢ · C_b^c v.
/// Tolerance: the difference (truth + v) − truth of values below 20 m/s² is exact to an ulp
/// of 20, 3.6e-15; 1e-13 leaves margin for the rotation's own rounding and still fails for
/// any unrotated or missing vibration (0.01 to 5 m/s²).
#[test]
fn a_turned_unit_senses_the_body_vibration_in_its_axes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (turned, skew_turn) = ([30.0, -20.0, 90.0], [0.0, 0.0, 90.0]);
    let axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.6, 0.8]];
    let mut skew = String::new();
    for kind in ["gyro", "accel"] {
        for a in axes {
            skew += &format!("[[imu.{kind}]]\naxis = {a:?}\n");
        }
    }
    let text = format!(
        "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 1.0\n\
         [[vibration.sine]]\nsensor = \"accel\"\naxis = \"x\"\namplitude = \"5 m/s^2\"\nfrequency = \"25 Hz\"\nphase = \"0.3 rad\"\n\
         [[vibration.sine]]\nsensor = \"gyro\"\naxis = \"z\"\namplitude = \"0.1 rad/s\"\nfrequency = \"10 Hz\"\n\
         [[vibration.random]]\nsensor = \"accel\"\naxis = \"y\"\npsd = [[\"10 Hz\", \"0.001 g^2/Hz\"], [\"50 Hz\", \"0.001 g^2/Hz\"]]\n\
         [[imu]]\nname = \"a\"\nrate_hz = 400.0\n\
         [[imu]]\nname = \"b\"\nrate_hz = 400.0\nmounting_deg = {turned:?}\n\
         [[imu]]\nname = \"s\"\nrate_hz = 400.0\nmounting_deg = {skew_turn:?}\n{skew}"
    );
    let path = d.join("rig.toml");
    std::fs::write(&path, text).unwrap();
    let rig = Simulation::from_scene_file(&path)
        .unwrap()
        .build_rig()
        .unwrap();
    let out = write_all(rig);
    let vib = |(main, truth): &(Vec<u8>, String)| -> Vec<Vec<f64>> {
        let m = rows(&String::from_utf8(main.clone()).unwrap());
        let t = rows(truth);
        assert_eq!(m.len(), 400);
        (m.iter().zip(&t))
            .map(|(m, t)| (1..m.len()).map(|j| m[j] - t[j]).collect())
            .collect()
    };
    let (va, vb, vs) = (vib(&out[0]), vib(&out[1]), vib(&out[2]));
    let dt = 1.0 / 400.0;
    let tol = 1e-13;
    let mut random_rms = 0.0;
    for (k, ((a, b), s)) in (1u64..).zip(va.iter().zip(&vb).zip(&vs)) {
        // 2πf(k − ½)Δt with the whole cycles taken off in integers: f(k − ½)Δt =
        // (2k − 1)f/800 cycles for f in whole Hz, so the phase carries no rounding of k.
        let phase = |f: u64| {
            let cycles = ((2 * k - 1) * f % 800) as f64 / 800.0;
            2.0 * std::f64::consts::PI * cycles
        };
        let ax = 5.0 * sinc(std::f64::consts::PI * 25.0 * dt) * (phase(25) + 0.3).sin();
        let gz = 0.1 * sinc(std::f64::consts::PI * 10.0 * dt) * phase(10).sin();
        let want = [0.0, 0.0, gz, ax];
        for (j, w) in want.iter().enumerate() {
            assert!(
                (a[j] - w).abs() < tol,
                "record {k} column {j}: {} vs {w}",
                a[j]
            );
        }
        assert_eq!(a[5], 0.0, "record {k}: accel z");
        random_rms += a[4] * a[4];
        let (g, f) = (Vec3::new(a[0], a[1], a[2]), Vec3::new(a[3], a[4], a[5]));
        let c = c_b_c(turned);
        let (gb, fb) = (c * g, c * f);
        let got = [b[0], b[1], b[2], b[3], b[4], b[5]];
        let want = [gb[0], gb[1], gb[2], fb[0], fb[1], fb[2]];
        for j in 0..6 {
            assert!(
                (got[j] - want[j]).abs() < tol,
                "record {k}, unit b column {j}"
            );
        }
        let c = c_b_c(skew_turn);
        let (gs, fs) = (c * g, c * f);
        for (i, u) in axes.iter().enumerate() {
            let u = Vec3::from(*u);
            assert!((s[i] - u.dot(&gs)).abs() < tol, "record {k}, gyro_{i}");
            assert!((s[3 + i] - u.dot(&fs)).abs() < tol, "record {k}, accel_{i}");
        }
    }
    // The random part is there (0.001 g²/Hz over 40 Hz: 0.2 m/s² rms), not a zero column.
    let rms = (random_rms / 400.0).sqrt();
    assert!(rms > 0.05, "random vibration rms {rms} m/s²");
}

/// Two KVH Format C units turned differently carry the magnetometer in their own axes: the
/// decoded field of unit u is C_b^c(u) B^b + its noise, B^b the noise-free sample (hard iron
/// 0, no soft iron) of a [`MagSampler`] on the same motion at the sample at or before the
/// frame's record time. Each component's noise is N(0, σ²) with σ = 0.1 µT, isotropic, so
/// its rotation has the same σ per axis: every one of the 2 units × 10 samples × 3 axes
/// stays within 4.5σ (a false alarm has probability 60 · 6.8e-6 = 4e-4), while a field left
/// in body axes is off by up to 30 µT. The units draw their own noise (seeds from the
/// master seed and their names): their residuals, turned back to the body, differ.
#[test]
fn each_unit_frames_carry_the_field_in_its_axes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (ma, mb) = ([0.0, 0.0, 0.0], [10.0, 40.0, 120.0]);
    let sigma = 1e-7;
    let text = format!(
        "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 1.0\n\
         [magnetometer]\nrate_hz = 10.0\nnoise_t = {sigma:e}\n\
         [[imu]]\nname = \"a\"\nformat = \"kvh1750-c\"\nmounting_deg = {ma:?}\n\
         [[imu]]\nname = \"b\"\nformat = \"kvh1750-c\"\nmounting_deg = {mb:?}\n"
    );
    let path = d.join("rig.toml");
    std::fs::write(&path, text).unwrap();
    let b = Simulation::from_scene_file(&path).unwrap().seed(3);
    let motion = b.motion().unwrap();
    let rig = b.build_rig().unwrap();
    let out = write_all(rig);
    let clean = MagConfig {
        rate_hz: 10.0,
        noise_t: 0.0,
        ..MagConfig::default()
    };
    let mut sampler = MagSampler::new(clean, 0, 0.0);
    let truth: Vec<(f64, Vec3)> = (0..11)
        .map(|_| sampler.next_sample(&motion).unwrap())
        .map(|s| (s.t, s.true_b))
        .collect();
    let mut residuals = Vec::new();
    for ((bytes, _), deg) in out.iter().zip([ma, mb]) {
        let c = c_b_c(deg);
        let frames = decode("kvh1750-c", bytes);
        assert_eq!(frames.len(), 1000);
        let mut res = [[f64::NAN; 3]; 11];
        for (k, f) in (1..).zip(&frames) {
            let t = k as f64 / 1000.0;
            let j = truth.iter().rposition(|s| s.0 <= t + 1e-12).unwrap();
            let want = c * truth[j].1;
            for i in 0..3 {
                let Some(got) = f.get(Source::Mag(i)) else {
                    continue;
                };
                let e = got - want[i];
                assert!(e.abs() < 4.5 * sigma, "frame {k} axis {i}: {e} T off");
                res[j][i] = e;
            }
        }
        residuals.push((c, res));
    }
    // Samples 1..9 appear in both units' frames on every axis (the multiplexed word cycles
    // through the axes within a few frames, each sample is held for 100).
    let (ca, ra) = residuals[0];
    let (cb, rb) = residuals[1];
    let mut differ = 0;
    for j in 1..10 {
        let (a, b) = (Vec3::from(ra[j]), Vec3::from(rb[j]));
        assert!(
            a.iter().chain(b.iter()).all(|x| x.is_finite()),
            "sample {j}"
        );
        if (ca.transpose() * a - cb.transpose() * b).amax() > 1e-9 {
            differ += 1;
        }
    }
    assert_eq!(differ, 9);
}

/// `generate --gps-time W,S` on a rig: every unit's GPS week and seconds (iMAR iXCOM frames)
/// and the GNSS stream's ZDA UTC date and time shift from the default reference (week 0,
/// 0 s at record time 0) by exactly the given time.
#[test]
fn gps_time_applies_to_every_unit_and_the_gnss_stream() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("rig.toml"),
        "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 1.0\n[gnss]\nrate_hz = 5.0\n\
         [[imu]]\nname = \"a\"\nformat = \"imar-ixcom\"\nrate_hz = 100.0\n\
         [[imu]]\nname = \"b\"\nformat = \"imar-ixcom\"\nrate_hz = 50.0\n",
    )
    .unwrap();
    let generate = |out: &str, extra: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
            .current_dir(d)
            .args(["generate", "rig.toml", "-o", out])
            .args(["--gnss", &format!("nmea:{out}/g.nmea")])
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    std::fs::create_dir_all(d.join("base")).unwrap();
    std::fs::create_dir_all(d.join("shifted")).unwrap();
    generate("base", &[]);
    generate("shifted", &["--gps-time", "2300,86400.5"]);
    let times = |dir: &str, unit: &str| -> Vec<f64> {
        let bytes = std::fs::read(d.join(dir).join(format!("{unit}.bin"))).unwrap();
        (decode("imar-ixcom", &bytes).iter())
            .map(|f| {
                let sow = f.get(Source::GpsWholeSeconds).unwrap()
                    + f.get(Source::GpsMicros).unwrap() * 1e-6;
                f.get(Source::GpsWeek).unwrap() * 604_800.0 + sow
            })
            .collect()
    };
    let shift = 2300.0 * 604_800.0 + 86_400.5;
    for (unit, n) in [("a", 100), ("b", 50)] {
        let (base, shifted) = (times("base", unit), times("shifted", unit));
        assert_eq!((base.len(), shifted.len()), (n, n));
        for (k, (x, y)) in base.iter().zip(&shifted).enumerate() {
            // The µs field: both readings are exact to 1 µs.
            assert!(
                (y - x - shift).abs() < 2e-6,
                "unit {unit} frame {k}: {x} → {y}"
            );
        }
    }
    // ZDA: (hhmmss.ss, day, month, year). Week 0 starts 1980-01-06; week 2300, 86 400.5 s is
    // 2024-02-05 00:00:00.5 GPS, i.e. UTC 18 s earlier: 2024-02-04 23:59:42.5. The 5 Hz epochs
    // fall on whole fifths of GPS time (docs/aiding.md), so the first after the start is at
    // 86 400.6 s (record time 0.1 s), and one fewer fits in the second than from record time 0.
    let zda = |dir: &str| -> Vec<String> {
        (std::fs::read_to_string(d.join(dir).join("g.nmea"))
            .unwrap()
            .lines())
        .filter(|l| l.starts_with("$GPZDA"))
        .map(|l| l.split(',').skip(1).take(4).collect::<Vec<_>>().join(","))
        .collect()
    };
    let (base, shifted) = (zda("base"), zda("shifted"));
    assert!(
        base.len() >= 5 && shifted.len() == base.len() - 1,
        "{base:?} {shifted:?}"
    );
    assert!(base[0].ends_with(",1980"), "{}", base[0]);
    assert!(
        shifted[0].starts_with("235942.60,04,02,2024"),
        "{}",
        shifted[0]
    );
}

/// Timing errors a rig unit cannot take are refused, naming where they come from, never
/// left out silently: a scene file's `[timing]` (every unit's) on a skew-redundant unit, whose
/// sensors have no sampling clock, and a template's jitter beyond 1/20 of its output filter's
/// internal sample interval (refused for one IMU too). Timing errors on three-axis units work,
/// with a filter too: tests/rig_units.rs, tests/filtered_timing.rs.
#[test]
fn timing_errors_a_unit_cannot_take_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let head = "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 1.0\n";
    let path = d.join("rig.toml");
    let refused = |text: String| -> String {
        std::fs::write(&path, text).unwrap();
        let e = Simulation::from_scene_file(&path)
            .unwrap()
            .build_rig()
            .err()
            .expect("refused");
        format!("{e}: {}", e.root())
    };
    let e = refused(format!(
        "{head}[timing]\njitter = \"1 us\"\n[[imu]]\nname = \"a\"\n[[imu]]\nname = \"s\"\n\
         [[imu.gyro]]\naxis = [1.0, 0.0, 0.0]\n"
    ));
    assert!(e.contains("rig.toml: `timing`"), "{e}");
    assert!(e.contains("unit `s` is skew-redundant"), "{e}");
    let model = d.join("clocked.toml");
    std::fs::write(
        &model,
        "name = \"clocked\"\n[timing]\njitter = \"100 us\"\n\
         [output_filter]\ninternal_rate_hz = 800\nkind = \"moving_average\"\ntaps = 4\n",
    )
    .unwrap();
    let e = refused(format!(
        "{head}[[imu]]\nname = \"a\"\n[[imu]]\nname = \"b\"\nrate_hz = 200.0\nmodel = \"{}\"\n",
        model.display()
    ));
    assert!(e.contains("`imu[1].model`"), "{e}");
    assert!(
        e.contains("template `clocked`: [timing]: `jitter` = 100 µs: at most 1/20 of the internal sample interval 1250 µs"),
        "{e}"
    );
}

/// `run` on a rig refuses what it cannot honour rather than ignoring it: time marks that do
/// not say whose frames they mark, a pulse with no modem line to drive, and `--gps-time` on a
/// time base that sets the reference itself. (A trigger on a rig works: tests/rig_trigger.rs.)
#[test]
fn run_on_a_rig_refuses_frame_timing_flags_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/rig.toml");
    let sinks = [
        "--unit-sink",
        "nav=file:nav.bin",
        "--duration",
        "0.1",
        "--speed",
        "1",
    ];
    for (flag, value, says) in [
        (
            "--time-marks",
            "marks.csv",
            "a rig's time marks are per unit: give UNIT=marks.csv",
        ),
        (
            "--pulse",
            "dtr:tov",
            "--pulse: drives a serial port's modem line: give --pulse-port DEV or a serial sink of unit `nav`",
        ),
        (
            "--gps-time",
            "2300,0",
            "--gps-time: sets the GPS reference of --time-base sim only",
        ),
    ] {
        let mut args = vec!["run", scene, flag, value];
        args.extend(sinks);
        if flag == "--gps-time" {
            args.extend(["--time-base", "gps"]);
        }
        let out = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
            .current_dir(dir.path())
            .args(&args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "{flag}: {err}");
        assert!(!dir.path().join("nav.bin").exists(), "{flag}");
    }
}
