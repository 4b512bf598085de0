//! A whole simulation from code with the library alone: the circle scene seen by an LN-200
//! error model that warms up by 2 °C/s and is mounted rolled by 90°, streamed as KVH 1750
//! frames to a file. `cargo run --release --example simulate -- circle.kvh`
//! (`imu-emu decode --protocol kvh1750 circle.kvh` reads it back).

use std::io::{BufWriter, Write};
use std::path::Path;

use imu_emu::errors::temperature::TemperatureProfile;
use imu_emu::sim::Simulation;

/// Simulates 10 s at 1 kHz into `out`; returns the number of frames written.
pub fn simulate(out: &Path) -> Result<u64, Box<dyn std::error::Error>> {
    let ramp = TemperatureProfile::Ramp {
        start: 10.0,
        rate: 2.0,
        limit: None,
    };
    let sim = Simulation::builder()
        .scene("circle")
        .imu("ln200")
        .format("kvh1750")
        .rate(1000.0)
        .duration(10.0)
        .temperature(ramp)
        .mounting_deg([90.0, 0.0, 0.0])
        .seed(7)
        .build()?;
    let frames = sim.grid().count;
    let mut file = BufWriter::new(std::fs::File::create(out)?);
    sim.write(&mut file)?;
    file.flush()?;
    Ok(frames)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "circle.kvh".into());
    let frames = simulate(Path::new(&out))?;
    eprintln!("{frames} KVH 1750 frames written to {out}");
    Ok(())
}
