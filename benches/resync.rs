//! How fast a decoder hunts for frames through garbage: `cargo bench --bench resync`.
//!
//! Feeds 64 MiB of zeros and 64 MiB of random bytes to the stream decoder of every built-in
//! protocol (the code `imu-emu decode` and `analyze --format` run), in 64 KiB reads as they
//! read a file, and prints MB/s, best of 5 (this 2-core VM is noisy), with the frames found
//! (none but `ln200`'s in zeros: an all-zero frame is one, its word sum is 0).

use std::time::Instant;

use imu_emu::protocol::{StreamDecoder, builtin_names, load};
use rand::{RngExt, SeedableRng};

const BYTES: usize = 64 << 20;

/// MB/s of the best of 5 passes over `data`, and the frames found.
fn measure(name: &str, data: &[u8]) -> (f64, u64) {
    let (_, plan) = load(name).expect("built in");
    let mut best = f64::INFINITY;
    let mut frames = 0;
    for _ in 0..5 {
        let mut dec = StreamDecoder::new(plan.clone());
        let t = Instant::now();
        for chunk in data.chunks(1 << 16) {
            dec.feed(chunk, |_| {});
        }
        dec.finish();
        best = best.min(t.elapsed().as_secs_f64());
        frames = dec.stats().frames;
    }
    (data.len() as f64 / best / 1e6, frames)
}

fn main() {
    let zeros = vec![0u8; BYTES];
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(38);
    let noise: Vec<u8> = (0..BYTES).map(|_| rng.random::<u8>()).collect();
    println!("| protocol | zeros MB/s | frames | random bytes MB/s | frames |");
    println!("|---|---:|---:|---:|---:|");
    for name in builtin_names() {
        let (z, fz) = measure(name, &zeros);
        let (r, fr) = measure(name, &noise);
        println!("| {name} | {z:.0} | {fz} | {r:.0} | {fr} |");
    }
}
