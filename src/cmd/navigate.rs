//! `imu-emu navigate`: records in, the free-inertial trajectory and its errors against a
//! reference out.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use imu_emu::csvio::num;
use imu_emu::input::RecordReader;
use imu_emu::math::Vec3;
use imu_emu::math::euler_from_quat;
use imu_emu::motion::limits::{MAX_ACCEL_M_S2, MAX_RATE_RAD_S};
use imu_emu::motion::{Motion, Pose};
use imu_emu::nav::aided::{AidedConfig, AidedNavigator};
use imu_emu::nav::gnss_fixes::{FixEpoch, read_fixes};
use imu_emu::nav::{NavState, Navigator, Settings, StateError};
use imu_emu::output::{AtomicFile, Format};
use imu_emu::record::Record;

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

/// The aided navigator and the fixes still to apply, from `--gnss`.
fn aided(
    a: &NavigateArgs,
    start: &Pose,
    rate: f64,
    settings: Settings,
) -> Result<Option<(AidedNavigator, Vec<FixEpoch>)>> {
    let Some(path) = &a.gnss else {
        return Ok(None);
    };
    let [sp, sv] = numbers::<2>("--gnss-sigma", &a.gnss_sigma)?;
    if !(sp > 0.0 && sv > 0.0) {
        bail!("--gnss-sigma `{}`: both σ must be positive", a.gnss_sigma);
    }
    let lever_arm_m = numbers::<3>("--gnss-lever-arm", &a.gnss_lever_arm)?;
    let mut fixes = read_fixes(path, Vec3::repeat(sp), Vec3::repeat(sv))?;
    fixes.reverse();
    let cfg = AidedConfig {
        lever_arm_m,
        ..AidedConfig::default()
    };
    let nav = AidedNavigator::new(NavState::from_pose(start), rate, settings, cfg)?;
    Ok(Some((nav, fixes)))
}

/// Header of the error CSV.
const ERROR_HEADER: &str =
    "t,north_m,east_m,down_m,vn_m_s,ve_m_s,vd_m_s,att_n_rad,att_e_rad,att_d_rad,position_m\n";

/// A CSV output: a file committed only when the run succeeds, or stdout.
enum Sink {
    Stdout,
    File(AtomicFile, PathBuf),
}

impl Sink {
    fn open(path: &Option<PathBuf>) -> Result<Option<Sink>> {
        Ok(match path {
            None => None,
            Some(p) if p == Path::new("-") => Some(Sink::Stdout),
            Some(p) => Some(Sink::File(
                AtomicFile::create(p).with_context(|| format!("creating {}", p.display()))?,
                p.clone(),
            )),
        })
    }

    /// Writes and clears `text`.
    fn drain(&mut self, text: &mut String) -> Result<()> {
        match self {
            Sink::Stdout => std::io::stdout().lock().write_all(text.as_bytes())?,
            Sink::File(f, p) => f
                .write_all(text.as_bytes())
                .with_context(|| format!("writing {}", p.display()))?,
        }
        text.clear();
        Ok(())
    }

    fn finish(self) -> Result<()> {
        match self {
            Sink::Stdout => std::io::stdout().lock().flush()?,
            Sink::File(f, p) => f
                .commit()
                .with_context(|| format!("finishing {}", p.display()))?,
        }
        Ok(())
    }
}

/// A vector for a message: `[x, y, z]`, each number as short as it reads back.
fn vec3(v: Vec3) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

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
    let mut reader = RecordReader::open(&a.input, format)?;
    let first: Vec<Record> = reader.by_ref().take(2).collect::<Result<_, _>>()?;
    let Some(r1) = first.first() else {
        bail!("{}: no records", a.input.display());
    };
    let rate = match (a.rate, first.get(1)) {
        (Some(r), _) => r,
        (None, Some(r2)) => 1.0 / (r2.t - r1.t),
        (None, None) => bail!(
            "{}: one record only; give --rate to navigate it",
            a.input.display()
        ),
    };
    if !(rate.is_finite() && rate > 0.0) {
        bail!(
            "{}: record times {} and {} do not increase; give --rate",
            a.input.display(),
            num(r1.t),
            num(first.get(1).map_or(f64::NAN, |r| r.t))
        );
    }
    let t0 = r1.t - 1.0 / rate;
    if !(t0 >= motion.start() - 1e-9 && t0 <= motion.end()) {
        bail!(
            "{}: the records start at t₀ = {} s, outside the reference [{}, {}] s",
            a.input.display(),
            num(t0),
            num(motion.start()),
            num(motion.end())
        );
    }
    let start = motion.pose(t0);
    let mut nav = Navigator::new(NavState::from_pose(&start), rate, settings)?;
    let mut aided = aided(&a, &start, rate, settings)?;
    let (mut free_max, mut free_last, mut fixes_used) = (0.0f64, 0.0f64, 0u64);

    let mut traj = Sink::open(&a.output)?;
    let mut errs = Sink::open(&a.errors)?;
    let mut traj_text = String::new();
    let mut err_text = String::new();
    traj_text.push_str(&imu_emu::trajectory::COLUMNS.join(","));
    traj_text.push('\n');
    err_text.push_str(ERROR_HEADER);
    let row = |text: &mut String, p: &Pose| {
        let (r, pi, y) = euler_from_quat(p.q_b_n);
        imu_emu::trajectory::format_row(
            text,
            p.t,
            p.lat.to_degrees(),
            p.lon.to_degrees(),
            p.h,
            p.v_n,
            (r.to_degrees(), pi.to_degrees(), y.to_degrees()),
        );
    };
    let mut fmt = ryu::Buffer::new();
    let mut err_row = |text: &mut String, t: f64, e: &StateError| {
        text.push_str(fmt.format(t));
        for v in [e.pos_ned, e.vel_ned, e.att_ned] {
            for &x in v.iter() {
                text.push(',');
                text.push_str(fmt.format(x));
            }
        }
        text.push(',');
        text.push_str(fmt.format(e.pos_ned.norm()));
        text.push('\n');
    };
    row(&mut traj_text, &start);
    err_row(&mut err_text, t0, &StateError::default());

    let (mut max_pos, mut max_vel, mut max_att) = (0.0f64, 0.0f64, 0.0f64);
    let mut last = StateError::default();
    let mut k = 0u64;
    let records = first.into_iter().map(Ok).chain(reader.by_ref());
    for rec in records {
        let rec = rec?;
        k += 1;
        let want = t0 + k as f64 / rate;
        let off = (rec.t - want).abs();
        if off.is_nan() || off > 1e-6 / rate + 1e-12 * want.abs() {
            bail!(
                "{}: record {k}: t = {} s, expected {} s for a {} Hz stream starting at {} s (gap, or --rate wrong)",
                a.input.display(),
                num(rec.t),
                num(want),
                num(rate),
                num(t0)
            );
        }
        // Increments no IMU measures (beyond 1e4 rad/s and 1e5 m/s² over the interval) make
        // any navigation meaningless: the record is named rather than the navigator.
        let (wmax, fmax) = (MAX_RATE_RAD_S / rate, MAX_ACCEL_M_S2 / rate);
        if !(rec.dtheta.amax() <= wmax && rec.dv.amax() <= fmax) {
            bail!(
                "{}: record {k} at t = {} s: increments dtheta {} rad, dv {} m/s are not finite or beyond what an IMU measures in 1/{} s ({} rad, {} m/s)",
                a.input.display(),
                num(rec.t),
                vec3(rec.dtheta),
                vec3(rec.dv),
                num(rate),
                num(wmax),
                num(fmax)
            );
        }
        nav.step(rec.dtheta, rec.dv);
        let s = match aided.as_mut() {
            None => nav.state(),
            Some((an, fixes)) => {
                let free = StateError::of(&nav.state(), &motion.pose(nav.state().t));
                free_max = free_max.max(free.pos_ned.norm());
                free_last = free.pos_ned.norm();
                an.step(rec.dtheta, rec.dv);
                // A fix applies at the first record at or after its time of validity.
                while let Some(&(t, fix)) = fixes.last()
                    && t <= rec.t + 1e-9
                {
                    fixes.pop();
                    if let Some(f) = fix {
                        an.update(&f);
                        fixes_used += 1;
                    }
                }
                an.state()
            }
        };
        if s.t > motion.end() + 1e-9 {
            bail!(
                "{}: record {k} at t = {} s is past the end of the reference ({} s)",
                a.input.display(),
                num(s.t),
                num(motion.end())
            );
        }
        let e = StateError::of(&s, &motion.pose(s.t));
        if !(e.pos_ned.norm().is_finite() && e.vel_ned.norm().is_finite()) {
            let which = if aided.is_some() {
                "the GNSS-aided filter diverged"
            } else {
                "the free-inertial solution overflowed"
            };
            bail!(
                "{}: record {k} at t = {} s: the navigated state is not finite ({which})",
                a.input.display(),
                num(s.t)
            );
        }
        max_pos = max_pos.max(e.pos_ned.norm());
        max_vel = max_vel.max(e.vel_ned.norm());
        max_att = max_att.max(e.att_ned.norm());
        last = e;
        if traj.is_some() {
            row(&mut traj_text, &s.pose());
        }
        if errs.is_some() {
            err_row(&mut err_text, s.t, &e);
        }
        for (text, sink) in [(&mut traj_text, &mut traj), (&mut err_text, &mut errs)] {
            if let Some(w) = sink
                && text.len() > 1 << 20
            {
                w.drain(text)?;
            }
        }
    }
    for (text, sink) in [(&mut traj_text, traj), (&mut err_text, errs)] {
        if let Some(mut w) = sink {
            w.drain(text)?;
            w.finish()?;
        }
    }
    let to_stdout =
        a.output.as_deref() == Some(Path::new("-")) || a.errors.as_deref() == Some(Path::new("-"));
    let summary = format!(
        "navigated {k} records at {rate} Hz, {:.3} s from t₀ = {t0} s (samples {}, stages {})\n\
         final error: position NED [{:+.3e}, {:+.3e}, {:+.3e}] m (|{:.3e}| m), velocity |{:.3e}| m/s, attitude NED [{:+.3e}, {:+.3e}, {:+.3e}] rad\n\
         max error:   position {:.3e} m, velocity {:.3e} m/s, attitude {:.3e} rad\n",
        k as f64 / rate,
        settings.samples,
        settings.stages,
        last.pos_ned.x,
        last.pos_ned.y,
        last.pos_ned.z,
        last.pos_ned.norm(),
        last.vel_ned.norm(),
        last.att_ned.x,
        last.att_ned.y,
        last.att_ned.z,
        max_pos,
        max_vel,
        max_att,
    );
    let summary = match &aided {
        None => summary,
        Some(_) => format!(
            "{summary}GNSS-aided with {fixes_used} fixes from {}; free-inertial: final position error {free_last:.3e} m, max {free_max:.3e} m\n",
            a.gnss.as_deref().unwrap_or(Path::new("-")).display()
        ),
    };
    if to_stdout {
        eprint!("{summary}");
    } else {
        // Written, not printed: a full disk or a closed pipe is an error, never a panic.
        let mut out = std::io::stdout().lock();
        out.write_all(summary.as_bytes())?;
        out.flush()?;
    }
    Ok(())
}
