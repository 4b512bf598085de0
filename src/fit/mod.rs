//! Fitting an IMU template to a recording (`imu-emu fit`): the stochastic model of each axis
//! fitted to its Allan variance ([`gmwm`]), narrow spectral lines found in its PSD
//! ([`lines`]), broad resonances as random vibrations ([`resonance`] from a PSD,
//! [`resonance_adev`] from a table's Allan deviation), the fitted template written as TOML
//! ([`template`]), a record simulated from it checked against the recording ([`closure`]), the
//! report ([`report`]) and the term-by-term comparison of two recordings ([`compare`]); the
//! Allan variance of a random vibration in [`vibration_avar`]. No file I/O: the command reads
//! the input and writes the outputs.

pub mod analysis_report;
pub mod checks;
pub mod closure;
pub mod compare;
pub mod filter;
pub mod gmwm;
pub mod lines;
pub mod output;
pub mod ramp;
pub mod recording_fit;
pub mod report;
pub mod resonance;
pub mod resonance_adev;
pub mod template;
pub mod vibration_avar;
