//! `imu-emu analyze`: statistics, Allan deviation with fitted IEEE terms, and PSD of a
//! recording (ours or anyone's), optionally against a template, with plots.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use imu_emu::analysis::analyzer::{Analyzer, DEFAULT_SEGMENT};
use imu_emu::analysis::conformance::{channel_theory, term_rows};
use imu_emu::analysis::reader::{self, CsvOptions, InputFormat};
use imu_emu::analysis::report;
use imu_emu::units::{self, Kind};

#[derive(clap::Args)]
pub struct AnalyzeArgs {
    /// Input file: CSV, our binary records, or a protocol frame stream.
    pub input: PathBuf,
    /// Input format: csv, bin, or a protocol name (kvh1750, imar-ixcom, novatel-rawimusx, stim300) [default: bin for *.bin, else csv]
    #[arg(long)]
    pub format: Option<String>,
    /// A protocol spec file describing the frames.
    #[arg(long, conflicts_with = "format")]
    pub protocol_file: Option<PathBuf>,
    /// Sampling rate (Hz); needed when the data have no time column [default: from the time column]
    #[arg(long)]
    pub rate: Option<f64>,
    /// CSV column roles in order, e.g. t,gx,gy,gz,ax,ay,az (- skips a column) [default: from the header]
    #[arg(long)]
    pub columns: Option<String>,
    /// Unit of the CSV gyro columns (rad/s, deg/s, deg/h, mrad/s)
    #[arg(long, default_value = "rad/s")]
    pub gyro_unit: String,
    /// Unit of the CSV accelerometer columns (m/s^2, g, mg, ug)
    #[arg(long, default_value = "m/s^2")]
    pub accel_unit: String,
    /// IMU template to compare with (name or file): theory curves and measured/specified per term
    #[arg(long)]
    pub imu: Option<String>,
    /// Write the plots here (.png or .svg)
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the ADEV / PSD curves here as CSV
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Welch segment length in samples (a power of two)
    #[arg(long, default_value_t = DEFAULT_SEGMENT)]
    pub segment: usize,
}

/// `imu-emu analyze`.
pub fn analyze(a: AnalyzeArgs) -> Result<()> {
    if let Some(r) = a.rate
        && !(r > 0.0 && r.is_finite())
    {
        bail!("--rate: expected a positive number of Hz, got {r}");
    }
    if let Some(p) = &a.plot
        && !p
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("png") || e.eq_ignore_ascii_case("svg"))
    {
        bail!("--plot {}: plot file must end in .png or .svg", p.display());
    }
    let unit = |text: &str, kind: Kind, flag: &str| -> Result<f64> {
        Ok(units::parse(&format!("1 {text}"), kind)
            .with_context(|| format!("{flag} `{text}`"))?
            .0)
    };
    let csv = CsvOptions {
        columns: match &a.columns {
            Some(c) => {
                Some(reader::parse_columns(c).map_err(|e| anyhow::anyhow!("--columns: {e}"))?)
            }
            None => None,
        },
        gyro_scale: unit(&a.gyro_unit, Kind::AngularRate, "--gyro-unit")?,
        accel_scale: unit(&a.accel_unit, Kind::Acceleration, "--accel-unit")?,
    };
    let is_bin = a.input.extension().is_some_and(|e| e == "bin");
    let (format, spec_rate) = match (a.format.as_deref(), &a.protocol_file) {
        (_, Some(p)) => {
            let (spec, plan) = imu_emu::protocol::load(&p.to_string_lossy())?;
            (InputFormat::Frames(plan), spec.rate_hz)
        }
        (Some("csv"), _) => (InputFormat::Csv(csv), None),
        (Some("bin"), _) => (InputFormat::Bin, None),
        (Some(name), _) => {
            let (spec, plan) = imu_emu::protocol::load(name).with_context(|| {
                format!(
                    "--format `{name}`: not csv, bin or a protocol (built-in: {})",
                    imu_emu::protocol::builtin_names().join(", ")
                )
            })?;
            (InputFormat::Frames(plan), spec.rate_hz)
        }
        (None, None) if is_bin => (InputFormat::Bin, None),
        (None, None) => (InputFormat::Csv(csv), None),
    };
    let rate = a.rate.or(spec_rate);
    let model = a
        .imu
        .as_deref()
        .map(imu_emu::errors::template::load)
        .transpose()?;

    let mut an = Analyzer::new(a.segment);
    let summary = reader::read(&a.input, &format, rate.map(|r| 1.0 / r), |t, v| {
        an.push(t, v)
    })?;
    if summary.samples < 8 {
        bail!(
            "{}: {} samples; the analysis needs at least 8",
            a.input.display(),
            summary.samples
        );
    }
    let dt = match (rate, an.measured_dt()) {
        (Some(r), _) => 1.0 / r,
        (None, Some(dt)) => dt,
        (None, None) => bail!(
            "{}: no usable time column; give the sampling rate with --rate",
            a.input.display()
        ),
    };
    let res = an.finish(dt);
    let (smin, smax) = res.step_range;
    if smin.is_finite() && (smin < 0.99 * dt || smax > 1.01 * dt) {
        eprintln!(
            "imu-emu analyze: warning: time steps range from {smin} s to {smax} s; the analysis assumes uniform sampling at Δt = {dt} s"
        );
    }
    // The report goes to stdout in one write at the end, so a reader that stops early
    // (`… | head`) ends the command quietly (main treats a broken pipe as success) instead of
    // a panic in println!.
    let mut text = String::new();
    if let Some(s) = summary.frames {
        writeln!(
            text,
            "frames: {} decoded, {} check failures, {} counter gaps, {} bytes skipped",
            s.frames, s.check_failures, s.counter_gaps, s.skipped_bytes
        )?;
    }
    writeln!(
        text,
        "{}: {} samples, Δt = {} s ({} Hz), {:.1} s",
        a.input.display(),
        res.samples,
        digits12(dt),
        digits12(1.0 / dt),
        res.samples as f64 * dt
    )?;
    writeln!(text)?;
    write!(text, "{}", report::stats_table(&res))?;
    writeln!(text)?;
    writeln!(
        text,
        "IEEE 952 terms, least squares on the octave Allan variance: σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)B² + K²τ/3 + R²τ²/2"
    )?;
    let rows = model.as_ref().map(|m| term_rows(m, &res));
    write!(text, "{}", report::term_table(&res, rows.as_deref()))?;
    if let Some(rows) = &rows {
        let failed = rows.iter().filter(|r| r.pass == Some(false)).count();
        let checked = rows.iter().filter(|r| r.pass.is_some()).count();
        writeln!(
            text,
            "template `{}`: {} of {checked} specified terms within their bands",
            model.as_ref().map_or("", |m| m.name.as_str()),
            checked - failed
        )?;
    }
    let theory = model.as_ref().map(|m| channel_theory(m, dt));
    let title = a
        .input
        .file_name()
        .map_or("input".into(), |n| n.to_string_lossy().into_owned());
    if let Some(p) = &a.plot {
        let panels = report::panels(&res, theory.as_deref(), &title);
        imu_emu::plot::render(p, &panels, 2, (1600, 1200))?;
        eprintln!("imu-emu analyze: plot written to {}", p.display());
    }
    if let Some(p) = &a.csv {
        write_file(p, report::curves_csv(&res, theory.as_deref()).as_bytes())?;
    }
    std::io::Write::write_all(&mut std::io::stdout().lock(), text.as_bytes())?;
    Ok(())
}

/// x rounded to 12 significant digits (a measured Δt prints as 0.0025, not 0.0024999999999999996).
fn digits12(x: f64) -> f64 {
    format!("{x:.11e}").parse().unwrap_or(x)
}

fn write_file(p: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let mut f = imu_emu::output::AtomicFile::create(p)
        .with_context(|| format!("{}: cannot create", p.display()))?;
    f.write_all(bytes)
        .with_context(|| format!("{}: write failed", p.display()))?;
    f.commit()
        .with_context(|| format!("{}: write failed", p.display()))?;
    Ok(())
}
