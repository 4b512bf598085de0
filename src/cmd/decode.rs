//! `imu-emu decode`: frames in (file, stdin, a pty or serial device, UDP), CSV of the decoded
//! values out, a tally on stderr (check failures, counter gaps, inter-frame timing).

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};

use imu_emu::protocol::StreamStats;
use imu_emu::realtime::clock::monotonic_ns;
use imu_emu::realtime::stats::Lateness;

#[derive(clap::Args)]
pub struct DecodeArgs {
    /// Built-in protocol: ln200, ln200-sdlc, hg4930, hg1700-sdlc, kvh1750, kvh1750-b,
    /// kvh1750-c, imar-ixcom, novatel-rawimusx, stim300 (0x93), stim300-90, stim300-91, stim300-a7,
    /// mavlink-hil-sensor, mavlink-highres-imu, skew6 (N-channel: printed as its own fields).
    #[arg(long, visible_alias = "format", conflicts_with = "protocol_file")]
    pub protocol: Option<String>,
    /// A protocol spec file.
    #[arg(long)]
    pub protocol_file: Option<PathBuf>,
    /// The stream's frame rate (Hz), or `nominal` for the protocol's nominal rate (the rate
    /// `generate --format NAME` writes by default): for counters that advance with it (STIM300)
    /// [default: the nominal rate], and for the record columns a frame lacks (rates from
    /// increments or increments from rates) [default: from the frames' time tags; without them
    /// those columns stay empty].
    #[arg(long, value_parser = parse_rate)]
    pub rate: Option<Rate>,
    /// Input file, or - for stdin [default: stdin].
    #[arg(conflicts_with_all = ["serial", "udp_listen"])]
    pub input: Option<PathBuf>,
    /// Read live from a pty or serial device (opened shared, input flushed first).
    #[arg(long, visible_alias = "pty", conflicts_with = "udp_listen")]
    pub serial: Option<String>,
    /// Baud rate of --serial.
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// Read live datagrams sent to HOST:PORT (a multicast group is joined).
    #[arg(long)]
    pub udp_listen: Option<String>,
    /// Stop after this many good frames.
    #[arg(long)]
    pub frames: Option<u64>,
    /// Stop after this many seconds (live input).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Print only the tally, not the decoded records.
    #[arg(long)]
    pub tally_only: bool,
    /// Print the protocol's own fields (wire names, SI units) instead of the record contract
    /// (t, gyro, accel, dtheta, dv, then the frame's other fields: counter, status, …).
    #[arg(long)]
    pub native: bool,
}

/// `--rate`: a rate in Hz, or the protocol's nominal one.
#[derive(Clone, Copy, Debug)]
pub enum Rate {
    /// This many frames per second.
    Hz(f64),
    /// The protocol's `rate_hz`.
    Nominal,
}

fn parse_rate(s: &str) -> Result<Rate, String> {
    if s == "nominal" {
        return Ok(Rate::Nominal);
    }
    s.parse()
        .map(Rate::Hz)
        .map_err(|_| format!("`{s}`: expected a rate in Hz or `nominal`"))
}

/// Where bytes come from.
enum Input {
    Stream(Box<dyn Read>),
    Udp(UdpSocket),
}

impl Input {
    /// Reads some bytes: `Ok(None)` at the end of the input, `Ok(Some(0))` on a timeout.
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<Option<usize>> {
        let r = match self {
            Input::Stream(r) => r.read(buf),
            Input::Udp(s) => s.recv(buf),
        };
        match r {
            Ok(0) if matches!(self, Input::Stream(_)) => Ok(None),
            Ok(n) => Ok(Some(n)),
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) =>
            {
                Ok(Some(0))
            }
            // A pty whose emulator went away (EIO, or a hang-up that serialport reports as a
            // broken pipe).
            Err(e) if e.raw_os_error() == Some(libc::EIO) || e.kind() == ErrorKind::BrokenPipe => {
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }
}

fn open_udp(addr: &str) -> Result<UdpSocket> {
    let a: SocketAddr = addr
        .to_socket_addrs()
        .with_context(|| format!("--udp-listen {addr}"))?
        .next()
        .with_context(|| format!("--udp-listen {addr}: no address"))?;
    let sock = match a {
        SocketAddr::V4(v4) if v4.ip().is_multicast() => {
            let s = UdpSocket::bind(("0.0.0.0", v4.port()))?;
            s.join_multicast_v4(v4.ip(), &std::net::Ipv4Addr::UNSPECIFIED)?;
            s
        }
        _ => UdpSocket::bind(a).with_context(|| format!("--udp-listen {addr}"))?,
    };
    sock.set_read_timeout(Some(Duration::from_millis(100)))?;
    imu_emu::realtime::udp::grow_receive_buffer(&sock);
    Ok(sock)
}

/// `imu-emu decode`: frames in, CSV of the decoded values out, a tally on stderr.
pub fn decode(a: DecodeArgs) -> Result<()> {
    let (_, mut plan) = match (&a.protocol, &a.protocol_file) {
        (Some(n), _) => imu_emu::protocol::load(n)?,
        (None, Some(p)) => imu_emu::protocol::load_file(p)?,
        (None, None) => bail!(
            "give --protocol NAME ({}) or --protocol-file FILE",
            imu_emu::protocol::builtin_names().join(", ")
        ),
    };
    let rate = match a.rate {
        None => None,
        Some(Rate::Hz(r)) => Some(r),
        Some(Rate::Nominal) => Some(plan.rate_hz.with_context(|| {
            format!(
                "--rate nominal: the `{}` spec gives no nominal rate (`rate_hz`); give the stream's rate in Hz",
                plan.name
            )
        })?),
    };
    if let Some(rate) = rate {
        plan.set_rate(rate)
            .map_err(|e| anyhow::anyhow!("--rate: {e}"))?;
    }
    if plan.evidence_bits() == 0 && matches!(plan.transport, imu_emu::protocol::Transport::Plain) {
        eprintln!(
            "imu-emu decode: `{}` frames have neither constant fields nor a check: any bytes decode as frames, noise included",
            plan.name
        );
    }
    let live = a.serial.is_some() || a.udp_listen.is_some();
    let mut input = if let Some(dev) = &a.serial {
        let mut port = serialport::new(dev, a.baud)
            .timeout(Duration::from_millis(100))
            .open_native()
            .with_context(|| format!("opening {dev}"))?;
        port.set_exclusive(false)?;
        serialport::SerialPort::clear(&port, serialport::ClearBuffer::Input)?;
        Input::Stream(Box::new(port))
    } else if let Some(addr) = &a.udp_listen {
        Input::Udp(open_udp(addr)?)
    } else {
        Input::Stream(match a.input.as_deref() {
            None => Box::new(std::io::stdin().lock()),
            Some(p) if p == Path::new("-") => Box::new(std::io::stdin().lock()),
            Some(p) => Box::new(
                std::fs::File::open(p).with_context(|| format!("opening {}", p.display()))?,
            ),
        })
    };
    // Live input ends on Ctrl-C / SIGTERM with its tally printed, like a finished stream.
    let stop = if live {
        Some(imu_emu::realtime::signal::watch()?)
    } else {
        None
    };
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    // Columns: the record contract (unless --native), then every message's other value
    // fields, merged by name (plus the message name when the protocol interleaves several);
    // a row leaves the columns its message lacks empty.
    let multi = plan.messages() > 1;
    // An N-channel frame (a skew-redundant unit's) has no three-axis record: its own fields.
    let contract = !a.native && plan.channels().is_none();
    let mut columns: Vec<String> = if contract {
        imu_emu::record::COLUMNS
            .iter()
            .map(|c| c.to_string())
            .collect()
    } else {
        Vec::new()
    };
    // The frame interval of the record columns a frame lacks: --rate, else the frames' time
    // tags; never the nominal rate, which a stream at another rate would silently mis-scale.
    let fixed_dt = rate.map(|r| 1.0 / r);
    let mut interval = imu_emu::protocol::FrameInterval::default();
    if contract && !a.tally_only && fixed_dt.is_none() && plan.needs_interval() {
        if plan.carries_time() {
            eprintln!(
                "imu-emu decode: `{}` frames lack rates or increments: derived over the interval of their time tags (give --rate HZ to set it)",
                plan.name
            );
        } else {
            eprintln!(
                "imu-emu decode: `{}` frames lack rates or increments and carry no time tag: those columns are left empty; give --rate HZ (the stream's rate), or --rate nominal, to derive them",
                plan.name
            );
        }
    }
    // Per message, the column of each decoded value (None: carried by the contract columns).
    let sources = plan.value_sources();
    let slots: Vec<Vec<Option<usize>>> = (0..plan.messages())
        .map(|m| {
            plan.value_names_of(m)
                .into_iter()
                .zip(&sources[m])
                .map(|(n, s)| {
                    if contract && imu_emu::protocol::Decoded::in_contract(*s) {
                        return None;
                    }
                    Some(match columns.iter().position(|c| c == n) {
                        Some(i) => i,
                        None => {
                            columns.push(n.to_string());
                            columns.len() - 1
                        }
                    })
                })
                .collect()
        })
        .collect();
    let names: Vec<String> = (0..plan.messages())
        .map(|m| plan.message_name(m).to_string())
        .collect();
    if !a.tally_only {
        if multi {
            write!(out, "message,")?;
        }
        writeln!(out, "{}", columns.join(","))?;
    }
    let mut cells: Vec<Option<f64>> = vec![None; columns.len()];
    let mut dec = imu_emu::protocol::StreamDecoder::new(plan);
    let mut buf = vec![0u8; 1 << 16];
    let mut fmt = ryu::Buffer::new();
    let mut line = String::new();
    let mut gaps = Lateness::default();
    let mut last_arrival: Option<i128> = None;
    let started = Instant::now();
    let mut last_tally = Instant::now();
    let mut tallied = StreamStats::default();
    let deadline = a
        .duration
        .map(|d| started + Duration::from_secs_f64(d.max(0.0)));
    let limit = a.frames.unwrap_or(u64::MAX);
    // One CSV row per good frame: the frames of a read (arrived at `now`), and those the end
    // of the input confirms.
    let mut on_frame = |d: &imu_emu::protocol::Decoded,
                        now: i128,
                        out: &mut dyn Write,
                        gaps: &mut Lateness|
     -> std::io::Result<()> {
        if let Some(t) = last_arrival {
            gaps.add(now - t);
        }
        last_arrival = Some(now);
        if a.tally_only {
            return Ok(());
        }
        line.clear();
        cells.iter_mut().for_each(|c| *c = None);
        if contract {
            let dt = fixed_dt.or_else(|| interval.observe(d));
            cells[..13].copy_from_slice(&d.contract(dt));
        }
        for (slot, (_, v)) in slots[d.message].iter().zip(&d.values) {
            if let Some(i) = slot {
                cells[*i] = Some(*v);
            }
        }
        if multi {
            line.push_str(&names[d.message]);
            line.push(',');
        }
        for (i, c) in cells.iter().enumerate() {
            if i > 0 {
                line.push(',');
            }
            if let Some(v) = c {
                line.push_str(fmt.format(*v));
            }
        }
        line.push('\n');
        out.write_all(line.as_bytes())
    };
    while stop.as_ref().is_none_or(|s| s.load(Ordering::Relaxed) == 0) && dec.stats().frames < limit
    {
        if deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        let read = input.read(&mut buf)?;
        let now = monotonic_ns();
        let mut err = Ok(());
        let mut each = |d: &imu_emu::protocol::Decoded| {
            if err.is_ok() {
                err = on_frame(d, now, &mut out, &mut gaps);
            }
        };
        match read {
            Some(n) => dec.feed(&buf[..n], &mut each),
            None => dec.finish_frames(&mut each),
        }
        err?;
        if read.is_none() {
            break;
        }
        if live && last_tally.elapsed() >= Duration::from_secs(1) {
            out.flush()?;
            last_tally = Instant::now();
            if dec.stats() == tallied {
                continue;
            }
            tallied = dec.stats();
            eprintln!(
                "imu-emu decode: {}",
                tally(&dec.stats(), live.then_some(&gaps))
            );
        }
    }
    out.flush()?;
    let stats = dec.stats();
    eprintln!("imu-emu decode: {}", tally(&stats, live.then_some(&gaps)));
    if stats.frames == 0 {
        bail!("no valid `{}` frame in the input", dec.plan().name);
    }
    Ok(())
}

/// The counts, and for live input the time between frame arrivals.
fn tally(s: &StreamStats, gaps: Option<&Lateness>) -> String {
    let mut t = format!(
        "{} frames, {} check failures, {} counter gaps, {} duplicates, {} stale counters, {} status flagged, {} bytes skipped, {} framing errors",
        s.frames,
        s.check_failures,
        s.counter_gaps,
        s.duplicates,
        s.stale_counters,
        s.status_flagged,
        s.skipped_bytes,
        s.framing_errors
    );
    if s.truncated > 0 {
        t += &format!(", {} frame cut short at the end", s.truncated);
    }
    if let Some(g) = gaps.filter(|g| g.count() > 0) {
        t += &format!(", inter-frame time {}", g.summary());
    }
    t
}
