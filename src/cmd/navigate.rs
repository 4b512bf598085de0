//! `imu-emu navigate`: records in, the free-inertial trajectory and its errors against a
//! reference out.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use imu_emu::input::RecordReader;
use imu_emu::nav::Settings;
use imu_emu::nav::replay::{ERROR_HEADER, Replay, Step};
use imu_emu::output::Format;
use imu_emu::output::text::TextOut;

#[derive(clap::Args)]
pub struct NavigateArgs {
    /// Records to navigate (`imu-emu generate` output, CSV or binary), or - for stdin.
    pub input: PathBuf,
    /// Input format: csv or bin [default: bin for a .bin file, else csv].
    #[arg(long)]
    pub format: Option<String>,
    /// The reference the records were generated from: a scene file (`--scene-file`, with its
    /// scene parameters or trajectory file), a built-in scene or a trajectory CSV.
    #[command(flatten)]
    pub reference: super::setup::ReferenceArgs,
    /// IMU rate (Hz) [default: from the first two record times].
    #[arg(long)]
    pub rate: Option<f64>,
    /// Write the navigated trajectory here (trajectory CSV), or - for stdout.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Write the errors against the reference here (CSV: position m NED, velocity m/s NED,
    /// attitude rad NED).
    #[arg(long)]
    pub errors: Option<PathBuf>,
    /// Navigator reconstruction window (intervals, 1–8) [default: 6].
    #[arg(long)]
    pub samples: Option<usize>,
    /// Navigator collocation stages (1–4, order 2s) [default: 3].
    #[arg(long)]
    pub stages: Option<usize>,
    /// GNSS fixes (`generate --gnss-truth` CSV): navigate GNSS-aided (15-state loosely coupled
    /// filter), and report the free-inertial error next to the aided one.
    #[arg(long)]
    pub gnss: Option<PathBuf>,
    /// The fixes' 1σ position (m) and velocity (m/s) errors the filter assumes, per axis.
    #[arg(long, value_name = "POS,VEL", default_value = "1,0.1")]
    pub gnss_sigma: String,
    /// The GNSS antenna from the IMU reference point, body axes (m).
    #[arg(
        long,
        value_name = "X,Y,Z",
        default_value = "0,0,0",
        allow_hyphen_values = true
    )]
    pub gnss_lever_arm: String,
}

/// `N` comma-separated finite numbers of flag `flag`.
fn numbers<const N: usize>(flag: &str, text: &str) -> Result<[f64; N]> {
    let v: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .with_context(|| format!("{flag} `{text}`: expected {N} comma-separated numbers"))?;
    v.try_into()
        .map_err(|_| anyhow::anyhow!("{flag} `{text}`: expected {N} comma-separated numbers"))
}

/// `imu-emu navigate`: the records navigated against the reference; the trajectory and the
/// errors written where asked, the summary printed (on stderr when a CSV goes to stdout).
pub fn navigate(a: NavigateArgs) -> Result<()> {
    let format = match a.format.as_deref() {
        Some(f) => Format::from_name(f)
            .with_context(|| format!("--format `{f}`: expected `csv` or `bin`"))?,
        None if a.input.extension().is_some_and(|e| e == "bin") => Format::Bin,
        None => Format::Csv,
    };
    if !a.reference.given() {
        bail!("give the reference: --scene-file FILE, --scene NAME or --trajectory FILE");
    }
    let motion = a.reference.builder()?.motion()?;
    let settings = Settings {
        samples: a.samples.unwrap_or(Settings::default().samples),
        stages: a.stages.unwrap_or(Settings::default().stages),
    };
    let reader = RecordReader::open(&a.input, format)?;
    let name = a.input.display().to_string();
    let mut replay = Replay::start(&name, reader, motion, a.rate, settings)?;
    if let Some(path) = &a.gnss {
        let [sp, sv] = numbers::<2>("--gnss-sigma", &a.gnss_sigma)?;
        if !(sp > 0.0 && sv > 0.0) {
            bail!("--gnss-sigma `{}`: both σ must be positive", a.gnss_sigma);
        }
        let lever_arm_m = numbers::<3>("--gnss-lever-arm", &a.gnss_lever_arm)?;
        replay.aid(path, sp, sv, lever_arm_m)?;
    }
    let open = |p: &PathBuf| TextOut::create(p);
    let mut traj = a.output.as_ref().map(open).transpose()?;
    let mut errs = a.errors.as_ref().map(open).transpose()?;
    let outs = [&traj, &errs];
    let to_stdout = (outs.iter()).any(|o| o.as_ref().is_some_and(TextOut::is_stdout));
    // Standard output (a CSV or the summary) is the only output when no file is written.
    let alone = !(outs.iter()).any(|o| o.as_ref().is_some_and(|o| !o.is_stdout()));
    // A file's errors name it; standard output's say which output it carried.
    let named = move |stdout: bool, what: &str, e: std::io::Error| match stdout {
        true => super::stdout::failed(e, what, alone),
        false => anyhow::Error::from(e),
    };
    let (mut row, mut fmt) = (String::new(), ryu::Buffer::new());
    let mut write = |step: &Step, header: bool| -> Result<()> {
        if let Some(w) = &mut traj {
            row.clear();
            if header {
                row.push_str(&imu_emu::trajectory::COLUMNS.join(","));
                row.push('\n');
            }
            step.trajectory_row(&mut row);
            (w.write_all(row.as_bytes())).map_err(|e| named(w.is_stdout(), "the trajectory", e))?;
        }
        if let Some(w) = &mut errs {
            row.clear();
            if header {
                row.push_str(ERROR_HEADER);
            }
            step.error_row(&mut row, &mut fmt);
            (w.write_all(row.as_bytes())).map_err(|e| named(w.is_stdout(), "the errors", e))?;
        }
        Ok(())
    };
    write(&replay.first_step(), true)?;
    let summary = replay.run(|s| write(s, false))?;
    for (w, what) in [(traj, "the trajectory"), (errs, "the errors")] {
        if let Some(w) = w {
            let stdout = w.is_stdout();
            w.finish().map_err(|e| named(stdout, what, e))?;
        }
    }
    if to_stdout {
        eprint!("{summary}");
        Ok(())
    } else {
        super::stdout::write(summary.to_string().as_bytes(), "the summary", alone)
    }
}
