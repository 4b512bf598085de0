//! What a front end says over a scene file's run, in the command line's words: each setting
//! given replaces the file's, each sink given replaces the file's routes of its streams, a
//! unit without a sink gets a pty. The text is read and refused here, naming the flag, so that
//! any front end (the `imu-emu` command line, a HIL program's own, a test) reads a setting
//! exactly as `imu-emu run` does.

use std::path::PathBuf;

use crate::aiding::sensors::SensorKind;
use crate::output::SinkAddr;

use super::RunError;
use super::error::refuse;
use super::scene::split_unit;
use super::spec::{LiveSpec, RunSpec, Speed, StreamId, TimeBase, read_gnss};

/// A live input's settings over the scene file's `[run.input]` (`imu-emu run --help` says what
/// each does; the names are the flags').
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LiveOverrides {
    /// `--motion`: the source of live states (replaces the scene's trajectory).
    pub motion: Option<String>,
    /// `--input-format`: csv, bin or mavlink.
    pub input_format: Option<String>,
    /// `--time-mode`: realtime or lockstep.
    pub time_mode: Option<String>,
    /// `--output-delay` (s).
    pub output_delay: Option<f64>,
    /// `--max-extrapolation` (s).
    pub max_extrapolation: Option<f64>,
    /// `--correction-horizon` (s).
    pub correction_horizon: Option<f64>,
    /// `--on-timeout`: stop, hold or extrapolate.
    pub on_timeout: Option<String>,
    /// `--record-input`: every message received, to this file.
    pub record_input: Option<PathBuf>,
    /// `--input-timeout` (s).
    pub input_timeout: Option<f64>,
}

/// The settings of `imu-emu run` over a scene file's run, each `None` or empty where not given.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overrides {
    /// The live input.
    pub live: LiveOverrides,
    /// The single IMU's sinks as (kind, value): kind `pty`, `serial`, `udp`, `tcp`,
    /// `tcp-listen` or `file`, value its target with an optional `,protocol=NAME`.
    pub imu_sinks: Vec<(String, String)>,
    /// `--unit-sink NAME=SINK`: a rig unit's sinks.
    pub unit_sinks: Vec<String>,
    /// `--gnss FORMAT:SINK`.
    pub gnss: Vec<String>,
    /// The odometer's, barometer's and magnetometer's sinks, in [`SensorKind::ALL`]'s order.
    pub sensors: [Vec<String>; 3],
    /// `--speed`: a factor of real time or `max`.
    pub speed: Option<String>,
    /// `--start-at`.
    pub start_at: Option<String>,
    /// `--time-base`: gps, utc or sim.
    pub time_base: Option<String>,
    /// `--max-behind-ms`.
    pub max_behind_ms: Option<f64>,
    /// `--realtime`: the pacer `SCHED_FIFO`.
    pub realtime_priority: bool,
    /// `--time-marks [UNIT=]TARGET`.
    pub time_marks: Vec<String>,
    /// `--pulse`.
    pub pulse: Option<String>,
    /// `--pulse-port`.
    pub pulse_port: Option<String>,
    /// `--pulse-unit`.
    pub pulse_unit: Option<String>,
    /// `--pps-in`.
    pub pps_in: Option<String>,
    /// `--trigger`.
    pub trigger: Option<String>,
    /// `--baud`.
    pub baud: Option<u32>,
    /// `--framing`.
    pub framing: Option<String>,
    /// `--udp-batch`.
    pub udp_batch: Option<usize>,
    /// `--take-over`.
    pub take_over: bool,
}

impl RunSpec {
    /// `o` over this run (the scene file's): the live input amended, the sinks given replacing
    /// the file's routes of their streams, the clock, sync lines and links set; then every unit
    /// still without a sink gets a pty of its own.
    pub fn apply_overrides(&mut self, o: &Overrides) -> Result<(), RunError> {
        self.apply_live(&o.live)?;
        self.imu_sinks(&o.imu_sinks)?;
        self.unit_sinks(&o.unit_sinks)?;
        let sensors = [&o.sensors[0][..], &o.sensors[1], &o.sensors[2]];
        self.aiding_sinks(&o.gnss, sensors, SinkAddr::parse)?;
        self.default_ptys()?;
        let c = &mut self.clock;
        if let Some(s) = &o.speed {
            c.speed = Some(Speed::read(s).map_err(|e| refuse(&format!("--speed {s}"), e))?);
        }
        if o.start_at.is_some() {
            c.start_at.clone_from(&o.start_at);
        }
        if let Some(t) = &o.time_base {
            let base = TimeBase::read(t).map_err(|e| refuse(&format!("--time-base {t}"), e))?;
            c.time_base = Some(base);
        }
        if o.max_behind_ms.is_some() {
            c.max_behind_ms = o.max_behind_ms;
        }
        c.realtime_priority |= o.realtime_priority;
        let s = &mut self.sync;
        if !o.time_marks.is_empty() {
            s.time_marks = o.time_marks.iter().map(|t| split_unit(t)).collect();
        }
        for (dst, src) in [
            (&mut s.pulse, &o.pulse),
            (&mut s.pulse_port, &o.pulse_port),
            (&mut s.pulse_unit, &o.pulse_unit),
            (&mut s.pps_in, &o.pps_in),
            (&mut s.trigger, &o.trigger),
        ] {
            if src.is_some() {
                dst.clone_from(src);
            }
        }
        let k = &mut self.link;
        k.baud = o.baud.or(k.baud);
        k.framing = o.framing.clone().or(k.framing.take());
        k.udp_batch = o.udp_batch.or(k.udp_batch);
        k.take_over |= o.take_over;
        Ok(())
    }

    /// The live input of `l` (or of the scene file's `[run.input]`, which `l` amends); a live
    /// setting without a live input is refused.
    fn apply_live(&mut self, l: &LiveOverrides) -> Result<(), RunError> {
        let source = (l.motion.clone()).or(self.input.as_ref().map(|i| i.source.clone()));
        let Some(source) = source else {
            let given = [
                ("--input-format", l.input_format.is_some()),
                ("--time-mode", l.time_mode.is_some()),
                ("--output-delay", l.output_delay.is_some()),
                ("--max-extrapolation", l.max_extrapolation.is_some()),
                ("--correction-horizon", l.correction_horizon.is_some()),
                ("--on-timeout", l.on_timeout.is_some()),
                ("--record-input", l.record_input.is_some()),
                ("--input-timeout", l.input_timeout.is_some()),
            ];
            return match given.iter().find(|g| g.1) {
                Some((flag, _)) => Err(refuse(
                    flag,
                    "applies to a live input: give --motion SOURCE",
                )),
                None => Ok(()),
            };
        };
        let lockstep = (l.time_mode.as_deref())
            .map(|m| LiveSpec::read_mode(m).map_err(|e| refuse(&format!("--time-mode {m}"), e)))
            .transpose()?;
        let format = (l.input_format.as_deref())
            .map(|f| {
                LiveSpec::read_format(f).map_err(|e| refuse(&format!("--input-format {f}"), e))
            })
            .transpose()?;
        // The flags replace the scene file's `[run.input]` keys they give, not the others.
        let file = (self.input.take()).unwrap_or_else(|| LiveSpec::new(source.clone()));
        self.input = Some(LiveSpec {
            source,
            format: format.or(file.format),
            lockstep: lockstep.unwrap_or(file.lockstep),
            output_delay_s: l.output_delay.or(file.output_delay_s),
            max_extrapolation_s: l.max_extrapolation.or(file.max_extrapolation_s),
            correction_horizon_s: l.correction_horizon.or(file.correction_horizon_s),
            on_timeout: l.on_timeout.clone().or(file.on_timeout),
            input_timeout_s: l.input_timeout.or(file.input_timeout_s),
            record: l.record_input.clone().or(file.record),
        });
        Ok(())
    }

    /// The single IMU's sinks (kind, value); any replaces the scene file's.
    fn imu_sinks(&mut self, sinks: &[(String, String)]) -> Result<(), RunError> {
        let mut routes = Vec::new();
        for (kind, v) in sinks {
            let flag = format!("--{kind} {v}");
            let (addr, protocol) = SinkAddr::parse_with_protocol(&format!("{kind}:{v}"))
                .map_err(|e| refuse(&flag, e))?;
            routes.push((
                StreamId::Unit {
                    unit: None,
                    protocol,
                },
                addr,
                flag,
            ));
        }
        if !routes.is_empty() {
            self.replace_routes(|s| matches!(s, StreamId::Unit { unit: None, .. }));
        }
        for (s, addr, origin) in routes {
            self.add_route(s, addr, origin);
        }
        Ok(())
    }

    /// `--unit-sink NAME=SINK`: replaces the scene file's sinks of each unit it names.
    fn unit_sinks(&mut self, values: &[String]) -> Result<(), RunError> {
        let mut replaced: Vec<&str> = Vec::new();
        for v in values {
            let flag = format!("--unit-sink {v}");
            let Some((name, sink)) = v.split_once('=') else {
                return Err(refuse(
                    &flag,
                    "expected NAME=SINK (e.g. nav=udp:127.0.0.1:9001)",
                ));
            };
            let (addr, protocol) =
                SinkAddr::parse_with_protocol(sink).map_err(|e| refuse(&flag, e))?;
            if !replaced.contains(&name) {
                self.replace_routes(
                    |s| matches!(s, StreamId::Unit { unit: Some(u), .. } if u == name),
                );
                replaced.push(name);
            }
            let unit = Some(name.to_string());
            self.add_route(StreamId::Unit { unit, protocol }, addr, flag);
        }
        Ok(())
    }

    /// `--gnss FORMAT:SINK` and the sensors' sinks (odometer, baro, magnetometer, in
    /// [`SensorKind::ALL`]'s order); `sink` reads a sink's text. Each replaces the scene file's
    /// routes of its streams (`[run] gnss`, `odometer`, …).
    pub(super) fn aiding_sinks(
        &mut self,
        gnss: &[String],
        sensors: [&[String]; 3],
        sink: impl Fn(&str) -> Result<SinkAddr, String>,
    ) -> Result<(), RunError> {
        if !gnss.is_empty() {
            self.replace_routes(|s| matches!(s, StreamId::Gnss(_)));
        }
        for (kind, values) in SensorKind::ALL.into_iter().zip(sensors) {
            if !values.is_empty() {
                self.replace_routes(|s| *s == StreamId::Sensor(kind));
            }
        }
        for v in gnss {
            let flag = format!("--gnss {v}");
            let (f, target) = read_gnss(v).map_err(|e| refuse(&flag, e))?;
            let addr = sink(target).map_err(|e| refuse(&flag, e))?;
            self.add_route(StreamId::Gnss(f), addr, flag);
        }
        for (kind, values) in SensorKind::ALL.into_iter().zip(sensors) {
            for v in values {
                let flag = format!("--{} {v}", kind.name());
                let addr = sink(v).map_err(|e| refuse(&flag, e))?;
                self.add_route(StreamId::Sensor(kind), addr, flag);
            }
        }
        Ok(())
    }

    /// A unit with no sink gets a pty of its own (its /dev/pts path is printed when opened).
    pub fn default_ptys(&mut self) -> Result<(), RunError> {
        let units: Vec<Option<String>> = if self.signal.is_rig() {
            (self.signal.unit_specs()?.into_iter())
                .map(|(_, u)| Some(u.name))
                .collect()
        } else {
            vec![None]
        };
        for unit in units {
            let routed = (self.routes.iter())
                .any(|r| matches!(&r.stream, StreamId::Unit { unit: u, .. } if *u == unit));
            if !routed {
                let stream = StreamId::Unit {
                    unit,
                    protocol: None,
                };
                self.add_route(stream, SinkAddr::Pty(None), "the default pty".into());
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::SimulationBuilder;

    fn spec() -> RunSpec {
        RunSpec::new(SimulationBuilder::default())
    }

    #[test]
    fn a_live_setting_without_a_live_input_is_refused_by_its_flag() {
        let o = Overrides {
            live: LiveOverrides {
                on_timeout: Some("hold".into()),
                ..Default::default()
            },
            ..Default::default()
        };
        let e = spec().apply_overrides(&o).unwrap_err().to_string();
        assert_eq!(
            e,
            "--on-timeout: applies to a live input: give --motion SOURCE"
        );
    }

    #[test]
    fn the_flags_amend_the_scene_files_live_input_key_by_key() {
        let mut s = spec();
        let mut file = LiveSpec::new("udp://127.0.0.1:9000");
        file.output_delay_s = Some(0.02);
        file.lockstep = true;
        s.input = Some(file);
        let o = Overrides {
            live: LiveOverrides {
                max_extrapolation: Some(0.5),
                ..Default::default()
            },
            ..Default::default()
        };
        s.apply_overrides(&o).unwrap();
        let l = s.input.unwrap();
        assert_eq!(l.source, "udp://127.0.0.1:9000");
        assert_eq!(
            (l.output_delay_s, l.max_extrapolation_s),
            (Some(0.02), Some(0.5))
        );
        assert!(l.lockstep);
    }

    #[test]
    fn an_imu_sink_replaces_the_files_and_the_default_pty_fills_the_gap() {
        let mut s = spec();
        s.add_route(StreamId::imu(), SinkAddr::Pty(None), "file".into());
        s.apply_overrides(&Overrides::default()).unwrap();
        assert_eq!(s.routes.len(), 1, "a routed unit gets no default pty");
        let o = Overrides {
            imu_sinks: vec![("udp".into(), "127.0.0.1:9001,protocol=ln200".into())],
            ..Default::default()
        };
        s.apply_overrides(&o).unwrap();
        assert_eq!(s.routes.len(), 1);
        assert_eq!(s.routes[0].origin, "--udp 127.0.0.1:9001,protocol=ln200");
        let p = StreamId::Unit {
            unit: None,
            protocol: Some("ln200".into()),
        };
        assert_eq!(s.routes[0].stream, p);
        let mut bare = spec();
        bare.apply_overrides(&Overrides::default()).unwrap();
        assert_eq!(bare.routes[0].sink, SinkAddr::Pty(None));
    }

    #[test]
    fn bad_values_are_refused_naming_the_flag_and_value() {
        let cases: [(Overrides, &str); 4] = [
            (
                Overrides {
                    speed: Some("fast".into()),
                    ..Default::default()
                },
                "--speed fast: expected a factor of real time",
            ),
            (
                Overrides {
                    time_base: Some("tai".into()),
                    ..Default::default()
                },
                "--time-base tai: expected sim, gps or utc",
            ),
            (
                Overrides {
                    unit_sinks: vec!["nav".into()],
                    ..Default::default()
                },
                "--unit-sink nav: expected NAME=SINK",
            ),
            (
                Overrides {
                    gnss: vec!["gps:udp:127.0.0.1:9".into()],
                    ..Default::default()
                },
                "--gnss gps:udp:127.0.0.1:9: unknown format `gps`",
            ),
        ];
        for (o, want) in cases {
            let e = spec().apply_overrides(&o).unwrap_err().to_string();
            assert!(e.starts_with(want), "{e}");
        }
    }
}
