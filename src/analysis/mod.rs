//! Analysis of simulated signals: pure functions over sample slices, no I/O.

pub mod allan;
