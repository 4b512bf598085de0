//! A hardware-in-the-loop rig with the library alone: a vehicle simulation sends its states
//! over UDP as GPS-tagged CSV lines (`gps_week,gps_sow,lat,lon,h,vn,ve,vd,roll,pitch,yaw`,
//! docs/live-input.md); the program follows them in real time with two IMUs and a GNSS
//! receiver, everything on GPS time:
//!
//! * `nav`, an iMAR FSAS at 400 Hz in iXCOM frames (GPS week and time of week in each), on a
//!   pseudo-terminal for the navigator under test;
//! * `aux`, a STIM300 0.8 m ahead and 0.2 m below, in NovAtel RAWIMUSX frames at 125 Hz, to UDP;
//! * the receiver's NMEA sentences at 5 Hz, to UDP.
//!
//! A status line every second; Ctrl-C (or SIGTERM) stops the run, then the summary.
//!
//! `cargo run --release --example hil -- udp://127.0.0.1:7000 /tmp/imu-nav 127.0.0.1:9001 127.0.0.1:9010`

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use imu_emu::aiding::{GnssConfig, GnssFormat};
use imu_emu::rig::UnitSpec;
use imu_emu::run::{Control, LiveSpec, RunSpec, StreamId, TimeBase};
use imu_emu::sim::Simulation;

const USAGE: &str = "usage: hil MOTION PTY_PATH IMU_UDP GNSS_UDP (e.g. udp://127.0.0.1:7000 /tmp/imu-nav 127.0.0.1:9001 127.0.0.1:9010)";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [motion, pty, imu_udp, gnss_udp] = args.as_slice() else {
        return Err(USAGE.into());
    };
    let nav = UnitSpec {
        rate_hz: Some(400.0),
        format: Some("imar-ixcom".into()),
        ..UnitSpec::imu("nav", "fsas")
    };
    let aux = UnitSpec {
        format: Some("novatel-rawimusx".into()),
        lever_arm_m: [0.8, 0.0, 0.2],
        ..UnitSpec::imu("aux", "stim300")
    };
    let signal = Simulation::builder()
        .unit(nav)
        .unit(aux)
        .gnss(GnssConfig::default())
        .seed(1);
    let run = RunSpec::new(signal)
        .live(LiveSpec::new(motion))
        .time_base(TimeBase::Gps)
        .sink(StreamId::unit("nav"), &format!("pty:{pty}"))?
        .sink(StreamId::unit("aux"), &format!("udp:{imu_udp}"))?
        .sink(StreamId::Gnss(GnssFormat::Nmea), &format!("udp:{gnss_udp}"))?
        .build()?;

    let streams = run.streams().to_vec();
    let signals = imu_emu::realtime::signal::watch()?;
    let ctl = Control::with_notes(|note| eprintln!("hil: {note}"));
    let report = std::thread::scope(|scope| {
        let worker = scope.spawn(|| run.execute(&ctl));
        let mut shown = Instant::now();
        while !worker.is_finished() {
            std::thread::sleep(Duration::from_millis(50));
            if signals.load(Ordering::Relaxed) != 0 {
                ctl.stop();
            }
            let status = ctl.status();
            if status.started && shown.elapsed() >= Duration::from_secs(1) {
                shown = Instant::now();
                eprintln!("hil: {}", status.line(&streams));
            }
        }
        worker.join().expect("the run's thread")
    })?;
    println!("{}", report.summary());
    Ok(())
}
