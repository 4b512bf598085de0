//! Aiding streams a navigator reads next to the IMU, computed from the same motion and clock:
//! GNSS position, velocity and time ([`gnss`]) and their wire formats ([`nmea`], [`ubx`],
//! [`mavlink`]), chosen by [`stream::GnssFormat`]. Pure models and encoders, no I/O.

pub mod baro;
pub mod field_table;
pub mod gnss;
pub mod mag_samples;
pub mod magnetometer;
pub mod mavlink;
pub mod nmea;
pub mod odometer;
pub mod sensors;
pub mod stream;
pub mod time;
pub mod ubx;

pub use gnss::{Fix, GnssConfig, GnssEpoch, Receiver};
pub use stream::{GnssEncoder, GnssFormat};

/// Why a sensor cannot give a sample (a position outside its field table, a value that is not
/// finite), naming the time.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct SampleError(pub String);
