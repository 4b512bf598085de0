//! The flags every simulating command shares, turned into a library
//! [`SimulationBuilder`] (the scene file first, the flags over it).

use std::path::PathBuf;

use anyhow::Result;

use imu_emu::protocol::FaultSpec;
use imu_emu::sim::{SimulationBuilder, SourceChoice};

/// Where the trajectory comes from: a scene file, a built-in scene or a trajectory CSV.
#[derive(clap::Args)]
pub struct SourceArgs {
    /// Scene file (TOML, `examples/survey.toml`); flags override it.
    pub scene_file: Option<PathBuf>,
    /// Built-in scene: static, straight, circle, survey, coning, polar [default: the scene
    /// file's, else survey].
    #[arg(long, conflicts_with = "trajectory")]
    pub scene: Option<String>,
    /// Trajectory CSV: t,lat,lon,h,vn,ve,vd,roll,pitch,yaw.
    #[arg(long, conflicts_with = "motion_def")]
    pub trajectory: Option<PathBuf>,
    /// Motion definition: a native `[motion]` TOML or a gnss-ins-sim motion-definition CSV
    /// (docs/motion-definitions.md).
    #[arg(long, conflicts_with = "scene")]
    pub motion_def: Option<PathBuf>,
}

impl SourceArgs {
    /// The source these flags name.
    pub fn choice(&self) -> SourceChoice {
        choice(
            &self.scene_file,
            &self.scene,
            &self.trajectory,
            &self.motion_def,
        )
    }

    /// How messages name the source.
    pub fn name(&self) -> String {
        self.choice().name()
    }

    /// The builder of the scene file (if any) with the scene or trajectory flag over it.
    pub fn builder(&self) -> Result<SimulationBuilder> {
        Ok(self.choice().builder()?)
    }
}

/// The reference trajectory of a command whose positional argument is something else
/// (`navigate`, `compare`): the same three sources, the scene file as `--scene-file`.
#[derive(clap::Args)]
pub struct ReferenceArgs {
    /// Scene file (TOML) whose `[trajectory]` (scene and parameters, or file) is the reference.
    #[arg(long)]
    pub scene_file: Option<PathBuf>,
    /// Built-in scene (the scene file's parameters apply, else the scene's defaults).
    #[arg(long, conflicts_with = "trajectory")]
    pub scene: Option<String>,
    /// Trajectory CSV: t,lat,lon,h,vn,ve,vd,roll,pitch,yaw.
    #[arg(long, conflicts_with = "motion_def")]
    pub trajectory: Option<PathBuf>,
    /// Motion definition: a native `[motion]` TOML or a gnss-ins-sim motion-definition CSV
    /// (docs/motion-definitions.md).
    #[arg(long, conflicts_with = "scene")]
    pub motion_def: Option<PathBuf>,
}

impl ReferenceArgs {
    /// The reference these flags name.
    pub fn choice(&self) -> SourceChoice {
        choice(
            &self.scene_file,
            &self.scene,
            &self.trajectory,
            &self.motion_def,
        )
    }

    /// Whether any source was given.
    pub fn given(&self) -> bool {
        self.choice().given()
    }

    /// How messages name the reference.
    pub fn name(&self) -> String {
        self.choice().name()
    }

    /// The builder of the reference (see [`SourceArgs::builder`]).
    pub fn builder(&self) -> Result<SimulationBuilder> {
        Ok(self.choice().builder()?)
    }
}

fn choice(
    scene_file: &Option<PathBuf>,
    scene: &Option<String>,
    trajectory: &Option<PathBuf>,
    motion_def: &Option<PathBuf>,
) -> SourceChoice {
    SourceChoice {
        scene_file: scene_file.clone(),
        scene: scene.clone(),
        trajectory: trajectory.clone(),
        motion_def: motion_def.clone(),
    }
}

/// The simulation flags of `generate` and `run`: one set, the same names and meanings.
#[derive(clap::Args)]
pub struct SimArgs {
    #[command(flatten)]
    pub source: SourceArgs,
    /// IMU error model: a template name (`imu-emu templates`) or a template file [default:
    /// the scene file's, else ideal in `generate` and ln200 in `run`].
    #[arg(long)]
    pub imu: Option<String>,
    /// IMU output rate (Hz) [default: the scene file's, else the protocol's nominal rate,
    /// else the template's, else 400].
    #[arg(long, allow_negative_numbers = true)]
    pub rate: Option<f64>,
    /// Duration (s) [default: to the end of the trajectory; for unbounded scenes 60 s in
    /// `generate`, until Ctrl-C in `run`].
    #[arg(long, allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// Start time t₀ (s) [default: the trajectory's start].
    #[arg(long, allow_negative_numbers = true)]
    pub start: Option<f64>,
    /// Output format: csv, bin, or a protocol's frames (`imu-emu decode --help` lists the
    /// built-in protocols) [default: the scene file's, else csv in `generate` and ln200
    /// frames in `run`].
    #[arg(long, alias = "protocol", conflicts_with = "protocol_file")]
    pub format: Option<String>,
    /// Frames of a protocol described in a spec file (protocols/README.md).
    #[arg(long)]
    pub protocol_file: Option<PathBuf>,
    /// GPS time of record time 0 for frames with GPS time fields, as WEEK,SECONDS_OF_WEEK
    /// [default: 0,0 — record times are GPS seconds since 1980-01-06].
    #[arg(long, value_parser = imu_emu::timebase::parse_week_seconds)]
    pub gps_time: Option<(u32, f64)>,
    /// Inject a fault into protocol frames: KIND@T1,T2,… (record times, s) or KIND~RATE (mean
    /// events per second); KIND is corrupt-check, drop, duplicate, stale-counter or status.
    /// Repeatable; adds to the scene file's [faults].
    #[arg(long = "fault", value_parser = FaultSpec::parse_flag)]
    pub faults: Vec<FaultSpec>,
    /// Master seed of every random error process [default: the scene file's, else 20261124].
    #[arg(long)]
    pub seed: Option<u64>,
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

impl SimArgs {
    /// The builder: the scene file, these flags over it, `imu` and `format` when neither
    /// says.
    pub fn builder(&self, imu: &str, format: &str) -> Result<SimulationBuilder> {
        let mut b = self.source.builder()?.defaults(imu, format);
        if let Some(v) = &self.imu {
            b = b.imu(v);
        }
        if let Some(v) = self.rate {
            b = b.rate(v);
        }
        if let Some(v) = self.duration {
            b = b.duration(v);
        }
        if let Some(v) = self.start {
            b = b.start(v);
        }
        if let Some(v) = &self.format {
            b = b.format(v);
        }
        if let Some(v) = &self.protocol_file {
            b = b.protocol_file(v);
        }
        if let Some((week, sow)) = self.gps_time {
            b = b.gps_time(week, sow);
        }
        for f in &self.faults {
            b = b.fault(f.clone());
        }
        if let Some(v) = self.seed {
            b = b.seed(v);
        }
        if let Some(v) = self.quadrature {
            b = b.quadrature_nodes(v);
        }
        if let Some(v) = &self.interp {
            b = b.interpolation(v);
        }
        if let Some(v) = self.stencil {
            b = b.stencil(v);
        }
        Ok(b)
    }
}

/// Prints what the user should know about a built run before it starts: for one IMU with
/// errors its template and seed, for a rig each unit's records, rate and seed.
pub fn announce_run(run: &imu_emu::run::Run) {
    for line in run.announcements() {
        eprintln!("imu-emu: {line}");
    }
}
