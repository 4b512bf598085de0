//! IMU templates: TOML files of datasheet figures with units (`templates/README.md`),
//! converted to SI once. Named templates are embedded in the binary; a user file may start from
//! a named one (`base = "ln200"`) and override any key.

use std::path::{Path, PathBuf};

use super::model::StageKind;
pub use super::model::{ImuModel, TriadModel};
use super::process::QuantMode;
use crate::units::bounds;
use crate::units::{self, Kind, Lsb};

/// The built-in templates, embedded at compile time (a test checks every file in `templates/`
/// is listed here).
pub const BUILTIN: &[(&str, &str)] = &[
    ("ideal", include_str!("../../templates/ideal.toml")),
    ("ln200", include_str!("../../templates/ln200.toml")),
    ("hg1700", include_str!("../../templates/hg1700.toml")),
    ("hg4930", include_str!("../../templates/hg4930.toml")),
    ("kvh1750", include_str!("../../templates/kvh1750.toml")),
    ("fsas", include_str!("../../templates/fsas.toml")),
    ("stim300", include_str!("../../templates/stim300.toml")),
    ("adis16488", include_str!("../../templates/adis16488.toml")),
    ("adis16405", include_str!("../../templates/adis16405.toml")),
    ("mpu6000", include_str!("../../templates/mpu6000.toml")),
    ("ltn101", include_str!("../../templates/ltn101.toml")),
    ("dmars", include_str!("../../templates/dmars.toml")),
    ("ssks", include_str!("../../templates/ssks.toml")),
    (
        "motionpak2",
        include_str!("../../templates/motionpak2.toml"),
    ),
    ("fji", include_str!("../../templates/fji.toml")),
    ("adis16448", include_str!("../../templates/adis16448.toml")),
    ("bmi160", include_str!("../../templates/bmi160.toml")),
    ("navchip", include_str!("../../templates/navchip.toml")),
];

/// A template that cannot be used, with the file and key at fault.
#[derive(Debug, thiserror::Error)]
pub enum TemplateError {
    /// Unreadable file.
    #[error("{path}: cannot read")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// TOML syntax.
    #[error("{path}: {message}")]
    Syntax {
        /// File.
        path: PathBuf,
        /// Parser message (with line and column).
        message: String,
    },
    /// A bad key or value.
    #[error("{path}: `{key}`: {message}")]
    Key {
        /// File.
        path: PathBuf,
        /// Dotted key.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// Not a built-in name and not a file.
    #[error("unknown IMU `{0}` (built-in: {1}; or give a template file)")]
    Unknown(String, String),
}

/// Names of the built-in templates.
pub fn builtin_names() -> Vec<&'static str> {
    BUILTIN.iter().map(|b| b.0).collect()
}

/// The suffix that selects a template's typical profile (`ln200:typical`); `:datasheet` (the
/// default) selects the figures the template's sources promise.
pub const TYPICAL: &str = "typical";

/// Which figures of a template to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Profile {
    /// The template's own figures (what the datasheet promises): the default.
    Datasheet,
    /// The `[typical]` table laid over them: how recorded units of that model behave.
    Typical,
}

/// Splits `NAME:typical` / `NAME:datasheet` into the name and the profile (other text is a
/// name or a path as given).
pub fn split_profile(name_or_path: &str) -> (&str, Profile) {
    match name_or_path.rsplit_once(':') {
        Some((n, TYPICAL)) if !n.is_empty() => (n, Profile::Typical),
        Some((n, "datasheet")) if !n.is_empty() => (n, Profile::Datasheet),
        _ => (name_or_path, Profile::Datasheet),
    }
}

/// Loads a built-in template by name or a template file by path, `NAME:typical` for its
/// typical profile.
pub fn load(name_or_path: &str) -> Result<ImuModel, TemplateError> {
    let (name, profile) = split_profile(name_or_path);
    if let Some((n, text)) = BUILTIN.iter().find(|b| b.0 == name) {
        return parse_profile(text, Path::new(&format!("templates/{n}.toml")), profile);
    }
    let path = Path::new(name);
    if path.extension().is_some_and(|e| e == "toml") || path.exists() {
        let text = std::fs::read_to_string(path).map_err(|source| TemplateError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        return parse_profile(&text, path, profile);
    }
    Err(TemplateError::Unknown(
        name_or_path.to_string(),
        builtin_names().join(", "),
    ))
}

/// Names of the built-in templates that carry a typical profile.
pub fn typical_names() -> Vec<&'static str> {
    BUILTIN
        .iter()
        .filter(|(_, text)| {
            text.parse::<toml::Table>()
                .is_ok_and(|t| t.contains_key(TYPICAL))
        })
        .map(|b| b.0)
        .collect()
}

/// Parses template text (`path` for messages), resolving `base`; the datasheet profile.
pub fn parse(text: &str, path: &Path) -> Result<ImuModel, TemplateError> {
    parse_profile(text, path, Profile::Datasheet)
}

/// Parses template text with the chosen profile. The `[typical]` table is checked whichever
/// profile is chosen, so a mistake in it is reported when the template is first used.
pub fn parse_profile(text: &str, path: &Path, profile: Profile) -> Result<ImuModel, TemplateError> {
    let syntax = |e: toml::de::Error| TemplateError::Syntax {
        path: path.to_path_buf(),
        message: crate::csvio::toml_error_line(text, &e),
    };
    let mut table: toml::Table = text.parse().map_err(syntax)?;
    if let Some(base) = table.remove("base") {
        let Some(base_ref) = base.as_str() else {
            return Err(key_err(path, "base", "expected a template name"));
        };
        let (base_name, base_profile) = split_profile(base_ref);
        let (_, base_text) = BUILTIN.iter().find(|b| b.0 == base_name).ok_or_else(|| {
            key_err(
                path,
                "base",
                &format!(
                    "unknown template `{base_name}` (built-in: {})",
                    builtin_names().join(", ")
                ),
            )
        })?;
        let mut merged: toml::Table = base_text.parse().map_err(syntax)?;
        let base_typical = merged.remove(TYPICAL);
        if base_profile == Profile::Typical {
            let Some(toml::Value::Table(t)) = base_typical else {
                return Err(key_err(
                    path,
                    "base",
                    &format!("template `{base_name}` has no typical profile"),
                ));
            };
            overlay(&mut merged, strip_notes(t));
        }
        overlay(&mut merged, table);
        table = merged;
    }
    let typical = match table.remove(TYPICAL) {
        None => None,
        Some(toml::Value::Table(t)) => Some(t),
        Some(_) => return Err(key_err(path, TYPICAL, "expected a table")),
    };
    let Some(typical) = typical else {
        if profile == Profile::Typical {
            return Err(key_err(
                path,
                TYPICAL,
                &format!(
                    "this template has no typical profile (built-in ones with one: {})",
                    typical_names().join(", ")
                ),
            ));
        }
        return from_table(&table, path);
    };
    let source = typical
        .get("source")
        .and_then(|v| v.as_str())
        .map(String::from);
    for (k, v) in &typical {
        let ok = match k.as_str() {
            "source" => v.is_str(),
            "gyro" | "accel" => v.is_table(),
            _ => false,
        };
        if !ok {
            return Err(key_err(
                path,
                &format!("{TYPICAL}.{k}"),
                "expected `source` (text), `[typical.gyro]` or `[typical.accel]`",
            ));
        }
    }
    let mut over = table.clone();
    overlay(&mut over, strip_notes(typical));
    let prefixed = |e: TemplateError| match e {
        TemplateError::Key { path, key, message } => TemplateError::Key {
            path,
            key: format!("{TYPICAL}.{key}"),
            message,
        },
        e => e,
    };
    let typical_model = from_table(&over, path).map_err(prefixed)?;
    if profile == Profile::Datasheet {
        return from_table(&table, path);
    }
    let mut m = typical_model;
    m.name = format!("{}:{TYPICAL}", m.name);
    m.description = match source {
        Some(s) => format!("{} — typical profile: {s}", m.description),
        None => format!("{} — typical profile", m.description),
    };
    Ok(m)
}

/// Lays `over` onto `base`: sensor tables merge key by key, other keys replace.
fn overlay(base: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(m)), toml::Value::Table(o)) => m.extend(o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// The typical table without its `source` text (not a template key).
fn strip_notes(mut t: toml::Table) -> toml::Table {
    t.remove("source");
    t
}

fn key_err(path: &Path, key: &str, message: &str) -> TemplateError {
    TemplateError::Key {
        path: path.to_path_buf(),
        key: key.to_string(),
        message: message.to_string(),
    }
}

fn from_table(t: &toml::Table, path: &Path) -> Result<ImuModel, TemplateError> {
    let text = |k: &str| t.get(k).and_then(|v| v.as_str()).map(String::from);
    for k in t.keys() {
        if ![
            "name",
            "description",
            "grade",
            "rate_hz",
            "sources",
            "gyro",
            "accel",
            "quantization_mode",
            "order",
            "temperature_ref",
            "timing",
            "output_filter",
        ]
        .contains(&k.as_str())
        {
            return Err(key_err(path, k, "unknown key"));
        }
    }
    let rate_hz = match t.get("rate_hz") {
        None => None,
        Some(v) => match v.as_float().or(v.as_integer().map(|i| i as f64)) {
            Some(r) if r > 0.0 && r <= bounds::MAX_RATE_HZ => Some(r),
            _ => {
                return Err(key_err(
                    path,
                    "rate_hz",
                    &format!(
                        "expected a number in (0, {}] (Hz)",
                        bounds::compact(bounds::MAX_RATE_HZ)
                    ),
                ));
            }
        },
    };
    let quantization_mode = match t.get("quantization_mode") {
        None => QuantMode::Carry,
        Some(v) => match v.as_str() {
            Some("carry") => QuantMode::Carry,
            Some("round") => QuantMode::Round,
            Some("truncate") => QuantMode::Truncate,
            _ => {
                return Err(key_err(
                    path,
                    "quantization_mode",
                    "expected `carry`, `round` or `truncate`",
                ));
            }
        },
    };
    let order = match t.get("order") {
        None => StageKind::PAPER_ORDER.to_vec(),
        Some(v) => {
            let arr = v
                .as_array()
                .ok_or_else(|| key_err(path, "order", "expected a list of stage names"))?;
            let mut out = Vec::new();
            for s in arr {
                let name = s.as_str().unwrap_or("");
                let k = StageKind::from_name(name).ok_or_else(|| {
                    key_err(path, "order", &format!("unknown stage `{name}` (scale_factor, bias, misalignment, noise, quantization)"))
                })?;
                if out.contains(&k) {
                    return Err(key_err(
                        path,
                        "order",
                        &format!("stage `{name}` appears twice"),
                    ));
                }
                out.push(k);
            }
            // Every stage exactly once: quantization also carries the saturation, so leaving a
            // stage out would silently drop terms the template sets.
            if out.len() != 5 {
                return Err(key_err(
                    path,
                    "order",
                    "list all five stages: scale_factor, bias, misalignment, noise, quantization",
                ));
            }
            out
        }
    };
    let temperature_ref = match t.get("temperature_ref") {
        None => 25.0,
        Some(v) => v
            .as_str()
            .and_then(|s| s.trim().strip_suffix("degC"))
            .and_then(|s| s.trim().parse::<f64>().ok())
            .filter(|x| (bounds::TEMPERATURE_REF_C.0..=bounds::TEMPERATURE_REF_C.1).contains(x))
            .ok_or_else(|| {
                key_err(
                    path,
                    "temperature_ref",
                    &format!(
                        "expected \"<number> degC\" from {} to {} degC",
                        bounds::TEMPERATURE_REF_C.0,
                        bounds::TEMPERATURE_REF_C.1
                    ),
                )
            })?,
    };
    let output_filter = match t.get("output_filter") {
        None => None,
        Some(toml::Value::Table(f)) => {
            Some(super::output_filter::from_toml(f).map_err(|(k, m)| {
                let key = if k.is_empty() {
                    "output_filter".to_string()
                } else {
                    format!("output_filter.{k}")
                };
                key_err(path, &key, &m)
            })?)
        }
        Some(_) => return Err(key_err(path, "output_filter", "expected a table")),
    };
    let gyro = triad(t.get("gyro"), "gyro", path)?;
    let accel = triad(t.get("accel"), "accel", path)?;
    let mut timing = crate::timing::TimingModel::default();
    if let Some(v) = t.get("timing") {
        let table = v
            .as_table()
            .ok_or_else(|| key_err(path, "timing", "expected a table"))?;
        timing
            .apply_table(table)
            .map_err(|e| key_err(path, &format!("timing.{}", e.key), &e.message))?;
    }
    Ok(ImuModel {
        name: text("name").unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        }),
        description: text("description").unwrap_or_default(),
        grade: text("grade").unwrap_or_default(),
        rate_hz,
        gyro,
        accel,
        quantization_mode,
        order,
        temperature_ref,
        timing,
        output_filter,
    })
}

/// Reads one `[gyro]` or `[accel]` table.
fn triad(v: Option<&toml::Value>, sensor: &str, path: &Path) -> Result<TriadModel, TemplateError> {
    let mut m = TriadModel {
        bias_instability_band: (1.0, 1000.0),
        ..TriadModel::default()
    };
    let Some(v) = v else { return Ok(m) };
    let table = v
        .as_table()
        .ok_or_else(|| key_err(path, sensor, "expected a table"))?;
    let gyro = sensor == "gyro";
    let (rate, rw, bias_rw, lsb) = if gyro {
        (
            Kind::AngularRate,
            Kind::AngleRandomWalk,
            Kind::RateRandomWalk,
            Kind::GyroLsb,
        )
    } else {
        (
            Kind::Acceleration,
            Kind::VelocityRandomWalk,
            Kind::AccelRandomWalk,
            Kind::AccelLsb,
        )
    };
    let ramp = if gyro {
        Kind::RateRamp
    } else {
        Kind::AccelRamp
    };
    for (key, val) in table {
        let full = format!("{sensor}.{key}");
        let err = |msg: String| key_err(path, &full, &msg);
        let nonneg = |x: &[f64]| -> Result<(), TemplateError> {
            if x.iter().any(|v| *v < 0.0) {
                Err(key_err(path, &full, "must not be negative (a magnitude)"))
            } else {
                Ok(())
            }
        };
        match key.as_str() {
            "bias" => m.bias = axes(val, rate).map_err(err)?,
            "bias_turn_on" => {
                m.bias_turn_on = axes(val, rate).map_err(err)?;
                nonneg(&m.bias_turn_on)?
            }
            "bias_instability" => {
                m.bias_instability = axes(val, rate).map_err(err)?;
                nonneg(&m.bias_instability)?
            }
            "bias_instability_band" => {
                let v = list(val, Kind::Time, 2).map_err(err)?;
                if !(v[0] > 0.0 && v[1] > v[0]) {
                    return Err(key_err(
                        path,
                        &full,
                        "expected [τ_lo, τ_hi] with 0 < τ_lo < τ_hi",
                    ));
                }
                m.bias_instability_band = (v[0], v[1]);
            }
            "bias_gm" => m.bias_gm = Some(gm(val, rate).map_err(err)?),
            "random_walk" => {
                m.random_walk = axes(val, bias_rw).map_err(err)?;
                nonneg(&m.random_walk)?
            }
            "ramp" => m.ramp = axes(val, ramp).map_err(err)?,
            "noise" => {
                m.noise = axes(val, rw).map_err(err)?;
                nonneg(&m.noise)?
            }
            "scale_factor" => m.scale_factor = axes(val, Kind::Ratio).map_err(err)?,
            "scale_factor_turn_on" => {
                m.scale_factor_turn_on = axes(val, Kind::Ratio).map_err(err)?;
                nonneg(&m.scale_factor_turn_on)?
            }
            "scale_factor_gm" => m.scale_factor_gm = Some(gm(val, Kind::Ratio).map_err(err)?),
            "scale_factor_random_walk" => {
                m.scale_factor_random_walk = axes(val, Kind::RatioRandomWalk).map_err(err)?;
                nonneg(&m.scale_factor_random_walk)?
            }
            "scale_factor_asymmetry" => {
                m.scale_factor_asymmetry = axes(val, Kind::Ratio).map_err(err)?
            }
            "scale_factor_quadratic" if !gyro => {
                m.scale_factor_quadratic = axes(val, Kind::Quadratic).map_err(err)?
            }
            "misalignment" => m.misalignment = six(val).map_err(err)?,
            "misalignment_turn_on" => {
                m.misalignment_turn_on = six(val).map_err(err)?;
                nonneg(&m.misalignment_turn_on)?
            }
            "g_sensitivity" if gyro => {
                let v = match val.as_array().map(|a| a.len()) {
                    Some(9) => list(val, Kind::GSensitivity, 9).map_err(err)?,
                    _ => {
                        let d = axes(val, Kind::GSensitivity).map_err(err)?;
                        vec![d[0], 0.0, 0.0, 0.0, d[1], 0.0, 0.0, 0.0, d[2]]
                    }
                };
                m.g_sensitivity.copy_from_slice(&v);
            }
            "quantization" => {
                let s = val
                    .as_str()
                    .ok_or_else(|| err("expected a string \"value unit\"".into()))?;
                let (q, inc) = units::parse(s, lsb).map_err(|e| err(e.to_string()))?;
                if q <= 0.0 {
                    return Err(err("must be positive".into()));
                }
                bounds::check(s, lsb, q, inc).map_err(err)?;
                m.quantization = Some(if inc { Lsb::Increment(q) } else { Lsb::Rate(q) });
            }
            "range" => {
                let s = val
                    .as_str()
                    .ok_or_else(|| err("expected a string \"value unit\"".into()))?;
                let (r, _) = units::parse(s, rate).map_err(|e| err(e.to_string()))?;
                if r <= 0.0 {
                    return Err(err("must be positive".into()));
                }
                bounds::check(s, rate, r, false).map_err(err)?;
                m.range = Some(r);
            }
            "bias_temperature" => m.bias_temperature = poly(val, rate).map_err(err)?,
            "noise_correlation" => m.noise_correlation = Some(correlation(val).map_err(err)?),
            "size_effect" if !gyro => {
                let v = list(val, Kind::Length, 9).map_err(err)?;
                m.size_effect = [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]];
            }
            "scale_factor_temperature" => {
                m.scale_factor_temperature = poly(val, Kind::Ratio).map_err(err)?
            }
            _ => return Err(err("unknown key".into())),
        }
    }
    Ok(m)
}

/// One value for all axes or three, each `"number unit"`.
fn axes(v: &toml::Value, kind: Kind) -> Result<[f64; 3], String> {
    match v {
        toml::Value::Array(_) => {
            let l = list(v, kind, 3)?;
            Ok([l[0], l[1], l[2]])
        }
        _ => {
            let x = one(v, kind)?;
            Ok([x; 3])
        }
    }
}

/// The six misalignment angles, or one value for all.
fn six(v: &toml::Value) -> Result<[f64; 6], String> {
    match v {
        toml::Value::Array(_) => {
            let l = list(v, Kind::Angle, 6)?;
            let mut o = [0.0; 6];
            o.copy_from_slice(&l);
            Ok(o)
        }
        _ => Ok([one(v, Kind::Angle)?; 6]),
    }
}

/// `{ sigma = "…", tau = "…" }` with per-axis or shared values.
fn gm(v: &toml::Value, kind: Kind) -> Result<([f64; 3], [f64; 3]), String> {
    let t = v
        .as_table()
        .ok_or("expected { sigma = \"…\", tau = \"…\" }")?;
    for k in t.keys() {
        if k != "sigma" && k != "tau" {
            return Err(format!("unknown key `{k}` (expected sigma, tau)"));
        }
    }
    let sigma = axes(t.get("sigma").ok_or("missing `sigma`")?, kind)?;
    let tau = axes(t.get("tau").ok_or("missing `tau`")?, Kind::Time)?;
    if sigma.iter().any(|s| *s < 0.0) {
        return Err("sigma must not be negative".into());
    }
    if tau.iter().any(|s| *s <= 0.0) {
        return Err("tau must be positive".into());
    }
    Ok((sigma, tau))
}

/// A 3×3 correlation matrix given as 9 numbers row-major (or the 3 off-diagonal values
/// [ρ_xy, ρ_xz, ρ_yz]); it must be symmetric with a unit diagonal and positive definite.
fn correlation(v: &toml::Value) -> Result<[[f64; 3]; 3], String> {
    let a = v
        .as_array()
        .ok_or("expected [ρ_xy, ρ_xz, ρ_yz] or 9 numbers row-major")?;
    let n: Vec<f64> = a
        .iter()
        .map(|x| {
            x.as_float()
                .or(x.as_integer().map(|i| i as f64))
                .ok_or("expected numbers")
        })
        .collect::<Result<_, _>>()?;
    let c = match n.len() {
        3 => [[1.0, n[0], n[1]], [n[0], 1.0, n[2]], [n[1], n[2], 1.0]],
        9 => [[n[0], n[1], n[2]], [n[3], n[4], n[5]], [n[6], n[7], n[8]]],
        k => return Err(format!("expected 3 or 9 numbers, got {k}")),
    };
    if (0..3).any(|i| c[i][i] != 1.0) {
        return Err("the diagonal must be 1".into());
    }
    let symmetric = (0..3)
        .all(|i| (0..3).all(|j| c[i][j] == c[j][i] && c[i][j].is_finite() && c[i][j].abs() <= 1.0));
    if !symmetric {
        return Err("must be symmetric with entries in [−1, 1]".into());
    }
    // Positive definite: leading minors > 0.
    let m2 = 1.0 - c[0][1] * c[0][1];
    let det = 1.0 + 2.0 * c[0][1] * c[0][2] * c[1][2]
        - c[0][1] * c[0][1]
        - c[0][2] * c[0][2]
        - c[1][2] * c[1][2];
    if m2 <= 0.0 || det <= 0.0 {
        return Err("not positive definite".into());
    }
    Ok(c)
}

/// Up to three polynomial coefficients, the k-th in `<unit>/degC^k` (`/degC` for k = 1).
fn poly(v: &toml::Value, kind: Kind) -> Result<[f64; 3], String> {
    let a = v.as_array().ok_or(
        "expected a list of coefficients, e.g. [\"0.1 deg/h/degC\", \"0.01 deg/h/degC^2\"]",
    )?;
    if a.is_empty() || a.len() > 3 {
        return Err(format!("expected 1 to 3 coefficients, got {}", a.len()));
    }
    let mut out = [0.0; 3];
    for (k, x) in a.iter().enumerate() {
        let s = x
            .as_str()
            .ok_or("expected strings \"value unit/degC^k\"")?
            .trim();
        let suffix = if k == 0 {
            "/degC".to_string()
        } else {
            format!("/degC^{}", k + 1)
        };
        let base = s
            .strip_suffix(suffix.as_str())
            .ok_or_else(|| format!("coefficient {} `{s}` must end in `{suffix}`", k + 1))?;
        out[k] = units::parse(base, kind)
            .map(|x| x.0)
            .map_err(|e| e.to_string())?;
        bounds::check(base, kind, out[k], false)
            .map_err(|e| format!("coefficient {} (per {}): {e}", k + 1, &suffix[1..]))?;
    }
    Ok(out)
}

fn list(v: &toml::Value, kind: Kind, n: usize) -> Result<Vec<f64>, String> {
    let a = v.as_array().ok_or_else(|| format!("expected {n} values"))?;
    if a.len() != n {
        return Err(format!("expected {n} values, got {}", a.len()));
    }
    a.iter().map(|x| one(x, kind)).collect()
}

/// One `"number unit"` value of `kind` in SI, within the template bounds.
pub(crate) use crate::units::quantity as one;

#[cfg(test)]
mod tests {
    use super::*;

    /// Every template file is built in under its file name, and every built-in one loads.
    #[test]
    fn every_template_file_is_built_in_and_loads() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("templates");
        let mut files: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
            .collect();
        files.sort();
        let mut names: Vec<String> = builtin_names().iter().map(|s| s.to_string()).collect();
        names.sort();
        assert_eq!(files, names);
        for n in builtin_names() {
            let m = load(n).unwrap_or_else(|e| panic!("{n}: {e}"));
            assert_eq!(m.name, n);
            assert!(
                n.chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit())
            );
        }
    }

    /// `order` must list every stage once: a duplicate would apply a stage twice, a missing
    /// quantization would silently drop the saturation.
    #[test]
    fn order_is_a_permutation() {
        let ok = parse(
            "order = [\"bias\", \"scale_factor\", \"misalignment\", \"noise\", \"quantization\"]\n",
            Path::new("o.toml"),
        );
        assert!(ok.is_ok());
        for bad in [
            "[\"bias\", \"bias\", \"misalignment\", \"noise\", \"quantization\"]",
            "[\"bias\", \"noise\"]",
            "[\"wobble\"]",
        ] {
            let e = parse(&format!("order = {bad}\n"), Path::new("o.toml"))
                .unwrap_err()
                .to_string();
            assert!(e.contains("o.toml") && e.contains("`order`"), "{e}");
        }
    }

    /// A user file can start from a built-in template and override single keys.
    #[test]
    fn base_template_with_overrides() {
        let m = parse(
            "base = \"ln200\"\nname = \"mine\"\n[gyro]\nnoise = \"0.1 deg/sqrt(h)\"\n",
            Path::new("mine.toml"),
        )
        .unwrap();
        let base = load("ln200").unwrap();
        assert_eq!(m.name, "mine");
        assert!((m.gyro.noise[0] - 0.1f64.to_radians() / 60.0).abs() < 1e-18);
        assert_eq!(m.gyro.bias_turn_on, base.gyro.bias_turn_on);
        assert_eq!(m.accel, base.accel);
    }

    /// Physically absurd values are refused with the file, the key, the value as written and
    /// the bound, in a short message; so are values that overflow in SI and negative
    /// magnitudes.
    #[test]
    fn absurd_values_are_refused() {
        for (text, key, shows) in [
            (
                "[gyro]\nnoise = \"1e300 deg/sqrt(h)\"\n",
                "`gyro.noise`",
                "`1e300 deg/sqrt(h)`",
            ),
            (
                "[accel]\nbias = [\"0 g\", \"2e6 g\", \"0 g\"]\n",
                "`accel.bias`",
                "`2e6 g`",
            ),
            (
                "[gyro]\nmisalignment = \"30 deg\"\n",
                "`gyro.misalignment`",
                "`30 deg`",
            ),
            (
                "[gyro]\nscale_factor_turn_on = \"150 %\"\n",
                "`gyro.scale_factor_turn_on`",
                "150 %",
            ),
            (
                "[gyro]\nbias_gm = { sigma = \"1 deg/h\", tau = \"1e10 s\" }\n",
                "`gyro.bias_gm`",
                "`1e10 s`",
            ),
            (
                "[gyro]\nquantization = \"2 rad\"\n",
                "`gyro.quantization`",
                "`2 rad`",
            ),
            (
                "[accel]\nrange = \"1e308 g\"\n",
                "`accel.range`",
                "`1e308 g`",
            ),
            (
                "[gyro]\nbias_temperature = [\"0 deg/h/degC\", \"1e9 deg/s/degC^2\"]\n",
                "`gyro.bias_temperature`",
                "coefficient 2",
            ),
            (
                "[gyro]\nnoise = \"-0.1 deg/sqrt(h)\"\n",
                "`gyro.noise`",
                "negative",
            ),
            ("rate_hz = 1e12\n", "`rate_hz`", "(0, 1e7]"),
            (
                "temperature_ref = \"-300 degC\"\n",
                "`temperature_ref`",
                "-273.15",
            ),
        ] {
            let e = parse(text, Path::new("t.toml")).unwrap_err().to_string();
            assert!(
                e.starts_with("t.toml: ") && e.contains(key) && e.contains(shows),
                "{e}"
            );
            assert!(e.len() < 260, "{e}");
        }
        let e = parse(
            "[gyro]\nnoise = \"1e300 deg/sqrt(h)\"\n",
            Path::new("t.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("at most 3438 deg/sqrt(h) = 1 rad/sqrt(s)"),
            "{e}"
        );
    }

    /// The bounds leave room for any real IMU: a deliberately poor consumer MEMS part loads.
    #[test]
    fn poor_consumer_mems_is_within_bounds() {
        let m = parse(
            "[gyro]\nbias = \"5 deg/s\"\nbias_turn_on = \"3 deg/s\"\nnoise = \"0.1 deg/s/sqrt(Hz)\"\n\
             scale_factor_turn_on = \"5 %\"\nmisalignment = \"3 deg\"\ng_sensitivity = \"0.5 deg/s/g\"\n\
             quantization = \"0.1 deg/s\"\nrange = \"4000 deg/s\"\n\
             bias_temperature = [\"0.05 deg/s/degC\"]\n\
             [accel]\nbias = \"200 mg\"\nnoise = \"2 mg/sqrt(Hz)\"\nscale_factor = \"5 %\"\n\
             range = \"400 g\"\nquantization = \"10 mg\"\nsize_effect = [\"5 mm\", \"0 mm\", \
             \"0 mm\", \"0 mm\", \"5 mm\", \"0 mm\", \"0 mm\", \"0 mm\", \"5 mm\"]\n",
            Path::new("mems.toml"),
        );
        assert!(m.is_ok(), "{:?}", m.err());
    }
}
