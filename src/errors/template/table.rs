//! A template's TOML table (after `base` and the profile are laid over it) read into the SI
//! model: every key checked, every `"number unit"` converted once, within the template bounds.

use std::path::Path;

use super::{ImuModel, TemplateError, TriadModel, key_err};
use crate::errors::model::StageKind;
use crate::errors::process::QuantMode;
use crate::units::bounds;
use crate::units::{self, Kind, Lsb};

/// One `"number unit"` value of `kind` in SI, within the template bounds.
use crate::units::quantity as one;

/// Reads a whole template table into the model, refusing unknown keys.
pub(super) fn from_table(t: &toml::Table, path: &Path) -> Result<ImuModel, TemplateError> {
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
        Some(toml::Value::Table(f)) => Some(crate::errors::output_filter::from_toml(f).map_err(
            |(k, m)| {
                let key = if k.is_empty() {
                    "output_filter".to_string()
                } else {
                    format!("output_filter.{k}")
                };
                key_err(path, &key, &m)
            },
        )?),
        Some(_) => return Err(key_err(path, "output_filter", "expected a table")),
    };
    let gyro = triad(t.get("gyro"), "gyro", path)?;
    let accel = triad(t.get("accel"), "accel", path)?;
    for (name, m) in [("gyro", &gyro), ("accel", &accel)] {
        if output_filter.is_none() && m.post_filter_noise.iter().any(|n| *n > 0.0) {
            return Err(key_err(
                path,
                &format!("{name}.post_filter_noise"),
                "needs an [output_filter] (without one, white noise at the output rate is `noise`)",
            ));
        }
    }
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
            "quantization_noise" => {
                m.quantization_noise = increments(val, lsb).map_err(err)?;
                nonneg(&m.quantization_noise)?
            }
            "post_filter_noise" => {
                m.post_filter_noise = axes(val, rw).map_err(err)?;
                nonneg(&m.post_filter_noise)?
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

/// One increment (angle or velocity, `"value unit"`) for all axes or three, in SI, within the
/// bounds of an LSB of `kind`: a rate unit is refused (Q is an angle or a velocity).
fn increments(v: &toml::Value, kind: Kind) -> Result<[f64; 3], String> {
    let one = |x: &toml::Value| -> Result<f64, String> {
        let s = x.as_str().ok_or(
            "expected a string \"value unit\" (an angle or a velocity, e.g. \"1e-6 rad\")",
        )?;
        let (q, inc) = units::parse(s, kind).map_err(|e| e.to_string())?;
        if !inc {
            return Err(format!(
                "`{s}`: expected an angle or a velocity (Q of 3Q²/τ²), not a rate"
            ));
        }
        bounds::check(s, kind, q, inc)?;
        Ok(q)
    };
    match v {
        toml::Value::Array(a) if a.len() == 3 => Ok([one(&a[0])?, one(&a[1])?, one(&a[2])?]),
        toml::Value::Array(a) => Err(format!("expected 3 values, got {}", a.len())),
        _ => Ok([one(v)?; 3]),
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
