//! A run in words: one line per part, the text `imu-emu run --describe` prints and a test
//! compares flag by flag (every setting that changes the run changes this text).

use super::build::{OnTimeout, Run, Signal};
use super::clock::Clock;
use super::spec::TimeBase;
use super::sync::PulseOut;
use crate::output::SinkAddr;
use crate::rig::Rig;
use crate::sim::Simulation;

impl Run {
    /// The run in words, one line per part: what `imu-emu run --describe` prints. Every
    /// setting that changes the run changes this text.
    pub fn describe(&self) -> String {
        lines(self).join("\n")
    }
}

/// The description of `run`, line by line.
fn lines(run: &Run) -> Vec<String> {
    let mut out = vec![
        format!("motion: {}", run.motion_line),
        format!("engine: {}", run.engine_line),
    ];
    out.push(format!("clock: {}", clock(run)));
    out.push(format!("time base: {}", time_base(run)));
    match &run.signal {
        Signal::Imu(sim) => out.push(imu_line(sim)),
        Signal::Rig(r) => out.extend(rig_lines(r)),
        Signal::Live { builder, rig, .. } => {
            // The stand-in motion gives the units' settings; the span is the live input's.
            let stand_in = super::build::stand_in(builder);
            let span = live_span(builder.span_given());
            if *rig {
                if let Ok(r) = stand_in.build_rig() {
                    out.extend(rig_lines(&r).into_iter().map(|l| cut_span(l) + &span));
                }
            } else if let Ok(s) = stand_in.build() {
                out.push(cut_span(imu_line(&s)) + &span);
            }
        }
    }
    for s in &run.layout.streams {
        let sinks: Vec<String> = s.sinks.iter().map(|(a, _)| a.to_string()).collect();
        let planned = match (&run.signal, s.planned) {
            (Signal::Live { .. }, _) | (_, None) => String::new(),
            (_, Some(n)) => format!(", {n} planned"),
        };
        out.push(format!(
            "stream {} ({} at {} Hz{planned}): {}",
            s.id,
            s.what,
            s.rate_hz,
            if sinks.is_empty() {
                "not sent".to_string()
            } else {
                sinks.join(", ")
            }
        ));
    }
    let sync = &run.sync;
    for (u, target) in &sync.time_marks {
        out.push(format!("time marks of {}: {target}", run.units[*u]));
    }
    if let Some((spec, line, u)) = &sync.pulse {
        let on = match line {
            PulseOut::Port(port) => port.clone(),
            #[cfg(feature = "realtime")]
            PulseOut::Line(_) => "the line given in code".into(),
        };
        out.push(format!("pulse {spec} on {on}, marking {}", run.units[*u]));
    }
    if let Some(p) = &sync.pps_in {
        out.push(format!("phase-locked to the PPS of {p}"));
    }
    if let Some(t) = &sync.trigger {
        out.push(format!("every unit samples at the edges of {t}"));
    }
    let l = &run.links;
    let any = |f: fn(&SinkAddr) -> bool| {
        (run.layout.streams.iter()).any(|s| s.sinks.iter().any(|(a, _)| f(a)))
    };
    if any(|a| matches!(a, SinkAddr::Serial(_))) {
        let baud = l
            .baud
            .map_or("the protocol's nominal".to_string(), |b| b.to_string());
        out.push(format!("serial: {baud} baud, {}", l.framing));
    }
    if any(|a| matches!(a, SinkAddr::Udp(_))) {
        out.push(format!("udp: {} frames per datagram", l.udp_batch));
    }
    if l.take_over {
        out.push("pty: take over a link another emulator holds".into());
    }
    for w in &run.warnings {
        out.push(format!("warning: {w}"));
    }
    out
}

fn clock(run: &Run) -> String {
    let wall = |w: &super::clock::Wall| {
        let mut s = format!(
            "frames later than {} ms skipped",
            w.max_behind_ns as f64 / 1e6
        );
        if w.fifo {
            s += ", pacer SCHED_FIFO";
        }
        s
    };
    match (&run.clock, &run.signal) {
        (Clock::Free, _) => "unpaced, as fast as the machine allows".into(),
        (Clock::Lockstep, _) => "lockstep: each state releases the records it completes".into(),
        (Clock::Paced(w), _) => format!(
            "paced at {}× real time, t₀ {}; {}",
            w.speed,
            w.start_at
                .as_deref()
                .map_or("when the first frames are ready".into(), |s| format!(
                    "at {s}"
                )),
            wall(w)
        ),
        (Clock::Realtime(w), Signal::Live { input, .. }) => format!(
            "real time behind the input: output delay {}, extrapolation up to {} s, correction horizon {} s, on timeout {}; {}",
            input.delay.map_or("measured".into(), |d| format!("{d} s")),
            input.chain.max_extrapolation,
            input.chain.horizon,
            match input.on_timeout {
                OnTimeout::Stop => "stop",
                OnTimeout::Hold => "hold",
                OnTimeout::Extrapolate => "extrapolate",
            },
            wall(w)
        ),
        (Clock::Realtime(w), _) => wall(w),
    }
}

fn time_base(run: &Run) -> String {
    match run.time_base {
        TimeBase::Gps => "gps (the host clock's GPS time)".into(),
        TimeBase::Utc => "utc (the host clock's UTC, no leap seconds)".into(),
        TimeBase::Sim => {
            let gps = match &run.signal {
                Signal::Imu(s) => s.gps_time(),
                Signal::Rig(r) => r.gps_time(),
                Signal::Live { builder, rig, .. } => {
                    let stand_in = super::build::stand_in(builder);
                    if *rig {
                        stand_in.build_rig().ok().and_then(|r| r.gps_time())
                    } else {
                        stand_in.build().ok().and_then(|s| s.gps_time())
                    }
                }
            };
            let live = matches!(run.signal, Signal::Live { .. });
            match gps {
                Some((w, sow)) if live => format!(
                    "sim, record time 0 at GPS week {w}, {sow} s (unless the input's tags carry a GPS week)"
                ),
                Some((w, sow)) => format!("sim, record time 0 at GPS week {w}, {sow} s"),
                None => "sim".into(),
            }
        }
    }
}

/// The span of a live run's units: from the given start or the motion's first piece, for
/// the given duration or until the input ends.
fn live_span((start, duration): (Option<f64>, Option<f64>)) -> String {
    let from = start.map_or("t₀ at the live motion's first piece".into(), |t| {
        format!("t₀ {t} s")
    });
    let till = duration.map_or("until the input ends".into(), |d| format!("for {d} s"));
    format!(", {from}, {till}")
}

/// A unit line without its span (`, t₀ … s, N records` and what follows), which a live
/// run's stand-in motion would give.
fn cut_span(line: String) -> String {
    match line.find(", t₀ ") {
        Some(i) => {
            // The faults and anything else after the record count stay.
            let rest = &line[i + 2..];
            let after = rest
                .find(" records")
                .map_or("", |j| &rest[j + " records".len()..]);
            format!("{}{after}", &line[..i])
        }
        None => line,
    }
}

fn imu_line(sim: &Simulation) -> String {
    let g = sim.grid();
    let format = match sim.plan() {
        Some(p) => format!("{} frames", p.name),
        None => format!("{:?} records", sim.output()).to_lowercase(),
    };
    let mut s = format!(
        "unit imu: template {} (seed {}), {format} at {} Hz, t₀ {} s, {} records",
        sim.imu().name,
        sim.seed(),
        g.rate_hz,
        g.t0,
        g.count
    );
    if let Some(f) = sim.faults() {
        s += &format!(", faults {}", f.describe());
    }
    s
}

fn rig_lines(r: &Rig) -> Vec<String> {
    (r.units().iter())
        .map(|u| {
            let g = u.grid();
            format!(
                "unit {}: {} (seed {}), {} at {} Hz, t₀ {} s, {} records",
                u.name(),
                u.model_name(),
                u.seed(),
                u.plan()
                    .map_or(u.extension().to_string(), |p| format!("{} frames", p.name)),
                g.rate_hz,
                g.t0,
                g.count
            )
        })
        .collect()
}
