//! IMU templates: TOML files of datasheet figures with units (`templates/README.md`),
//! converted to SI once. Named templates are embedded in the binary; a user file may start from
//! a named one (`base = "ln200"`) and override any key.
//!
//! This file finds a template's text and resolves it (`base`, the `[typical]` profile);
//! `table` reads the resolved table into the model.

mod table;

use std::path::{Path, PathBuf};

pub use super::model::{ImuModel, TriadModel};
use table::from_table;

/// The built-in templates, embedded at compile time (a test checks every file in `templates/`
/// is listed here).
pub const BUILTIN: &[(&str, &str)] = &[
    ("ideal", include_str!("../../../templates/ideal.toml")),
    ("ln200", include_str!("../../../templates/ln200.toml")),
    ("hg1700", include_str!("../../../templates/hg1700.toml")),
    ("hg4930", include_str!("../../../templates/hg4930.toml")),
    ("kvh1750", include_str!("../../../templates/kvh1750.toml")),
    ("fsas", include_str!("../../../templates/fsas.toml")),
    ("stim300", include_str!("../../../templates/stim300.toml")),
    (
        "adis16488",
        include_str!("../../../templates/adis16488.toml"),
    ),
    (
        "adis16405",
        include_str!("../../../templates/adis16405.toml"),
    ),
    ("mpu6000", include_str!("../../../templates/mpu6000.toml")),
    ("ltn101", include_str!("../../../templates/ltn101.toml")),
    ("dmars", include_str!("../../../templates/dmars.toml")),
    ("ssks", include_str!("../../../templates/ssks.toml")),
    (
        "motionpak2",
        include_str!("../../../templates/motionpak2.toml"),
    ),
    ("fji", include_str!("../../../templates/fji.toml")),
    (
        "adis16448",
        include_str!("../../../templates/adis16448.toml"),
    ),
    ("bmi160", include_str!("../../../templates/bmi160.toml")),
    ("navchip", include_str!("../../../templates/navchip.toml")),
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
        let text = crate::csvio::read_text(path).map_err(|source| TemplateError::Io {
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

/// A bad key's error.
pub(super) fn key_err(path: &Path, key: &str, message: &str) -> TemplateError {
    TemplateError::Key {
        path: path.to_path_buf(),
        key: key.to_string(),
        message: message.to_string(),
    }
}

#[cfg(test)]
mod tests;
