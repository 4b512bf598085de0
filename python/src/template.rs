//! Python values turned into library inputs: an IMU template given as a dict (the keys of a
//! template file, `templates/README.md`), and scene parameters.

use std::path::Path;

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use imu_emu::errors::ImuModel;

use crate::errors::{err, invalid};

/// A Python value (dict, list, str, int, float, bool) as TOML; `at` names the key for errors.
fn to_toml(v: &Bound<'_, PyAny>, at: &str) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(v.extract()?));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = toml::map::Map::new();
        for (k, x) in d.iter() {
            let k: String = k
                .extract()
                .map_err(|_| invalid(format!("template dict {at}: keys must be strings")))?;
            let here = if at.is_empty() {
                k.clone()
            } else {
                format!("{at}.{k}")
            };
            t.insert(k, to_toml(&x, &here)?);
        }
        return Ok(toml::Value::Table(t));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let items = v
            .try_iter()?
            .enumerate()
            .map(|(i, x)| to_toml(&x?, &format!("{at}[{i}]")))
            .collect::<PyResult<Vec<_>>>()?;
        return Ok(toml::Value::Array(items));
    }
    // numpy scalars and anything else with a float value.
    if let Ok(x) = v.extract::<f64>() {
        return Ok(toml::Value::Float(x));
    }
    Err(invalid(format!(
        "template dict `{at}`: {} is not a number, string, bool, list or dict",
        v.get_type().name()?
    )))
}

/// The IMU model of a template given as a dict: written as the TOML of a template file and
/// loaded by the library's template loader, so that it is checked exactly as a file is.
pub fn model_from_dict(d: &Bound<'_, PyDict>) -> PyResult<ImuModel> {
    let value = to_toml(d.as_any(), "")?;
    let text = toml::to_string(&value).map_err(err)?;
    imu_emu::errors::template::parse(&text, Path::new("template dict")).map_err(err)
}
