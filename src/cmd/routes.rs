//! Sink flags turned into a run's routes: a rig unit's `--unit-sink`, the aiding streams'
//! `--gnss FORMAT:SINK` and sensor flags, and the default pty of a unit with no sink.

use anyhow::{Result, bail};

use imu_emu::aiding::GnssFormat;
use imu_emu::aiding::sensors::SensorKind;
use imu_emu::output::SinkAddr;
use imu_emu::run::{RunSpec, StreamId};
use imu_emu::sim::SimulationBuilder;

/// The run of `signal` with the sinks its scene file gives.
pub fn from_scene(signal: SimulationBuilder) -> Result<RunSpec> {
    Ok(RunSpec::from_signal(signal)?)
}

/// `--unit-sink NAME=SINK`: replaces the scene file's sinks of each unit it names.
pub fn unit_sinks(spec: &mut RunSpec, values: &[String]) -> Result<()> {
    let mut replaced: Vec<&str> = Vec::new();
    for v in values {
        let Some((name, sink)) = v.split_once('=') else {
            bail!("--unit-sink {v}: expected NAME=SINK (e.g. nav=udp:127.0.0.1:9001)");
        };
        let addr = SinkAddr::parse(sink).map_err(|e| anyhow::anyhow!("--unit-sink {v}: {e}"))?;
        if !replaced.contains(&name) {
            spec.replace_routes(|s| matches!(s, StreamId::Unit { unit: Some(u), .. } if u == name));
            replaced.push(name);
        }
        spec.add_route(StreamId::unit(name), addr, format!("--unit-sink {v}"));
    }
    Ok(())
}

/// `--gnss FORMAT:SINK` and the sensor flags (odometer, baro, magnetometer); `sink` reads a
/// flag's sink text. Like the IMU's sink flags, each replaces the scene file's routes of its
/// streams (`[run] gnss`, `odometer`, …).
pub fn aiding(
    spec: &mut RunSpec,
    gnss: &[String],
    sensors: [&[String]; 3],
    sink: impl Fn(&str) -> Result<SinkAddr, String>,
) -> Result<()> {
    if !gnss.is_empty() {
        spec.replace_routes(|s| matches!(s, StreamId::Gnss(_)));
    }
    for (kind, values) in SensorKind::ALL.into_iter().zip(sensors) {
        if !values.is_empty() {
            spec.replace_routes(|s| *s == StreamId::Sensor(kind));
        }
    }
    for v in gnss {
        let (name, target) = v.split_once(':').unwrap_or((v, ""));
        let Some(f) = GnssFormat::from_name(name) else {
            bail!(
                "--gnss {v}: unknown format `{name}` (expected FORMAT:SINK with FORMAT one of {})",
                GnssFormat::NAMES.join(", ")
            );
        };
        let addr = sink(target).map_err(|e| anyhow::anyhow!("--gnss {v}: {e}"))?;
        spec.add_route(StreamId::Gnss(f), addr, format!("--gnss {v}"));
    }
    for (kind, values) in SensorKind::ALL.into_iter().zip(sensors) {
        for v in values {
            let flag = format!("--{} {v}", kind.name());
            let addr = sink(v).map_err(|e| anyhow::anyhow!("{flag}: {e}"))?;
            spec.add_route(StreamId::Sensor(kind), addr, flag);
        }
    }
    Ok(())
}

/// A unit with no sink gets a pty of its own (its /dev/pts path is printed).
pub fn default_ptys(spec: &mut RunSpec) -> Result<()> {
    let units: Vec<Option<String>> = if spec.signal.is_rig() {
        (spec.signal.unit_specs()?.into_iter())
            .map(|(_, u)| Some(u.name))
            .collect()
    } else {
        vec![None]
    };
    for u in units {
        let routed = (spec.routes.iter())
            .any(|r| matches!(&r.stream, StreamId::Unit { unit, .. } if *unit == u));
        if !routed {
            let stream = StreamId::Unit {
                unit: u,
                protocol: None,
            };
            spec.add_route(stream, SinkAddr::Pty(None), "the default pty".into());
        }
    }
    Ok(())
}
