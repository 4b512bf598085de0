//! The paper's §4 as one report (`imu-emu validate`): the error-free signal against closed
//! forms and the definition, closure through the reference navigator, and the perturbed
//! signal's fitted noise terms against the template — a Markdown report with ADEV/PSD plots,
//! and the names of the checks that failed.

use std::fmt::Write as _;
use std::path::PathBuf;

use crate::analysis::analyzer::{Analysis, Analyzer};
use crate::analysis::conformance::{channel_theory, term_rows};
use crate::analysis::report;
use crate::errors::ImuModel;
use crate::truth::{self, Check};

/// What to validate, and where the report goes.
#[derive(Clone, Debug)]
pub struct Settings {
    /// IMU template (name or file) of the perturbed half.
    pub imu: String,
    /// Rate of the perturbed runs (Hz); a second run at ten times it shows the fitted terms
    /// do not depend on Δt. `None`: 100 Hz (the template's own for a unit with an output
    /// filter).
    pub rate: Option<f64>,
    /// Folder of `report.md` and the plots (created).
    pub out: PathBuf,
    /// Master seed of the perturbed runs.
    pub seed: u64,
    /// Length of the static perturbed runs (s); `None`: an hour.
    pub duration: Option<f64>,
    /// Motion definitions also closed through the reference navigator.
    pub motion_defs: Vec<PathBuf>,
    /// Break the generator on purpose (white noise σ·√Δt instead of σ/√Δt), to show the
    /// report can fail.
    pub sabotage: bool,
    /// The command line the report names (after `imu-emu validate`).
    pub command_line: String,
}

/// A written report.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// Checks passed.
    pub passed: usize,
    /// The checks that failed, by name.
    pub failed: Vec<String>,
    /// The report's path.
    pub path: PathBuf,
}

/// Why the report could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ValidateError {
    /// A file or folder could not be created or finished: `what` names it.
    #[error("{what}")]
    File {
        /// What was being done, and to which path.
        what: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// Writing the report failed.
    #[error(transparent)]
    Write(std::io::Error),
    /// The template does not load.
    #[error(transparent)]
    Template(#[from] crate::errors::template::TemplateError),
    /// A motion definition does not load.
    #[error(transparent)]
    MotionDef(#[from] crate::csvio::FileError),
    /// A run could not be set up or went wrong.
    #[error(transparent)]
    Engine(#[from] crate::engine::EngineError),
    /// A plot could not be written.
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    /// The template has no error figures (and is not the ideal one).
    #[error("--imu {0}: the template has no error figures to validate against")]
    NoFigures(String),
}

fn file_error(what: String) -> impl FnOnce(std::io::Error) -> ValidateError {
    move |source| ValidateError::File { what, source }
}

/// Largest position error of a closure (m).
const BOUND_M: f64 = 1e-3;

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
fn error_free(motion_defs: &[PathBuf]) -> Result<Section, ValidateError> {
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
    closure(&mut s, motion_defs)?;
    Ok(s)
}

/// Closure through the reference navigator: each scene's error-free records at 400 Hz,
/// navigated free-inertially from the true initial state, must end within 1 mm of the truth;
/// so must each motion definition's over its whole length.
fn closure(s: &mut Section, motion_defs: &[PathBuf]) -> Result<(), ValidateError> {
    const RATE: f64 = 400.0;
    let _ = writeln!(
        s.markdown,
        "### Closure through the reference navigator ({RATE} Hz, `src/nav/`)\n\n\
         | scene | records | final position error (m) | max position error (m) | max velocity error (m/s) | max attitude error (rad) | bound (m) | result |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |"
    );
    for name in crate::scenes::NAMES {
        let seconds = match name {
            "coning" => Some(60.0),
            "polar" => Some(120.0),
            "survey" => None,
            _ => Some(600.0),
        };
        s.closure_row(name, crate::nav::closure::close_scene(name, RATE, seconds));
    }
    for path in motion_defs {
        let m = crate::source::AnyMotion::Defined(crate::motiondef::open(path)?);
        let grid = crate::engine::plan(&m, RATE, None, None)?;
        let c = crate::nav::close(&m, &grid, Default::default(), None, 100);
        s.closure_row(&path.display().to_string(), c);
    }
    s.markdown.push('\n');
    Ok(())
}

impl Section {
    /// A row of the closure table: `name`'s closure against the 1 mm bound.
    fn closure_row(
        &mut self,
        name: &str,
        c: Result<crate::nav::closure::Closure, crate::nav::closure::CloseError>,
    ) {
        match c {
            Ok(c) => {
                let last = c.last.pos_ned.norm();
                let v = self.verdict(&format!("closure {name}"), c.max_pos <= BOUND_M);
                let _ = writeln!(
                    self.markdown,
                    "| {name} | {} | {last:.1e} | {:.1e} | {:.1e} | {:.1e} | {BOUND_M:.0e} | {v} |",
                    c.records, c.max_pos, c.max_vel, c.max_att
                );
            }
            Err(e) => {
                let v = self.verdict(&format!("closure {name}"), false);
                let _ = writeln!(self.markdown, "| {name} | — | {e} | | | | | {v} |");
            }
        }
    }
}

/// A static run of `model` at `rate_hz` for `seconds`, streamed through the analyzer.
fn static_analysis(
    model: &ImuModel,
    rate_hz: f64,
    seconds: f64,
    seed: u64,
) -> Result<Analysis, ValidateError> {
    let source = crate::engine::SourceSpec::Scene(
        "static".into(),
        crate::scenes::SceneParams::defaults_for("static"),
    );
    let motion = crate::engine::build_motion(&source, Default::default())?;
    let grid = crate::engine::plan(&motion, rate_hz, None, Some(seconds))?;
    let mut producer = crate::engine::Producer::for_model(motion, grid, model, seed)?;
    let mut an = Analyzer::new(SEGMENT);
    while let Some(b) = producer.next_records(crate::engine::BLOCK) {
        b.records.iter().for_each(|r| an.push_record(r));
    }
    producer.finished()?;
    Ok(an.finish(1.0 / grid.rate_hz))
}

/// Welch segment of the perturbed runs' PSD (samples).
const SEGMENT: usize = 1 << 14;

/// The perturbed half: static runs of the template at two rates, each fitted IEEE term
/// against the template within its record-length band, with ADEV/PSD plots and theory.
fn perturbed(a: &Settings, model: &ImuModel, seed: u64) -> Result<Section, ValidateError> {
    let mut s = Section::new(&format!("2. Perturbed signal: template `{}`", model.name));
    let rate = a.rate.unwrap_or(100.0);
    let seconds = a.duration.unwrap_or(3600.0);
    // A unit with an output filter runs at the output rate its filter decimates to: only the
    // one given (or the template's); the other would rarely divide its internal rate.
    let rates = match &model.output_filter {
        None => vec![rate, rate * 10.0],
        Some(_) => vec![a.rate.or(model.rate_hz).unwrap_or(rate)],
    };
    let _ = writeln!(
        s.markdown,
        "Static runs at 41° N of {seconds} s, seed {seed}, at {}. Each IEEE Std 952 term is fitted \
         by least squares on the octave Allan variance (`imu-emu analyze`) and compared with the template: the band \
         is the {:.0} % χ² interval of the Allan variance at the octave that tells most about the term, for this \
         record length (wider for short records, so a pass means the same thing at any length). Terms the record is too \
         short to see are reported as not resolved. Passing at both rates shows the fitted terms do not depend on Δt.\n",
        rates
            .iter()
            .map(|r| format!("{r} Hz"))
            .collect::<Vec<_>>()
            .join(" and "),
        crate::analysis::conformance::BAND_CONFIDENCE * 100.0
    );
    if let Some(w) = crate::analysis::conformance::white_allan(model, 1.0 / rates[0]) {
        let (g, acc) = (w.sensor(false), w.sensor(true));
        let each = if g == acc {
            format!("its Allan variance at τ = Δt is {:.4} of N²/τ", g.ratio(1))
        } else {
            format!(
                "its Allan variance at τ = Δt is {:.4} of N²/τ on the gyros and {:.4} on the accelerometers, which have their own filter",
                g.ratio(1),
                acc.ratio(1)
            )
        };
        let gains = if g == acc {
            format!("{:.6}", g.long_tau().sqrt())
        } else {
            format!(
                "{:.6} (gyro), {:.6} (accel)",
                g.long_tau().sqrt(),
                acc.long_tau().sqrt()
            )
        };
        let _ = writeln!(
            s.markdown,
            "The template's output filter marks white noise at short τ ({each}), \
             so the terms are fitted and checked on the octaves from the first where it is within {:.0} % of its long-τ \
             value on; N is expected as N·√r∞ = N·{gains} (the filter's aliasing). See docs/fidelity.md, \"Output filters\".\n",
            crate::analysis::conformance::FILTER_TOLERANCE * 100.0,
        );
    }
    if a.sabotage {
        s.markdown.push_str(
            "**Sabotaged run** (`--sabotage noise-scaling`): white noise generated with σ·√Δt instead of σ/√Δt.\n\n",
        );
    }
    for r in rates {
        let mut m = model.clone();
        if a.sabotage {
            // σ = N/√Δt becomes N·√Δt: the density itself scaled by Δt.
            let dt = 1.0 / r;
            m.gyro.noise.iter_mut().for_each(|x| *x *= dt);
            m.accel.noise.iter_mut().for_each(|x| *x *= dt);
        }
        let res = static_analysis(&m, r, seconds, seed)?;
        let rows = term_rows(model, &res);
        let _ = writeln!(
            s.markdown,
            "### {r} Hz ({} records)\n\n| sensor | axis | term | specified | fitted | fitted/specified | τ read (s) | band | result |\n| --- | --- | --- | ---: | ---: | ---: | ---: | --- | --- |",
            res.samples
        );
        for row in rows.iter().filter(|row| row.specified > 0.0) {
            let (unit, f) = report::term_unit(row.sensor == "gyro", row.term);
            let axis = ["x", "y", "z"][row.axis];
            let name = format!("{r} Hz {} {axis} {}", row.sensor, row.term.name());
            let verdict = match row.pass {
                Some(p) if row.resolved => s.verdict(&name, p),
                _ => "not resolved",
            };
            let band = row.band.map_or("—".to_string(), |(lo, hi)| {
                format!("{:.4} – {:.4}", lo * f, hi * f)
            });
            let _ = writeln!(
                s.markdown,
                "| {} | {axis} | {} | {:.4} {unit} | {:.4} | {:.3} | {} | {band} | {verdict} |",
                row.sensor,
                row.term.name(),
                row.specified * f,
                row.fitted * f,
                row.ratio(),
                row.tau.map_or("—".to_string(), |t| format!("{t:.3}")),
            );
        }
        let theory = channel_theory(model, 1.0 / r);
        let file = format!("adev-psd-{r}hz.png");
        let filter = crate::analysis::conformance::white_allan(model, 1.0 / r);
        let panels = report::panels_filtered(
            &res,
            Some(&theory),
            filter.as_ref(),
            &format!("{} static, {r} Hz", model.name),
        );
        crate::plot::render(&a.out.join(&file), &panels, 2, (1600, 1200))?;
        let _ = writeln!(
            s.markdown,
            "\n![ADEV and PSD at {r} Hz with the template's theory]({file})\n"
        );
    }
    Ok(s)
}

/// The perturbed half for an error-free template: it must add nothing at all.
fn ideal(model: &ImuModel, seed: u64) -> Section {
    let mut s = Section::new(&format!("2. Perturbed signal: template `{}`", model.name));
    let rate = 100.0;
    let chain = crate::errors::ErrorChain::new(model, rate, seed);
    let v = s.verdict("ideal adds no error", chain.is_empty());
    let _ = writeln!(
        s.markdown,
        "The template sets no error term, so its error chain must be empty and its records the \
         error-free ones bit for bit: error chain empty — {v}.\n"
    );
    s
}

/// Runs every check and writes `report.md` (and the plots) into `s.out`, whatever the verdict.
pub fn validate(s: &Settings) -> Result<Outcome, ValidateError> {
    std::fs::create_dir_all(&s.out).map_err(file_error(format!("creating {}", s.out.display())))?;
    let model = crate::errors::template::load(&s.imu)?;
    let second = if model.has_error_figures() {
        perturbed(s, &model, s.seed)?
    } else if model.grade == "ideal" {
        ideal(&model, s.seed)
    } else {
        return Err(ValidateError::NoFigures(s.imu.clone()));
    };
    let sections = vec![error_free(&s.motion_defs)?, second];
    let passed: usize = sections.iter().map(|s| s.passed).sum();
    let failed: Vec<String> = sections.iter().flat_map(|s| s.failed.clone()).collect();
    let mut md = String::from("# imu-emu validation report\n\n");
    let _ = writeln!(
        md,
        "imu-emu {} · `imu-emu validate{}`\n",
        env!("CARGO_PKG_VERSION"),
        s.command_line
    );
    let _ = writeln!(
        md,
        "**{}**: {passed} checks passed, {} failed{}.\n",
        if failed.is_empty() { "PASS" } else { "FAIL" },
        failed.len(),
        if failed.is_empty() {
            String::new()
        } else {
            format!(" ({})", failed.join(", "))
        }
    );
    for s in &sections {
        md.push_str(&s.markdown);
    }
    let path = s.out.join("report.md");
    let mut f = crate::output::AtomicFile::create(&path)
        .map_err(file_error(format!("creating {}", path.display())))?;
    std::io::Write::write_all(&mut f, md.as_bytes()).map_err(ValidateError::Write)?;
    f.commit()
        .map_err(file_error(format!("finishing {}", path.display())))?;
    Ok(Outcome {
        passed,
        failed,
        path,
    })
}
