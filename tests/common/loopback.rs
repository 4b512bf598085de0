//! Helpers of the wall-clock tests (tests/sync.rs, tests/timebase.rs): a loopback UDP
//! receiver whose datagrams the kernel stamps on CLOCK_REALTIME, and simple order statistics.
#![allow(dead_code)]

use std::net::UdpSocket;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

#[path = "udp_rx.rs"]
mod udp_rx;

/// CLOCK_REALTIME now (ns since the Unix epoch).
pub fn utc_now_ns() -> i128 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_nanos() as i128
}

/// A datagram: the kernel's CLOCK_REALTIME stamp of its arrival (ns), and its bytes.
pub type Arrival = (i128, Vec<u8>);

/// A loopback UDP receiver ([`udp_rx::UdpRx`]: kernel arrival stamps, a large buffer):
/// its address and a handle whose `join`, called once the sender has exited, gives every
/// datagram with its CLOCK_REALTIME arrival.
pub fn receive() -> (String, Receiving) {
    let rx = udp_rx::UdpRx::start();
    (rx.dest.clone(), Receiving(rx))
}

/// A receiver started by [`receive`].
pub struct Receiving(udp_rx::UdpRx);

impl Receiving {
    /// Everything received (call once the sender has exited).
    pub fn join(self) -> std::thread::Result<Vec<Arrival>> {
        Ok(self.0.stop())
    }
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
