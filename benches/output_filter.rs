//! Cost of an output filter: ns per output record of the error chain alone (white noise and
//! a flicker bias at 200 Hz) against the same chain with an `[output_filter]` (internal rate
//! 1600 Hz, decimated to 200 Hz), for each filter kind. Static zero input, blocks of 4096.
//!
//! `cargo bench --bench output_filter` prints the table docs/fidelity.md shows.

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use imu_emu::errors::filtered::FilteredChain;
use imu_emu::errors::{ErrorChain, template};
use imu_emu::record::Record;

const BASE: &str = "[gyro]\nnoise = \"0.15 deg/sqrt(h)\"\nbias_instability = \"0.5 deg/h\"\n\
                    [accel]\nnoise = \"0.07 m/s/sqrt(h)\"\nbias_instability = \"50 ug\"\n";
const OUT_RATE: f64 = 200.0;
const OUTPUTS: usize = 2_000_000;

fn zeros(n: usize, rate: f64) -> Vec<Record> {
    (0..n)
        .map(|k| Record {
            t: (k + 1) as f64 / rate,
            ..Record::default()
        })
        .collect()
}

fn main() {
    let m = template::parse(BASE, Path::new("bench.toml")).unwrap();
    let mut chain = ErrorChain::new(&m, OUT_RATE, 1);
    let mut block = zeros(4096, OUT_RATE);
    let t0 = Instant::now();
    for _ in 0..OUTPUTS / 4096 {
        chain.apply(&mut block);
        black_box(&block);
    }
    let base = t0.elapsed().as_secs_f64() * 1e9 / (OUTPUTS / 4096 * 4096) as f64;
    println!("| chain | ns per output record |\n|---|---|");
    println!("| no filter, 200 Hz | {base:.1} |");
    for (name, filter) in [
        (
            "moving average, 8 taps",
            "kind = \"moving_average\"\ntaps = 8",
        ),
        ("CIC, 3 stages of 8", "kind = \"cic\"\norder = 3\ntaps = 8"),
        (
            "FIR, 32 taps",
            "kind = \"fir\"\ncoefficients = [1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1]",
        ),
        (
            "Butterworth, order 4",
            "kind = \"butterworth\"\norder = 4\ncutoff = \"40 Hz\"",
        ),
    ] {
        let text = format!("{BASE}[output_filter]\ninternal_rate_hz = 1600\n{filter}\n");
        let m = template::parse(&text, Path::new("bench.toml")).unwrap();
        let mut chain = FilteredChain::new(&m, OUT_RATE, 1).unwrap();
        let input = zeros(4096, 1600.0);
        let mut out = Vec::with_capacity(1024);
        let blocks = OUTPUTS * 8 / 4096;
        let t0 = Instant::now();
        for _ in 0..blocks {
            out.clear();
            chain.apply(&input, &mut out);
            black_box(&out);
        }
        let ns = t0.elapsed().as_secs_f64() * 1e9 / (blocks * 512) as f64;
        println!("| {name}, 1600 → 200 Hz | {ns:.1} ({:.1}×) |", ns / base);
    }
}
