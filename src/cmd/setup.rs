//! Resolving a simulation's settings: the scene file merged with the flags, the error chain.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

use imu_emu::config::{self, SceneFile};
use imu_emu::errors::ErrorChain;
use imu_emu::generator::DEFAULT_NODES;
use imu_emu::job::{self, Grid, JobError, SourceSpec};
use imu_emu::motion::sampled::{Degree, ModelSettings};
use imu_emu::output::Format;
use imu_emu::scenes;

#[derive(clap::Args)]
pub struct SourceArgs {
    /// Scene file (TOML); flags override it.
    pub scene_file: Option<PathBuf>,
    /// Built-in scene: static, straight, circle, survey, coning, polar.
    #[arg(long, conflicts_with = "trajectory")]
    pub scene: Option<String>,
    /// Trajectory CSV: t,lat,lon,h,vn,ve,vd,roll,pitch,yaw.
    #[arg(long)]
    pub trajectory: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct GenerateArgs {
    #[command(flatten)]
    pub source: SourceArgs,
    /// IMU output rate (Hz) [default: 400].
    #[arg(long, allow_negative_numbers = true)]
    pub rate: Option<f64>,
    /// Duration (s) [default: to the end of the trajectory; 60 s for unbounded scenes].
    #[arg(long, allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// Start time t₀ (s) [default: the trajectory's start].
    #[arg(long, allow_negative_numbers = true)]
    pub start: Option<f64>,
    /// Output format: csv, bin, or a protocol's frames (`imu-emu decode --help` lists the
    /// built-in protocols) [default: csv].
    #[arg(long)]
    pub format: Option<String>,
    /// Frames of a protocol described in a spec file (protocols/README.md).
    #[arg(long)]
    pub protocol_file: Option<PathBuf>,
    /// GPS time of record time 0 for frames with GPS time fields, as WEEK,SECONDS_OF_WEEK
    /// [default: 0,0 — record times are GPS seconds since 1980-01-06].
    #[arg(long, value_parser = parse_gps_time)]
    pub gps_time: Option<(u32, f64)>,
    /// Inject a fault into protocol frames: KIND@T1,T2,… (record times, s) or KIND~RATE (mean
    /// events per second); KIND is corrupt-check, drop, duplicate, stale-counter or status.
    /// Repeatable; adds to the scene file's [faults].
    #[arg(long = "fault", value_parser = imu_emu::protocol::FaultSpec::parse_flag)]
    pub faults: Vec<imu_emu::protocol::FaultSpec>,
    /// Output file, or - for stdout [default: stdout].
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// IMU error model: a template name (`imu-emu templates`) or a template file [default: ideal].
    #[arg(long)]
    pub imu: Option<String>,
    /// Master seed of every random error process [default: 20261124].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Also write the error-free records here (same format and time grid).
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Also write the error each stage injected into each record here (same format).
    #[arg(long)]
    pub truth_errors: Option<PathBuf>,
    /// Gauss–Legendre nodes per interval (order 2n) [default: 3].
    #[arg(long)]
    pub quadrature: Option<usize>,
    /// Motion-model polynomials for trajectory files: cubic or quintic [default: quintic].
    #[arg(long)]
    pub interp: Option<String>,
    /// Finite-difference stencil (samples) for knot derivatives [default: 9].
    #[arg(long)]
    pub stencil: Option<usize>,
}

pub struct Resolved {
    pub source: SourceSpec,
    /// The scene file, if any, and whether the scene name and the parameters came from it.
    pub scene_file: Option<PathBuf>,
    pub scene_from_file: bool,
    pub params_from_file: bool,
    /// Settings checked later whose value came from the scene file: (setting, file key).
    pub file_settings: Vec<(&'static str, &'static str)>,
    pub rate: f64,
    pub start: Option<f64>,
    pub duration: Option<f64>,
    pub format: Output,
    pub output: Option<PathBuf>,
    pub truth: Option<PathBuf>,
    pub truth_errors: Option<PathBuf>,
    pub gps_time: Option<(u32, f64)>,
    /// Faults injected into protocol frames (the tally is shared with the job's copy).
    pub faults: Option<imu_emu::protocol::FaultInjector>,
    pub imu: imu_emu::errors::ImuModel,
    pub seed: u64,
    pub temperature: Option<imu_emu::errors::temperature::TemperatureProfile>,
    pub mounting_deg: Option<[f64; 3]>,
    pub lever_arm_m: Option<[f64; 3]>,
    pub vibration: imu_emu::errors::vibration::VibrationSpec,
    pub nodes: usize,
    pub model: ModelSettings,
}

/// What a command assumes when neither a flag nor the scene file says.
pub struct Defaults {
    /// IMU template.
    pub imu: &'static str,
    /// Output format or protocol.
    pub format: &'static str,
}

/// `generate`'s defaults: error-free records as CSV.
pub const GENERATE_DEFAULTS: Defaults = Defaults {
    imu: "ideal",
    format: "csv",
};

pub fn resolve(a: GenerateArgs) -> Result<Resolved> {
    resolve_with(a, &GENERATE_DEFAULTS)
}

/// Resolves flags over the scene file over `defaults`.
pub fn resolve_with(a: GenerateArgs, defaults: &Defaults) -> Result<Resolved> {
    let (file, file_path) = match &a.source.scene_file {
        Some(p) => (SceneFile::read(p)?, p.clone()),
        None => (SceneFile::default(), PathBuf::from("<flags>")),
    };
    let base = file_path
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let scene_from_file = a.source.trajectory.is_none() && a.source.scene.is_none();
    // Prefix naming the scene-file key, for a value that came from the file and not a flag.
    let in_file = |flag_given: bool, set_in_file: bool, key: &str| {
        if flag_given || !set_in_file {
            String::new()
        } else {
            format!("{}: `{key}`: ", file_path.display())
        }
    };
    let params_from_file = file.trajectory.params.is_some();
    let source = if let Some(t) = a.source.trajectory {
        SourceSpec::File(t)
    } else if let Some(s) = a.source.scene {
        let params = config::scene_params(&s, file.trajectory.params.as_ref())
            .map_err(|m| anyhow::anyhow!("{}: `trajectory.params`: {m}", file_path.display()))?;
        SourceSpec::Scene(s, params)
    } else {
        match (&file.trajectory.scene, &file.trajectory.file) {
            (Some(_), Some(_)) => bail!(
                "{}: `trajectory`: give either `scene` or `file`, not both",
                file_path.display()
            ),
            (_, Some(f)) => SourceSpec::File(base.join(f)),
            (Some(s), None) => SourceSpec::Scene(s.clone(), file.scene_params(s, &file_path)?),
            (None, None) => SourceSpec::Scene(
                scenes::DEFAULT.into(),
                file.scene_params(scenes::DEFAULT, &file_path)?,
            ),
        }
    };
    let at = in_file(a.imu.is_some(), file.imu.model.is_some(), "imu.model");
    let imu_name = a
        .imu
        .or(file.imu.model)
        .unwrap_or_else(|| defaults.imu.into());
    let imu = imu_emu::errors::template::load(&imu_name).map_err(|e| anyhow::anyhow!("{at}{e}"))?;
    let seed = a
        .seed
        .or(file.imu.seed)
        .unwrap_or(imu_emu::rng::DEFAULT_SEED);
    let temperature = file.temperature.profile(&file_path, &base)?;
    for (key, v) in [
        ("imu.mounting_deg", file.imu.mounting_deg),
        ("imu.lever_arm_m", file.imu.lever_arm_m),
    ] {
        if v.is_some_and(|v| v.iter().any(|x| !x.is_finite())) {
            bail!(
                "{}: `{key}`: expected three finite numbers",
                file_path.display()
            );
        }
    }
    let vibration = file.vibration.spec(&file_path)?;
    let at = in_file(
        a.format.is_some(),
        file.output.format.is_some(),
        "output.format",
    );
    let format_name = a
        .format
        .or(file.output.format)
        .unwrap_or_else(|| defaults.format.into());
    let protocol_file = a.protocol_file.clone();
    let mut format = match (Format::from_name(&format_name), &protocol_file) {
        (_, Some(p)) => Output::Frames(imu_emu::protocol::load(&p.to_string_lossy())?.1),
        (Some(f), None) => Output::Records(f),
        (None, None) => match imu_emu::protocol::load(&format_name) {
            Ok((_, plan)) if imu_emu::protocol::builtin_names().contains(&format_name.as_str()) => {
                Output::Frames(plan)
            }
            _ => bail!(
                "{at}output format `{format_name}`: expected `csv`, `bin` or a protocol ({})",
                imu_emu::protocol::builtin_names().join(", ")
            ),
        },
    };
    let at = in_file(
        a.interp.is_some(),
        file.engine.interpolation.is_some(),
        "engine.interpolation",
    );
    let interp = a
        .interp
        .or(file.engine.interpolation)
        .unwrap_or_else(|| "quintic".into());
    let degree = match interp.as_str() {
        "cubic" => Degree::Cubic,
        "quintic" => Degree::Quintic,
        other => bail!("{at}interpolation `{other}`: expected `cubic` or `quintic`"),
    };
    let at = in_file(
        a.stencil.is_some(),
        file.engine.stencil.is_some(),
        "engine.stencil",
    );
    let stencil = a
        .stencil
        .or(file.engine.stencil)
        .unwrap_or(ModelSettings::default().stencil);
    if !(3..=15).contains(&stencil) {
        bail!("{at}stencil {stencil}: expected 3 to 15 samples");
    }
    let at = in_file(
        a.quadrature.is_some(),
        file.engine.quadrature_nodes.is_some(),
        "engine.quadrature_nodes",
    );
    let nodes = a
        .quadrature
        .or(file.engine.quadrature_nodes)
        .unwrap_or(DEFAULT_NODES);
    if !(1..=imu_emu::quadrature::MAX_NODES).contains(&nodes) {
        bail!("{at}quadrature {nodes}: expected 1 to 16 Gauss–Legendre nodes");
    }
    let rate = a
        .rate
        .or(file.imu.rate_hz)
        .or(match &format {
            Output::Frames(p) => p.rate_hz,
            Output::Records(_) => None,
        })
        .or(imu.rate_hz)
        .unwrap_or(400.0);
    if let Output::Frames(plan) = &mut format {
        let at = in_file(a.rate.is_some(), file.imu.rate_hz.is_some(), "imu.rate_hz");
        plan.set_rate(rate)
            .map_err(|e| anyhow::anyhow!("{at}{e}"))?;
    }
    let faults = resolve_faults(&file.faults, &file_path, a.faults, &format, rate, seed)?;
    let file_settings = [
        (
            "rate",
            a.rate.is_none() && file.imu.rate_hz.is_some(),
            "imu.rate_hz",
        ),
        (
            "start",
            a.start.is_none() && file.output.start_s.is_some(),
            "output.start_s",
        ),
        (
            "duration",
            a.duration.is_none() && file.output.duration_s.is_some(),
            "output.duration_s",
        ),
    ]
    .into_iter()
    .filter(|s| s.1)
    .map(|(setting, _, key)| (setting, key))
    .collect();
    Ok(Resolved {
        source,
        scene_file: a.source.scene_file,
        scene_from_file,
        params_from_file,
        file_settings,
        rate,
        start: a.start.or(file.output.start_s),
        duration: a.duration.or(file.output.duration_s),
        format,
        output: a.output.or(file.output.path),
        truth: a.truth,
        truth_errors: a.truth_errors,
        gps_time: a.gps_time,
        faults,
        imu,
        seed,
        temperature,
        mounting_deg: file.imu.mounting_deg,
        lever_arm_m: file.imu.lever_arm_m,
        vibration,
        nodes,
        model: ModelSettings { degree, stencil },
    })
}

/// The scene file's `[faults]` plus the `--fault` flags, checked against the protocol.
fn resolve_faults(
    section: &config::FaultsSection,
    file_path: &Path,
    flags: Vec<imu_emu::protocol::FaultSpec>,
    format: &Output,
    rate: f64,
    seed: u64,
) -> Result<Option<imu_emu::protocol::FaultInjector>> {
    let mut specs = section.specs(file_path, rate)?;
    let from_file = specs.len();
    for f in &flags {
        f.validate(rate)
            .map_err(|e| anyhow::anyhow!("--fault {}: {e}", f.kind.name()))?;
    }
    specs.extend(flags);
    if specs.is_empty() {
        return Ok(None);
    }
    let Output::Frames(plan) = format else {
        bail!("faults apply to protocol frames: give --format PROTOCOL or --protocol-file");
    };
    for (i, s) in specs.iter().enumerate() {
        if let Err(e) = plan.supports(s.kind) {
            if i < from_file {
                bail!("{}: `faults.event[{i}].kind`: {e}", file_path.display());
            }
            bail!("--fault {}: {e}", s.kind.name());
        }
    }
    Ok(Some(imu_emu::protocol::FaultInjector::new(
        specs,
        rate,
        section.seed.unwrap_or(seed),
    )))
}

/// Parses `WEEK,SECONDS` (seconds of week in [0, 604800)).
pub fn parse_gps_time(s: &str) -> Result<(u32, f64), String> {
    let (w, sow) = s
        .split_once(',')
        .ok_or("expected WEEK,SECONDS_OF_WEEK, e.g. 2209,491674.0")?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("week `{w}` is not a whole number"))?;
    let sow: f64 = sow
        .trim()
        .parse()
        .map_err(|_| format!("seconds `{sow}` is not a number"))?;
    if !(0.0..604_800.0).contains(&sow) {
        return Err(format!("seconds of week {sow} outside [0, 604800)"));
    }
    Ok((w, sow))
}

/// What `generate` writes: the record contract or a protocol's frames.
#[derive(Clone, Debug)]
pub enum Output {
    Records(Format),
    Frames(imu_emu::protocol::Plan),
}

impl Resolved {
    /// The error chain of the IMU model with the scene's temperature, mounting, lever arm and
    /// vibration; `None` when nothing would change the error-free records. Prints the seed.
    pub fn chain(&self, grid: &Grid) -> Result<Option<ErrorChain>> {
        let r = self;
        let mut chain = imu_emu::errors::ErrorChain::new(&r.imu, grid.rate_hz, r.seed);
        if let Some(p) = r.temperature.clone() {
            chain = chain.with_temperature(p, &r.imu);
        }
        if let Some([roll, pitch, yaw]) = r.mounting_deg {
            // The file gives the case's attitude in the body (C_c^b); the chain wants C_b^c.
            let q_c_b = imu_emu::math::quat_from_euler(
                roll.to_radians(),
                pitch.to_radians(),
                yaw.to_radians(),
            );
            chain = chain.with_mounting(q_c_b.conj());
        }
        if let Some(r) = r.lever_arm_m {
            chain = chain.with_lever_arm(imu_emu::math::Vec3(r));
        }
        if !r.vibration.is_empty() {
            let v = imu_emu::errors::vibration::Vibration::new(
                &r.vibration,
                1.0 / grid.rate_hz,
                r.seed,
            )
            .map_err(|e| {
                anyhow::anyhow!(
                    "{}: `vibration`: {e}",
                    r.scene_file
                        .as_deref()
                        .unwrap_or(Path::new("<flags>"))
                        .display()
                )
            })?;
            for s in v.random_summaries() {
                if let Some(f) = s.truncated_at_hz {
                    eprintln!(
                        "imu-emu: warning: random vibration on {} {} cut at the Nyquist frequency {f} Hz",
                        s.sensor.name(),
                        ["x", "y", "z"][s.axis]
                    );
                }
            }
            chain = chain.with_vibration(v);
        }
        if r.imu.grade != "ideal" && !r.imu.has_error_figures() {
            eprintln!(
                "imu-emu: warning: template `{}` has no error figures (no public source was found; see its file): the output is error-free apart from the interface's quantization and range",
                r.imu.name
            );
        }
        let chain = (!chain.is_empty()).then_some(chain);
        if chain.is_some() {
            eprintln!("imu-emu: IMU `{}`, seed {}", r.imu.name, r.seed);
        }
        Ok(chain)
    }

    /// The job's encoding; side files of a frame stream are CSV.
    pub fn encoding(&self) -> job::Encoding {
        match &self.format {
            Output::Records(f) => job::Encoding::Records(*f),
            Output::Frames(plan) => self.frames_encoding(plan.clone()),
        }
    }

    /// Frames of `plan` with this run's GPS time reference; side files in CSV.
    pub fn frames_encoding(&self, plan: imu_emu::protocol::Plan) -> job::Encoding {
        job::Encoding::Frames {
            plan: Box::new(plan),
            state: imu_emu::protocol::EncoderState {
                gps_week0: self.gps_time.map_or(0, |g| g.0),
                gps_sow0: self.gps_time.map_or(0.0, |g| g.1),
                faults: self.faults.clone().map(Box::new),
                ..Default::default()
            },
            temperature: 25.0,
            side: Format::Csv,
        }
    }

    /// Adds the file (and scene-file key) at fault to an error the library reports without it.
    pub fn locate(&self, e: JobError) -> anyhow::Error {
        let place = match (&e, &self.source, &self.scene_file) {
            (JobError::UnknownScene(_), _, Some(f)) if self.scene_from_file => {
                Some(format!("{}: `trajectory.scene`", f.display()))
            }
            (JobError::SceneParam(p), _, Some(f)) if self.params_from_file => {
                Some(format!("{}: `trajectory.params.{}`", f.display(), p.key))
            }
            (JobError::Span { .. }, _, _) => {
                // The scene-file keys that set the span, then the trajectory file it misses.
                let mut place: Vec<String> = Vec::new();
                if let Some(f) = &self.scene_file {
                    let keys: Vec<String> = (self.file_settings.iter())
                        .filter(|s| s.0 == "start" || s.0 == "duration")
                        .map(|s| format!("`{}`", s.1))
                        .collect();
                    if !keys.is_empty() {
                        place.push(format!("{}: {}", f.display(), keys.join(", ")));
                    }
                }
                if let SourceSpec::File(path) = &self.source {
                    place.push(path.display().to_string());
                }
                (!place.is_empty()).then(|| place.join(": "))
            }
            (JobError::Setting { key, .. }, _, Some(f)) => self
                .file_settings
                .iter()
                .find(|s| s.0 == *key)
                .map(|s| format!("{}: `{}`", f.display(), s.1)),
            _ => None,
        };
        match place {
            Some(place) => anyhow::Error::new(e).context(place),
            None => e.into(),
        }
    }
}
