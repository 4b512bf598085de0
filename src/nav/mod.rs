//! The reference strapdown navigator: free-inertial navigation on WGS-84 from our own
//! increments (`strapdown`), the causal signal reconstruction and collocation tableau it uses
//! (`poly`), closure runs on the built-in scenes (`closure`) and Monte Carlo comparison of
//! IMU templates (`montecarlo`), and the GNSS-aided error-state Kalman filter (`aided`). Pure
//! computation, no I/O.

pub mod aided;
pub mod campaign;
pub mod closure;
pub mod gnss_fixes;
pub mod montecarlo;
pub mod poly;
pub mod strapdown;

pub use closure::{CloseError, Closure, close, close_scene};
pub use strapdown::{NavState, Navigator, Settings, SettingsError, StateError};
