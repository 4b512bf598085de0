//! Opening a run's sinks: each stream's addresses turned into [`Sink`]s, the links checked
//! against the stream's frames (a serial line's bandwidth, a UDP datagram's size). Files work
//! in every build; the pty, serial, UDP and TCP sinks need the `realtime` feature.

use std::path::Path;

use crate::output::SinkAddr;
use crate::output::failure::Named;
use crate::output::sink::{FileMode, FileSink, Sink};

use super::error::RunError;
use super::routing::StreamPlan;

/// The link settings, checked.
#[derive(Clone, Debug)]
pub struct Links {
    /// Serial baud rate, when given.
    pub baud: Option<u32>,
    /// Serial character framing (`8N1`…).
    pub framing: String,
    /// Frames per UDP datagram.
    pub udp_batch: usize,
    /// Replace a pty link another emulator holds.
    pub take_over: bool,
}

/// Opens every sink of `stream` (frames per wall-clock second `frames_per_s`, `paced`: file
/// sinks written live rather than atomically), each [`Named`] after the flag or key that asked
/// for it; `note` is told what each pty published.
pub fn open(
    stream: &StreamPlan,
    links: &Links,
    frames_per_s: f64,
    paced: bool,
    note: &dyn Fn(&str),
) -> Result<Vec<Box<dyn Sink>>, RunError> {
    let mut out: Vec<Box<dyn Sink>> = Vec::new();
    for (addr, origin) in &stream.sinks {
        match open_one(stream, addr, origin, links, frames_per_s, paced, note) {
            Ok(s) => out.push(Box::new(Named::new(origin.as_str(), s))),
            Err(e) => {
                // A live file opened before is already there: a refused run leaves none.
                out.iter_mut().for_each(|s| s.discard());
                return Err(e);
            }
        }
    }
    Ok(out)
}

/// Opens the sink at `addr` of `stream`, which `origin` asked for.
fn open_one(
    stream: &StreamPlan,
    addr: &SinkAddr,
    origin: &str,
    links: &Links,
    frames_per_s: f64,
    paced: bool,
    note: &dyn Fn(&str),
) -> Result<Box<dyn Sink>, RunError> {
    let what = format!("{origin}: `{}` to {addr}", stream.id);
    Ok(match addr {
        SinkAddr::File(path) => {
            let mode = if paced {
                FileMode::Live
            } else {
                FileMode::Atomic
            };
            Box::new(FileSink::create(Path::new(path), mode).map_err(|e| RunError::io(what, e))?)
        }
        _ => open_link(stream, addr, links, frames_per_s, note).map_err(|e| match e {
            RunError::Io { source, .. } => RunError::io(what, source),
            RunError::Spec { why, .. } => RunError::spec(&what, why),
            e => e,
        })?,
    })
}

#[cfg(feature = "realtime")]
fn open_link(
    stream: &StreamPlan,
    addr: &SinkAddr,
    links: &Links,
    frames_per_s: f64,
    note: &dyn Fn(&str),
) -> Result<Box<dyn Sink>, RunError> {
    use crate::realtime::pty::PtySink;
    use crate::realtime::serial::{Framing, SerialSink, check_link};
    use crate::realtime::tcp::{TcpListenSink, TcpSink};
    use crate::realtime::udp::{UdpSink, max_wire_len};
    let io = |e| RunError::io("", e);
    Ok(match addr {
        SinkAddr::Pty(link) => {
            let s = PtySink::open(link.as_deref().map(Path::new), links.take_over).map_err(io)?;
            let slave = if s.path() != s.slave() {
                format!(" -> {}", s.slave().display())
            } else {
                String::new()
            };
            note(&format!(
                "`{}` on {}{slave}, {} Hz",
                stream.id,
                s.path().display(),
                stream.rate_hz
            ));
            Box::new(s)
        }
        SinkAddr::Serial(dev) => {
            let framing: Framing = links.framing.parse().map_err(|e| RunError::spec("", e))?;
            let baud = (links.baud)
                .or(stream.plan.as_ref().and_then(|p| p.baud).map(|b| b as u32))
                .unwrap_or(921_600);
            if let Some(p) = &stream.plan {
                check_link(p.len(), frames_per_s, baud, framing)
                    .map_err(|e| RunError::spec("", e))?;
            }
            Box::new(SerialSink::open(dev, baud, framing).map_err(io)?)
        }
        SinkAddr::Udp(dest) => {
            let s = UdpSink::open(dest, links.udp_batch).map_err(io)?;
            if let Some(p) = &stream.plan {
                s.check_datagram(max_wire_len(p))
                    .map_err(|e| RunError::spec("", e))?;
            }
            Box::new(s)
        }
        SinkAddr::Tcp(dest) => {
            let s = TcpSink::open(dest).map_err(io)?;
            if !s.connected() {
                note(&format!(
                    "`{}` to tcp {dest}: nobody listening yet, retrying every {} s",
                    stream.id,
                    crate::realtime::tcp::RETRY.as_secs_f64()
                ));
            }
            Box::new(s)
        }
        SinkAddr::TcpListen(addr) => {
            let s = TcpListenSink::open(addr).map_err(io)?;
            let at = s.local_addr().map_err(io)?;
            note(&format!(
                "`{}` on tcp {at} (listening), {} Hz",
                stream.id, stream.rate_hz
            ));
            Box::new(s)
        }
        SinkAddr::File(_) => unreachable!("files are opened above"),
    })
}

#[cfg(not(feature = "realtime"))]
fn open_link(
    _: &StreamPlan,
    addr: &SinkAddr,
    _: &Links,
    _: f64,
    _: &dyn Fn(&str),
) -> Result<Box<dyn Sink>, RunError> {
    Err(RunError::spec(
        &addr.to_string(),
        "this build has no real-time sinks (the `realtime` feature): write to files".into(),
    ))
}
