//! `imu-emu`: the command-line front end. Flags and files here; everything else in the library.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};

use imu_emu::config::{self, SceneFile};
use imu_emu::generator::DEFAULT_NODES;
use imu_emu::job::{self, JobError, SourceSpec};
use imu_emu::motion::sampled::{Degree, ModelSettings};
use imu_emu::output::{AtomicFile, Format};
use imu_emu::scenes;

/// IMU simulator and emulator: error-free and corrupted inertial signals from a trajectory.
#[derive(Parser)]
#[command(name = "imu-emu", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Generate IMU records offline, as fast as the machine allows.
    Generate(Box<GenerateArgs>),
    /// Write a scene's reference trajectory as trajectory CSV (the input format).
    Trajectory(TrajectoryArgs),
    /// List the built-in scenes.
    Scenes,
    /// List the built-in IMU templates with their headline figures.
    Templates,
    /// Decode a frame stream (file or stdin) to CSV, counting check failures and counter gaps.
    Decode(DecodeArgs),
}

#[derive(clap::Args)]
struct DecodeArgs {
    /// Built-in protocol (kvh1750, imar-ixcom, novatel-rawimusx, stim300).
    #[arg(long, conflicts_with = "protocol_file")]
    protocol: Option<String>,
    /// A protocol spec file.
    #[arg(long)]
    protocol_file: Option<PathBuf>,
    /// Input file, or - for stdin [default: stdin].
    input: Option<PathBuf>,
}

#[derive(clap::Args)]
struct SourceArgs {
    /// Scene file (TOML); flags override it.
    scene_file: Option<PathBuf>,
    /// Built-in scene: static, straight, circle, survey, coning, polar.
    #[arg(long, conflicts_with = "trajectory")]
    scene: Option<String>,
    /// Trajectory CSV: t,lat,lon,h,vn,ve,vd,roll,pitch,yaw.
    #[arg(long)]
    trajectory: Option<PathBuf>,
}

#[derive(clap::Args)]
struct GenerateArgs {
    #[command(flatten)]
    source: SourceArgs,
    /// IMU output rate (Hz) [default: 400].
    #[arg(long, allow_negative_numbers = true)]
    rate: Option<f64>,
    /// Duration (s) [default: to the end of the trajectory; 60 s for unbounded scenes].
    #[arg(long, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Start time t₀ (s) [default: the trajectory's start].
    #[arg(long, allow_negative_numbers = true)]
    start: Option<f64>,
    /// Output format: csv, bin, or a protocol's frames (kvh1750, imar-ixcom, novatel-rawimusx,
    /// stim300) [default: csv].
    #[arg(long)]
    format: Option<String>,
    /// Frames of a protocol described in a spec file (protocols/README.md).
    #[arg(long)]
    protocol_file: Option<PathBuf>,
    /// GPS time of record time 0 for frames with GPS time fields, as WEEK,SECONDS_OF_WEEK
    /// [default: 0,0 — record times are GPS seconds since 1980-01-06].
    #[arg(long, value_parser = parse_gps_time)]
    gps_time: Option<(u32, f64)>,
    /// Output file, or - for stdout [default: stdout].
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// IMU error model: a template name (`imu-emu templates`) or a template file [default: ideal].
    #[arg(long)]
    imu: Option<String>,
    /// Master seed of every random error process [default: 20261124].
    #[arg(long)]
    seed: Option<u64>,
    /// Also write the error-free records here (same format and time grid).
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Also write the error each stage injected into each record here (same format).
    #[arg(long)]
    truth_errors: Option<PathBuf>,
    /// Gauss–Legendre nodes per interval (order 2n) [default: 3].
    #[arg(long)]
    quadrature: Option<usize>,
    /// Motion-model polynomials for trajectory files: cubic or quintic [default: quintic].
    #[arg(long)]
    interp: Option<String>,
    /// Finite-difference stencil (samples) for knot derivatives [default: 9].
    #[arg(long)]
    stencil: Option<usize>,
}

#[derive(clap::Args)]
struct TrajectoryArgs {
    /// Built-in scene.
    #[arg(long, default_value = scenes::DEFAULT)]
    scene: String,
    /// Sample rate (Hz).
    #[arg(long, default_value_t = 100.0)]
    rate: f64,
    /// Duration (s) [default: the scene's; 60 s for unbounded scenes].
    #[arg(long)]
    duration: Option<f64>,
    /// Output file, or - for stdout.
    #[arg(short, long, default_value = "-")]
    output: PathBuf,
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Generate(a) => generate(*a),
        Command::Trajectory(a) => export_trajectory(a),
        Command::Templates => list_templates(),
        Command::Decode(a) => decode(a),
        Command::Scenes => {
            for name in scenes::NAMES {
                println!(
                    "{name}{}",
                    if name == scenes::DEFAULT {
                        " (default)"
                    } else {
                        ""
                    }
                );
            }
            Ok(())
        }
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// The settings of a generate run after merging the scene file and the flags.
struct Resolved {
    source: SourceSpec,
    /// The scene file, if any, and whether the scene name and the parameters came from it.
    scene_file: Option<PathBuf>,
    scene_from_file: bool,
    params_from_file: bool,
    /// Settings checked later whose value came from the scene file: (setting, file key).
    file_settings: Vec<(&'static str, &'static str)>,
    rate: f64,
    start: Option<f64>,
    duration: Option<f64>,
    format: Output,
    output: Option<PathBuf>,
    truth: Option<PathBuf>,
    truth_errors: Option<PathBuf>,
    gps_time: Option<(u32, f64)>,
    imu: imu_emu::errors::ImuModel,
    seed: u64,
    temperature: Option<imu_emu::errors::temperature::TemperatureProfile>,
    mounting_deg: Option<[f64; 3]>,
    lever_arm_m: Option<[f64; 3]>,
    vibration: imu_emu::errors::vibration::VibrationSpec,
    nodes: usize,
    model: ModelSettings,
}

fn resolve(a: GenerateArgs) -> Result<Resolved> {
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
    let imu_name = a.imu.or(file.imu.model).unwrap_or_else(|| "ideal".into());
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
        .unwrap_or_else(|| "csv".into());
    let protocol_file = a.protocol_file.clone();
    let format = match (Format::from_name(&format_name), &protocol_file) {
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
        rate: a
            .rate
            .or(file.imu.rate_hz)
            .or(match &format {
                Output::Frames(p) => p.rate_hz,
                Output::Records(_) => None,
            })
            .or(imu.rate_hz)
            .unwrap_or(400.0),
        start: a.start.or(file.output.start_s),
        duration: a.duration.or(file.output.duration_s),
        format,
        output: a.output.or(file.output.path),
        truth: a.truth,
        truth_errors: a.truth_errors,
        gps_time: a.gps_time,
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

/// Parses `WEEK,SECONDS` (seconds of week in [0, 604800)).
fn parse_gps_time(s: &str) -> Result<(u32, f64), String> {
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
enum Output {
    Records(Format),
    Frames(imu_emu::protocol::Plan),
}

impl Resolved {
    /// The job's encoding; side files of a frame stream are CSV.
    fn encoding(&self) -> job::Encoding {
        match &self.format {
            Output::Records(f) => job::Encoding::Records(*f),
            Output::Frames(plan) => job::Encoding::Frames {
                plan: Box::new(plan.clone()),
                state: imu_emu::protocol::EncoderState {
                    frames: 0,
                    gps_week0: self.gps_time.map_or(0, |g| g.0),
                    gps_sow0: self.gps_time.map_or(0.0, |g| g.1),
                },
                temperature: 25.0,
                side: Format::Csv,
            },
        }
    }

    /// Adds the file (and scene-file key) at fault to an error the library reports without it.
    fn locate(&self, e: JobError) -> anyhow::Error {
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

fn generate(a: GenerateArgs) -> Result<()> {
    let r = resolve(a)?;
    let motion = job::build_motion(&r.source, r.model).map_err(|e| r.locate(e))?;
    let grid = job::plan(&motion, r.rate, r.start, r.duration).map_err(|e| r.locate(e))?;
    let mut chain = imu_emu::errors::ErrorChain::new(&r.imu, grid.rate_hz, r.seed);
    if let Some(p) = r.temperature.clone() {
        chain = chain.with_temperature(p, &r.imu);
    }
    if let Some([roll, pitch, yaw]) = r.mounting_deg {
        // The file gives the case's attitude in the body (C_c^b); the chain wants C_b^c.
        let q_c_b =
            imu_emu::math::quat_from_euler(roll.to_radians(), pitch.to_radians(), yaw.to_radians());
        chain = chain.with_mounting(q_c_b.conj());
    }
    if let Some(r) = r.lever_arm_m {
        chain = chain.with_lever_arm(imu_emu::math::Vec3(r));
    }
    if !r.vibration.is_empty() {
        let v =
            imu_emu::errors::vibration::Vibration::new(&r.vibration, 1.0 / grid.rate_hz, r.seed)
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
    let show = std::io::stderr().is_terminal() && grid.count >= 500_000;
    let bar = if show {
        indicatif::ProgressBar::new(grid.count)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let started = Instant::now();
    // Side files (error-free truth, injected errors): written beside the output, committed
    // only when the whole run succeeded.
    let side = |p: &Option<PathBuf>| -> Result<Option<(AtomicFile, PathBuf)>> {
        p.as_ref()
            .map(|p| {
                Ok((
                    AtomicFile::create(p).with_context(|| format!("creating {}", p.display()))?,
                    p.clone(),
                ))
            })
            .transpose()
    };
    let mut truth_file = side(&r.truth)?;
    let mut errors_file = side(&r.truth_errors)?;
    {
        let mut truth_out = truth_file
            .as_mut()
            .map(|(f, _)| std::io::BufWriter::with_capacity(1 << 20, f));
        let mut errors_out = errors_file
            .as_mut()
            .map(|(f, _)| std::io::BufWriter::with_capacity(1 << 20, f));
        let truth_w = truth_out.as_mut().map(|w| w as &mut dyn Write);
        let errors_w = errors_out.as_mut().map(|w| w as &mut dyn Write);
        let to_stdout = r.output.as_deref().is_none_or(|p| p == Path::new("-"));
        let mut file = match (&r.output, to_stdout) {
            (Some(path), false) => Some((
                AtomicFile::create(path).with_context(|| format!("creating {}", path.display()))?,
                path.clone(),
            )),
            _ => None,
        };
        let label = file
            .as_ref()
            .map_or("stdout".to_string(), |(_, p)| p.display().to_string());
        {
            let mut out: Box<dyn Write + '_> = match file.as_mut() {
                Some((f, _)) => Box::new(std::io::BufWriter::with_capacity(1 << 20, f)),
                None => Box::new(std::io::BufWriter::with_capacity(
                    1 << 20,
                    std::io::stdout().lock(),
                )),
            };
            job::run(
                motion,
                grid,
                r.nodes,
                r.encoding(),
                chain,
                &mut out,
                truth_w,
                errors_w,
                |k| bar.set_position(k),
            )
            .with_context(|| format!("writing {label}"))?;
            out.flush()?;
        }
        if let Some((f, path)) = file {
            f.commit()
                .with_context(|| format!("finishing {}", path.display()))?;
        }
        for w in [truth_out.as_mut(), errors_out.as_mut()]
            .into_iter()
            .flatten()
        {
            w.flush()?;
        }
    }
    for (f, p) in [truth_file, errors_file].into_iter().flatten() {
        f.commit()
            .with_context(|| format!("finishing {}", p.display()))?;
    }
    bar.finish_and_clear();
    if show {
        let s = started.elapsed().as_secs_f64();
        eprintln!(
            "{} records in {s:.2} s ({:.3e} records/s)",
            grid.count,
            grid.count as f64 / s
        );
    }
    Ok(())
}

/// `imu-emu decode`: frames in, CSV of the decoded values out, a tally on stderr.
fn decode(a: DecodeArgs) -> Result<()> {
    use std::io::Read;
    let spec = match (&a.protocol, &a.protocol_file) {
        (Some(n), _) => n.clone(),
        (None, Some(p)) => p.to_string_lossy().into_owned(),
        (None, None) => bail!(
            "give --protocol NAME ({}) or --protocol-file FILE",
            imu_emu::protocol::builtin_names().join(", ")
        ),
    };
    let (_, plan) = imu_emu::protocol::load(&spec)?;
    let mut input: Box<dyn Read> = match a.input.as_deref() {
        None => Box::new(std::io::stdin().lock()),
        Some(p) if p == Path::new("-") => Box::new(std::io::stdin().lock()),
        Some(p) => {
            Box::new(std::fs::File::open(p).with_context(|| format!("opening {}", p.display()))?)
        }
    };
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    writeln!(out, "{}", plan.value_names().join(","))?;
    let mut dec = imu_emu::protocol::StreamDecoder::new(plan);
    let mut buf = vec![0u8; 1 << 16];
    let mut fmt = ryu::Buffer::new();
    let mut line = String::new();
    loop {
        let n = input.read(&mut buf)?;
        if n == 0 {
            break;
        }
        let mut err = Ok(());
        dec.feed(&buf[..n], |d| {
            line.clear();
            for (i, (_, v)) in d.values.iter().enumerate() {
                if i > 0 {
                    line.push(',');
                }
                line.push_str(fmt.format(*v));
            }
            line.push('\n');
            if err.is_ok() {
                err = out.write_all(line.as_bytes());
            }
        });
        err?;
    }
    out.flush()?;
    let s = dec.stats;
    eprintln!(
        "imu-emu decode: {} frames, {} check failures, {} counter gaps, {} bytes skipped",
        s.frames, s.check_failures, s.counter_gaps, s.skipped_bytes
    );
    Ok(())
}

/// `imu-emu templates`: the built-in IMU templates and their headline figures.
fn list_templates() -> Result<()> {
    use std::f64::consts::PI;
    println!(
        "{:<11} {:<11} {:>12} {:>13} {:>12} {:>13}  description",
        "name", "grade", "gyro BI", "ARW", "accel BI", "VRW"
    );
    println!(
        "{:<11} {:<11} {:>12} {:>13} {:>12} {:>13}",
        "", "", "deg/h", "deg/sqrt(h)", "ug", "m/s/sqrt(h)"
    );
    for name in imu_emu::errors::template::builtin_names() {
        let m = imu_emu::errors::template::load(name)?;
        let deg_h = 180.0 / PI * 3600.0;
        println!(
            "{:<11} {:<11} {:>12.3} {:>13.4} {:>12.1} {:>13.4}  {}",
            m.name,
            m.grade,
            m.gyro.bias_instability[0] * deg_h,
            m.gyro.noise[0] * 180.0 / PI * 60.0,
            m.accel.bias_instability[0] / imu_emu::units::G0 * 1e6,
            m.accel.noise[0] * 60.0,
            m.description
        );
    }
    Ok(())
}

fn export_trajectory(a: TrajectoryArgs) -> Result<()> {
    let params = scenes::SceneParams::defaults_for(&a.scene);
    let motion = job::build_motion(
        &SourceSpec::Scene(a.scene.clone(), params),
        ModelSettings::default(),
    )?;
    // Samples at t₀ + k/rate for k = 0..=n, including the start.
    let grid = job::plan(&motion, a.rate, None, a.duration)?;
    let text = imu_emu::trajectory::sample_motion(
        &motion,
        grid.t0,
        grid.rate_hz,
        grid.count,
        Some(&format!("imu-emu trajectory of scene {}", a.scene)),
    );
    if a.output == Path::new("-") {
        std::io::stdout().write_all(text.as_bytes())?;
    } else {
        let mut f = AtomicFile::create(&a.output)
            .with_context(|| format!("creating {}", a.output.display()))?;
        f.write_all(text.as_bytes())?;
        f.commit()?;
    }
    Ok(())
}
