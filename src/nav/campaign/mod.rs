//! An IMU-selection campaign: units × missions × outage lengths × seeded runs, each run
//! navigated (free-inertial, or GNSS-aided around outages) and its errors sampled; the runs'
//! errors merged into median and 95th-percentile error growth per (mission, unit, outage).
//! `imu-emu compare` is one campaign run on local threads; the same tasks can run anywhere
//! (a Dask cluster, through the Python binding) and merge into the identical table.
//!
//! The pieces, all plain data:
//! * [`CampaignSpec`] (serde): what to run — the missions, the templates, the rate, the span,
//!   the outage lengths, runs, master seed, samples per window, GNSS aiding.
//! * [`Campaign`]: the spec resolved (motions built, templates loaded, every scene-file table
//!   used or refused) by [`Campaign::new`]; cheap enough to rebuild on each worker.
//! * [`Task`] (serde): one (mission, unit, outage length, run); [`Campaign::tasks`] lists them.
//! * [`Summary`] (serde): a task's result — its errors, window by window, sample by sample.
//!   [`Campaign::run_task`] makes one; it depends only on the spec and the task.
//! * [`Campaign::merge`]: summaries in any order → [`Row`]s. The statistics are order
//!   statistics of the pooled samples, so the table is a function of the set of summaries:
//!   bit-identical however the tasks were spread or ordered. [`Campaign::run_local`] = every
//!   task on local threads, then the merge.
//!
//! Seeds: run r's seed is [`run_seed`]`(seed, r)`; every template draws its errors from it
//! (common random numbers across templates), a rig unit from it and its name (independent
//! units, as a rig draws them), and the GNSS receiver from it (the same fixes for every unit
//! of a run).

mod fly;
mod mission;
pub mod report;
mod unit;

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use serde::{Deserialize, Serialize};

pub use fly::{FlyError, Mode, Windows, filter_model, offsets};
pub use mission::MissionSpec;
pub use unit::{Candidate, UnitRecords};

use crate::aiding::GnssConfig;
use crate::engine::{self, EngineError, Grid};
use crate::errors::template;
use crate::nav::montecarlo::{Point, Spread, quantile, run_seed};
use crate::nav::strapdown::{Settings, SettingsError};
use crate::sim::SimError;
use crate::source::AnyMotion;

/// Whether the runs are GNSS-aided.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Aiding {
    /// Aided when the mission's scene file has a `[gnss]` table (its receiver), else free.
    #[default]
    Auto,
    /// Aided: the scene file's `[gnss]` receiver, else the default receiver.
    Gnss,
    /// Free-inertial; a scene file's `[gnss]` is not used (the table header says so).
    Free,
}

/// Most seeded runs per (mission, unit, outage): a 95th percentile is sound from a few
/// hundred; the tasks and their results are held in memory (10^9 runs took 5 GB in 8 s).
pub const MAX_RUNS: usize = 100_000;

/// What a campaign runs (serde: a Python dict or JSON maps onto it field by field).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CampaignSpec {
    /// The missions (at least one).
    pub missions: Vec<MissionSpec>,
    /// Templates (names or files) to compare on every mission; a mission's scene file adds
    /// its `[[imu]]` units, or its `[imu] model` when no template is given.
    pub templates: Vec<String>,
    /// Record rate (Hz) of the templates and of rig units without their own
    /// [default: the scene file's `imu.rate_hz`, else 200].
    pub rate_hz: Option<f64>,
    /// Span (s) [default: the scene file's `output.duration_s`, else the scene's; 60 s for an
    /// unbounded scene].
    pub duration_s: Option<f64>,
    /// Outage lengths (s); empty: one window over the whole span (free-inertial from the
    /// truth, or aided throughout).
    pub outages_s: Vec<f64>,
    /// Seeded runs per (mission, unit, outage).
    pub runs: usize,
    /// Master seed [default: the scene file's `imu.seed`, else the project's default].
    pub seed: Option<u64>,
    /// Error samples per window (the growth curve's resolution), at least 1.
    pub points: usize,
    /// GNSS aiding.
    pub aiding: Aiding,
    /// Aided (GNSS on) time before each outage (s).
    pub aided_s: f64,
}

impl Default for CampaignSpec {
    fn default() -> CampaignSpec {
        CampaignSpec {
            missions: vec![MissionSpec::default()],
            templates: Vec::new(),
            rate_hz: None,
            duration_s: None,
            outages_s: Vec::new(),
            runs: 20,
            seed: None,
            points: 50,
            aiding: Aiding::Auto,
            aided_s: 60.0,
        }
    }
}

/// Why a campaign cannot be built or run.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    /// A setting or a scene-file table is refused; the message names it.
    #[error("{0}")]
    Invalid(String),
    /// The simulation builder refused the mission.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The engine refused a run.
    #[error(transparent)]
    Engine(#[from] EngineError),
    /// Bad navigator settings.
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// A run failed.
    #[error(transparent)]
    Fly(#[from] FlyError),
}

/// One task: a seeded run of one unit on one mission with one outage length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Task {
    /// Index into [`Campaign::missions`].
    pub mission: usize,
    /// Index into the mission's units.
    pub unit: usize,
    /// Index into [`CampaignSpec::outages_s`] (0 when it is empty).
    pub outage: usize,
    /// Run number (its seed is [`run_seed`]`(seed, run)`).
    pub run: usize,
}

/// A task's result: the 3-D position (m), velocity (m/s) and attitude (rad) errors at each
/// sample of each window, window-major.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// The task.
    pub task: Task,
    /// The run's seed.
    pub seed: u64,
    /// Windows (outages) in the run.
    pub windows: u64,
    /// [window × sample] → [position, velocity, attitude].
    pub errors: Vec<[f64; 3]>,
}

/// One mission, resolved.
#[derive(Clone, Debug)]
pub struct Mission {
    /// How the table names it.
    pub name: String,
    /// Its motion.
    pub motion: AnyMotion,
    /// The units compared, each with its grid.
    pub units: Vec<(Candidate, Grid)>,
    /// The receiver when aided.
    pub gnss: Option<GnssConfig>,
}

/// A campaign, resolved and ready to run tasks.
#[derive(Clone, Debug)]
pub struct Campaign {
    /// The spec it was built from.
    pub spec: CampaignSpec,
    /// The missions.
    pub missions: Vec<Mission>,
    /// The master seed.
    pub seed: u64,
    /// The navigator's settings.
    pub settings: Settings,
    /// Notes for the table's header (e.g. a `[gnss]` table not used because of `Free`).
    pub notes: Vec<String>,
}

/// The statistics of one (mission, unit, outage length).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// Mission name.
    pub mission: String,
    /// Unit name (template or rig unit).
    pub unit: String,
    /// Its template's grade.
    pub grade: String,
    /// Record rate (Hz).
    pub rate_hz: f64,
    /// Outage length (s); `None`: one window over the span.
    pub outage_s: Option<f64>,
    /// Whether GNSS-aided.
    pub aided: bool,
    /// Windows per run.
    pub windows: u64,
    /// Samples behind each statistic (runs × windows).
    pub samples: usize,
    /// Statistics along the window (time since its start); the last is its end. Aided with
    /// outages, the first (t = 0) is the aided error at the outage start.
    pub growth: Vec<Point>,
}

impl Row {
    /// The statistics at the window's end.
    pub fn last(&self) -> Point {
        self.growth.last().copied().unwrap_or_default()
    }

    /// Aided with outages: the statistics at the outage start (the aided error).
    pub fn at_start(&self) -> Option<Point> {
        (self.aided && self.outage_s.is_some()).then(|| self.growth[0])
    }
}

impl Campaign {
    /// Resolves `spec`: builds every mission's motion, loads the templates, resolves the
    /// scene files' units and receivers, and checks the windows fit every unit's span.
    pub fn new(spec: CampaignSpec) -> Result<Campaign, CampaignError> {
        if spec.missions.is_empty() {
            return Err(CampaignError::Invalid("no mission given".into()));
        }
        if !(1..=MAX_RUNS).contains(&spec.runs) {
            return Err(CampaignError::Invalid(format!(
                "runs {}: expected 1 to {MAX_RUNS} runs",
                spec.runs
            )));
        }
        if spec.points == 0 {
            return Err(CampaignError::Invalid(
                "points 0: expected at least one sample per window".into(),
            ));
        }
        if let Some(s) = spec
            .outages_s
            .iter()
            .find(|s| !(s.is_finite() && **s > 0.0))
        {
            return Err(CampaignError::Invalid(format!(
                "outage {s}: expected a positive number of seconds"
            )));
        }
        if !(spec.aided_s.is_finite() && spec.aided_s > 0.0) {
            return Err(CampaignError::Invalid(format!(
                "aided {}: expected a positive number of seconds",
                spec.aided_s
            )));
        }
        let templates = spec
            .templates
            .iter()
            .map(|n| {
                let m = template::load(n.trim())
                    .map_err(|e| CampaignError::Invalid(format!("template `{n}`: {e}")))?;
                mission::check_model(&m).map_err(CampaignError::Invalid)?;
                Ok(m)
            })
            .collect::<Result<Vec<_>, CampaignError>>()?;
        let mut missions = Vec::new();
        let (mut seed, mut notes) = (None, Vec::new());
        for m in &spec.missions {
            let r = mission::resolve(m)?;
            seed = seed.or(spec.seed).or(r.seed);
            let rate = spec.rate_hz.or(r.rate).unwrap_or(200.0);
            let mut units: Vec<(Candidate, Option<f64>)> = Vec::new();
            let models = match (templates.is_empty(), &r.imu_model) {
                (true, Some(name)) => vec![
                    template::load(name)
                        .map_err(|e| CampaignError::Invalid(format!("`imu.model`: {e}")))?,
                ],
                _ => templates.clone(),
            };
            for model in models {
                units.push((
                    Candidate {
                        name: model.name.clone(),
                        model,
                        rate_hz: rate,
                        mounting_deg: r.mounting_deg,
                        lever_arm_m: r.lever_arm_m,
                        rig_unit: false,
                    },
                    None,
                ));
            }
            units.extend(r.rig);
            if units.is_empty() {
                return Err(CampaignError::Invalid(format!(
                    "{}: no unit to compare: give templates (--imu) or a scene file with `[imu] model` or `[[imu]]` units",
                    m.name()
                )));
            }
            let gnss = match spec.aiding {
                Aiding::Free => {
                    if r.gnss.is_some() {
                        notes.push(format!(
                            "{}: its [gnss] receiver is not used (free-inertial asked for)",
                            m.name()
                        ));
                    }
                    None
                }
                Aiding::Auto => r.gnss,
                Aiding::Gnss => Some(r.gnss.unwrap_or_default()),
            };
            let mut resolved = Vec::new();
            for (mut c, own_rate) in units {
                c.rate_hz = own_rate.unwrap_or(rate);
                if c.model.output_filter.is_some() && !c.at_reference() {
                    return Err(CampaignError::Invalid(format!(
                        "unit `{}`: template `{}` has an [output_filter]: a placed unit does not run output filters (a unit at the reference point does)",
                        c.name, c.model.name
                    )));
                }
                let grid = engine::plan(
                    &r.motion,
                    c.rate_hz,
                    r.start,
                    spec.duration_s.or(r.duration),
                )?;
                resolved.push((c, grid));
            }
            missions.push(Mission {
                name: m.name(),
                motion: r.motion,
                units: resolved,
                gnss,
            });
        }
        let c = Campaign {
            seed: seed.unwrap_or(crate::rng::DEFAULT_SEED),
            spec,
            missions,
            settings: Settings::default(),
            notes,
        };
        for t in c.tasks().iter().filter(|t| t.run == 0) {
            c.windows(t)?;
        }
        Ok(c)
    }

    /// Every task, in (mission, unit, outage, run) order.
    pub fn tasks(&self) -> Vec<Task> {
        let outages = self.spec.outages_s.len().max(1);
        let mut v = Vec::new();
        for (mission, m) in self.missions.iter().enumerate() {
            for unit in 0..m.units.len() {
                for outage in 0..outages {
                    for run in 0..self.spec.runs {
                        v.push(Task {
                            mission,
                            unit,
                            outage,
                            run,
                        });
                    }
                }
            }
        }
        v
    }

    /// The outage length of a task (s), if any.
    fn outage_s(&self, t: &Task) -> Option<f64> {
        self.spec.outages_s.get(t.outage).copied()
    }

    /// The mode of a task's mission.
    fn mode(&self, t: &Task) -> Mode {
        match &self.missions[t.mission].gnss {
            None => Mode::Free,
            Some(g) => Mode::Aided {
                gnss: Box::new(g.clone()),
                outage: self.outage_s(t).is_some(),
            },
        }
    }

    /// Where a task's windows lie on its unit's grid.
    pub fn windows(&self, t: &Task) -> Result<Windows, CampaignError> {
        let m = self.missions.get(t.mission).ok_or_else(|| bad_task(t))?;
        let (u, grid) = m.units.get(t.unit).ok_or_else(|| bad_task(t))?;
        let n = grid.count;
        let records = |s: f64| (s * grid.rate_hz).round() as u64;
        let span = n as f64 / grid.rate_hz;
        let w = match (self.outage_s(t), &m.gnss) {
            (None, _) => Windows {
                first: 0,
                gap: 0,
                len: n,
                count: 1,
            },
            (Some(s), None) => {
                let len = records(s);
                if len == 0 || len > n {
                    return Err(CampaignError::Invalid(format!(
                        "outage {s} s: expected between one record and the run's {span} s ({})",
                        u.name
                    )));
                }
                Windows {
                    first: 0,
                    gap: 0,
                    len,
                    count: n / len,
                }
            }
            (Some(s), Some(_)) => {
                let (len, gap) = (records(s), records(self.spec.aided_s));
                if len == 0 || gap + len > n {
                    return Err(CampaignError::Invalid(format!(
                        "outage {s} s after {} s aided: the run's {span} s holds none ({})",
                        self.spec.aided_s, u.name
                    )));
                }
                Windows {
                    first: gap,
                    gap,
                    len,
                    count: (n - gap) / (gap + len) + 1,
                }
                .fit(n)
            }
        };
        if w.len == 0 || w.count == 0 {
            return Err(CampaignError::Invalid(format!("{}: an empty span", u.name)));
        }
        Ok(w)
    }

    /// Runs one task.
    pub fn run_task(&self, t: &Task) -> Result<Summary, CampaignError> {
        let windows = self.windows(t)?;
        if t.run >= self.spec.runs || t.outage >= self.spec.outages_s.len().max(1) {
            return Err(bad_task(t));
        }
        let m = &self.missions[t.mission];
        let (unit, grid) = &m.units[t.unit];
        let mode = self.mode(t);
        let offs = offsets(
            windows.len,
            self.spec.points,
            matches!(mode, Mode::Aided { outage: true, .. }),
        );
        let seed = run_seed(self.seed, t.run);
        let errors = fly::fly(
            unit,
            &m.motion,
            *grid,
            windows,
            &offs,
            &mode,
            self.settings,
            seed,
        )?;
        Ok(Summary {
            task: *t,
            seed,
            windows: windows.count,
            errors,
        })
    }

    /// Merges summaries (any order; every task of the campaign exactly once) into one row per
    /// (mission, unit, outage), in task order.
    pub fn merge(
        &self,
        summaries: impl IntoIterator<Item = Summary>,
    ) -> Result<Vec<Row>, CampaignError> {
        let mut all: Vec<Summary> = summaries.into_iter().collect();
        all.sort_by_key(|s| s.task);
        let tasks = self.tasks();
        if all.len() != tasks.len() || all.iter().zip(&tasks).any(|(s, t)| s.task != *t) {
            let missing = tasks
                .iter()
                .find(|t| all.binary_search_by_key(*t, |s| s.task).is_err());
            return Err(CampaignError::Invalid(match missing {
                Some(t) => format!("merge: no summary of task {t:?}"),
                None => format!(
                    "merge: {} summaries for {} tasks (a task twice, or one not of this campaign)",
                    all.len(),
                    tasks.len()
                ),
            }));
        }
        let mut rows = Vec::new();
        for group in all.chunk_by(|a, b| {
            (a.task.mission, a.task.unit, a.task.outage)
                == (b.task.mission, b.task.unit, b.task.outage)
        }) {
            let t = group[0].task;
            let w = self.windows(&t)?;
            let (unit, grid) = &self.missions[t.mission].units[t.unit];
            let mode = self.mode(&t);
            let offs = offsets(
                w.len,
                self.spec.points,
                matches!(mode, Mode::Aided { outage: true, .. }),
            );
            let per = offs.len();
            if let Some(s) = group
                .iter()
                .find(|s| s.errors.len() != per * w.count as usize || s.windows != w.count)
            {
                return Err(CampaignError::Invalid(format!(
                    "merge: task {:?} has {} samples, expected {} windows × {per}",
                    s.task,
                    s.errors.len(),
                    w.count
                )));
            }
            let growth = offs
                .iter()
                .enumerate()
                .map(|(p, &off)| {
                    let spread = |q: usize| {
                        let mut v: Vec<f64> = group
                            .iter()
                            .flat_map(|s| {
                                (0..w.count as usize).map(move |o| s.errors[o * per + p][q])
                            })
                            .collect();
                        v.sort_by(f64::total_cmp);
                        Spread {
                            median: quantile(&v, 0.5),
                            p95: quantile(&v, 0.95),
                        }
                    };
                    Point {
                        t: off as f64 / grid.rate_hz,
                        position: spread(0),
                        velocity: spread(1),
                        attitude: spread(2),
                    }
                })
                .collect();
            rows.push(Row {
                mission: self.missions[t.mission].name.clone(),
                unit: unit.name.clone(),
                grade: unit.model.grade.clone(),
                rate_hz: grid.rate_hz,
                outage_s: self.outage_s(&t).map(|_| w.len as f64 / grid.rate_hz),
                aided: matches!(mode, Mode::Aided { .. }),
                windows: w.count,
                samples: group.len() * w.count as usize,
                growth,
            });
        }
        Ok(rows)
    }

    /// Runs every task on `threads` local threads and merges them.
    pub fn run_local(&self, threads: usize) -> Result<Vec<Row>, CampaignError> {
        let tasks = self.tasks();
        let next = AtomicUsize::new(0);
        let results: Mutex<Vec<Option<Result<Summary, CampaignError>>>> =
            Mutex::new((0..tasks.len()).map(|_| None).collect());
        std::thread::scope(|scope| {
            for _ in 0..threads.clamp(1, tasks.len().max(1)) {
                scope.spawn(|| {
                    loop {
                        let j = next.fetch_add(1, Ordering::Relaxed);
                        let Some(t) = tasks.get(j) else { break };
                        let r = self.run_task(t);
                        results.lock().expect("no worker panics holding the lock")[j] = Some(r);
                    }
                });
            }
        });
        let summaries = results
            .into_inner()
            .expect("workers finished")
            .into_iter()
            .map(|r| r.expect("every task ran"))
            .collect::<Result<Vec<_>, _>>()?;
        self.merge(summaries)
    }
}

impl Windows {
    /// At most as many windows as end within `n` records.
    fn fit(mut self, n: u64) -> Windows {
        while self.count > 0 && self.start(self.count - 1) + self.len > n {
            self.count -= 1;
        }
        self
    }
}

fn bad_task(t: &Task) -> CampaignError {
    CampaignError::Invalid(format!("task {t:?} is not of this campaign"))
}
