//! Monte Carlo comparison of IMU templates (`imu-emu compare`): for each template, N runs with
//! independent seeds, each generating the scene's records block by block, corrupting them
//! with the template's error chain and navigating them free-inertially from the true state —
//! over the whole span, or over consecutive GNSS outages of a given length (the navigator is
//! reset to the truth at each outage start; its IMU history is kept). Errors are sampled along
//! each outage, so the result gives both the end-of-outage statistics and the error growth.
//! Runs are spread over threads; the result does not depend on the thread count.

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::closure::CloseError;
use super::strapdown::{NavState, Navigator, Settings, StateError};
use crate::engine::{BLOCK, Grid, Producer};
use crate::errors::template::ImuModel;
use crate::motion::Motion;
use crate::rng::{fnv1a64, splitmix64};
use crate::source::AnyMotion;

/// What to run.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The scene.
    pub motion: AnyMotion,
    /// Time grid of the records.
    pub grid: Grid,
    /// Outage length in records; `None`: one free-inertial run over the whole grid.
    pub outage_records: Option<u64>,
    /// Runs per template.
    pub runs: usize,
    /// Master seed; run r uses [`run_seed`]`(seed, r)` for every template.
    pub seed: u64,
    /// Error samples per outage (the growth curve's resolution), at least 1.
    pub points: usize,
    /// Navigator settings.
    pub settings: Settings,
    /// Worker threads (at least 1).
    pub threads: usize,
}

/// Median and 95th percentile of one error quantity.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 95th percentile.
    pub p95: f64,
}

/// Error statistics at one time since the outage start.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Point {
    /// Time since the (re)start (s).
    pub t: f64,
    /// 3-D position error (m).
    pub position: Spread,
    /// 3-D velocity error (m/s).
    pub velocity: Spread,
    /// Attitude error angle (rad).
    pub attitude: Spread,
}

/// The result of one template.
#[derive(Clone, Debug, PartialEq)]
pub struct TemplateResult {
    /// Template name.
    pub name: String,
    /// Its grade.
    pub grade: String,
    /// Outages per run (1 when free-inertial).
    pub outages: u64,
    /// Samples behind each statistic (runs × outages).
    pub samples: usize,
    /// Statistics along the outage; the last point is the end of the outage.
    pub growth: Vec<Point>,
}

impl TemplateResult {
    /// The statistics at the end of the outage (or of the free-inertial run).
    pub fn last(&self) -> Point {
        self.growth.last().copied().unwrap_or_default()
    }
}

/// The seed of run `r` derived from the master seed (the same for every template: the
/// templates are compared on common random numbers where they share terms).
pub fn run_seed(seed: u64, r: usize) -> u64 {
    splitmix64(seed ^ fnv1a64(&format!("compare/run/{r}")))
}

/// q-quantile of sorted values with linear interpolation between order statistics
/// (Hyndman–Fan type 7, the default of R and NumPy).
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = q * (sorted.len() - 1) as f64;
    let i = pos.floor() as usize;
    let frac = pos - i as f64;
    match sorted.get(i + 1) {
        Some(next) => sorted[i] + frac * (next - sorted[i]),
        None => sorted[i],
    }
}

/// Elapsed records at which an outage of `len` records is sampled: round(p·len/P), p = 1..=P.
fn sample_offsets(len: u64, points: usize) -> Vec<u64> {
    let p = (points as u64).clamp(1, len.max(1));
    (1..=p).map(|i| (i * len + p / 2) / p).collect()
}

/// Errors of one run: [outage][point] → (position, velocity, attitude).
type RunErrors = Vec<[f64; 3]>;

/// One run of one template.
fn run_one(
    plan: &Plan,
    model: &ImuModel,
    run: usize,
    offsets: &[u64],
    outage: u64,
    outages: u64,
) -> Result<RunErrors, CloseError> {
    let g = &plan.grid;
    let total = outage * outages;
    let grid = Grid { count: total, ..*g };
    let seed = run_seed(plan.seed, run);
    let mut producer = Producer::for_model(plan.motion.clone(), grid, model, seed)?;
    let truth_at = |k: u64| NavState::from_pose(&plan.motion.pose(imu_time(g, k)));
    let mut nav = Navigator::new(truth_at(0), g.rate_hz, plan.settings)?;
    let mut out = Vec::with_capacity(offsets.len() * outages as usize);
    let mut next = 0usize;
    while let Some(b) = producer.next_records(BLOCK) {
        for (i, r) in b.records.iter().enumerate() {
            let kk = b.first + 1 + i as u64;
            let elapsed_before = (kk - 1) % outage;
            if elapsed_before == 0 && kk > 1 {
                nav.reset(&truth_at(kk - 1));
                next = 0;
            }
            nav.step(r.dtheta, r.dv);
            if offsets.get(next) == Some(&(elapsed_before + 1)) {
                let s = nav.state();
                let e = StateError::of(&s, &plan.motion.pose(s.t));
                out.push([e.pos_ned.norm(), e.vel_ned.norm(), e.att_ned.norm()]);
                next += 1;
            }
        }
    }
    producer.finished()?;
    Ok(out)
}

/// Time of record k, from the integer k.
fn imu_time(g: &Grid, k: u64) -> f64 {
    g.t0 + k as f64 / g.rate_hz
}

/// Runs the plan for every model, in parallel, and returns one result per model (in order).
pub fn compare(plan: &Plan, models: &[ImuModel]) -> Result<Vec<TemplateResult>, CloseError> {
    let outage = plan.outage_records.unwrap_or(plan.grid.count).max(1);
    let outages = (plan.grid.count / outage).max(1);
    let outage = outage.min(plan.grid.count);
    let offsets = sample_offsets(outage, plan.points);
    let jobs = models.len() * plan.runs;
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Result<RunErrors, CloseError>>>> =
        Mutex::new((0..jobs).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..plan.threads.clamp(1, jobs.max(1)) {
            scope.spawn(|| {
                loop {
                    let j = next.fetch_add(1, Ordering::Relaxed);
                    if j >= jobs {
                        break;
                    }
                    let (m, r) = (j / plan.runs, j % plan.runs);
                    let res = run_one(plan, &models[m], r, &offsets, outage, outages);
                    results
                        .lock()
                        .expect("no worker panics while holding the lock")[j] = Some(res);
                }
            });
        }
    });
    let mut results = results.into_inner().expect("workers finished").into_iter();
    let mut out = Vec::with_capacity(models.len());
    for model in models {
        let runs: Vec<RunErrors> = results
            .by_ref()
            .take(plan.runs)
            .map(|r| r.expect("every job ran"))
            .collect::<Result<_, _>>()?;
        let per_run = offsets.len();
        let growth = offsets
            .iter()
            .enumerate()
            .map(|(p, &off)| {
                let spread = |q: usize| {
                    let mut v: Vec<f64> = runs
                        .iter()
                        .flat_map(|run| (0..outages as usize).map(move |o| run[o * per_run + p][q]))
                        .collect();
                    v.sort_by(f64::total_cmp);
                    Spread {
                        median: quantile(&v, 0.5),
                        p95: quantile(&v, 0.95),
                    }
                };
                Point {
                    t: off as f64 / plan.grid.rate_hz,
                    position: spread(0),
                    velocity: spread(1),
                    attitude: spread(2),
                }
            })
            .collect();
        out.push(TemplateResult {
            name: model.name.clone(),
            grade: model.grade.clone(),
            outages,
            samples: plan.runs * outages as usize,
            growth,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_type7() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(quantile(&v, 0.5), 3.0);
        assert_eq!(quantile(&v, 0.95), 4.8);
        assert_eq!(quantile(&[7.0], 0.95), 7.0);
        assert!(quantile(&[], 0.5).is_nan());
    }

    #[test]
    fn offsets_end_at_the_outage_end() {
        assert_eq!(sample_offsets(10, 4), vec![3, 5, 8, 10]);
        assert_eq!(sample_offsets(3, 100), vec![1, 2, 3]);
    }
}
