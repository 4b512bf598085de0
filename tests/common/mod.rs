//! Helpers shared by the error-model test targets (`error_model`, `gauss_markov`,
//! `quantization`): templates from text, records built directly, and streaming through a chain.
// Each test target uses only some of these.
#![allow(dead_code)]

pub mod cli;

use std::path::Path;

use imu_emu::errors::{ErrorChain, ImuModel, template};
use imu_emu::math::Vec3;
use imu_emu::record::Record;

/// Records per call to `ErrorChain::apply`, as the generator streams them.
pub const BLOCK: usize = 4096;

/// A template from its TOML text.
pub fn model(text: &str) -> ImuModel {
    template::parse(text, Path::new("x.toml")).expect("test template")
}

/// Record k (time tag at the end of its interval) with interval-mean rates and their increments.
pub fn record(k: usize, rate: f64, gyro: [f64; 3], accel: [f64; 3]) -> Record {
    let dt = 1.0 / rate;
    Record {
        t: (k + 1) as f64 / rate,
        gyro: Vec3::from(gyro),
        accel: Vec3::from(accel),
        dtheta: Vec3::from(gyro) * dt,
        dv: Vec3::from(accel) * dt,
        flags: 0,
    }
}

/// The static zero-motion input (all-zero signal).
pub fn zero(k: usize, rate: f64) -> Record {
    record(k, rate, [0.0; 3], [0.0; 3])
}

/// Feeds records `input(0..n)` through `chain` in blocks of `block`, handing each corrupted
/// block and the index of its first record to `sink`; only one block is ever held.
pub fn stream(
    chain: &mut ErrorChain,
    rate: f64,
    n: usize,
    block: usize,
    input: impl Fn(usize, f64) -> Record,
    mut sink: impl FnMut(usize, &[Record]),
) {
    let mut buf = Vec::with_capacity(block);
    let mut k0 = 0;
    while k0 < n {
        buf.clear();
        buf.extend((k0..n.min(k0 + block)).map(|k| input(k, rate)));
        chain.apply(&mut buf);
        sink(k0, &buf);
        k0 += buf.len();
    }
}

/// The six error axes (gyro x y z, accel x y z) of a record against its input.
pub fn errors6(out: &Record, inp: &Record) -> [f64; 6] {
    let (g, a) = (out.gyro - inp.gyro, out.accel - inp.accel);
    [g[0], g[1], g[2], a[0], a[1], a[2]]
}
