//! `imu-emu compare`: which IMU fits a mission — a Monte Carlo campaign
//! ([`imu_emu::nav::campaign`]) run on local threads, printed as a median/95 % table.

use std::path::PathBuf;

use anyhow::Result;

use imu_emu::nav::campaign::{Aiding, Campaign, CampaignSpec, MissionSpec, report};

#[derive(clap::Args)]
pub struct CompareArgs {
    /// IMU templates to compare, comma-separated (names from `imu-emu templates`, or files)
    /// [default: the scene file's `[[imu]]` units, else its `[imu] model`]; with a rig scene
    /// file, compared next to its units.
    #[arg(long, value_delimiter = ',')]
    pub imu: Vec<String>,
    /// The mission: a scene file (`--scene-file`: its trajectory, span, units and `[gnss]`), a
    /// built-in scene or a trajectory CSV [default: the survey scene].
    #[command(flatten)]
    pub reference: super::setup::ReferenceArgs,
    /// Monte Carlo runs per unit and outage length.
    #[arg(long, default_value_t = 20)]
    pub runs: usize,
    /// Outage lengths (s), comma-separated. Free-inertial: back to back along the run, the
    /// navigator reset to the truth at each start. GNSS-aided: each after `--aided` seconds
    /// of fixes [default: one window over the whole run].
    #[arg(long, value_delimiter = ',')]
    pub outage: Vec<f64>,
    /// Aid the navigator with the simulated GNSS receiver (the scene file's `[gnss]`, else
    /// the default receiver); a scene file with `[gnss]` is aided without this flag.
    #[arg(long, conflicts_with = "no_gnss")]
    pub gnss: bool,
    /// Free-inertial even when the scene file has a `[gnss]` table.
    #[arg(long)]
    pub no_gnss: bool,
    /// GNSS-aided seconds before each outage (the filter's convergence).
    #[arg(long, default_value_t = 60.0)]
    pub aided: f64,
    /// Master seed; run r uses a seed derived from it and r [default: the scene file's
    /// `imu.seed`, else 20261124].
    #[arg(long)]
    pub seed: Option<u64>,
    /// IMU rate (Hz) of the templates [default: the scene file's `imu.rate_hz`, else 200].
    #[arg(long)]
    pub rate: Option<f64>,
    /// Duration (s) [default: the scene file's, else the scene's; 60 s for unbounded scenes].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Error samples along each window (resolution of the growth curve).
    #[arg(long, default_value_t = 50)]
    pub points: usize,
    /// Write the error growth here: t, unit, median and 95th percentile of each error.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Plot the error growth here (.png or .svg): median line, band to the 95th percentile.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Worker threads [default: all cores]; the table does not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
}

pub fn compare(a: CompareArgs) -> Result<()> {
    let r = &a.reference;
    let spec = CampaignSpec {
        missions: vec![MissionSpec {
            scene_file: r.scene_file.clone(),
            scene: r.scene.clone(),
            trajectory: r.trajectory.clone(),
            motion_def: r.motion_def.clone(),
        }],
        templates: a.imu.clone(),
        rate_hz: a.rate,
        duration_s: a.duration,
        outages_s: a.outage.clone(),
        runs: a.runs,
        seed: a.seed,
        points: a.points,
        aiding: match (a.gnss, a.no_gnss) {
            (true, _) => Aiding::Gnss,
            (_, true) => Aiding::Free,
            _ => Aiding::Auto,
        },
        aided_s: a.aided,
    };
    let campaign = Campaign::new(spec)?;
    for m in &campaign.missions {
        for (u, _) in &m.units {
            if u.model.grade != "ideal" && !u.model.has_error_figures() {
                eprintln!(
                    "imu-emu: warning: template `{}` has no error figures: it will look ideal apart from quantization",
                    u.model.name
                );
            }
        }
    }
    let threads = a
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let rows = campaign.run_local(threads)?;
    let mut text = report::header(&campaign, &rows, &a.reference.name()) + "\n";
    for n in &campaign.notes {
        text += &format!("note: {n}\n");
    }
    text += &report::table(&rows);
    if let Some(path) = &a.plot {
        let what = report::plot_title(&campaign);
        imu_emu::plot::render(path, &report::growth_panels(&rows, &what), 1, (1200, 1500))?;
        eprintln!("imu-emu compare: plot written to {}", path.display());
    }
    if let Some(path) = &a.csv {
        imu_emu::output::write_whole(path, report::growth_csv(&rows).as_bytes())?;
    }
    // Last, after the files are whole.
    let alone = a.plot.is_none() && a.csv.is_none();
    super::stdout::write(text.as_bytes(), "the table", alone)
}
