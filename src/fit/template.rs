//! The fitted model as template TOML (`templates/README.md` format) in datasheet units, each
//! figure preceded by a comment saying how it was fitted and its 99 % interval, and the
//! spectral lines as a scene file's `[[vibration.sine]]` entries. Pure text.

use std::fmt::Write;

use super::gmwm::{AxisFit, Component, Estimate};
use super::lines::Line;
use super::ramp::{GATE_CONFIDENCE, RampTest, normal_point};
use crate::analysis::fit::Term;
use crate::analysis::report::{adev_unit, term_unit};

/// What the template says about where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Provenance {
    /// Template name.
    pub name: String,
    /// The recording (as named on the command line).
    pub source: String,
    /// Samples per channel.
    pub samples: u64,
    /// Sampling interval (s).
    pub dt: f64,
    /// The output LSB of the gyro and accelerometer triads, from the value lattice (rate
    /// units, SI; None: the values sit on no grid).
    pub lsb: [Option<f64>; 2],
    /// The output filter read from the PSD roll-off.
    pub filter: Option<super::filter::FittedFilter>,
    /// Whether the LSB quantizes by carrying the residual (else by rounding each sample).
    pub carry: bool,
    /// The broad resonances of each channel (gyro x y z, accel x y z; empty: none).
    pub resonances: Vec<Vec<super::resonance::Resonance>>,
    /// Whether the input is an Allan deviation table (no time series, no PSD).
    pub table: bool,
    /// Channels (gyro x y z, accel x y z) the input does not have: written error-free.
    pub missing: [bool; 6],
}

/// A number with 4 significant digits, plain or in exponent form, that parses back.
pub fn sig4(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.3e}")
    }
}

/// Unit and factor (SI × factor) of a component in the template.
pub fn unit(gyro: bool, k: Component) -> (&'static str, f64) {
    match k {
        Component::Quantization => term_unit(gyro, Term::Quantization),
        Component::WhiteNoise => term_unit(gyro, Term::WhiteNoise),
        Component::BiasInstability => term_unit(gyro, Term::BiasInstability),
        Component::RandomWalk => term_unit(gyro, Term::RandomWalk),
        Component::Ramp => term_unit(gyro, Term::Ramp),
        Component::GaussMarkov => adev_unit(gyro),
    }
}

/// One comment line on an estimate: value, interval, where read, χ² gain.
fn describe(axis: usize, k: Component, e: &Estimate, gyro: bool, extra: &str) -> String {
    let (u, f) = unit(gyro, k);
    let symbol = match k {
        Component::Quantization => "Q",
        Component::WhiteNoise => "N",
        Component::BiasInstability => "B",
        Component::RandomWalk => "K",
        Component::Ramp => "R",
        Component::GaussMarkov => "σ",
    };
    format!(
        "# {}: {symbol} = {} {u}, 99 % interval [{}, {}]{extra}; read at τ = {} s ({:.0} % of σ²), Δχ² = {} (> {:.1} to be kept)\n",
        ["x", "y", "z"][axis],
        sig4(e.value * f),
        sig4(e.lo * f),
        sig4(e.hi * f),
        sig4(e.tau),
        100.0 * e.share,
        sig4(e.gain),
        k.penalty()
    )
}

/// The template text for the fits of the six channels (gyro x y z, accel x y z; None for a
/// channel that could not be fitted) and the lines found in each channel.
pub fn template_toml(p: &Provenance, fits: &[Option<AxisFit>], lines: &[Vec<Line>]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Fitted by `imu-emu fit` to {} ({} samples at {} Hz, {} s).\n\
         # Method (docs/fit.md): weighted least squares of the exact Allan variance of the error\n\
         # model's terms against the measured octave Allan variance; a term is kept when it lowers\n\
         # χ² by more than its 99 % point (Δχ²). Intervals are 99 %, from the record length\n\
         # (degrees of freedom of the octave where the term is read best).",
        p.source,
        p.samples,
        sig4(1.0 / p.dt),
        sig4(p.samples as f64 * p.dt)
    );
    let _ = writeln!(s, "name = \"{}\"", p.name.replace('"', "'"));
    let _ = writeln!(
        s,
        "description = \"Fitted by imu-emu fit to {}\"",
        p.source.replace('"', "'")
    );
    let _ = writeln!(s, "rate_hz = {}", sig4(1.0 / p.dt));
    if p.lsb.iter().any(Option::is_some) && !p.carry {
        let _ = writeln!(
            s,
            "# The recorded values sit on a grid (the unit's output LSB): each rate sample is rounded to it,\n# which adds white noise of variance q²/12 per sample; the white noise below is what is left.\nquantization_mode = \"round\""
        );
    }
    for (gyro, base) in [(true, 0), (false, 3)] {
        let _ = writeln!(s, "\n[{}]", if gyro { "gyro" } else { "accel" });
        let axes: Vec<Option<&AxisFit>> = (0..3).map(|a| fits[base + a].as_ref()).collect();
        let missing: Vec<&str> = (0..3)
            .filter(|a| p.missing[base + a])
            .map(|a| ["x", "y", "z"][a])
            .collect();
        if !missing.is_empty() {
            // Zero is what the template can say of an axis it knows nothing of; the comment
            // keeps it from being read as a measured perfect axis.
            let _ = writeln!(
                s,
                "# not in the input: {} (written error-free; copy a measured axis's values to simulate {})",
                missing.join(", "),
                if missing.len() == 1 { "it" } else { "them" }
            );
        }
        if missing.len() < 3 {
            triad_toml(&mut s, gyro, &axes);
        }
        if let Some(q) = p.lsb[base / 3].filter(|_| p.carry) {
            let u = if gyro { "rad" } else { "m/s" };
            let _ = writeln!(
                s,
                "# output LSB from the value lattice of x, y, z (median), increments carried (the fit of a\n\
                 # rounding quantizer was worse): rate grid q, increment LSB qΔt\n\
                 quantization = \"{:.7e} {u}\"",
                q * p.dt
            );
        } else if let Some(q) = p.lsb[base / 3] {
            let (u, f) = if gyro {
                ("deg/s", 180.0 / std::f64::consts::PI)
            } else {
                ("m/s^2", 1.0)
            };
            let _ = writeln!(
                s,
                "# output LSB from the value lattice of x, y, z (median): every value within 2 % of an LSB of the grid\nquantization = \"{:.7e} {u}\"",
                q * f
            );
        }
        for a in 0..3 {
            for l in &lines[base + a] {
                let (u, f) = crate::units::report_unit(gyro);
                let _ = writeln!(
                    s,
                    "# {}: spectral line at {} Hz, amplitude {} {u} ({}× the background; not in the template: `fit --sines` writes it as a vibration sine)",
                    ["x", "y", "z"][a],
                    sig4(l.freq),
                    sig4(l.amplitude * f),
                    sig4(l.ratio)
                );
            }
            for r in p.resonances.get(base + a).into_iter().flatten() {
                let _ = writeln!(
                    s,
                    "# {}: {}",
                    ["x", "y", "z"][a],
                    describe_resonance(r, gyro)
                );
            }
        }
    }
    if let Some(f) = &p.filter {
        s.push_str(&super::filter::toml(f));
    }
    s
}

/// `post_filter_noise` when an axis's PSD showed a floor above its filter's roll-off:
/// P = N·√(P²/N²), the ratio the fit took ([`super::filter::floors`]).
fn post_filter_toml(s: &mut String, axes: &[Option<&AxisFit>], u: &str, f: f64) {
    let p: Vec<f64> = axes
        .iter()
        .map(|a| {
            a.and_then(|a| {
                let n = a.estimate(Component::WhiteNoise)?.value;
                Some(n * a.model.output.post_filter.sqrt())
            })
            .unwrap_or(0.0)
        })
        .collect();
    if p.iter().all(|x| *x == 0.0) {
        return;
    }
    let v: Vec<String> = p
        .iter()
        .map(|x| format!("\"{} {u}\"", sig4(x * f)))
        .collect();
    let _ = writeln!(
        s,
        "# The white floor each axis's PSD keeps near the Nyquist frequency above its filter's\n# roll-off (docs/fit.md, post-filter noise; the fit per axis is under [output_filter]).\npost_filter_noise = [{}]",
        v.join(", ")
    );
}

fn triad_toml(s: &mut String, gyro: bool, axes: &[Option<&AxisFit>]) {
    let est = |a: usize, k: Component| axes[a].and_then(|f| f.estimate(k));
    let kept = |k: Component| (0..3).any(|a| est(a, k).is_some());
    let values = |k: Component, f: f64, u: &str| -> String {
        let v: Vec<String> = (0..3)
            .map(|a| format!("\"{} {u}\"", sig4(est(a, k).map_or(0.0, |e| e.value) * f)))
            .collect();
        format!("[{}]", v.join(", "))
    };
    for (k, key) in [
        (Component::WhiteNoise, "noise"),
        (Component::BiasInstability, "bias_instability"),
        (Component::RandomWalk, "random_walk"),
    ] {
        if !kept(k) {
            let _ = writeln!(
                s,
                "# {}: not seen on any axis (no term earned its place)",
                k.name()
            );
            continue;
        }
        for a in 0..3 {
            if let Some(e) = est(a, k) {
                s.push_str(&describe(a, k, &e, gyro, ""));
            }
        }
        let (u, f) = unit(gyro, k);
        let _ = writeln!(s, "{key} = {}", values(k, f, u));
        if k == Component::WhiteNoise {
            post_filter_toml(s, axes, u, f);
        }
        if k == Component::BiasInstability {
            // One band per triad in the template: the band of the axis where B gained most.
            let (a, band) = (0..3)
                .filter_map(|a| Some((a, est(a, k)?, axes[a]?.model.band)))
                .max_by(|x, y| x.1.gain.total_cmp(&y.1.gain))
                .map(|(a, _, b)| (a, b))
                .expect("kept on some axis");
            let _ = writeln!(
                s,
                "# τ band of the floor: fitted on axis {} (half-decade grid; one band per triad)",
                ["x", "y", "z"][a]
            );
            let _ = writeln!(
                s,
                "bias_instability_band = [\"{} s\", \"{} s\"]",
                sig4(band.0),
                sig4(band.1)
            );
        }
    }
    if kept(Component::GaussMarkov) {
        let (u, f) = unit(gyro, Component::GaussMarkov);
        let mut taus = Vec::new();
        for (a, fit) in axes.iter().enumerate() {
            let fit = fit.filter(|f| f.model.c[5] > 0.0);
            if let (Some(e), Some(fit)) = (est(a, Component::GaussMarkov), fit) {
                let (lo, hi) = fit
                    .gm_tau_interval
                    .unwrap_or((fit.model.gm_tau, fit.model.gm_tau));
                let extra = format!(
                    ", T = {} s [{}, {}]",
                    sig4(fit.model.gm_tau),
                    sig4(lo),
                    sig4(hi)
                );
                s.push_str(&describe(a, Component::GaussMarkov, &e, gyro, &extra));
                taus.push(format!("\"{} s\"", sig4(fit.model.gm_tau)));
            } else {
                // An axis without the component: σ = 0 (its τ is then irrelevant).
                taus.push("\"1 s\"".into());
            }
        }
        let _ = writeln!(
            s,
            "bias_gm = {{ sigma = {}, tau = [{}] }}",
            values(Component::GaussMarkov, f, u),
            taus.join(", ")
        );
    }
    if kept(Component::Quantization) {
        for a in 0..3 {
            if let Some(e) = est(a, Component::Quantization) {
                s.push_str(&describe(a, Component::Quantization, &e, gyro, ""));
            }
        }
        // No lattice was seen (a table, or float samples), so Q is written as what its 3Q²/τ²
        // is: white angle (velocity) noise, per axis. An LSB of q = √12·Q under a carry
        // quantizer gives the same only when the noise dithers it: the LN-200 table's fitted
        // white noise is far below an LSB per sample, and such an LSB left the simulated
        // quantizer idle (its accelerometers 19× low at 5 ms).
        let (u, f) = unit(gyro, Component::Quantization);
        let qs: Vec<f64> = (0..3)
            .filter_map(|a| est(a, Component::Quantization).map(|e| e.value))
            .collect();
        let median = {
            let mut q = qs.clone();
            q.sort_by(f64::total_cmp);
            q[(q.len() - 1) / 2]
        };
        let _ = writeln!(
            s,
            "# the unit's LSB, if Q is one (increments carried, its noise dithering it): about √12·Q = {} {u}\nquantization_noise = {}",
            sig4(12f64.sqrt() * median * f),
            values(Component::Quantization, f, u)
        );
    }
    // The Allan variance sees R², not its sign: the key is written positive.
    let (u, f) = unit(gyro, Component::Ramp);
    if kept(Component::Ramp) {
        for a in 0..3 {
            if let Some(e) = est(a, Component::Ramp) {
                s.push_str(&describe(a, Component::Ramp, &e, gyro, ""));
            }
        }
        let _ = writeln!(
            s,
            "ramp = {}   # sign not observable from the Allan variance",
            values(Component::Ramp, f, u)
        );
    }
    ramp_toml(s, gyro, axes);
    let alternative = |a: usize| axes[a].and_then(|f| f.ramp_alternative);
    if (0..3).any(|a| alternative(a).is_some()) {
        for a in 0..3 {
            if let Some(e) = alternative(a) {
                s.push_str(&describe(a, Component::Ramp, &e, gyro, ""));
            }
        }
        let v: Vec<String> = (0..3)
            .map(|a| {
                format!(
                    "\"{} {u}\"",
                    sig4(alternative(a).map_or(0.0, |e| e.value) * f)
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "#    a rate ramp (a slow drift such as warm-up) fits better than the figures above, which were\n\
             #    fitted without it; to simulate the drift instead, uncomment (sign not observable from the ADEV):\n\
             # ramp = [{}]",
            v.join(", ")
        );
    }
}

/// The time-domain ramp test of a recording (docs/fit.md): the slope of each axis with its z,
/// and the kept ramps as a `ramp` key (signed: the slope sees the sign).
fn ramp_toml(s: &mut String, gyro: bool, axes: &[Option<&AxisFit>]) {
    let tests: Vec<Option<RampTest>> = axes.iter().map(|f| f.and_then(|f| f.ramp)).collect();
    if tests.iter().all(Option::is_none) {
        return;
    }
    let gate = normal_point(GATE_CONFIDENCE);
    let (u, f) = unit(gyro, Component::Ramp);
    if !tests.iter().flatten().any(|t| t.kept) {
        let z: Vec<String> = tests
            .iter()
            .map(|t| t.map_or("-".into(), |t| format!("{:.2}", t.z)))
            .collect();
        let _ = writeln!(
            s,
            "# rate ramp: not kept on any axis; z = slope/σ(slope) of x, y, z: {} (|z| > {gate:.2} to be kept)",
            z.join(", ")
        );
        return;
    }
    for (a, t) in tests.iter().enumerate() {
        let Some(t) = t else { continue };
        let axis = ["x", "y", "z"][a];
        match t.interval {
            Some((lo, hi)) if t.kept => {
                let _ = writeln!(
                    s,
                    "# {axis}: R = {} {u}, 99 % interval [{}, {}]; least-squares slope of the record, z = {} (|z| > {gate:.2} to be kept), the other figures fitted around it",
                    sig4(t.slope * f),
                    sig4(lo * f),
                    sig4(hi * f),
                    sig4(t.z)
                );
            }
            _ => {
                let _ = writeln!(
                    s,
                    "# {axis}: slope {} {u}, z = {:.2}: no ramp (|z| ≤ {gate:.2})",
                    sig4(t.slope * f),
                    t.z
                );
            }
        }
    }
    let v: Vec<String> = tests
        .iter()
        .map(|t| {
            let r = t.filter(|t| t.kept).map_or(0.0, |t| t.slope);
            format!("\"{} {u}\"", sig4(r * f))
        })
        .collect();
    let _ = writeln!(s, "ramp = [{}]", v.join(", "));
}

/// The lines as `[[vibration.sine]]` entries of a scene file on the static scene, and the
/// broad resonances as `[[vibration.random]]` entries, so that
/// `imu-emu generate LINES.toml --imu UNIT.toml` adds them (vibration belongs to the scene,
/// not to the template).
pub fn sines_scene(p: &Provenance, lines: &[Vec<Line>]) -> String {
    let mut s = format!(
        "# Spectral lines and broad resonances found by `imu-emu fit` in {} (docs/fit.md), as\n\
         # vibration sines and random vibrations on the static scene; run with\n\
         # `imu-emu generate THIS.toml --imu UNIT.toml`. Phases are not estimated (0).\n\
         [trajectory]\nscene = \"static\"\n",
        p.source
    );
    for (ch, ls) in lines.iter().enumerate() {
        let gyro = ch < 3;
        let (u, f) = crate::units::report_unit(gyro);
        for l in ls {
            let _ = write!(
                s,
                "\n[[vibration.sine]]\nsensor = \"{}\"\naxis = \"{}\"\namplitude = \"{} {u}\"\nfrequency = \"{} Hz\"\n",
                if gyro { "gyro" } else { "accel" },
                ["x", "y", "z"][ch % 3],
                sig4(
                    super::closure::source_amplitude(
                        l.amplitude,
                        l.freq,
                        p.dt,
                        p.filter.as_ref().map(|f| f.spec.channel(ch)).as_ref()
                    ) * f
                ),
                sig4(l.freq)
            );
        }
    }
    for (ch, r) in p
        .resonances
        .iter()
        .enumerate()
        .filter(|(_, r)| !r.is_empty())
    {
        let gyro = ch < 3;
        let (u, f) = psd_unit(gyro);
        let filter = p.filter.as_ref().map(|f| f.spec.channel(ch));
        let rows: Vec<String> = super::resonance::source_table(r, p.dt, filter.as_ref())
            .iter()
            .map(|&(hz, v)| format!("[\"{} Hz\", \"{} {u}\"]", sig4(hz), sig4(v * f)))
            .collect();
        let _ = write!(
            s,
            "\n# broad resonance(s) of {} {} (docs/fit.md): the PSD's excess over the fitted floor\n\
             [[vibration.random]]\nsensor = \"{}\"\naxis = \"{}\"\npsd = [\n    {},\n]\n",
            if gyro { "gyro" } else { "accel" },
            ["x", "y", "z"][ch % 3],
            if gyro { "gyro" } else { "accel" },
            ["x", "y", "z"][ch % 3],
            rows.join(",\n    ")
        );
    }
    s
}

/// A PSD table's unit and factor (SI × factor).
fn psd_unit(gyro: bool) -> (&'static str, f64) {
    if gyro {
        ("(deg/s)^2/Hz", (180.0 / std::f64::consts::PI).powi(2))
    } else {
        ("g^2/Hz", crate::units::G0.powi(-2))
    }
}

/// One line on a broad resonance: where, how strong, how significant.
pub fn describe_resonance(r: &super::resonance::Resonance, gyro: bool) -> String {
    let (u, f) = crate::units::report_unit(gyro);
    let significance = if r.from_adev {
        format!(
            "read from the Allan deviation: Δχ² = {} (> {} to be kept",
            sig4(r.z * r.z),
            sig4(r.z_gate * r.z_gate)
        )
    } else {
        format!("z = {} (> {} to be kept", sig4(r.z), sig4(r.z_gate))
    };
    format!(
        "broad resonance {}–{} Hz (centre {} Hz), RMS {} {u}, peak {}× the floor, {significance}; not in the template: `fit --sines` writes it as a random vibration)",
        sig4(r.rows[0].0),
        sig4(r.rows[r.rows.len() - 1].0),
        sig4(r.centre()),
        sig4(r.variance().sqrt() * f),
        sig4(1.0 + r.peak),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_significant_digits_round_trip() {
        assert_eq!(sig4(0.15), "0.1500");
        assert_eq!(sig4(1234.5678), "1235");
        assert_eq!(sig4(2.5e-7), "2.500e-7");
        assert_eq!(sig4(0.0), "0");
        for x in [3.3e-9, 0.0123456, 98765.4, 1.0] {
            let back: f64 = sig4(x).parse().unwrap();
            assert!((back / x - 1.0).abs() < 5e-4, "{x}");
        }
    }
}
