//! `imu_emu._native`: the imu-emu library for Python. Each function converts its Python
//! arguments, releases the GIL while the library works (`Python::detach`, PyO3's former
//! `allow_threads`), and hands back numpy arrays that own the library's buffers (no copy),
//! plain dicts, or bytes. Library errors become `imu_emu.ImuEmuError` with the library's
//! message (the same text the CLI prints).

mod analysis;
mod campaign;
mod codec;
mod errors;
mod live;
mod simulate;
mod template;

use pyo3::prelude::*;

/// The native module; `imu_emu/__init__.py` wraps it.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ImuEmuError", m.py().get_type::<errors::ImuEmuError>())?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::names, m)?)?;
    m.add_function(wrap_pyfunction!(codec::encode, m)?)?;
    m.add_function(wrap_pyfunction!(codec::decode, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::analyze, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::fit, m)?)?;
    m.add_class::<live::LiveRun>()?;
    m.add_class::<campaign::Campaign>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
