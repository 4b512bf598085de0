//! A scene file's `[run]` table and `[imu] sink` turned into a [`RunSpec`]'s parts; every
//! value that cannot be read is refused naming the file and the key.

use crate::aiding::sensors::SensorKind;
use crate::config::run::{RunSection, SpeedValue};
use crate::output::SinkAddr;
use crate::sim::SimError;

use super::spec::{FileKey, LiveSpec, RunSpec, Speed, StreamId, TimeBase, read_gnss};
use crate::sim::SimulationBuilder;

impl RunSpec {
    /// A run of the signal a scene file (or code) describes, with what the scene file says of
    /// the run: its `[run]` table (clock, time base, streams, sync lines, live input), the
    /// single IMU's `[imu] sink` and each rig unit's `[[imu]] sink`.
    pub fn from_signal(signal: SimulationBuilder) -> Result<RunSpec, crate::sim::SimError> {
        let mut spec = RunSpec::new(signal);
        let file = spec
            .signal
            .scene_file_path()
            .map(|p| p.display().to_string());
        for (i, u) in spec.signal.unit_specs()? {
            for (j, (sink, protocol)) in u.sinks.iter().enumerate() {
                let origin = match (&file, i) {
                    (Some(f), Some(i)) => format!("{f}: `imu[{i}].sink[{j}]`"),
                    _ => format!("unit `{}`: sink {j}", u.name),
                };
                let stream = StreamId::Unit {
                    unit: Some(u.name.clone()),
                    protocol: protocol.clone(),
                };
                spec.add_route(stream, sink.clone(), origin);
            }
        }
        apply(&mut spec, file.as_deref().unwrap_or("<scene>"))?;
        Ok(spec)
    }
}

/// Applies the scene file `file`'s `[run]` table and `[imu] sink` to `spec`.
pub fn apply(spec: &mut RunSpec, file: &str) -> Result<(), SimError> {
    let bad = |key: &str, m: String| SimError::Invalid(m).at(Some(format!("{file}: `{key}`")));
    if let Some(sinks) = spec.signal.scene_contents().imu.sink.clone() {
        for (key, v) in sinks.keyed("imu.sink") {
            let (addr, protocol) = SinkAddr::parse_with_protocol(&v).map_err(|m| bad(&key, m))?;
            let stream = StreamId::Unit {
                unit: None,
                protocol,
            };
            spec.add_route(stream, addr, format!("{file}: `{key}`"));
        }
    }
    let Some(r) = spec.signal.scene_contents().run.clone() else {
        return Ok(());
    };
    // The keys given, with the flags that give the same settings.
    let given: Vec<(&str, &'static str)> = [
        ("speed", "--speed", r.speed.is_some()),
        ("start_at", "--start-at", r.start_at.is_some()),
        ("time_base", "--time-base", r.time_base.is_some()),
        (
            "max_behind_ms",
            "--max-behind-ms",
            r.max_behind_ms.is_some(),
        ),
        (
            "realtime_priority",
            "--realtime",
            r.realtime_priority.is_some(),
        ),
        ("time_marks", "--time-marks", r.time_marks.is_some()),
        ("pulse", "--pulse", r.pulse.is_some()),
        ("pulse_port", "--pulse-port", r.pulse_port.is_some()),
        ("pulse_unit", "--pulse-unit", r.pulse_unit.is_some()),
        ("pps_in", "--pps-in", r.pps_in.is_some()),
        ("trigger", "--trigger", r.trigger.is_some()),
        ("baud", "--baud", r.baud.is_some()),
        ("framing", "--framing", r.framing.is_some()),
        ("udp_batch", "--udp-batch", r.udp_batch.is_some()),
        ("take_over", "--take-over", r.take_over.is_some()),
    ]
    .into_iter()
    .filter(|g| g.2)
    .map(|g| (g.0, g.1))
    .collect();
    let RunSection {
        speed,
        start_at,
        time_base,
        max_behind_ms,
        realtime_priority,
        truth,
        truth_errors,
        gnss,
        gnss_truth,
        odometer,
        baro,
        magnetometer,
        time_marks,
        pulse,
        pulse_port,
        pulse_unit,
        pps_in,
        trigger,
        baud,
        framing,
        udp_batch,
        take_over,
        input,
    } = r;
    let c = &mut spec.clock;
    c.speed = match speed {
        None => None,
        Some(SpeedValue::Factor(x)) => Some(Speed::Factor(x)),
        Some(SpeedValue::Word(w)) => {
            Some(Speed::read(&w).map_err(|e| bad("run.speed", format!("`{w}`: {e}")))?)
        }
    };
    c.start_at = start_at;
    c.time_base = match time_base {
        None => None,
        Some(t) => {
            Some(TimeBase::read(&t).map_err(|e| bad("run.time_base", format!("`{t}`: {e}")))?)
        }
    };
    c.max_behind_ms = max_behind_ms;
    c.realtime_priority = realtime_priority.unwrap_or(false);
    let mut route = |key: &str, v: &str, stream: StreamId| -> Result<(), SimError> {
        let addr = SinkAddr::parse(v).map_err(|m| bad(key, m))?;
        spec.add_route(stream, addr, format!("{file}: `{key}`"));
        Ok(())
    };
    if let Some(t) = truth {
        route("run.truth", &t, StreamId::Truth { unit: None })?;
    }
    if let Some(t) = truth_errors {
        route("run.truth_errors", &t, StreamId::Errors)?;
    }
    for (key, v) in gnss.map(|g| g.keyed("run.gnss")).unwrap_or_default() {
        let (f, target) = read_gnss(&v).map_err(|e| bad(&key, format!("`{v}`: {e}")))?;
        route(&key, target, StreamId::Gnss(f))?;
    }
    if let Some(t) = gnss_truth {
        route("run.gnss_truth", &t, StreamId::GnssTruth)?;
    }
    for (kind, values) in SensorKind::ALL
        .into_iter()
        .zip([odometer, baro, magnetometer])
    {
        let key = format!("run.{}", kind.name());
        for (key, v) in values.map(|x| x.keyed(&key)).unwrap_or_default() {
            route(&key, &v, StreamId::Sensor(kind))?;
        }
    }
    let s = &mut spec.sync;
    for (_, v) in time_marks
        .map(|t| t.keyed("run.time_marks"))
        .unwrap_or_default()
    {
        let (unit, target) = split_unit(&v);
        s.time_marks.push((unit, target));
    }
    s.pulse = pulse;
    s.pulse_port = pulse_port;
    s.pulse_unit = pulse_unit;
    s.pps_in = pps_in;
    s.trigger = trigger;
    let l = &mut spec.link;
    l.baud = baud;
    l.framing = framing;
    l.udp_batch = udp_batch;
    l.take_over = take_over.unwrap_or(false);
    if let Some(i) = &input {
        let lockstep = (i.mode.as_deref())
            .map(|m| {
                LiveSpec::read_mode(m).map_err(|e| bad("run.input.mode", format!("`{m}`: {e}")))
            })
            .transpose()?
            .unwrap_or(false);
        let format = (i.format.as_deref())
            .map(|f| {
                LiveSpec::read_format(f).map_err(|e| bad("run.input.format", format!("`{f}`: {e}")))
            })
            .transpose()?;
        spec.input = Some(LiveSpec {
            format,
            lockstep,
            output_delay_s: i.output_delay_s,
            max_extrapolation_s: i.max_extrapolation_s,
            correction_horizon_s: i.correction_horizon_s,
            on_timeout: i.on_timeout.clone(),
            input_timeout_s: i.timeout_s,
            record: i.record.clone(),
            ..LiveSpec::new(i.source.clone())
        });
    }
    // What the file gave, for refusals to name its keys.
    for (key, flag) in given {
        let value = spec.setting(flag);
        (spec.file_keys).push(FileKey {
            flag,
            origin: format!("{file}: `run.{key}`"),
            value,
        });
    }
    if let Some(i) = &input {
        let keys = [
            ("source", "--motion", true),
            ("format", "--input-format", i.format.is_some()),
            ("mode", "--time-mode", i.mode.is_some()),
            (
                "output_delay_s",
                "--output-delay",
                i.output_delay_s.is_some(),
            ),
            (
                "max_extrapolation_s",
                "--max-extrapolation",
                i.max_extrapolation_s.is_some(),
            ),
            (
                "correction_horizon_s",
                "--correction-horizon",
                i.correction_horizon_s.is_some(),
            ),
            ("on_timeout", "--on-timeout", i.on_timeout.is_some()),
            ("timeout_s", "--input-timeout", i.timeout_s.is_some()),
            ("record", "--record-input", i.record.is_some()),
        ];
        for (key, flag, _) in keys.into_iter().filter(|k| k.2) {
            let value = spec.setting(flag);
            (spec.file_keys).push(FileKey {
                flag,
                origin: format!("{file}: `run.input.{key}`"),
                value,
            });
        }
    }
    Ok(())
}

impl RunSpec {
    /// The value of the setting `flag` gives, in words: whether a scene file's value is still
    /// in place when the run is built.
    pub fn setting(&self, flag: &str) -> String {
        let (c, s, l) = (&self.clock, &self.sync, &self.link);
        let i = self.input.as_ref();
        match flag {
            "--speed" => format!("{:?}", c.speed),
            "--start-at" => format!("{:?}", c.start_at),
            "--time-base" => format!("{:?}", c.time_base),
            "--max-behind-ms" => format!("{:?}", c.max_behind_ms),
            "--realtime" => format!("{:?}", c.realtime_priority),
            "--time-marks" => format!("{:?}", s.time_marks),
            "--pulse" => format!("{:?}", s.pulse),
            "--pulse-port" => format!("{:?}", s.pulse_port),
            "--pulse-unit" => format!("{:?}", s.pulse_unit),
            "--pps-in" => format!("{:?}", s.pps_in),
            "--trigger" => format!("{:?}", s.trigger),
            "--baud" => format!("{:?}", l.baud),
            "--framing" => format!("{:?}", l.framing),
            "--udp-batch" => format!("{:?}", l.udp_batch),
            "--take-over" => format!("{:?}", l.take_over),
            "--motion" => format!("{:?}", i.map(|i| &i.source)),
            "--input-format" => format!("{:?}", i.map(|i| i.format)),
            "--time-mode" => format!("{:?}", i.map(|i| i.lockstep)),
            "--output-delay" => format!("{:?}", i.map(|i| i.output_delay_s)),
            "--max-extrapolation" => format!("{:?}", i.map(|i| i.max_extrapolation_s)),
            "--correction-horizon" => format!("{:?}", i.map(|i| i.correction_horizon_s)),
            "--on-timeout" => format!("{:?}", i.map(|i| &i.on_timeout)),
            "--input-timeout" => format!("{:?}", i.map(|i| i.input_timeout_s)),
            "--record-input" => format!("{:?}", i.map(|i| &i.record)),
            _ => String::new(),
        }
    }

    /// The reason of a refusal, with the scene file's key named after each flag it mentions
    /// whose value the file gave (a flag the user did not type: `--start-at` in "drop
    /// --start-at" when `run.start_at` set it).
    pub fn why_of(&self, why: &str) -> String {
        let mut out = why.to_string();
        for k in &self.file_keys {
            let whole = why.match_indices(k.flag).any(|(i, _)| {
                let next = why[i + k.flag.len()..].chars().next();
                !next.is_some_and(|c| c.is_ascii_alphanumeric() || c == '-')
            });
            if whole && k.value == self.setting(k.flag) && !out.contains(&k.origin) {
                out += &format!(" ({} gives {})", k.origin, k.flag);
            }
        }
        out
    }

    /// Where a refused setting came from: `FILE: `run.KEY` (FLAG …)` when the scene file's
    /// value of the flag that `what` starts with is still in place, else `what`.
    pub fn origin_of(&self, what: &str) -> String {
        let flag = what.split_whitespace().next().unwrap_or("");
        match (self.file_keys.iter()).find(|k| k.flag == flag && k.value == self.setting(flag)) {
            Some(k) => format!("{} ({what})", k.origin),
            None => what.to_string(),
        }
    }
}

/// `UNIT=TARGET` names a rig's unit; a target itself has no `=` before its scheme.
pub fn split_unit(v: &str) -> (Option<String>, String) {
    match v.split_once('=') {
        Some((u, rest)) if !u.contains(':') && !u.contains('/') => {
            (Some(u.to_string()), rest.to_string())
        }
        _ => (None, v.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scene file's `[run]` values that do not read are refused naming the file, the key
    /// and the value, with what was expected (the same readers as the flags').
    #[test]
    fn bad_run_values_name_the_file_key_and_value() {
        use std::error::Error;
        let dir = tempfile::tempdir().unwrap();
        for (table, key, want) in [
            (
                "speed = \"fast\"",
                "run.speed",
                "`fast`: expected a factor of real time",
            ),
            (
                "time_base = \"tai\"",
                "run.time_base",
                "`tai`: expected sim, gps or utc",
            ),
            (
                "gnss = \"sirf:udp:127.0.0.1:9\"",
                "run.gnss",
                "unknown format `sirf`",
            ),
            (
                "[run.input]\nsource = \"-\"\nmode = \"fast\"",
                "run.input.mode",
                "`fast`: expected realtime or lockstep",
            ),
            (
                "[run.input]\nsource = \"-\"\nformat = \"xml\"",
                "run.input.format",
                "`xml`: expected csv, bin or mavlink",
            ),
        ] {
            let p = dir.path().join("s.toml");
            std::fs::write(&p, format!("[run]\n{table}\n")).unwrap();
            let signal = crate::sim::Simulation::from_scene_file(&p).unwrap();
            let e = RunSpec::from_signal(signal).unwrap_err();
            // The place, then its cause, as the command line prints the chain.
            let mut e: (String, Option<&dyn std::error::Error>) = (e.to_string(), e.source());
            while let Some(c) = e.1 {
                e = (format!("{}: {c}", e.0), c.source());
            }
            let e = e.0;
            let at = format!("{}: `{key}`: ", p.display());
            assert!(e.contains(&at) && e.contains(want), "{e}");
        }
    }
}
