//! `imu-emu compare`: which IMU fits a mission — Monte Carlo free-inertial error per template.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use imu_emu::engine;
use imu_emu::nav::Settings;
use imu_emu::nav::montecarlo::{self, Plan, TemplateResult};
use imu_emu::output::AtomicFile;

#[derive(clap::Args)]
pub struct CompareArgs {
    /// IMU templates to compare, comma-separated (names from `imu-emu templates`, or files).
    #[arg(long, value_delimiter = ',', required = true)]
    pub imu: Vec<String>,
    /// The mission: a scene file (`--scene-file`), a built-in scene or a trajectory CSV
    /// [default: the survey scene].
    #[command(flatten)]
    pub reference: super::setup::ReferenceArgs,
    /// Monte Carlo runs per template.
    #[arg(long, default_value_t = 20)]
    pub runs: usize,
    /// GNSS outages of this many seconds, back to back along the scene: the navigator is
    /// reset to the truth at each outage start and scored at its end [default: one
    /// free-inertial run over the whole scene].
    #[arg(long)]
    pub outage: Option<f64>,
    /// Master seed; run r of every template uses a seed derived from it and r.
    #[arg(long, default_value_t = imu_emu::rng::DEFAULT_SEED)]
    pub seed: u64,
    /// IMU rate (Hz), the same for every template.
    #[arg(long, default_value_t = 200.0)]
    pub rate: f64,
    /// Duration (s) [default: the scene's; 60 s for unbounded scenes].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Error samples along each outage (resolution of the growth curve).
    #[arg(long, default_value_t = 50)]
    pub points: usize,
    /// Write the error growth here: t, template, median and 95th percentile of each error.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Plot the error growth here (.png or .svg): median line, band to the 95th percentile.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Worker threads [default: all cores].
    #[arg(long)]
    pub threads: Option<usize>,
}

/// Error-growth panels (position, velocity, attitude against time since the outage start,
/// log ordinate): per template the median, shaded up to the 95th percentile.
pub fn growth_panels(results: &[TemplateResult], what: &str) -> Vec<imu_emu::plot::Panel> {
    use imu_emu::nav::montecarlo::Point;
    type Pick = fn(&Point) -> (f64, f64);
    let quantities: [(&str, &str, Pick); 3] = [
        ("position", "position error (m)", |p| {
            (p.position.median, p.position.p95)
        }),
        ("velocity", "velocity error (m/s)", |p| {
            (p.velocity.median, p.velocity.p95)
        }),
        ("attitude", "attitude error (deg)", |p| {
            (p.attitude.median.to_degrees(), p.attitude.p95.to_degrees())
        }),
    ];
    quantities
        .iter()
        .map(|(name, label, pick)| imu_emu::plot::Panel {
            title: format!("{name} error growth, {what}"),
            x_label: "time since start (s)".into(),
            y_label: (*label).into(),
            log_x: false,
            log_y: true,
            series: results
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    // A log axis cannot show the exact zero at the start.
                    let pts: Vec<_> = r.growth.iter().filter(|p| pick(p).0 > 0.0).collect();
                    let med: Vec<f64> = pts.iter().map(|p| pick(p).0).collect();
                    let p95: Vec<f64> = pts.iter().map(|p| pick(p).1).collect();
                    imu_emu::plot::Series {
                        label: format!("{} ({})", r.name, r.grade),
                        x: pts.iter().map(|p| p.t).collect(),
                        band: Some((med.clone(), p95)),
                        y: med,
                        color: i,
                        dashed: false,
                    }
                })
                .collect(),
        })
        .collect()
}

/// Header of the growth CSV.
pub const GROWTH_HEADER: &str = "t_s,template,grade,position_median_m,position_p95_m,velocity_median_m_s,velocity_p95_m_s,attitude_median_deg,attitude_p95_deg\n";

/// The growth CSV of `results`: one row per template and sample time.
pub fn growth_csv(results: &[TemplateResult]) -> String {
    let mut s = String::from(GROWTH_HEADER);
    let mut f = ryu::Buffer::new();
    for r in results {
        for p in &r.growth {
            s.push_str(f.format(p.t));
            s.push(',');
            s.push_str(&r.name);
            s.push(',');
            s.push_str(&r.grade);
            for v in [
                p.position.median,
                p.position.p95,
                p.velocity.median,
                p.velocity.p95,
                p.attitude.median.to_degrees(),
                p.attitude.p95.to_degrees(),
            ] {
                s.push(',');
                s.push_str(f.format(v));
            }
            s.push('\n');
        }
    }
    s
}

pub fn compare(a: CompareArgs) -> Result<()> {
    if a.runs == 0 {
        bail!("--runs 0: expected at least one run");
    }
    if a.points == 0 {
        bail!("--points 0: expected at least one sample per outage");
    }
    let models = a
        .imu
        .iter()
        .map(|n| imu_emu::errors::template::load(n.trim()).with_context(|| format!("--imu `{n}`")))
        .collect::<Result<Vec<_>>>()?;
    for m in &models {
        if m.grade != "ideal" && !m.has_error_figures() {
            eprintln!(
                "imu-emu: warning: template `{}` has no error figures: it will look ideal apart from quantization",
                m.name
            );
        }
    }
    let motion = a.reference.builder()?.motion()?;
    let grid = engine::plan(&motion, a.rate, None, a.duration)?;
    let outage_records = match a.outage {
        None => None,
        Some(s) if s.is_finite() && s > 0.0 => {
            let n = (s * a.rate).round() as u64;
            if n == 0 || n > grid.count {
                bail!(
                    "--outage {s}: expected between one record and the run's {} s",
                    grid.count as f64 / a.rate
                );
            }
            Some(n)
        }
        Some(s) => bail!("--outage {s}: expected a positive number of seconds"),
    };
    let threads = a.threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let plan = Plan {
        motion,
        grid,
        outage_records,
        runs: a.runs,
        seed: a.seed,
        points: a.points,
        settings: Settings::default(),
        threads,
    };
    let results = montecarlo::compare(&plan, &models)?;
    let span = grid.count as f64 / grid.rate_hz;
    let mode = match outage_records {
        None => format!("free-inertial from the true state over {span} s"),
        Some(n) => format!(
            "{} outages of {} s each (reset to the truth at each start)",
            results.first().map_or(0, |r| r.outages),
            n as f64 / grid.rate_hz
        ),
    };
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "compare: {}, {} Hz, {mode}; {} runs per template, seed {}",
        a.reference.name(),
        grid.rate_hz,
        a.runs,
        a.seed
    )?;
    writeln!(
        out,
        "{:<11} {:<11} {:>7}  {:>23}  {:>23}  {:>23}",
        "template", "grade", "samples", "position m", "velocity m/s", "attitude deg"
    )?;
    writeln!(
        out,
        "{:<11} {:<11} {:>7}  {:>11} {:>11}  {:>11} {:>11}  {:>11} {:>11}",
        "", "", "", "median", "95 %", "median", "95 %", "median", "95 %"
    )?;
    for r in &results {
        let p = r.last();
        writeln!(
            out,
            "{:<11} {:<11} {:>7}  {:>11.4e} {:>11.4e}  {:>11.4e} {:>11.4e}  {:>11.4e} {:>11.4e}",
            r.name,
            r.grade,
            r.samples,
            p.position.median,
            p.position.p95,
            p.velocity.median,
            p.velocity.p95,
            p.attitude.median.to_degrees(),
            p.attitude.p95.to_degrees()
        )?;
    }
    if let Some(path) = &a.plot {
        let what = match a.outage {
            Some(s) => format!("{s} s outages"),
            None => "free inertial".to_string(),
        };
        imu_emu::plot::render(path, &growth_panels(&results, &what), 1, (1200, 1500))?;
        eprintln!("imu-emu compare: plot written to {}", path.display());
    }
    if let Some(path) = &a.csv {
        let mut f =
            AtomicFile::create(path).with_context(|| format!("creating {}", path.display()))?;
        f.write_all(growth_csv(&results).as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
        f.commit()
            .with_context(|| format!("finishing {}", path.display()))?;
    }
    Ok(())
}
