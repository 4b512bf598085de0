//! Rig units with a producer of their own (docs/rig.md, "Timing errors and output filters"):
//! a template's output filter, its timing errors or the scene file's `[timing]`, and every
//! unit on an external trigger. Each is checked against the single IMU with the same template
//! and seed, against a plain neighbour, and against closed forms, through the library (no
//! wall clock; tests/rig_trigger.rs runs the trigger through `imu-emu run`).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use imu_emu::engine::Producer;
use imu_emu::engine::frames::{Part, Until, WindowSource};
use imu_emu::engine::trigger::EdgeList;
use imu_emu::errors::template;
use imu_emu::math::{Mat3, QuatExt, Vec3, quat_from_euler};
use imu_emu::motion::Motion;
use imu_emu::quadrature::GaussLegendre;
use imu_emu::record::Record;
use imu_emu::rig::{Rig, RigStream, UnitOutputs};
use imu_emu::sim::{SideOutputs, Simulation};

/// The example template with an output filter (ADIS16448 figures, 819.2 → 204.8 Hz).
const FILTERED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/filtered.toml");

/// Temperature ramp, sinusoidal and random vibration, a noisy 40 Hz magnetometer (as
/// tests/rig_environment.rs): what a producer-backed unit must take from the scene too.
const ENVIRONMENT: &str = "[temperature]\nprofile = \"ramp\"\nstart_celsius = 10.0\n\
rate_celsius_per_s = 20.0\n\
[[vibration.sine]]\nsensor = \"accel\"\naxis = \"x\"\namplitude = \"0.5 g\"\nfrequency = \"25 Hz\"\n\
[[vibration.sine]]\nsensor = \"gyro\"\naxis = \"y\"\namplitude = \"2 deg/s\"\nfrequency = \"7 Hz\"\n\
phase = \"30 deg\"\n\
[[vibration.random]]\nsensor = \"gyro\"\naxis = \"z\"\n\
psd = [[\"5 Hz\", \"0.01 (deg/s)^2/Hz\"], [\"40 Hz\", \"0.01 (deg/s)^2/Hz\"]]\n\
[magnetometer]\nrate_hz = 40.0\nnoise_t = 2e-7\nhard_iron_t = [1e-6, 0.0, -2e-6]\n";

/// An LN-200 with every timing error: its own clock (offset, drift, random walk), jitter,
/// gyro–accelerometer skew, latency with a spread, late frames and skipped samples.
const TIMED: &str = "name = \"timed\"\nbase = \"ln200\"\n[timing]\nclock_offset = \"50 ppm\"\n\
clock_drift = \"0.5 ppm/s\"\nclock_random_walk = \"0.1 ppm/sqrt(s)\"\njitter = \"2 us\"\n\
skew = \"20 us\"\nlatency = \"400 us\"\nlatency_spread = \"50 us\"\nlate_probability = 0.05\n\
late_delay = \"3 ms\"\nmissing_probability = 0.03\n";

/// The circle scene for 1 s.
const HEAD: &str = "[trajectory]\nscene = \"circle\"\n[output]\nduration_s = 1.0\n";

/// Writes `text` to `dir/name`.
fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Every unit's main output and truth.
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

/// The rig of scene file `path` with master seed `seed`, every unit's output and truth.
fn rig(path: &Path, seed: u64) -> Vec<(Vec<u8>, String)> {
    write_all(build_rig(path, seed))
}

fn build_rig(path: &Path, seed: u64) -> Rig {
    (Simulation::from_scene_file(path).unwrap().seed(seed))
        .build_rig()
        .unwrap()
}

/// The single IMU of scene file `path` (its `[imu]`) with `seed` in `format`: its output and
/// its truth.
fn single(path: &Path, seed: u64, format: &str) -> (Vec<u8>, String) {
    let sim = (Simulation::from_scene_file(path).unwrap().seed(seed))
        .format(format)
        .build()
        .unwrap();
    let (mut out, mut truth) = (Vec::new(), Vec::new());
    let side = SideOutputs {
        truth: Some(&mut truth),
        injected: None,
    };
    sim.write_with(&mut out, side, |_| ControlFlow::Continue(()))
        .unwrap();
    (out, String::from_utf8(truth).unwrap())
}

/// The data lines of a CSV text (header skipped).
fn lines(text: &str) -> Vec<&str> {
    text.lines().skip(1).collect()
}

/// A rig unit's truth lines (header skipped) without their `failed` column, which must be 0
/// (no failures).
fn without_failed(truth: &str) -> Vec<&str> {
    lines(truth).into_iter().map(drop_failed).collect()
}

/// A rig unit's truth line without its `failed` column, which must be 0.
fn drop_failed(l: &str) -> &str {
    let (head, failed) = l.rsplit_once(',').unwrap();
    assert_eq!(failed, "0", "{l}");
    head
}

/// The numeric rows of a CSV text (header skipped).
fn rows(text: &str) -> Vec<Vec<f64>> {
    (lines(text).into_iter())
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// A one-unit rig whose template has an output filter, at the reference point in the body's
/// axes with the seed one IMU is given (unit seed = master seed), in the scene's temperature
/// ramp, vibration and magnetometer, writes byte for byte the single IMU's CSV records and
/// KVH 1750 Format C frames (temperature and magnetic field inside), and the single IMU's
/// truth rows (the exact increments over the output intervals, valid the filter's delay
/// before the tag: `tov` < `t`) with the rig's `failed` column after them — also under a
/// scene `[timing]` table of sampling-clock errors (clock offset, jitter, skipped frames),
/// which the filter's internal sampler runs on (tests/filtered_timing.rs).
#[test]
fn one_unit_rig_with_a_filtered_template_is_the_single_imu() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let clock =
        "[timing]\nclock_offset = \"200 ppm\"\njitter = \"2 us\"\nmissing_probability = 0.02\n";
    for (timing, format) in [
        ("", "csv"),
        ("", "kvh1750-c"),
        (clock, "csv"),
        (clock, "kvh1750-c"),
    ] {
        let one = write(
            d,
            "single.toml",
            &format!("{HEAD}{timing}[imu]\nmodel = \"{FILTERED}\"\nrate_hz = 204.8\n{ENVIRONMENT}"),
        );
        let unit = format!(
            "[[imu]]\nname = \"f\"\nmodel = \"{FILTERED}\"\nrate_hz = 204.8\nseed = 7\nformat = \"{format}\"\n"
        );
        let many = write(d, "rig.toml", &format!("{HEAD}{timing}{unit}{ENVIRONMENT}"));
        let (out, truth) = single(&one, 7, format);
        let r = rig(&many, 7);
        assert!(out.len() > 1000, "{format}");
        assert!(
            r[0].0 == out,
            "{format} {timing}: the rig unit's bytes differ"
        );
        assert_eq!(without_failed(&r[0].1), lines(&truth), "{format} {timing}");
        let t = rows(&r[0].1);
        if timing.is_empty() {
            assert_eq!(t.len(), 204);
        } else {
            assert!((190..204).contains(&t.len()), "{} frames", t.len());
        }
        assert!(
            t.iter().all(|x| x[13] < x[0] - 1e-3),
            "tov {} t {}",
            t[0][13],
            t[0][0]
        );
    }
}

/// A unit with an output filter next to a plain unit: the plain unit's bytes and truth are
/// those it writes alone (the filtered unit's own producer leaves the shared evaluation
/// alone), and the filtered unit's are those it writes alone. Its truth is the error-free
/// reading at its place and in its axes (lever arm and mounting): the same, to round-off
/// (1e-12 of values up to 11 m/s²), as an ideal plain unit's at that place on the same grid —
/// while the reference point in body axes is 1e-2 or more away.
#[test]
fn a_filtered_unit_leaves_its_plain_neighbour_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let place = "mounting_deg = [10.0, -5.0, 30.0]\nlever_arm_m = [0.5, -0.2, 0.1]\n";
    let plain = "[[imu]]\nname = \"p\"\nmodel = \"ln200\"\nrate_hz = 200.0\nseed = 3\n";
    let filtered = format!(
        "[[imu]]\nname = \"f\"\nmodel = \"{FILTERED}\"\nrate_hz = 204.8\nseed = 4\n{place}"
    );
    let ideal = format!("[[imu]]\nname = \"i\"\nrate_hz = 204.8\n{place}");
    let at_ref = "[[imu]]\nname = \"r\"\nrate_hz = 204.8\n";
    let alone = rig(&write(d, "a.toml", &format!("{HEAD}{plain}")), 1);
    let f_alone = rig(&write(d, "f.toml", &format!("{HEAD}{filtered}")), 1);
    let all = format!("{HEAD}{plain}{filtered}{ideal}{at_ref}");
    let both = rig(&write(d, "both.toml", &all), 1);
    assert!(
        alone[0] == both[0],
        "the plain unit changed next to a filtered one"
    );
    assert!(
        f_alone[0] == both[1],
        "the filtered unit changed next to others"
    );
    let (f, i, r) = (rows(&both[1].1), rows(&both[2].1), rows(&both[3].1));
    assert_eq!((f.len(), i.len()), (204, 204));
    let mut off_ref = 0.0f64;
    for (k, ((f, i), r)) in f.iter().zip(&i).zip(&r).enumerate() {
        assert_eq!(f[0], i[0], "record {k}: time tags");
        for j in 1..13 {
            assert!(
                (f[j] - i[j]).abs() <= 1e-12 * 11.0,
                "record {k} column {j}: {} vs {}",
                f[j],
                i[j]
            );
            off_ref = off_ref.max((f[j] - r[j]).abs());
        }
    }
    assert!(off_ref > 1e-2, "{off_ref}");
}

/// A unit with every timing error writes byte for byte what the single IMU with that template
/// and seed writes — CSV records, and KVH 1750 frames whose counter steps over the skipped
/// samples — and the single IMU's truth with its `tov`, `tov_accel` and `emit` columns. A
/// scene file's `[timing]` table is every three-axis unit's, over its template's own key by
/// key: a unit whose template has none gets the table's errors, each unit as the single IMU
/// with the table and its template.
#[test]
fn timing_errors_in_a_rig_unit_are_the_single_imus() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = write(d, "timed.toml", TIMED);
    let m = model.display();
    for format in ["csv", "kvh1750"] {
        let one = write(
            d,
            "single.toml",
            &format!("{HEAD}[imu]\nmodel = \"{m}\"\nrate_hz = 200.0\n"),
        );
        let unit = format!(
            "[[imu]]\nname = \"t\"\nmodel = \"{m}\"\nrate_hz = 200.0\nseed = 9\nformat = \"{format}\"\n"
        );
        let many = write(d, "rig.toml", &format!("{HEAD}{unit}"));
        let (out, truth) = single(&one, 9, format);
        let r = rig(&many, 1);
        assert!(r[0].0 == out, "{format}: the rig unit's bytes differ");
        assert_eq!(without_failed(&r[0].1), lines(&truth), "{format}");
        // Skipped samples: fewer records than the grid's 200.
        let n = lines(&truth).len();
        assert!((170..199).contains(&n), "{format}: {n} records");
    }
    let table = "[timing]\nlatency = \"1 ms\"\njitter = \"1 us\"\n";
    let units = format!(
        "[[imu]]\nname = \"t\"\nmodel = \"{m}\"\nrate_hz = 200.0\nseed = 9\n\
         [[imu]]\nname = \"u\"\nmodel = \"ln200\"\nrate_hz = 200.0\nseed = 10\n"
    );
    let r = rig(&write(d, "rig.toml", &format!("{HEAD}{table}{units}")), 1);
    for (i, (model, seed)) in [(m.to_string(), 9), ("ln200".to_string(), 10)]
        .into_iter()
        .enumerate()
    {
        let one = format!("{HEAD}{table}[imu]\nmodel = \"{model}\"\nrate_hz = 200.0\n");
        let (out, truth) = single(&write(d, "single.toml", &one), seed, "csv");
        assert!(r[i].0 == out, "unit {i}: the rig unit's bytes differ");
        assert_eq!(without_failed(&r[i].1), lines(&truth), "unit {i}");
        // The table's latency: emit − tov = 1 ms (no spread in the table; unit t's template
        // spread stays: 1 ms ± 50 µs, or 3 ms more when late).
        let t = rows(&r[i].1);
        assert!(t.iter().all(|x| x[15] - x[13] > 0.9e-3), "unit {i}");
    }
}

/// A rig as a frame source: a unit with timing errors (latency, late frames, its own clock,
/// skipped samples) is held until its frames are due, as one IMU's source holds them. Filled
/// in 1 ms windows, every frame of every stream comes in the window its emission time falls
/// in; the timed unit's frames go out at the truth's `emit` time (ns, after t₀) and its truth
/// rows with them; a plain unit's record k at k/rate.
#[test]
fn a_timed_unit_goes_out_at_its_emission_times() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = write(d, "timed.toml", TIMED);
    let text = format!(
        "{HEAD}[[imu]]\nname = \"t\"\nmodel = \"{}\"\nrate_hz = 200.0\n\
         [[imu]]\nname = \"p\"\nrate_hz = 200.0\n",
        model.display()
    );
    let mut s = build_rig(&write(d, "rig.toml", &text), 1)
        .stream()
        .with_truth(&[true, true]);
    let origin = s.origin();
    let mut parts = vec![Part::default(); s.streams()];
    let mut got: Vec<Vec<(i64, String)>> = vec![Vec::new(); 4];
    let mut until = 0i64;
    while !s.done() {
        let from = until;
        until += 1_000_000;
        parts.iter_mut().for_each(Part::clear);
        s.fill(Until::ns(origin, until), &mut parts).unwrap();
        for (p, g) in parts.iter().zip(got.iter_mut()) {
            let mut start = 0;
            for (&e, &end) in p.emit_ns.iter().zip(&p.ends) {
                assert!(
                    from < e && e <= until,
                    "frame at {e} ns in the window ({from}, {until}]"
                );
                g.push((e, String::from_utf8(p.bytes[start..end].to_vec()).unwrap()));
                start = end;
            }
        }
        assert!(until < 2_000_000_000, "never done");
    }
    let (frames, truth) = (&got[0], &got[2]);
    assert_eq!(frames.len(), truth.len());
    assert!((170..199).contains(&frames.len()), "{}", frames.len());
    for ((e, _), (te, row)) in frames.iter().zip(truth) {
        assert_eq!(e, te);
        let emit: f64 = row.split(',').nth(15).unwrap().parse().unwrap();
        assert!(
            (*e as f64 - (emit - origin) * 1e9).abs() <= 1.0,
            "{e} ns vs emit {emit} s"
        );
    }
    assert_eq!(got[1].len(), 200);
    for (k, (e, _)) in got[1].iter().enumerate() {
        assert_eq!(*e, (k as i64 + 1) * 5_000_000);
    }
}

/// C_b^c of a unit mounted at `deg` (roll, pitch, yaw of C_c^b).
fn c_b_c(deg: [f64; 3]) -> Mat3 {
    let [r, p, y] = deg.map(f64::to_radians);
    quat_from_euler(r, p, y).to_mat().transpose()
}

/// The interval means of ω and of the specific force at `r` (body frame) over (lo, hi] on
/// `m`, by a 16-point Gauss–Legendre rule (the engine uses 3 points: an independent
/// quadrature) and mean(ω̇) = Δω/T; the gravitation's gradient at the middle, as in
/// tests/rig.rs.
fn closed_form(m: &impl Motion, lo: f64, hi: f64, r: Vec3) -> (Vec3, Vec3) {
    let t = hi - lo;
    let sense = |x: f64| m.sense(m.piece_at(x, 0), x);
    let gl = GaussLegendre::new(16).unwrap();
    let (mut w, mut f, mut c) = (Vec3::zeros(), Vec3::zeros(), Vec3::zeros());
    for (x, wt) in gl.nodes.iter().zip(&gl.weights) {
        let s = sense(lo + x * t);
        w += s.omega_ib_b * *wt;
        f += s.f_b * *wt;
        c += s.omega_ib_b.cross(&s.omega_ib_b.cross(&r)) * *wt;
    }
    c -= imu_emu::generator::gravitation_gradient_b(&m.pose(0.5 * (lo + hi))) * r;
    let alpha = (sense(hi).omega_ib_b - sense(lo).omega_ib_b) * (1.0 / t);
    (w, f + alpha.cross(&r) + c)
}

/// Irregular trigger intervals after t₀ (s): 3 to 17 ms long, `n` of them.
fn intervals(n: usize) -> Vec<(f64, f64)> {
    let mut at = 0.0;
    (0..n)
        .map(|i| {
            let lo = at;
            at += 0.003 + 0.001 * ((i * 7) % 15) as f64;
            (lo, at)
        })
        .collect()
}

/// Every unit of a triggered rig takes one record per interval between edges, integrating over
/// it: an ideal unit at a lever arm and mounting (sharing the evaluation), an ideal unit with
/// an output filter and one with timing errors at the same place (each with its own
/// producer: under the trigger the filter averages over the interval and the sensor clock
/// gives way to the edges), and a skew-redundant unit. On the circle with a 1 Hz roll
/// oscillation (ω̇ up to 3.4 rad/s², so the lever arm's terms are large) the records equal
/// the closed form over each interval — ω̄ and f̄ + mean(ω̇) × r + mean(ω × (ω × r)), turned
/// into the unit's axes — to 1e-10 (values up to 11 m/s²; the quadratures agree to
/// round-off over ≤ 17 ms); each record's time tag is its closing edge and its increments
/// its rates times its own interval, and it leaves at the edge; the truth is the output (an
/// ideal unit) and carries `tov` = `tov_accel` = `emit` = the edge. Lever-arm terms whose mean of ω ωᵀ were taken over the nominal 10 ms instead of the
/// interval would be off by a factor 10 ms/T − 1 of ω × (ω × r) (−0.4 to 2.3 here).
#[test]
fn a_triggered_rig_samples_every_unit_over_each_interval() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (r, mount) = ([1.5, -0.8, 0.4], [10.0, 20.0, 30.0]);
    let place = format!("lever_arm_m = {r:?}\nmounting_deg = {mount:?}\nrate_hz = 100.0\n");
    let filt = write(
        d,
        "fi.toml",
        "name = \"fi\"\n[output_filter]\ninternal_rate_hz = 400\nkind = \"moving_average\"\ntaps = 4\n",
    );
    let timed = write(
        d,
        "ti.toml",
        "name = \"ti\"\n[timing]\nclock_offset = \"100 ppm\"\nlatency = \"1 ms\"\n",
    );
    let axes = [[1.0, 0.0, 0.0], [0.0, 0.6, 0.8], [0.0, 1.0, 0.0]];
    let mut skew = String::from("[[imu]]\nname = \"s\"\nrate_hz = 100.0\n");
    for a in axes {
        skew += &format!("[[imu.gyro]]\naxis = {a:?}\n");
    }
    let text = format!(
        "[trajectory]\nscene = \"circle\"\n[trajectory.params]\nroll_osc_deg = 5.0\nroll_osc_hz = 1.0\n\
         [output]\nduration_s = 3.0\n\
         [[imu]]\nname = \"arm\"\n{place}\
         [[imu]]\nname = \"farm\"\nmodel = \"{}\"\n{place}\
         [[imu]]\nname = \"tarm\"\nmodel = \"{}\"\n{place}{skew}",
        filt.display(),
        timed.display()
    );
    let rig = build_rig(&write(d, "rig.toml", &text), 1);
    let motion = rig.motion().clone();
    assert!(rig.units()[1].has_own_producer() && rig.units()[2].has_own_producer());
    let mut s = rig.stream().with_truth(&[true; 4]).triggered();
    let origin = s.origin();
    let iv = intervals(150);
    let mut parts = vec![Part::default(); s.streams()];
    let mut text: Vec<String> = vec![String::new(); 8];
    let mut emitted: Vec<Vec<i64>> = vec![Vec::new(); 8];
    for (i, &(lo, hi)) in iv.iter().enumerate() {
        s.edge(lo, hi);
        // Now and then several edges at once, as a driver that woke late hands them over.
        if i % 3 == 2 || i + 1 == iv.len() {
            parts.iter_mut().for_each(Part::clear);
            s.fill(Until::ALL, &mut parts).unwrap();
            for ((p, t), e) in parts.iter().zip(text.iter_mut()).zip(emitted.iter_mut()) {
                t.push_str(std::str::from_utf8(&p.bytes).unwrap());
                e.extend_from_slice(&p.emit_ns);
            }
        }
    }
    // Every frame and truth row leaves at its closing edge.
    let at: Vec<i64> = iv.iter().map(|x| (x.1 * 1e9).round() as i64).collect();
    assert!(emitted.iter().all(|e| *e == at));
    let c = c_b_c(mount);
    let num = |line: &str| -> Vec<f64> { line.split(',').map(|x| x.parse().unwrap()).collect() };
    let rows_of = |t: &str| -> Vec<Vec<f64>> { t.lines().map(num).collect() };
    let main: Vec<Vec<Vec<f64>>> = text[..4].iter().map(|t| rows_of(t)).collect();
    let truth: Vec<Vec<Vec<f64>>> = text[4..].iter().map(|t| rows_of(t)).collect();
    let mut lever = 0.0f64;
    for (k, &(lo, hi)) in iv.iter().enumerate() {
        let span = hi - lo;
        let (w, f) = closed_form(&motion, origin + lo, origin + hi, Vec3::from(r));
        let (wc, fc) = (c * w, c * f);
        let want = [wc[0], wc[1], wc[2], fc[0], fc[1], fc[2]];
        let (_, f_nominal) = closed_form(&motion, origin + lo, origin + hi, Vec3::zeros());
        lever = lever.max((f - f_nominal).amax());
        for (u, rows) in main[..3].iter().enumerate() {
            let x = &rows[k];
            assert!(
                (x[0] - (origin + hi)).abs() < 1e-12,
                "unit {u} record {k}: t {}",
                x[0]
            );
            for j in 0..6 {
                assert!(
                    (x[1 + j] - want[j]).abs() < 1e-10,
                    "unit {u} record {k} column {}: {} vs {}",
                    1 + j,
                    x[1 + j],
                    want[j]
                );
                let inc = x[7 + j] / x[1 + j];
                assert!(
                    (inc - span).abs() < 1e-12,
                    "unit {u} record {k}: increment/rate {inc} vs {span}"
                );
            }
            // An ideal unit's truth is its output: exactly for the shared unit; to round-off
            // for the others, whose chains turn the lever arm into their axes first.
            let t = &truth[u][k];
            for j in 0..13 {
                let tol = if u == 0 { 0.0 } else { 1e-14 * 11.0 };
                assert!(
                    (t[j] - x[j]).abs() <= tol,
                    "unit {u} record {k} column {j}: truth {} vs {}",
                    t[j],
                    x[j]
                );
            }
            assert_eq!(t[13..], [x[0], x[0], x[0], 0.0], "unit {u} record {k}");
        }
        let sk = &main[3][k];
        for (i, a) in axes.iter().enumerate() {
            let a = Vec3::from(*a);
            let u = a * (1.0 / a.norm());
            assert!(
                (sk[1 + i] - u.dot(&w)).abs() < 1e-12,
                "skew record {k} gyro_{i}"
            );
            assert!(
                (sk[4 + i] / sk[1 + i] - span).abs() < 1e-12,
                "skew record {k}"
            );
        }
    }
    assert!(main.iter().all(|m| m.len() == iv.len()));
    assert!(lever > 0.5, "lever-arm terms {lever} m/s²");
}

/// Edges (ns) at the offsets (s) of `iv`'s bounds from an arbitrary monotonic origin, and
/// the intervals as the trigger computes them from those integer ns.
fn edges_of(iv: &[(f64, f64)]) -> (Vec<i128>, Vec<(f64, f64)>) {
    let mut ns = vec![7_000_000_000i128];
    ns.extend(
        iv.iter()
            .map(|&(_, hi)| 7_000_000_000 + (hi * 1e9).round() as i128),
    );
    let s: Vec<f64> = ns.iter().map(|x| (x - ns[0]) as f64 * 1e-9).collect();
    let pairs = s.windows(2).map(|w| (w[0], w[1])).collect();
    (ns, pairs)
}

/// A one-unit rig whose filtered unit samples on a trigger writes byte for byte what the
/// single IMU with that template and seed writes on the same edges (CSV records and KVH 1750
/// Format C frames, in the scene's temperature, vibration and magnetometer), and the single
/// IMU's truth with the edges as `tov`, `tov_accel` and `emit`.
#[test]
fn a_triggered_filtered_unit_is_the_triggered_single_imu() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (ns, iv) = edges_of(&intervals(60));
    for format in ["csv", "kvh1750-c"] {
        let one = write(
            d,
            "single.toml",
            &format!("{HEAD}[imu]\nmodel = \"{FILTERED}\"\nrate_hz = 204.8\n{ENVIRONMENT}"),
        );
        let sim = (Simulation::from_scene_file(&one).unwrap().seed(7))
            .format(format)
            .build()
            .unwrap();
        let span = 1.0;
        let mut p = sim.producer().unwrap();
        p.set_keep_truth(true);
        let mut p = p.with_trigger(Box::new(EdgeList::new(ns.clone(), span)));
        let (mut out, mut truth) = (p.preamble().into_bytes(), String::new());
        loop {
            let (mut buf, mut ends) = (Vec::new(), Vec::new());
            let Some(b) = p.next_block(64, &mut buf, &mut ends) else {
                break;
            };
            let mut side = Vec::new();
            imu_emu::output::encode_truth(
                imu_emu::output::Format::Csv,
                b.truth,
                b.times.as_ref(),
                None,
                &mut side,
            );
            truth.push_str(std::str::from_utf8(&side).unwrap());
            out.extend(buf);
        }
        assert!(p.take_error().is_none());
        let unit = format!(
            "[[imu]]\nname = \"f\"\nmodel = \"{FILTERED}\"\nrate_hz = 204.8\nseed = 7\nformat = \"{format}\"\n"
        );
        let rig = build_rig(
            &write(d, "rig.toml", &format!("{HEAD}{unit}{ENVIRONMENT}")),
            7,
        );
        let mut s = rig.stream().with_truth(&[true]).triggered();
        let pre = s.preambles();
        let mut parts = vec![Part::default(); 2];
        for &(lo, hi) in &iv {
            s.edge(lo, hi);
        }
        s.fill(Until::ALL, &mut parts).unwrap();
        assert_eq!(parts[0].ends.len(), iv.len());
        assert!(
            [&pre[0][..], &parts[0].bytes].concat() == out,
            "{format}: the rig unit's bytes differ"
        );
        let rig_truth = String::from_utf8(parts[1].bytes.clone()).unwrap();
        let rig_truth: Vec<&str> = rig_truth.lines().map(drop_failed).collect();
        assert_eq!(rig_truth, truth.lines().collect::<Vec<_>>(), "{format}");
    }
}

/// A model from TOML text.
fn model(text: &str) -> imu_emu::errors::ImuModel {
    template::parse(text, Path::new("t.toml")).unwrap()
}

/// The output filter of these tests: a 4-tap moving average, 400 → 100 Hz.
const AVERAGER: &str =
    "[output_filter]\ninternal_rate_hz = 400\nkind = \"moving_average\"\ntaps = 4\n";

/// A producer of `m` (seed 5) on `scene` at 100 Hz over 45 s, sampling at `edges`.
fn triggered(scene: &str, m: imu_emu::errors::ImuModel, edges: &[i128]) -> Vec<Record> {
    let p = Simulation::builder()
        .scene(scene)
        .imu_model(m)
        .rate(100.0)
        .duration(45.0)
        .seed(5)
        .build()
        .unwrap()
        .producer()
        .unwrap();
    drain(p.with_trigger(Box::new(EdgeList::new(edges.to_vec(), 45.0))))
}

/// Every record of a producer.
fn drain(mut p: Producer) -> Vec<Record> {
    let mut recs = Vec::new();
    while let Some(b) = p.next_records(256) {
        recs.extend_from_slice(b.records);
    }
    assert!(p.take_error().is_none());
    recs
}

/// Edges alternating 2 ms and 8 ms apart, `pairs` of each (ns), and the intervals (s).
fn alternating(pairs: usize) -> (Vec<i128>, Vec<f64>) {
    let mut ns = vec![7_000_000_000i128];
    for i in 0..2 * pairs {
        let step = if i % 2 == 0 { 2_000_000 } else { 8_000_000 };
        ns.push(ns[i] + step);
    }
    let iv = ns.windows(2).map(|w| (w[1] - w[0]) as f64 * 1e-9).collect();
    (ns, iv)
}

/// A unit with an output filter on a trigger takes, as KVH's units under external sync, the
/// uniform average over the interval between edges: standing still (constant Earth rate and
/// gravity), each record's increments are the rates times its own interval (2 or 8 ms, where
/// the unit's own filter would give 10 ms worth) and its rates the constant ones, to 1e-12;
/// on the circle, the ideal filtered unit's records are the exact interval means an ideal
/// unit without a filter takes over the same edges, to 1e-12 of their scale.
#[test]
fn a_filtered_unit_on_a_trigger_gives_the_interval_means() {
    let (edges, iv) = alternating(50);
    let plain = triggered("static", model("name = \"i\"\n"), &edges[..3]);
    let (w, f) = (plain[0].gyro, plain[0].accel);
    let recs = triggered(
        "static",
        model(&format!("name = \"fi\"\n{AVERAGER}")),
        &edges,
    );
    assert_eq!(recs.len(), iv.len());
    for (k, (r, t)) in recs.iter().zip(&iv).enumerate() {
        for j in 0..3 {
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1e-6);
            assert!(
                close(r.gyro[j], w[j]) && close(r.accel[j], f[j]),
                "record {k} axis {j}"
            );
            assert!(
                close(r.dtheta[j], w[j] * t) && close(r.dv[j], f[j] * t),
                "record {k} axis {j}"
            );
        }
    }
    let ideal = triggered("circle", model("name = \"i\"\n"), &edges);
    let filtered = triggered(
        "circle",
        model(&format!("name = \"fi\"\n{AVERAGER}")),
        &edges,
    );
    for (k, (a, b)) in filtered.iter().zip(&ideal).enumerate() {
        let scale = b.accel.amax();
        assert!((a.gyro - b.gyro).amax() <= 1e-12 * scale, "record {k}");
        assert!((a.accel - b.accel).amax() <= 1e-12 * scale, "record {k}");
        assert!((a.dv - b.dv).amax() <= 1e-12 * scale, "record {k}");
    }
}

/// 2000 samples per class and axis, three axes: the mean of 6000 squared N(0, v) draws
/// estimates v with relative standard deviation √(2/6000) = 1.83 %, so 4σ is 7.3 % (a fixed
/// seed: the test is deterministic; the bound says how far a correct unit can stray).
const TOL: f64 = 4.0 * 0.018_257_418_583_505_54;

/// A filtered unit's white noise on a trigger averages over each interval T: its increment
/// errors have variance N²·T (its rate errors σ = N/√T) for each of the 2 ms and 8 ms
/// intervals, within [`TOL`]. The unit's filter run at its internal rate would instead give
/// the 10 ms output interval's figure for both (5× and 1.25× off), and internal samples
/// taken without averaging 20 × N²·T (400 Hz, 2.5 ms apart).
#[test]
fn a_filtered_units_noise_on_a_trigger_scales_with_the_interval() {
    let n = [2e-3, 3e-2]; // rad/√s, m/s/√s
    let mut m = model(&format!("name = \"fn\"\n{AVERAGER}"));
    m.gyro.noise = [n[0]; 3];
    m.accel.noise = [n[1]; 3];
    let (edges, iv) = alternating(2000);
    let (x, ideal) = (
        triggered("static", m, &edges),
        triggered(
            "static",
            model(&format!("name = \"fi\"\n{AVERAGER}")),
            &edges,
        ),
    );
    let errors: Vec<[[f64; 3]; 2]> = (x.iter().zip(&ideal))
        .map(|(a, b)| [0, 1, 2].map(|j| (a.dtheta[j] - b.dtheta[j], a.dv[j] - b.dv[j])))
        .map(|e| [e.map(|x| x.0), e.map(|x| x.1)])
        .collect();
    for (c, t) in iv[..2].iter().enumerate() {
        let picked: Vec<_> = errors.iter().skip(c).step_by(2).collect();
        let count = (3 * picked.len()) as f64;
        for s in 0..2 {
            let ms = picked.iter().flat_map(|r| r[s]).map(|v| v * v).sum::<f64>() / count;
            let ratio = ms / (n[s] * n[s] * t);
            assert!(
                (ratio - 1.0).abs() < TOL,
                "class {c} ({t} s) sensor {s}: {ratio}"
            );
        }
    }
}

/// The stream of a triggered rig's unit is the RigStream of its rig (a compile-time check of
/// the public path the drivers use).
#[allow(dead_code)]
fn stream_type(r: Rig) -> RigStream {
    r.stream().triggered()
}

/// The gravitation across a lever arm, end to end: an error-free unit 1.5 m below the
/// reference point of a body at rest (level, so body z is down) reads what an error-free IMU
/// at rest 1.5 m lower reads, built independently from a second trajectory at that height —
/// to 2.5e-12 m/s²: the gradient is linear, and γ's h² term (3γ/a²·h²) leaves
/// 3·9.8·1.5²/a² = 1.6e-12 (measured 1.62e-12), the other second-order terms
/// (r/R)²·g ≈ 5e-13 and the engine's round-off a few 1e-15. It reads (∂γ/∂h)·1.5 ≈ −4.6e-6 m/s² more along z than the reference unit, so
/// leaving the gradient out would miss by 4.6e-6; the gyros are the same everywhere.
#[test]
fn a_unit_below_the_reference_reads_the_gravity_there() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let trajectory = |name: &str, h: f64| {
        let mut text = String::from("t,lat,lon,h,vn,ve,vd,roll,pitch,yaw\n");
        for i in 0..=40 {
            text += &format!("{},41.0,-3.0,{h},0,0,0,0,0,0\n", i as f64 * 0.25);
        }
        write(d, name, &text)
    };
    let high = trajectory("high.csv", 650.0);
    let low = trajectory("low.csv", 648.5);
    let head = |t: &Path| {
        format!(
            "[trajectory]\nfile = \"{}\"\n[output]\nduration_s = 2.0\n",
            t.display()
        )
    };
    let units = "[[imu]]\nname = \"ref\"\nmodel = \"ideal\"\nrate_hz = 100.0\nformat = \"csv\"\n\
                 [[imu]]\nname = \"low\"\nmodel = \"ideal\"\nrate_hz = 100.0\nformat = \"csv\"\n\
                 lever_arm_m = [0.0, 0.0, 1.5]\n";
    let r = rig(&write(d, "rig.toml", &format!("{}{units}", head(&high))), 1);
    let one = format!("{}[imu]\nmodel = \"ideal\"\nrate_hz = 100.0\n", head(&low));
    let (there, _) = single(&write(d, "one.toml", &one), 1, "csv");
    let (reference, below, there) = (
        rows(&String::from_utf8(r[0].0.clone()).unwrap()),
        rows(&String::from_utf8(r[1].0.clone()).unwrap()),
        rows(&String::from_utf8(there).unwrap()),
    );
    assert_eq!(below.len(), 200);
    assert_eq!(there.len(), 200);
    for ((a, b), c) in below.iter().zip(&there).zip(&reference) {
        for i in 1..7 {
            assert!(
                (a[i] - b[i]).abs() < 2.5e-12,
                "column {i}: {} vs {}",
                a[i],
                b[i]
            );
        }
        assert!(
            (a[6] - c[6]) < -4.5e-6 && (a[6] - c[6]) > -4.7e-6,
            "{a:?} {c:?}"
        );
    }
}
