//! The external sample trigger through the library, with edges given up front (no wall
//! clock): one record per edge after the first, each integrating over the interval since the
//! previous edge.

use imu_emu::job::{JobError, Producer};
use imu_emu::record::Record;
use imu_emu::sim::Simulation;
use imu_emu::timing::trigger::EdgeList;

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
fn drain(mut p: Producer) -> (Vec<Record>, Vec<f64>, Option<JobError>) {
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
