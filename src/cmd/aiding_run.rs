//! The aiding streams of `imu-emu run` (`--gnss FORMAT:SINK`, `--odometer SINK`, `--baro
//! SINK`, `--magnetometer SINK`): parsed into one stream per receiver format or sensor, each
//! with its sinks, for the merger that puts them on the IMU's (or the rig's) pacer.

use anyhow::{Result, bail};

use imu_emu::aiding::GnssFormat;
use imu_emu::aiding::sensors::SensorKind;
use imu_emu::rig::SinkAddr;
use imu_emu::run::merge::WindowSource;
use imu_emu::sim::aiding_frames::sensor_window;

use super::run::RunArgs;

/// What an aiding stream carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aiding {
    /// A GNSS receiver's epochs in one wire format.
    Gnss(GnssFormat),
    /// A sensor's CSV rows.
    Sensor(SensorKind),
}

impl Aiding {
    /// The stream's name in messages and the summary (`gnss-nmea`, `odometer`).
    pub fn name(self) -> String {
        match self {
            Aiding::Gnss(f) => format!("gnss-{}", GnssFormat::NAMES[f as usize]),
            Aiding::Sensor(k) => k.name().to_string(),
        }
    }

    /// What its frames are called in the summary.
    pub fn unit(self) -> &'static str {
        match self {
            Aiding::Gnss(_) => "epochs",
            Aiding::Sensor(_) => "samples",
        }
    }
}

/// One aiding stream of a run, ready for the merger.
pub struct AidingStream {
    /// What it carries.
    pub what: Aiding,
    /// Where it goes.
    pub sinks: Vec<SinkAddr>,
    /// Frames per simulated second.
    pub rate_hz: f64,
    /// Frames over the run.
    pub planned: u64,
    /// Its frames with their emission times.
    pub source: Box<dyn WindowSource>,
}

/// The aiding streams `a` asks for, one per GNSS format or sensor (a stream asked for twice
/// goes to both sinks), in the order first asked.
pub fn requests(a: &RunArgs) -> Result<Vec<(Aiding, Vec<SinkAddr>)>> {
    let mut out: Vec<(Aiding, Vec<SinkAddr>)> = Vec::new();
    let mut add = |what: Aiding, addr: SinkAddr| match out.iter_mut().find(|o| o.0 == what) {
        Some(o) => o.1.push(addr),
        None => out.push((what, vec![addr])),
    };
    for v in &a.gnss {
        let (name, sink) = v.split_once(':').unwrap_or((v, ""));
        let Some(f) = GnssFormat::from_name(name) else {
            bail!(
                "--gnss {v}: unknown format `{name}` (expected FORMAT:SINK with FORMAT one of {})",
                GnssFormat::NAMES.join(", ")
            );
        };
        let addr = SinkAddr::parse(sink).map_err(|e| anyhow::anyhow!("--gnss {v}: {e}"))?;
        add(Aiding::Gnss(f), addr);
    }
    let sensors = [&a.odometer, &a.baro, &a.magnetometer];
    for (kind, values) in SensorKind::ALL.into_iter().zip(sensors) {
        for v in values {
            let addr =
                SinkAddr::parse(v).map_err(|e| anyhow::anyhow!("--{} {v}: {e}", kind.name()))?;
            add(Aiding::Sensor(kind), addr);
        }
    }
    Ok(out)
}

/// Flags of a run that aiding streams cannot share yet. (`--time-marks` and `--pulse` can:
/// they mark the IMU's records only, the aiding frames pass unmarked.)
pub fn refuse_with_aiding(a: &RunArgs, asked: &[(Aiding, Vec<SinkAddr>)]) -> Result<()> {
    let Some((what, _)) = asked.first() else {
        return Ok(());
    };
    let given = [
        (
            "--motion",
            a.live.motion.is_some(),
            "the live motion's aiding streams are not built",
        ),
        (
            "--trigger",
            a.trigger.is_some(),
            "the IMU samples at the trigger's edges, whose times the aiding streams, on the simulated clock, would have to follow",
        ),
    ];
    if let Some((flag, _, why)) = given.iter().find(|g| g.1) {
        bail!(
            "{flag} and the aiding stream `{}` cannot share a run yet: {why} (docs/aiding.md)",
            what.name()
        );
    }
    Ok(())
}

/// A simulation or a rig: what its aiding streams follow (motion, clock, seed, span).
pub trait AidingHost {
    /// The GNSS receiver's epochs in `f` as a stream, its epochs per second and over the run.
    fn gnss(&self, f: GnssFormat) -> (Box<dyn WindowSource>, f64, u64);
    /// The span's samples of sensor `k` as a stream: (stream, rate, samples).
    fn sensor(&self, k: SensorKind) -> (Box<dyn WindowSource>, f64, u64);
}

impl AidingHost for imu_emu::sim::Simulation {
    fn gnss(&self, f: GnssFormat) -> (Box<dyn WindowSource>, f64, u64) {
        let w = Box::new(self.gnss_window(f));
        (w, self.gnss_rate_hz(), self.gnss_epochs())
    }
    fn sensor(&self, k: SensorKind) -> (Box<dyn WindowSource>, f64, u64) {
        let rows = self.sensor_rows(k);
        let (rate, n) = (rows.rate_hz(), rows.count());
        (Box::new(sensor_window(rows, self.grid().t0)), rate, n)
    }
}

impl AidingHost for imu_emu::rig::Rig {
    fn gnss(&self, f: GnssFormat) -> (Box<dyn WindowSource>, f64, u64) {
        let w = Box::new(self.gnss_window(f));
        (w, self.gnss_rate_hz(), self.gnss_epochs())
    }
    fn sensor(&self, k: SensorKind) -> (Box<dyn WindowSource>, f64, u64) {
        let rows = self.sensor_rows(k);
        let (rate, n) = (rows.rate_hz(), rows.count());
        (Box::new(sensor_window(rows, self.span().0)), rate, n)
    }
}

/// The streams `asked` for, following `host`.
pub fn build(asked: Vec<(Aiding, Vec<SinkAddr>)>, host: &impl AidingHost) -> Vec<AidingStream> {
    (asked.into_iter())
        .map(|(what, sinks)| {
            let (source, rate_hz, planned) = match what {
                Aiding::Gnss(f) => host.gnss(f),
                Aiding::Sensor(k) => host.sensor(k),
            };
            AidingStream {
                what,
                sinks,
                rate_hz,
                planned,
                source,
            }
        })
        .collect()
}
