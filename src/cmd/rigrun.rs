//! `imu-emu run` on a scene file with an `[[imu]]` list: every unit streamed from one
//! process on one pacer, each in its own format and at its own rate to its own sinks, the
//! frames of all units merged in emission-time order.

use std::path::Path;

use anyhow::{Context, Result, bail};

use imu_emu::protocol::Plan;
use imu_emu::realtime::pacer::{Clocking, Pacing, Routed, Status};
use imu_emu::realtime::serial::{SerialSink, check_link};
use imu_emu::realtime::signal::StopSignals;
use imu_emu::realtime::sink::Sink;
use imu_emu::realtime::udp::{self, UdpSink};
use imu_emu::realtime::{clock, pty::PtySink};
use imu_emu::rig::SinkAddr;
use imu_emu::rig::Unit;
use imu_emu::run::merge::{self, WindowSource};

use super::aiding_run;
use super::run::{FOREVER_S, RunArgs, drive, file_sink, time_base_start};

/// Simulated time the producer merges at a time (ns): short enough that the first frames
/// are ready at once and the look-ahead stays small, long enough that channel traffic is
/// negligible.
pub(super) const WINDOW_NS: i64 = 100_000_000;

/// Flags that describe one IMU or its sinks, which each `[[imu]]` entry gives for itself.
fn refuse_single_imu_flags(a: &RunArgs) -> Result<()> {
    let s = &a.sim;
    if a.time_base != "sim" && s.gps_time.is_some() {
        bail!("--gps-time sets the GPS reference of --time-base sim only");
    }
    let sync = [
        ("--time-marks", !a.time_marks.is_empty()),
        ("--pulse", a.pulse.is_some()),
        ("--pps-in", a.pps_in.is_some()),
        ("--trigger", a.trigger.is_some()),
    ];
    if let Some((flag, _)) = sync.iter().find(|g| g.1) {
        bail!(
            "{flag} does not apply to a rig yet: it times one IMU's frames, and a rig's units are merged on one pacer that does not tell which frame is whose (docs/rig.md)"
        );
    }
    let given = [
        ("--imu", s.imu.is_some()),
        ("--format", s.format.is_some()),
        ("--protocol-file", s.protocol_file.is_some()),
        ("--fault", !s.faults.is_empty()),
        ("--pty", !a.pty.is_empty()),
        ("--serial", !a.serial.is_empty()),
        ("--udp", !a.udp.is_empty()),
        ("--file", !a.file.is_empty()),
    ];
    if let Some((flag, _)) = given.iter().find(|g| g.1) {
        let file = s.source.scene_file.as_deref().unwrap_or(Path::new("?"));
        bail!(
            "{flag} does not apply to a rig ({} lists `[[imu]]` units): give each unit its `model`, `format` and `sink` in the scene file, or `--unit-sink NAME=SINK`",
            file.display()
        );
    }
    Ok(())
}

/// Each unit's sinks: `--unit-sink NAME=SINK` replaces the scene file's `sink` of that unit;
/// a unit with neither gets a pty of its own.
fn unit_sinks(a: &RunArgs, units: &[Unit]) -> Result<Vec<Vec<SinkAddr>>> {
    let mut out: Vec<Vec<SinkAddr>> = units.iter().map(|u| u.sinks().to_vec()).collect();
    let mut given = vec![false; units.len()];
    for v in &a.unit_sink {
        let Some((name, sink)) = v.split_once('=') else {
            bail!("--unit-sink {v}: expected NAME=SINK (e.g. nav=udp:127.0.0.1:9001)");
        };
        let Some(i) = units.iter().position(|u| u.name() == name) else {
            let names: Vec<&str> = units.iter().map(Unit::name).collect();
            bail!(
                "--unit-sink {v}: no unit `{name}` (the rig has {})",
                names.join(", ")
            );
        };
        let addr = SinkAddr::parse(sink).map_err(|e| anyhow::anyhow!("--unit-sink {v}: {e}"))?;
        if !given[i] {
            out[i].clear();
            given[i] = true;
        }
        out[i].push(addr);
    }
    for s in out.iter_mut().filter(|s| s.is_empty()) {
        s.push(SinkAddr::Pty(None));
    }
    Ok(out)
}

/// A stream of the run: its name (a unit's, or `gnss-FORMAT`), rate and frame layout.
pub(super) struct Stream<'a> {
    pub name: String,
    pub rate_hz: f64,
    pub plan: Option<&'a Plan>,
}

/// Opens `addr` for stream `unit`, checking that the link or datagram can carry its frames.
pub(super) fn open(
    a: &RunArgs,
    unit: &Stream,
    addr: &SinkAddr,
    paced: bool,
    speed: f64,
) -> Result<Box<dyn Sink>> {
    let plan = unit.plan;
    let what = format!("`{}`: {addr}", unit.name);
    Ok(match addr {
        SinkAddr::Pty(link) => {
            let link = link.as_deref().map(Path::new);
            let s = PtySink::open(link, a.take_over).with_context(|| what.clone())?;
            let slave = if s.path() != s.slave() {
                format!(" -> {}", s.slave().display())
            } else {
                String::new()
            };
            eprintln!("imu-emu: `{}` on {}{slave}", unit.name, s.path().display());
            Box::new(s)
        }
        SinkAddr::Serial(dev) => {
            let baud = (a.baud.or(plan.and_then(|p| p.baud).map(|b| b as u32))).unwrap_or(921_600);
            if let Some(p) = plan {
                check_link(p.len(), unit.rate_hz * speed, baud, a.framing)
                    .map_err(|e| anyhow::anyhow!("{what}: {e}"))?;
            }
            Box::new(SerialSink::open(dev, baud, a.framing).with_context(|| what.clone())?)
        }
        SinkAddr::Udp(dest) => {
            let s = UdpSink::open(dest, a.udp_batch).with_context(|| what.clone())?;
            if let Some(p) = plan {
                s.check_datagram(udp::max_wire_len(p))
                    .map_err(|e| anyhow::anyhow!("{what}: {e}"))?;
            }
            Box::new(s)
        }
        SinkAddr::File(path) => file_sink(path, paced).with_context(|| what.clone())?,
    })
}

/// Streams every unit of the rig in `a`'s scene file until the end of the span or a signal.
pub fn run(a: RunArgs) -> Result<()> {
    refuse_single_imu_flags(&a)?;
    if let Some(source) = &a.live.motion {
        // The units' names and sinks, from the settings alone (the motion comes later).
        let builder = (a.sim.builder("ideal", "csv")?).unbounded_duration(FOREVER_S);
        let stand_in = imu_emu::run::target::stand_in(&builder).build_rig()?;
        let sinks = unit_sinks(&a, stand_in.units())?;
        return super::live::run_rig(&a, source, stand_in.units(), &sinks);
    }
    let mut rig = (a.sim.builder("ideal", "csv")?)
        .unbounded_duration(FOREVER_S)
        .build_rig()?;
    for w in rig.warnings() {
        eprintln!("imu-emu: warning: {w}");
    }
    let leap = imu_emu::timebase::LeapTable::builtin();
    let mut start_at = (a.start_at.as_deref())
        .map(|s| {
            imu_emu::timebase::parse_start(s, clock::realtime_ns(), &leap)
                .map_err(|e| anyhow::anyhow!("--start-at {e}"))
        })
        .transpose()?;
    // Frames and GNSS epochs carry the time base's GPS time from the rig's t₀ on.
    let host = imu_emu::realtime::hostclock::GpsClock::new(leap.clone());
    if let Some(((week, sow), (gw, gs))) = time_base_start(&a, &host, &leap, &mut start_at) {
        rig.set_gps_time(week, sow - rig.span().0);
        rig.set_gnss_gps_time(gw, gs - rig.span().0);
    }
    let aiding = aiding_run::build(aiding_run::requests(&a)?, &rig);
    let stream = rig.stream();
    let units = stream.units();
    let mut addrs = unit_sinks(&a, units)?;
    let n_units = units.len();
    let mut streams: Vec<Stream> = (units.iter())
        .map(|u| Stream {
            name: u.name().to_string(),
            rate_hz: u.grid().rate_hz,
            plan: u.plan(),
        })
        .collect();
    let mut planned: Vec<u64> = units.iter().map(|u| u.grid().count).collect();
    let mut kinds: Vec<&str> = vec!["records"; n_units];
    let mut sources: Vec<Box<dyn WindowSource>> = Vec::new();
    for s in aiding {
        streams.push(Stream {
            name: s.what.name(),
            rate_hz: s.rate_hz,
            plan: None,
        });
        addrs.push(s.sinks);
        planned.push(s.planned);
        kinds.push(s.what.unit());
        sources.push(s.source);
    }
    let speed = match a.speed.as_deref() {
        None if addrs.iter().flatten().all(SinkAddr::is_file) => f64::INFINITY,
        None => 1.0,
        Some("max") => f64::INFINITY,
        Some(s) => match s.parse::<f64>() {
            Ok(x) if x.is_finite() && x > 0.0 => x,
            _ => bail!("--speed {s}: expected a positive factor (1 = real time) or `max`"),
        },
    };
    let paced = speed.is_finite();
    for u in units {
        eprintln!(
            "imu-emu: unit `{}`: {} at {} Hz, {} records, seed {}",
            u.name(),
            u.plan().map_or(u.extension(), |p| p.name.as_str()),
            u.grid().rate_hz,
            u.grid().count,
            u.seed()
        );
    }

    // Before any sink is visible: a signal from then on ends the run with its summary.
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let mut signals = {
        let _rt = rt.enter();
        StopSignals::new()?
    };
    let mut sinks = Vec::new();
    for (i, (u, list)) in streams.iter().zip(&addrs).enumerate() {
        for addr in list {
            let sink = open(&a, u, addr, paced, speed)?;
            sinks.push(Routed { stream: i, sink });
        }
    }
    let owner: Vec<usize> = sinks.iter().map(|r| r.stream).collect();
    let names: Vec<String> = streams.iter().map(|u| u.name.clone()).collect();
    let frames_per_s: f64 = streams.iter().map(|u| u.rate_hz).sum::<f64>() * speed;
    let pacing = if paced {
        let start_ns = start_at
            .map(clock::start_at)
            .transpose()
            .map_err(|e| anyhow::anyhow!("--start-at: {e}"))?;
        let mut c = Clocking::new(frames_per_s, start_ns, a.realtime)
            .map_err(|e| anyhow::anyhow!(e))?
            .with_speed(speed);
        c.max_behind_ns = (a.max_behind_ms * 1e6) as i128;
        Pacing::Paced(c)
    } else {
        Pacing::Unpaced
    };
    sources.insert(0, Box::new(stream));
    let line_names = names.clone();
    let ended = drive(
        &rt,
        &mut signals,
        sinks,
        pacing,
        Default::default(),
        move |tx, recycled| merge::produce_merged(sources, WINDOW_NS, tx, recycled),
        move |s| status_line(s, &line_names),
    )?;
    eprintln!(
        "imu-emu: {}{}",
        ended
            .interrupted
            .map_or(String::new(), |i| format!("{i}: ")),
        summary(
            &ended.status,
            &names,
            (n_units, &kinds),
            &planned,
            &owner,
            paced
        )
    );
    if let Some(e) = ended.failed {
        return Err(anyhow::Error::new(e).context("stopped: nothing non-finite was sent"));
    }
    ended.interrupted.map_or(Ok(()), |i| Err(i.into()))
}

/// The one-line live status: frames per unit, lateness, skipped and dropped frames.
fn status_line(s: &Status, names: &[String]) -> String {
    let elapsed = s
        .start_ns
        .map_or(0.0, |t| (clock::monotonic_ns() - t) as f64 / 1e9);
    let mut line = format!("{elapsed:.1} s");
    for (n, c) in names.iter().zip(&s.streams) {
        line += &format!(" | {n}: {}", c.frames);
        if c.skipped > 0 {
            line += &format!(" ({} skipped)", c.skipped);
        }
    }
    let dropped: u64 = s.sinks.iter().map(|x| x.1.dropped + x.1.no_reader).sum();
    line + &format!(" | late {} | {dropped} dropped", s.lateness.summary())
}

/// The end-of-run summary: per unit its records, per aiding stream its epochs or samples
/// (`kinds`), skipped frames and sinks.
fn summary(
    s: &Status,
    names: &[String],
    (units, kinds): (usize, &[&str]),
    planned: &[u64],
    owner: &[usize],
    paced: bool,
) -> String {
    let mut out = format!("{} frames of {} streams", s.frames, names.len());
    if paced {
        out += &format!(", write lateness {}", s.lateness.summary());
    }
    if let Some(f) = s.fifo {
        out += if f {
            ", SCHED_FIFO"
        } else {
            ", SCHED_FIFO refused"
        };
    }
    for (i, n) in names.iter().enumerate() {
        let c = s.streams.get(i).copied().unwrap_or_default();
        out += &format!(
            "\n  {} {n}: {} of {} {}, {} skipped (too late)",
            if i < units { "unit" } else { "stream" },
            c.frames,
            planned[i],
            kinds[i],
            c.skipped
        );
        for ((label, st), _) in (s.sinks.iter().zip(owner)).filter(|x| *x.1 == i) {
            out += &format!(
                "\n    {label}: {} sent, {} dropped (slow consumer), {} dropped (no reader), {} bytes",
                st.sent, st.dropped, st.no_reader, st.bytes
            );
        }
    }
    out
}
