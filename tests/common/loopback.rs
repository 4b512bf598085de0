//! Helpers of the wall-clock tests (tests/sync.rs, tests/timebase.rs): a loopback UDP
//! receiver timestamping each datagram on CLOCK_REALTIME, and simple order statistics.
#![allow(dead_code)]

use std::net::UdpSocket;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// CLOCK_REALTIME now (ns since the Unix epoch).
pub fn utc_now_ns() -> i128 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_nanos() as i128
}

/// A datagram: CLOCK_REALTIME when `recv` returned (ns), and its bytes.
pub type Arrival = (i128, Vec<u8>);

/// A loopback UDP receiver on its own thread until `secs` have passed: its address and, when
/// joined, each datagram with CLOCK_REALTIME at its arrival.
pub fn receive(secs: f64) -> (String, std::thread::JoinHandle<Vec<Arrival>>) {
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let dest = rx.local_addr().unwrap().to_string();
    let end = utc_now_ns() + (secs * 1e9) as i128;
    let h = std::thread::spawn(move || {
        let (mut got, mut buf) = (Vec::new(), [0u8; 2048]);
        while utc_now_ns() < end {
            if let Ok(n) = rx.recv(&mut buf) {
                got.push((utc_now_ns(), buf[..n].to_vec()));
            }
        }
        got
    });
    (dest, h)
}

/// The median (the upper one of an even count).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The q-quantile (0..=1) as the ⌈q·n⌉-th smallest value; sorts `v`.
pub fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1]
}

/// An `ln200`-based IMU template with the `[timing]` table `timing`, written into `dir`.
pub fn timed_ln200(dir: &std::path::Path, timing: &str) -> std::path::PathBuf {
    let p = dir.join("timed.toml");
    std::fs::write(&p, format!("base = \"ln200\"\n[timing]\n{timing}")).unwrap();
    p
}

/// The survey scene's states every 10 ms from t = 0 to `seconds`, as trajectory CSV lines
/// (what `imu-emu trajectory --rate 100` writes).
pub fn survey_csv(seconds: f64) -> String {
    let motion = imu_emu::sim::Simulation::builder()
        .build()
        .unwrap()
        .motion()
        .clone();
    imu_emu::trajectory::sample_motion(&motion, 0.0, 100.0, (seconds * 100.0) as u64, None)
}

/// Sends each line of `text` as one datagram to `port` on loopback, line k at k·10 ms after
/// the call (a vehicle simulation's 100 Hz states in real time).
pub fn send_states(port: u16, text: &str) {
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let start = std::time::Instant::now();
    for (k, line) in text.lines().enumerate() {
        if let Some(w) = Duration::from_millis(10 * k as u64).checked_sub(start.elapsed()) {
            std::thread::sleep(w);
        }
        sock.send_to(line.as_bytes(), ("127.0.0.1", port)).unwrap();
    }
}
