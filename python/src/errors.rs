//! Library errors as Python exceptions, with the library's messages.

use pyo3::PyErr;
use pyo3::create_exception;

create_exception!(
    imu_emu,
    ImuEmuError,
    pyo3::exceptions::PyValueError,
    "An input or setting the imu-emu library refused; the message names the file, line, key or setting to fix."
);

/// The error and its causes joined by `: `, as the CLI prints them (`{:#}`), a cause that the
/// message already ends with not repeated.
pub fn message(e: &(dyn std::error::Error + 'static)) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        let t = c.to_string();
        if !t.is_empty() && !s.ends_with(&t) {
            s.push_str(": ");
            s.push_str(&t);
        }
        cur = c.source();
    }
    s
}

/// A library error as an [`ImuEmuError`].
pub fn err(e: impl std::error::Error + 'static) -> PyErr {
    ImuEmuError::new_err(message(&e))
}

/// A message of ours as an [`ImuEmuError`].
pub fn invalid(m: impl Into<String>) -> PyErr {
    ImuEmuError::new_err(m.into())
}
