//! Monte Carlo comparison of IMU templates (filled below).
