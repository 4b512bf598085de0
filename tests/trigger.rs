//! The external sample trigger through the library, with edges given up front (no wall
//! clock): one record per edge after the first, each integrating over the interval since the
//! previous edge.

use imu_emu::engine::trigger::EdgeList;
use imu_emu::engine::{EngineError, Producer};
use imu_emu::record::Record;
use imu_emu::sim::Simulation;

/// An ideal IMU on `scene` at 100 Hz for 2 s.
fn producer(scene: &str) -> Producer {
    Simulation::builder()
        .scene(scene)
        .rate(100.0)
        .duration(2.0)
        .build()
        .unwrap()
        .producer()
        .unwrap()
}

/// Every record a producer gives, with the run's error.
fn drain(mut p: Producer) -> (Vec<Record>, Vec<f64>, Option<EngineError>) {
    let (mut recs, mut tov) = (Vec::new(), Vec::new());
    while let Some(b) = p.next_records(64) {
        recs.extend_from_slice(b.records);
        if let Some(t) = b.times {
            tov.extend_from_slice(t.tov);
        }
    }
    (recs, tov, p.take_error())
}

/// Edges (ns) at the given offsets (s) from an arbitrary monotonic origin.
fn edges(at: &[f64]) -> Vec<i128> {
    at.iter()
        .map(|s| 7_000_000_000 + (s * 1e9).round() as i128)
        .collect()
}

/// Standing still the rates are constant, so each record's increments are the rate times its
/// own interval — whatever the interval; the time of validity is the edge. Sampling on the
/// nominal grid instead gives 10 ms increments for every record.
#[test]
fn one_record_per_edge_over_its_interval() {
    let (nominal, _, _) = drain(producer("static"));
    let (w, f) = (nominal[0].gyro, nominal[0].accel);
    let at = [0.0, 0.0031, 0.0197, 0.2804, 0.281, 1.5, 1.99];
    let e = edges(&at);
    // The instants as the trigger computes them from the integer ns.
    let at: Vec<f64> = e.iter().map(|x| (x - e[0]) as f64 * 1e-9).collect();
    let p = producer("static").with_trigger(Box::new(EdgeList::new(e, 2.0)));
    let (recs, tov, err) = drain(p);
    assert!(err.is_none(), "{err:?}");
    assert_eq!((recs.len(), tov.len()), (at.len() - 1, at.len() - 1));
    for (i, r) in recs.iter().enumerate() {
        let h = at[i + 1] - at[i];
        for j in 0..3 {
            let tol = |x: f64| 4.0 * f64::EPSILON * x.abs() + 1e-300;
            assert!(
                (r.dtheta[j] - w[j] * h).abs() <= tol(w[j] * h),
                "{i} gyro {j}"
            );
            assert!((r.dv[j] - f[j] * h).abs() <= tol(f[j] * h), "{i} accel {j}");
        }
        assert!((tov[i] - at[i + 1]).abs() < 1e-15, "{i}: {}", tov[i]);
    }
}

/// On the circle, edges exactly on the nominal grid reproduce the nominal records' increments,
/// and splitting every interval at an irregular point gives two records whose increments sum
/// to the whole interval's (the integral is additive), both to round-off.
#[test]
fn grid_edges_and_split_intervals_on_the_circle() {
    let (nominal, _, _) = drain(producer("circle"));
    let grid: Vec<f64> = (0..=50).map(|k| k as f64 / 100.0).collect();
    let p = producer("circle").with_trigger(Box::new(EdgeList::new(edges(&grid), 2.0)));
    let (whole, _, err) = drain(p);
    assert!(err.is_none());
    assert_eq!(whole.len(), 50);
    let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-12 * scale;
    for (i, (t, n)) in whole.iter().zip(&nominal).enumerate() {
        for j in 0..3 {
            let (sg, sa) = (n.dtheta.norm(), n.dv.norm());
            assert!(close(t.dtheta[j], n.dtheta[j], sg), "{i} gyro {j}");
            assert!(close(t.dv[j], n.dv[j], sa), "{i} accel {j}");
        }
    }
    let mut split = Vec::new();
    for (k, g) in grid[..50].iter().enumerate() {
        split.push(*g);
        split.push(g + 0.0037 + 0.0001 * (k % 7) as f64);
    }
    split.push(grid[50]);
    let p = producer("circle").with_trigger(Box::new(EdgeList::new(edges(&split), 2.0)));
    let (halves, _, _) = drain(p);
    assert_eq!(halves.len(), 100);
    for (i, w) in whole.iter().enumerate() {
        let (a, b) = (&halves[2 * i], &halves[2 * i + 1]);
        for j in 0..3 {
            assert!(
                close(a.dtheta[j] + b.dtheta[j], w.dtheta[j], w.dtheta.norm()),
                "{i} gyro {j}"
            );
            assert!(
                close(a.dv[j] + b.dv[j], w.dv[j], w.dv.norm()),
                "{i} accel {j}"
            );
        }
    }
}

/// An edge past the end of the motion stops the run with an error naming the edge, after the
/// records before it.
#[test]
fn edge_past_the_motion_is_an_error() {
    let p = producer("static").with_trigger(Box::new(EdgeList::new(edges(&[0.0, 0.5, 2.5]), 2.0)));
    let (recs, _, err) = drain(p);
    assert_eq!(recs.len(), 1);
    let e = err.expect("an error").to_string();
    assert!(e.contains("edge 3") && e.contains("past the end"), "{e}");
}

/// A producer on the static scene at 100 Hz, long enough for 4000 triggered records (the
/// run stops after the grid's count), with `model` and seed 5.
fn model_producer(model: imu_emu::errors::ImuModel) -> Producer {
    Simulation::builder()
        .scene("static")
        .imu_model(model)
        .rate(100.0)
        .duration(45.0)
        .seed(5)
        .build()
        .unwrap()
        .producer()
        .unwrap()
}

/// A model with no error terms, to set fields of in SI units.
fn blank() -> imu_emu::errors::ImuModel {
    imu_emu::errors::template::parse("name = \"t\"\n", std::path::Path::new("t.toml")).unwrap()
}

/// Edges alternating 2 ms and 8 ms apart, `pairs` of each, and the intervals (s).
fn alternating(pairs: usize) -> (Vec<i128>, Vec<f64>) {
    let mut ns = vec![7_000_000_000i128];
    for i in 0..2 * pairs {
        let step = if i % 2 == 0 { 2_000_000 } else { 8_000_000 };
        ns.push(ns[i] + step);
    }
    let iv = ns.windows(2).map(|w| (w[1] - w[0]) as f64 * 1e-9).collect();
    (ns, iv)
}

/// Each triggered record's injected error (record − ideal record over the same edges):
/// gyro and accelerometer increments.
fn increment_errors(model: imu_emu::errors::ImuModel, edges: &[i128]) -> Vec<[[f64; 3]; 2]> {
    let span = 45.0;
    let run = |p: Producer| {
        let p = p.with_trigger(Box::new(EdgeList::new(edges.to_vec(), span)));
        let (recs, _, err) = drain(p);
        assert!(err.is_none(), "{err:?}");
        assert_eq!(recs.len(), edges.len() - 1);
        recs
    };
    let (noisy, ideal) = (run(model_producer(model)), run(model_producer(blank())));
    noisy
        .iter()
        .zip(&ideal)
        .map(|(n, i)| {
            let d = |a: imu_emu::math::Vec3, b: imu_emu::math::Vec3| [0, 1, 2].map(|j| a[j] - b[j]);
            [d(n.dtheta, i.dtheta), d(n.dv, i.dv)]
        })
        .collect()
}

/// Mean over the three axes and the records of interval class `c` (0: 2 ms, 1: 8 ms) of
/// `x(record)²`, per sensor.
fn class_mean_square(x: &[[[f64; 3]; 2]], c: usize) -> [f64; 2] {
    let picked: Vec<_> = x.iter().skip(c).step_by(2).collect();
    let n = (3 * picked.len()) as f64;
    [0, 1].map(|s| picked.iter().flat_map(|r| r[s]).map(|v| v * v).sum::<f64>() / n)
}

/// 2000 samples per class and axis, three axes: the mean of 6000 squared N(0, v) draws
/// estimates v with relative standard deviation √(2/6000) = 1.83 %, so 4σ is 7.3 %. A unit
/// that scales its errors for the nominal 10 ms instead would be off by 5× (2 ms) and 1.25×
/// (8 ms).
const PAIRS: usize = 2000;
const TOL: f64 = 4.0 * 0.018_257_418_583_505_54;

/// Triggered at intervals alternating 2 ms and 8 ms, white noise of density N gives
/// increment errors of variance N²·T for each interval class T (σ ∝ √T), not N²·Δt_nominal.
#[test]
fn white_noise_over_the_actual_interval() {
    let mut m = blank();
    let n = [2e-3, 3e-2]; // rad/√s, m/s/√s
    m.gyro.noise = [n[0]; 3];
    m.accel.noise = [n[1]; 3];
    let (edges, iv) = alternating(PAIRS);
    let e = increment_errors(m, &edges);
    for (c, t) in iv[..2].iter().enumerate() {
        let ms = class_mean_square(&e, c);
        for s in 0..2 {
            let ratio = ms[s] / (n[s] * n[s] * t);
            assert!((ratio - 1.0).abs() < TOL, "class {c} sensor {s}: {ratio}");
        }
    }
}

/// A bias random walk of density K steps by N(0, K²·T) over each interval T: the rate error
/// e/T of consecutive records differs by that step, so its variance per class of the
/// closing interval is K²·T.
#[test]
fn random_walk_over_the_actual_interval() {
    let mut m = blank();
    let k = [1e-2, 1e-1]; // rad/s/√s, m/s²/√s
    m.gyro.random_walk = [k[0]; 3];
    m.accel.random_walk = [k[1]; 3];
    let (edges, iv) = alternating(PAIRS);
    let e = increment_errors(m, &edges);
    let rate: Vec<[[f64; 3]; 2]> = e
        .iter()
        .zip(iv.iter().cycle())
        .map(|(r, t)| r.map(|a| a.map(|v| v / t)))
        .collect();
    // Step i (closing interval i) for i ≥ 1; the first record's step comes from 0.
    let mut steps = vec![rate[0]];
    steps.extend(
        rate.windows(2)
            .map(|w| [0, 1].map(|s| [0, 1, 2].map(|j| w[1][s][j] - w[0][s][j]))),
    );
    for (c, t) in iv[..2].iter().enumerate() {
        let ms = class_mean_square(&steps, c);
        for s in 0..2 {
            let ratio = ms[s] / (k[s] * k[s] * t);
            assert!((ratio - 1.0).abs() < TOL, "class {c} sensor {s}: {ratio}");
        }
    }
}

/// A constant bias b and a ramp R add (b + R·(s + T/2))·T to the increment of a record over
/// (s, s + T] after the first edge — the exact integral, to round-off.
#[test]
fn bias_and_ramp_over_the_actual_interval() {
    let mut m = blank();
    let (b, r) = ([0.02, -0.5], [1e-3, 2e-2]); // rad/s, m/s²; per second
    m.gyro.bias = [b[0]; 3];
    m.accel.bias = [b[1]; 3];
    m.gyro.ramp = [r[0]; 3];
    m.accel.ramp = [r[1]; 3];
    let (edges, iv) = alternating(200);
    let e = increment_errors(m, &edges);
    let mut start = 0.0;
    for (i, (x, t)) in e.iter().zip(iv.iter().cycle()).enumerate() {
        for s in 0..2 {
            let want = (b[s] + r[s] * (start + 0.5 * t)) * t;
            // The error is a difference of increments of up to ~0.1 (gravity over 8 ms).
            for v in x[s] {
                assert!((v - want).abs() < 1e-15, "{i} sensor {s}: {v} vs {want}");
            }
        }
        start += t;
    }
}
