//! `imu-emu validate`: the paper's §4 as one command — the error-free signal against closed
//! forms and the definition, closure through the reference navigator, and the perturbed
//! signal's fitted noise terms against the template — written as a Markdown report with plots.

use std::path::PathBuf;

use anyhow::{Result, bail};

use imu_emu::validation::report::{Settings, validate as report};

#[derive(clap::Args)]
pub struct ValidateArgs {
    /// IMU template (or template file) for the perturbed half [default: ln200].
    #[arg(long)]
    pub imu: Option<String>,
    /// IMU rate of the perturbed runs (Hz); a second run at ten times it shows the fitted
    /// terms do not depend on Δt [default: 100].
    #[arg(long)]
    pub rate: Option<f64>,
    /// Folder for report.md and the plots [default: validation].
    #[arg(long, default_value = "validation")]
    pub out: PathBuf,
    /// Master seed of the perturbed runs [default: 20261124].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Length of the static perturbed run (s) [default: long enough for the template's terms].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Also close the reference navigator over this motion definition (native TOML or
    /// gnss-ins-sim CSV) in the closure table; repeatable.
    #[arg(long)]
    pub motion_def: Vec<PathBuf>,
    /// Deliberately break the generator, to show the report can fail. `noise-scaling`: white
    /// noise σ·√Δt instead of σ/√Δt.
    #[arg(long, hide = true)]
    pub sabotage: Option<String>,
}

/// Runs `validate`; exits with an error when any check failed (the report is written either way).
pub fn validate(a: ValidateArgs) -> Result<()> {
    if let Some(s) = &a.sabotage
        && s != "noise-scaling"
    {
        bail!("--sabotage `{s}`: expected `noise-scaling`");
    }
    let settings = Settings {
        imu: a.imu.unwrap_or_else(|| "ln200".into()),
        rate: a.rate,
        out: a.out,
        seed: a.seed.unwrap_or(imu_emu::rng::DEFAULT_SEED),
        duration: a.duration,
        motion_defs: a.motion_def,
        sabotage: a.sabotage.is_some(),
        command_line: std::env::args().skip(2).map(|x| format!(" {x}")).collect(),
    };
    let done = report(&settings)?;
    let verdict = if done.failed.is_empty() {
        "PASS"
    } else {
        "FAIL"
    };
    eprintln!(
        "imu-emu validate: {verdict} — {} passed, {} failed; report in {}",
        done.passed,
        done.failed.len(),
        done.path.display()
    );
    if !done.failed.is_empty() {
        bail!("validation failed: {} check(s)", done.failed.len());
    }
    Ok(())
}
