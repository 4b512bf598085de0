//! Which streams a run has and where each goes: the routes of a [`RunSpec`](super::RunSpec)
//! resolved against what the signal is (one IMU or a rig's units, their formats), and the
//! frame sources that make those streams, built from a [`Simulation`] or a [`Rig`].

use crate::aiding::GnssFormat;
use crate::aiding::sensors::SensorKind;
use crate::engine::frames::WindowSource;
use crate::output::SinkAddr;
use crate::protocol::Plan;
use crate::rig::Rig;
use crate::sim::{AidingStreams, Output, SimError, Simulation};

use super::error::RunError;
use super::sources::aiding::{GnssSource, sensor_source};
use super::sources::imu::{ImuFrames, Sides};
use super::spec::{Route, StreamId};

/// Frame sources, and the preamble (a CSV header, or nothing) of each of their streams.
pub type SourcesWithPreambles = (Vec<Box<dyn WindowSource>>, Vec<Vec<u8>>);

/// One stream of a run, resolved.
#[derive(Clone, Debug)]
pub struct StreamPlan {
    /// What it is.
    pub id: StreamId,
    /// What its frames are called in reports (`records`, `frames`, `epochs`, `samples`, `rows`).
    pub what: &'static str,
    /// Frames per simulated second.
    pub rate_hz: f64,
    /// Frames over the run, when the run has an end.
    pub planned: Option<u64>,
    /// The wire format, when the stream is a protocol's frames (links are checked against it).
    pub plan: Option<Plan>,
    /// Where it goes, with where each sink was given.
    pub sinks: Vec<(SinkAddr, String)>,
    /// The unit (index) whose records these frames are: time marks and pulses follow them.
    pub unit: Option<usize>,
}

/// What the signal is, as routes see it.
pub enum Units<'a> {
    /// One IMU.
    Imu(&'a Simulation),
    /// A rig's units.
    Rig(&'a Rig),
}

/// How a run's streams lie over its sources, decided once the routes are resolved.
#[derive(Clone, Debug, Default)]
pub struct Layout {
    /// One IMU: the further protocols of its records, its side streams.
    pub protocols: Vec<String>,
    /// One IMU's truth and injected-error streams.
    pub sides: Sides,
    /// A rig: which units' truth is streamed.
    pub rig_truth: Vec<bool>,
    /// A rig: the further protocols of its units' records (unit index, protocol), in unit
    /// order.
    pub rig_protocols: Vec<(usize, String)>,
    /// A rig: which units' failure schedules are written.
    pub rig_failures: Vec<bool>,
    /// GNSS wire formats, in stream order.
    pub gnss: Vec<GnssFormat>,
    /// The GNSS truth rows.
    pub gnss_truth: bool,
    /// Aiding sensors, in stream order.
    pub sensors: Vec<SensorKind>,
    /// Every stream, in source order.
    pub streams: Vec<StreamPlan>,
}

impl Layout {
    /// The streams `routes` ask for on `units` (a unit's own stream always exists, routed or
    /// not), in source order: the units' (and their side streams), then GNSS, then sensors.
    pub fn resolve(routes: &[Route], units: &Units<'_>) -> Result<Layout, RunError> {
        let mut l = Layout::default();
        let names: Vec<String> = match units {
            Units::Imu(_) => Vec::new(),
            Units::Rig(r) => r.units().iter().map(|u| u.name().to_string()).collect(),
        };
        let unit_index = |name: &str, route: &Route| {
            (names.iter().position(|n| n == name)).ok_or_else(|| {
                RunError::spec(
                    &route.origin,
                    format!("no unit `{name}` (the rig has {})", names.join(", ")),
                )
            })
        };
        for r in routes {
            let rig_only = |what: &str| {
                RunError::spec(
                    &r.origin,
                    format!(
                        "{what} belong to a rig's units, and the scene file lists no `[[imu]]` units"
                    ),
                )
            };
            match (&r.stream, units) {
                (
                    StreamId::Unit {
                        unit: None,
                        protocol,
                    },
                    Units::Imu(sim),
                ) => {
                    if let Some(p) = protocol
                        && !l.protocols.contains(p)
                    {
                        // Checked here, where the route's origin names the sink that asked.
                        extra_plan(p, sim.grid().rate_hz)
                            .map_err(|e| RunError::spec(&r.origin, e.to_string()))?;
                        l.protocols.push(p.clone());
                    }
                }
                (StreamId::Unit { unit: Some(_), .. }, Units::Imu(_)) => {
                    return Err(rig_only("named units"));
                }
                (StreamId::Unit { unit: None, .. }, Units::Rig(_)) => {
                    return Err(RunError::spec(
                        &r.origin,
                        format!(
                            "a rig's streams name their unit ({}): give the unit's `sink` in the scene file, or `--unit-sink NAME=SINK`",
                            names.join(", ")
                        ),
                    ));
                }
                (
                    StreamId::Unit {
                        unit: Some(u),
                        protocol,
                    },
                    Units::Rig(rig),
                ) => {
                    let i = unit_index(u, r)?;
                    if let Some(p) = protocol
                        && !l.rig_protocols.contains(&(i, p.clone()))
                    {
                        let unit = &rig.units()[i];
                        if unit.is_skew() {
                            return Err(RunError::spec(
                                &r.origin,
                                format!(
                                    "unit `{u}` is skew-redundant: its frames carry its own channels (its `format`); a further protocol per unit is built for three-axis units"
                                ),
                            ));
                        }
                        extra_plan(p, unit.grid().rate_hz)
                            .map_err(|e| RunError::spec(&r.origin, e.to_string()))?;
                        l.rig_protocols.push((i, p.clone()));
                    }
                }
                (StreamId::Truth { unit: None }, Units::Imu(_)) => l.sides.truth = true,
                (StreamId::Truth { unit: Some(u) }, Units::Rig(_)) => {
                    let i = unit_index(u, r)?;
                    l.rig_truth.resize(names.len(), false);
                    l.rig_truth[i] = true;
                }
                (StreamId::Failures { unit }, Units::Rig(_)) => {
                    let i = unit_index(unit, r)?;
                    l.rig_failures.resize(names.len(), false);
                    l.rig_failures[i] = true;
                }
                (StreamId::Truth { unit: Some(_) } | StreamId::Failures { .. }, Units::Imu(_)) => {
                    return Err(rig_only("failure schedules and per-unit truth"));
                }
                (StreamId::Truth { unit: None }, Units::Rig(_)) => {
                    return Err(RunError::spec(
                        &r.origin,
                        "a rig's truth is per unit: name the unit".into(),
                    ));
                }
                (StreamId::Errors, Units::Imu(_)) => l.sides.errors = true,
                (StreamId::Errors, Units::Rig(_)) => {
                    return Err(RunError::spec(
                        &r.origin,
                        "the injected errors are written for one IMU; a rig's units write their truth and failure schedules".into(),
                    ));
                }
                (StreamId::Gnss(f), _) => {
                    if !l.gnss.contains(f) {
                        l.gnss.push(*f);
                    }
                }
                (StreamId::GnssTruth, _) => l.gnss_truth = true,
                (StreamId::Sensor(k), _) => {
                    if !l.sensors.contains(k) {
                        l.sensors.push(*k);
                    }
                }
            }
        }
        // The rig's streams list each unit's further protocols in unit order.
        l.rig_protocols.sort_by_key(|x| x.0);
        l.streams = l.stream_plans(units)?;
        for r in routes {
            let i = (l.streams.iter().position(|s| s.id == r.stream))
                .or_else(|| {
                    // A rig unit's own stream, named with or without its protocol.
                    l.streams.iter().position(|s| match (&s.id, &r.stream) {
                        (
                            StreamId::Unit { unit: a, .. },
                            StreamId::Unit {
                                unit: b,
                                protocol: None,
                            },
                        ) => a == b,
                        _ => false,
                    })
                })
                .expect("every route's stream was laid out");
            l.streams[i].sinks.push((r.sink.clone(), r.origin.clone()));
        }
        Ok(l)
    }

    /// The streams, in source order, without sinks yet.
    fn stream_plans(&self, units: &Units<'_>) -> Result<Vec<StreamPlan>, RunError> {
        let mut out = Vec::new();
        let plan = |id: StreamId, what, rate_hz, planned, plan, unit| StreamPlan {
            id,
            what,
            rate_hz,
            planned: Some(planned),
            plan,
            sinks: Vec::new(),
            unit,
        };
        let aid = match units {
            Units::Imu(sim) => {
                let g = sim.grid();
                // A unit's stream counts its records, whatever their wire format.
                let what = "records";
                out.push(plan(
                    StreamId::imu(),
                    what,
                    g.rate_hz,
                    g.count,
                    sim.plan().cloned(),
                    Some(0),
                ));
                for p in &self.protocols {
                    let id = StreamId::Unit {
                        unit: None,
                        protocol: Some(p.clone()),
                    };
                    let frames = extra_plan(p, g.rate_hz)?;
                    out.push(plan(id, "frames", g.rate_hz, g.count, Some(frames), None));
                }
                if self.sides.truth {
                    out.push(plan(
                        StreamId::Truth { unit: None },
                        "records",
                        g.rate_hz,
                        g.count,
                        None,
                        None,
                    ));
                }
                if self.sides.errors {
                    out.push(plan(
                        StreamId::Errors,
                        "records",
                        g.rate_hz,
                        g.count,
                        None,
                        None,
                    ));
                }
                sim.aiding()
            }
            Units::Rig(rig) => {
                for (i, u) in rig.units().iter().enumerate() {
                    let g = u.grid();
                    // A unit's stream counts its records, whatever their wire format.
                    let what = "records";
                    out.push(plan(
                        StreamId::unit(u.name()),
                        what,
                        g.rate_hz,
                        g.count,
                        u.plan().cloned(),
                        Some(i),
                    ));
                }
                for (u, _) in rig.units().iter().zip(&self.rig_truth).filter(|x| *x.1) {
                    let g = u.grid();
                    let id = StreamId::Truth {
                        unit: Some(u.name().to_string()),
                    };
                    out.push(plan(id, "records", g.rate_hz, g.count, None, None));
                }
                for (i, p) in &self.rig_protocols {
                    let u = &rig.units()[*i];
                    let g = u.grid();
                    let id = StreamId::Unit {
                        unit: Some(u.name().to_string()),
                        protocol: Some(p.clone()),
                    };
                    let frames = extra_plan(p, g.rate_hz)?;
                    out.push(plan(id, "frames", g.rate_hz, g.count, Some(frames), None));
                }
                for (u, _) in rig.units().iter().zip(&self.rig_failures).filter(|x| *x.1) {
                    let id = StreamId::Failures {
                        unit: u.name().to_string(),
                    };
                    out.push(plan(
                        id,
                        "failures",
                        0.0,
                        u.failures().len() as u64,
                        None,
                        None,
                    ));
                }
                rig.aiding()
            }
        };
        let gnss_rate = aid
            .gnss
            .map_or(crate::aiding::GnssConfig::default().rate_hz, |g| g.rate_hz);
        let epochs = aid.gnss_epochs();
        for f in &self.gnss {
            out.push(plan(
                StreamId::Gnss(*f),
                "epochs",
                gnss_rate,
                epochs,
                None,
                None,
            ));
        }
        if self.gnss_truth {
            out.push(plan(
                StreamId::GnssTruth,
                "epochs",
                gnss_rate,
                epochs,
                None,
                None,
            ));
        }
        for k in &self.sensors {
            let rows = aid.sensor_rows(*k);
            out.push(plan(
                StreamId::Sensor(*k),
                "samples",
                rows.rate_hz(),
                rows.count(),
                None,
                None,
            ));
        }
        Ok(out)
    }

    /// The sources of one IMU's run (`sim`), emission times counted from its t₀; a triggered
    /// IMU samples at the edges it is handed.
    pub fn imu_sources(
        &self,
        sim: Simulation,
        triggered: bool,
    ) -> Result<SourcesWithPreambles, RunError> {
        let origin = sim.grid().t0;
        let mut aiding = self.aiding_sources(&sim.aiding(), origin)?;
        let extra = (self.protocols.iter())
            .map(|p| Ok(sim.frames_encoding(extra_plan(p, sim.grid().rate_hz)?)))
            .collect::<Result<Vec<_>, RunError>>()?;
        let n = 1 + extra.len();
        let producer = sim.producer()?.with_extra_encodings(extra);
        let imu = ImuFrames::new(producer, n, self.sides, origin, triggered);
        let mut preambles = imu.preambles();
        preambles.append(&mut aiding.1);
        let mut sources: Vec<Box<dyn WindowSource>> = vec![Box::new(imu)];
        sources.append(&mut aiding.0);
        Ok((sources, preambles))
    }

    /// The sources of a rig's run, emission times counted from its earliest unit's t₀; a
    /// triggered rig's units sample at the edges they are handed (every unit at every edge).
    pub fn rig_sources(
        &self,
        mut rig: Rig,
        triggered: bool,
    ) -> Result<SourcesWithPreambles, RunError> {
        let origin = rig.span().0;
        for (i, p) in &self.rig_protocols {
            let plan = extra_plan(p, rig.units()[*i].grid().rate_hz)?;
            (rig.add_protocol(*i, plan))
                .map_err(|e| RunError::spec(&format!("protocol `{p}`"), e))?;
        }
        let mut aiding = self.aiding_sources(&rig.aiding(), origin)?;
        let failures: Vec<Vec<u8>> = (rig.units().iter())
            .zip(&self.rig_failures)
            .filter(|x| *x.1)
            .map(|(u, _)| u.failure_csv().into_bytes())
            .collect();
        let mut truth = self.rig_truth.clone();
        truth.resize(rig.units().len(), false);
        let mut stream = rig.stream().with_truth(&truth);
        if triggered {
            stream = stream.triggered();
        }
        let mut preambles = stream.preambles();
        let mut sources: Vec<Box<dyn WindowSource>> = vec![Box::new(stream)];
        for f in failures {
            preambles.push(f);
            sources.push(Box::new(Empty));
        }
        preambles.append(&mut aiding.1);
        sources.append(&mut aiding.0);
        Ok((sources, preambles))
    }

    /// The GNSS and sensor sources of `aid`, and their streams' preambles.
    fn aiding_sources(
        &self,
        aid: &AidingStreams<'_>,
        origin: f64,
    ) -> Result<SourcesWithPreambles, RunError> {
        let (mut sources, mut preambles): (Vec<Box<dyn WindowSource>>, Vec<Vec<u8>>) =
            (Vec::new(), Vec::new());
        if !self.gnss.is_empty() || self.gnss_truth {
            let encoders = self.gnss.iter().map(|f| aid.gnss_encoder(*f)).collect();
            let src = GnssSource::new(
                aid.gnss_receiver(),
                aid.motion.clone(),
                encoders,
                self.gnss_truth,
                aid.span,
                origin,
            );
            preambles.extend(self.gnss.iter().map(|_| Vec::new()));
            if self.gnss_truth {
                preambles.push(crate::aiding::stream::TRUTH_HEADER.as_bytes().to_vec());
            }
            sources.push(Box::new(src));
        }
        for k in &self.sensors {
            preambles.push(k.header().as_bytes().to_vec());
            sources.push(Box::new(sensor_source(aid.sensor_rows(*k), origin)));
        }
        Ok((sources, preambles))
    }
}

/// The aiding sensors `aid` has settings for (a scene file's `[gnss]`, `[odometer]`, `[baro]`,
/// `[magnetometer]` tables, or the builder's) whose streams `layout` does not route: one
/// warning each, naming the table and how to route it. A magnetometer that a unit's frames
/// carry is used by them.
pub(super) fn unrouted_aiding(
    aid: &AidingStreams<'_>,
    layout: &Layout,
    file: Option<&str>,
) -> Vec<String> {
    use crate::aiding::sensors::SensorKind;
    use crate::protocol::spec::Source;
    let place = |table: &str| match file {
        Some(f) => format!("{f}: [{table}]"),
        None => format!("the {table} settings"),
    };
    let mut out = Vec::new();
    if aid.gnss.is_some() && layout.gnss.is_empty() && !layout.gnss_truth {
        out.push(format!(
            "{} configures a GNSS receiver, but no GNSS stream is routed, so none is made: give --gnss FORMAT:SINK (`generate`: FORMAT:FILE), or for `run` the `gnss` key in the scene file's [run] table (`gnss = [\"nmea:udp:127.0.0.1:9010\"]`)",
            place("gnss")
        ));
    }
    let in_frames = (layout.streams.iter())
        .filter_map(|s| s.plan.as_ref())
        .any(|p| (p.value_sources().iter().flatten()).any(|s| matches!(s, Source::Mag(_))));
    let s = &aid.sensors;
    for (kind, set) in [
        (SensorKind::Odometer, s.odometer.is_some()),
        (SensorKind::Baro, s.baro.is_some()),
        (
            SensorKind::Magnetometer,
            s.magnetometer.is_some() && !in_frames,
        ),
    ] {
        if set && !layout.sensors.contains(&kind) {
            let n = kind.name();
            out.push(format!(
                "{} configures the {n}, but its stream is not routed, so it is not made: give --{n} SINK (`generate`: FILE), or for `run` the `{n}` key in the scene file's [run] table (`{n} = [\"udp:127.0.0.1:9011\"]`)",
                place(n)
            ));
        }
    }
    out
}

/// The compiled frame of a further protocol of a three-axis unit's records, at its rate.
fn extra_plan(name: &str, rate_hz: f64) -> Result<Plan, RunError> {
    let e = |m: String| RunError::Sim(SimError::Invalid(format!("sink protocol `{name}`: {m}")));
    let (_, mut plan) = crate::protocol::load(name).map_err(|x| e(x.to_string()))?;
    if plan.channels().is_some() {
        return Err(e(
            "is a skew-redundant unit's frame; the unit's records are three-axis".into(),
        ));
    }
    plan.set_rate(rate_hz).map_err(e)?;
    Ok(plan)
}

/// A stream with no frames: only its preamble (a rig unit's failure schedule).
struct Empty;

impl WindowSource for Empty {
    fn streams(&self) -> usize {
        1
    }
    fn fill(
        &mut self,
        _: crate::engine::frames::Until,
        _: &mut [crate::engine::frames::Part],
    ) -> Result<(), crate::engine::EngineError> {
        Ok(())
    }
    fn done(&self) -> bool {
        true
    }
}

/// Whether `output` is a protocol's frames.
pub fn is_frames(output: &Output) -> bool {
    matches!(output, Output::Frames(_))
}
