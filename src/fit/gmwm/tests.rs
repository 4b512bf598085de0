use super::*;

fn exact_points(model: &Model, octaves: usize) -> Vec<AdevPoint> {
    (0..octaves)
        .map(|j| {
            let m = 1usize << j;
            let adev = model.avar(m).sqrt();
            AdevPoint {
                m,
                tau: m as f64 * model.dt,
                adev,
                terms: 1,
                edf: 1.0,
                lo: adev,
                hi: adev,
            }
        })
        .collect()
}

/// An exact model curve on the search grids is recovered to round-off, every component
/// at once, and the intervals contain the values. Each component holds a good share of
/// σ² somewhere (white noise below 1 s, the Gauss–Markov bump near 6 s, the floor from 10
/// to 1000 s, the random walk beyond), so the exact answer is the only one of zero χ².
#[test]
fn recovers_an_exact_curve_with_every_component() {
    let dt = 0.01;
    let truth = Model {
        c: [1e-11, 1e-8, 1e-8, 4.4e-12, 0.0, 1e-8],
        band: (10.0, 1000.0),
        gm_tau: 10f64.powf(0.5),
        dt,
        output: OutputStage::default(),
    };
    let f = fit_axis(&exact_points(&truth, 22), 1 << 23, dt).unwrap();
    assert!(
        (f.model.band.0 / 10.0 - 1.0).abs() < 1e-12,
        "{:?}",
        f.model.band
    );
    assert!(
        (f.model.band.1 / 1000.0 - 1.0).abs() < 1e-12,
        "{:?}",
        f.model.band
    );
    assert!((f.model.gm_tau / truth.gm_tau - 1.0).abs() < 1e-12);
    for k in COMPONENTS {
        let (got, want) = (f.model.c[k as usize], truth.c[k as usize]);
        if want == 0.0 {
            assert!(f.estimate(k).is_none(), "{k:?}: {got:e}");
            continue;
        }
        assert!(
            (got / want - 1.0).abs() < 1e-6,
            "{k:?}: {got:e} vs {want:e}"
        );
        let e = f.estimate(k).unwrap();
        assert!(e.lo < e.value && e.value < e.hi, "{k:?} {e:?}");
    }
    assert!(f.chi2 < 1e-6, "{}", f.chi2);
}
