//! The Allan variance of a random vibration as recorded samples carry it: the table's PSD
//! through the interval mean at the generator's step and the output filter, integrated against
//! the Allan kernel 2 sin⁴(πfτ)/(m sin πfΔt)² (one-sided PSD). Pure math, a known term of an
//! axis's fit (`super::output::OutputStage`) that `super::resonance` fills.

use std::f64::consts::PI;

use crate::errors::output_filter::FilterSpec;

/// The squared gain from a vibration table to the recorded samples: the interval mean at the
/// generator's step (the filter's internal step when there is one), then the filter.
pub fn gain2(f: f64, dt: f64, filter: Option<&FilterSpec>) -> f64 {
    let sinc = |x: f64| if x == 0.0 { 1.0 } else { x.sin() / x };
    match filter {
        None => sinc(PI * f * dt).powi(2),
        Some(s) => (sinc(PI * f / s.internal_rate_hz) * s.magnitude(f)).powi(2),
    }
}

/// The Allan variance of a random vibration as the recorded samples carry it: a known term of
/// an axis's fit ([`super::output::OutputStage`]).
#[derive(Clone, Debug, PartialEq)]
pub struct KnownVibration {
    /// The table as written (f in Hz, unit²/Hz).
    pub table: Vec<(f64, f64)>,
    /// Output interval Δt (s).
    pub dt: f64,
    /// The squared gain at the pieces' nodes is interpolated from this grid over the table
    /// (uniform; |H|² and sinc² vary over tens of Hz, the grid step is 1/1024 of the table).
    gain: Vec<f64>,
    /// σ² at the cluster sizes given when built.
    cache: Vec<(usize, f64)>,
}

/// Nodes and weights of 8-point Gauss–Legendre quadrature on [−1, 1].
const GAUSS8: [(f64, f64); 4] = [
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
    (0.960_289_856_497_536_2, 0.101_228_536_290_376_3),
];

/// Quadrature pieces per period 1/τ of the kernel sin⁴(πfτ) = (3 − 4cos 2πfτ + cos 4πfτ)/8: its
/// fastest part then spans one period per piece, which 8-point Gauss–Legendre takes to 1e-9
/// (the unit test checks it against 16 times as many pieces; 8 per period, 4× the work, are
/// no closer).
const PIECES_PER_PERIOD: f64 = 2.0;

/// Grid points of the tabulated gain.
const GAIN_GRID: usize = 1024;

impl KnownVibration {
    /// The vibration of table `table` (at least two rows) on samples at interval Δt shaped by
    /// `filter`, its σ² computed at the cluster sizes `ms`.
    pub fn new(
        table: Vec<(f64, f64)>,
        dt: f64,
        filter: Option<&FilterSpec>,
        ms: &[usize],
    ) -> KnownVibration {
        let (a, b) = (table[0].0, table[table.len() - 1].0);
        let gain = (0..=GAIN_GRID)
            .map(|i| gain2(a + (b - a) * i as f64 / GAIN_GRID as f64, dt, filter))
            .collect();
        let mut v = KnownVibration {
            table,
            dt,
            gain,
            cache: Vec::new(),
        };
        v.cache = ms.iter().map(|&m| (m, v.integrate(m))).collect();
        v
    }

    /// σ² at cluster size m.
    pub fn avar(&self, m: usize) -> f64 {
        match self.cache.iter().find(|c| c.0 == m) {
            Some(c) => c.1,
            None => self.integrate(m),
        }
    }

    /// The long-τ limit of σ² at cluster size m: the kernel's sin⁴(πfτ) replaced by its mean
    /// 3/8. What that leaves out, ∫G·(cos 4πfτ − 4 cos 2πfτ) df/(4m²) with G = P/sin²(πfΔt),
    /// is at most (9/(16πτm²))·V by parts (V: G's values at the table's ends plus its total
    /// variation), 3V/(4πτ∫G) of the limit: 3/(2πτw) for a table of width w across which G
    /// varies little (a search's narrow cell, [`super::resonance_adev`]).
    pub fn avar_long(&self, m: usize) -> f64 {
        let x = PI * self.dt;
        let mf = m as f64;
        let mut total = 0.0;
        for w in self.table.windows(2) {
            let (a, b) = (w[0], w[1]);
            let slope = (b.1 / a.1).ln() / (b.0 / a.0).ln();
            let (mid, half) = (0.5 * (a.0 + b.0), 0.5 * (b.0 - a.0));
            for &(u, wt) in &GAUSS8 {
                for f in [mid - half * u, mid + half * u] {
                    let d = mf * (x * f).sin();
                    total += half * wt * self.psd(f, a, slope) * 0.75 / (d * d);
                }
            }
        }
        total
    }

    /// The recorded samples' PSD at f inside the table: S(f) (log-log on the row pair a, b)
    /// times the squared gain.
    fn psd(&self, f: f64, a: (f64, f64), slope: f64) -> f64 {
        // A flat piece (a step of a table fitted to an Allan deviation, flat to round-off
        // once divided by the gain) needs no power: a slope of 1e-9 moves S by less than
        // 1e-9·ln(b/a), below the quadrature's own error.
        let s = if slope.abs() <= 1e-9 {
            a.1
        } else {
            a.1 * (f / a.0).powf(slope)
        };
        let (lo, hi) = (self.table[0].0, self.table[self.table.len() - 1].0);
        let x = ((f - lo) / (hi - lo) * GAIN_GRID as f64).clamp(0.0, GAIN_GRID as f64);
        let i = (x.floor() as usize).min(GAIN_GRID - 1);
        let t = x - i as f64;
        s * (self.gain[i] * (1.0 - t) + self.gain[i + 1] * t)
    }

    fn integrate(&self, m: usize) -> f64 {
        self.integrate_with(m, PIECES_PER_PERIOD)
    }

    /// σ² at cluster size m with `per_period` quadrature pieces per period 1/τ of the kernel.
    fn integrate_with(&self, m: usize, per_period: f64) -> f64 {
        let dt = self.dt;
        let tau = m as f64 * dt;
        let mf = m as f64;
        let mut total = 0.0;
        for w in self.table.windows(2) {
            let (a, b) = (w[0], w[1]);
            // log-log between the rows: S = a.1·(f/a.0)^slope.
            let slope = (b.1 / a.1).ln() / (b.0 / a.0).ln();
            let pieces = ((per_period * (b.0 - a.0) * tau).ceil() as usize).max(1);
            let h = (b.0 - a.0) / pieces as f64;
            // The nodes sit at the same offsets d from every piece's middle: sin(πfτ) and
            // sin(πfΔt) at mid ± d by the angle-addition rule, the middle's angles turned by
            // one piece at a time and set afresh every ANCHOR pieces (rounding stays ~1e-14).
            let nodes = GAUSS8.map(|(x, wt)| {
                let d = 0.5 * h * x;
                ((PI * tau * d).sin_cos(), (PI * dt * d).sin_cos(), d, wt)
            });
            let (turn_t, turn_d) = ((PI * tau * h).sin_cos(), (PI * dt * h).sin_cos());
            let (mut at, mut ad) = ((0.0, 1.0), (0.0, 1.0));
            for p in 0..pieces {
                let mid = a.0 + (p as f64 + 0.5) * h;
                if p % ANCHOR == 0 {
                    at = (PI * tau * mid).sin_cos();
                    ad = (PI * dt * mid).sin_cos();
                } else {
                    at = turn(at, turn_t);
                    ad = turn(ad, turn_d);
                }
                for &(bt, bd, d, wt) in &nodes {
                    for sign in [-1.0, 1.0] {
                        // sin(A ± B) = sin A cos B ± cos A sin B.
                        let num = at.0 * bt.1 + sign * at.1 * bt.0;
                        let den = mf * (ad.0 * bd.1 + sign * ad.1 * bd.0);
                        let n2 = num * num;
                        total +=
                            h * wt * self.psd(mid + sign * d, a, slope) * n2 * n2 / (den * den);
                    }
                }
            }
        }
        total
    }
}

/// Pieces between fresh evaluations of the middle's angles in the quadrature.
const ANCHOR: usize = 64;

/// (sin, cos) of A + δ from those of A and δ.
fn turn((s, c): (f64, f64), (sd, cd): (f64, f64)) -> (f64, f64) {
    (s * cd + c * sd, c * cd - s * sd)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::errors::output_filter::FilterKind;

    /// The quadrature has converged at [`PIECES_PER_PERIOD`]: sixteen times as many pieces
    /// change σ² by less than 1e-9 at every octave to m = 2^17 (a 20 Hz bump 10 Hz wide, bare
    /// and under a CIC at 4× the output rate). What is left, up to 6e-10 at m ≤ 1024, is the
    /// table's log-log shape over a piece that spans a whole row pair at short τ; 8 pieces per
    /// period leave the same (0.5 per period fail it from m = 32, by 6e-8).
    #[test]
    fn the_quadrature_has_converged() {
        let table = vec![
            (15.0, 1e-6),
            (18.0, 8e-6),
            (20.0, 1e-5),
            (22.0, 8e-6),
            (25.0, 1e-6),
        ];
        let cic = FilterSpec {
            internal_rate_hz: 400.0,
            kind: FilterKind::Cic { order: 2, taps: 4 },
            accel: None,
        };
        for filter in [None, Some(&cic)] {
            let v = KnownVibration::new(table.clone(), 0.01, filter, &[]);
            for j in 0..18 {
                let m = 1usize << j;
                let (got, fine) = (
                    v.integrate(m),
                    v.integrate_with(m, 16.0 * PIECES_PER_PERIOD),
                );
                assert!(
                    (got / fine - 1.0).abs() < 1e-9,
                    "m {m}: {got:e} vs {fine:e}"
                );
            }
        }
    }

    /// The long-τ limit stays within its bound 3/(2πτw) of the exact σ² for a flat cell
    /// (20–20.74 Hz, under the CIC of 4 taps at 400 Hz) from τw = 5 to 5000, and the bound is
    /// not loose by more than a factor 50 at τw = 50 (so it says what the limit costs).
    #[test]
    fn the_long_tau_limit_keeps_its_bound() {
        let cic = FilterSpec {
            internal_rate_hz: 400.0,
            kind: FilterKind::Cic { order: 2, taps: 4 },
            accel: None,
        };
        let (a, b) = (20.0, 20.0 * 10f64.powf(1.0 / 64.0));
        let v = KnownVibration::new(vec![(a, 1.0), (b, 1.0)], 0.01, Some(&cic), &[]);
        for tw in [5.0, 50.0, 500.0, 5000.0] {
            let m = (tw / ((b - a) * 0.01)).round() as usize;
            let tau = m as f64 * 0.01;
            let bound = 3.0 / (2.0 * PI * tau * (b - a));
            let off = (v.avar_long(m) / v.integrate(m) - 1.0).abs();
            assert!(off <= bound, "τw {tw}: {off:e} > {bound:e}");
            if tw == 50.0 {
                assert!(off > bound / 50.0, "τw {tw}: {off:e} ≪ {bound:e}");
            }
        }
    }
}
