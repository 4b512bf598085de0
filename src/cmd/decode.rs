//! `imu-emu decode`: frames in (file, stdin, a pty or serial device, UDP), CSV of the decoded
//! values out, a tally on stderr (check failures, counter gaps, inter-frame timing).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Result, bail};

use imu_emu::decode::capture::{self, CaptureError, Source};
use imu_emu::decode::{self, Options, Rate, Session};

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

fn parse_rate(s: &str) -> Result<Rate, String> {
    if s == "nominal" {
        return Ok(Rate::Nominal);
    }
    s.parse()
        .map(Rate::Hz)
        .map_err(|_| format!("`{s}`: expected a rate in Hz or `nominal`"))
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
    let rate = decode::set_rate(&mut plan, a.rate).map_err(anyhow::Error::msg)?;
    if let Some(w) = decode::unchecked(&plan) {
        eprintln!("imu-emu decode: {w}");
    }
    let source = match (&a.serial, &a.udp_listen, &a.input) {
        (Some(dev), _, _) => Source::Serial(dev.clone(), a.baud),
        (_, Some(addr), _) => Source::Udp(addr.clone()),
        (_, _, Some(p)) => Source::File(p.clone()),
        _ => Source::Stdin,
    };
    let mut input = capture::Input::open(&source).map_err(io_first)?;
    if let Source::Udp(addr) = &source {
        // Said once the socket is bound: a script can start the sender then.
        eprintln!("imu-emu decode: listening on udp://{addr}");
    }
    // Live input ends on Ctrl-C / SIGTERM with its tally printed, like a finished stream.
    let until = capture::Until {
        frames: a.frames,
        duration_s: a.duration,
        stop: (source.is_live())
            .then(imu_emu::realtime::signal::watch)
            .transpose()?,
    };
    let opts = Options {
        native: a.native,
        rate,
        tally_only: a.tally_only,
    };
    let mut session = Session::new(plan, opts);
    if let Some(n) = session.note() {
        eprintln!("imu-emu decode: {n}");
    }
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    if let Some(h) = session.header() {
        (out.write_all(h.as_bytes())).map_err(|e| super::stdout::failed(e, "the records", true))?;
    }
    let tell = |t: &str| eprintln!("imu-emu decode: {t}");
    let (stats, tally) = capture::run(
        &mut input,
        source.is_live(),
        &mut session,
        &until,
        &mut out,
        tell,
    )
    .map_err(io_first)?;
    eprintln!("imu-emu decode: {tally}");
    if stats.frames == 0 {
        bail!("no valid `{}` frame in the input", session.plan().name);
    }
    Ok(())
}

/// A capture's I/O error as itself; a broken pipe is standard output's (the decoded records,
/// the command's only output: reading one ends the input), whose reader left.
fn io_first(e: CaptureError) -> anyhow::Error {
    match e {
        CaptureError::Io(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            super::stdout::failed(e, "the records", true)
        }
        CaptureError::Io(e) => e.into(),
        e => e.into(),
    }
}
