//! `imu-emu generate`: a run on the offline clock — records or frames, their truth, and the
//! aiding streams, each to a file, as fast as the machine allows.

use std::path::PathBuf;

use anyhow::Result;

use imu_emu::run::{OfflineFiles, RunSpec};

use super::setup::SimArgs;

#[derive(clap::Args)]
pub struct GenerateArgs {
    #[command(flatten)]
    pub sim: SimArgs,
    /// Output file, or - for stdout [default: the scene file's `output.path`, else stdout].
    /// For a rig (`[[imu]]` units): the directory of the units' files [default: `.`].
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Also write the error-free records here (same format and time grid). For a rig: a
    /// directory receiving each unit's error-free readings and failure schedule.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Also write the error each stage injected into each record here (same format).
    #[arg(long)]
    pub truth_errors: Option<PathBuf>,
    /// Also write the GNSS receiver's epochs (scene file `[gnss]`, else the default receiver)
    /// as FORMAT:FILE, FORMAT one of nmea, ubx, mavlink. Repeatable (docs/aiding.md).
    #[arg(long = "gnss")]
    pub gnss: Vec<String>,
    /// Also write the truth of each GNSS epoch here (CSV).
    #[arg(long)]
    pub gnss_truth: Option<PathBuf>,
    /// Also write the odometer's samples here (CSV; scene file `[odometer]`, else the default).
    #[arg(long)]
    pub odometer: Option<PathBuf>,
    /// Also write the barometer's samples here (CSV; scene file `[baro]`, else the default).
    #[arg(long)]
    pub baro: Option<PathBuf>,
    /// Also write the magnetometer's samples here (CSV; scene file `[magnetometer]`, else the
    /// default).
    #[arg(long)]
    pub magnetometer: Option<PathBuf>,
}

pub fn generate(a: GenerateArgs) -> Result<()> {
    let files = OfflineFiles {
        output: a.output.clone(),
        truth: a.truth.clone(),
        truth_errors: a.truth_errors.clone(),
        gnss: a.gnss.clone(),
        gnss_truth: a.gnss_truth.clone(),
        sensors: [&a.odometer, &a.baro, &a.magnetometer].map(Clone::clone),
    };
    let offline = RunSpec::offline(a.sim.builder("ideal", "csv")?, &files)?;
    for n in &offline.notes {
        eprintln!("imu-emu: {n}");
    }
    let run = offline.spec.build()?;
    for d in offline.dirs {
        std::fs::create_dir_all(&d)
            .map_err(|e| anyhow::anyhow!("creating directory {}: {e}", d.display()))?;
    }
    super::setup::announce_run(&run);
    super::flow::run(run, true).map(drop)
}
