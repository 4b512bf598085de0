//! `imu-emu decode`: frames in, CSV of the decoded values out, a tally on stderr.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

#[derive(clap::Args)]
pub struct DecodeArgs {
    /// Built-in protocol: ln200, ln200-sdlc, kvh1750, imar-ixcom, novatel-rawimusx, stim300.
    #[arg(long, conflicts_with = "protocol_file")]
    pub protocol: Option<String>,
    /// A protocol spec file.
    #[arg(long)]
    pub protocol_file: Option<PathBuf>,
    /// Input file, or - for stdin [default: stdin].
    pub input: Option<PathBuf>,
}

/// `imu-emu decode`: frames in, CSV of the decoded values out, a tally on stderr.
pub fn decode(a: DecodeArgs) -> Result<()> {
    use std::io::Read;
    let spec = match (&a.protocol, &a.protocol_file) {
        (Some(n), _) => n.clone(),
        (None, Some(p)) => p.to_string_lossy().into_owned(),
        (None, None) => bail!(
            "give --protocol NAME ({}) or --protocol-file FILE",
            imu_emu::protocol::builtin_names().join(", ")
        ),
    };
    let (_, plan) = imu_emu::protocol::load(&spec)?;
    let mut input: Box<dyn Read> = match a.input.as_deref() {
        None => Box::new(std::io::stdin().lock()),
        Some(p) if p == Path::new("-") => Box::new(std::io::stdin().lock()),
        Some(p) => {
            Box::new(std::fs::File::open(p).with_context(|| format!("opening {}", p.display()))?)
        }
    };
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    writeln!(out, "{}", plan.value_names().join(","))?;
    let mut dec = imu_emu::protocol::StreamDecoder::new(plan);
    let mut buf = vec![0u8; 1 << 16];
    let mut fmt = ryu::Buffer::new();
    let mut line = String::new();
    loop {
        let n = input.read(&mut buf)?;
        if n == 0 {
            break;
        }
        let mut err = Ok(());
        dec.feed(&buf[..n], |d| {
            line.clear();
            for (i, (_, v)) in d.values.iter().enumerate() {
                if i > 0 {
                    line.push(',');
                }
                line.push_str(fmt.format(*v));
            }
            line.push('\n');
            if err.is_ok() {
                err = out.write_all(line.as_bytes());
            }
        });
        err?;
    }
    out.flush()?;
    let s = dec.stats();
    eprintln!(
        "imu-emu decode: {} frames, {} check failures, {} counter gaps, {} duplicates, {} stale counters, {} status flagged, {} bytes skipped, {} framing errors",
        s.frames,
        s.check_failures,
        s.counter_gaps,
        s.duplicates,
        s.stale_counters,
        s.status_flagged,
        s.skipped_bytes,
        s.framing_errors
    );
    Ok(())
}
