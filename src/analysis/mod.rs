//! Analysis of IMU signals: statistics, Allan deviation with confidence intervals, IEEE 952
//! term fit, Welch PSD, the template's theoretical curves and the term-by-term check against
//! a template. Pure functions and streaming accumulators; [`reader`] is the only I/O.

pub mod adev_table;
pub mod allan;
pub mod analyzer;
pub mod blocks;
pub mod confidence;
pub mod conformance;
pub mod error_plot;
pub mod fit;
pub mod lattice;
pub mod octave_adev;
pub mod passes;
pub mod psd;
pub mod psd_band;
pub mod reader;
pub mod recording;
pub mod report;
pub mod stats;
pub mod theory;
pub mod transients;
