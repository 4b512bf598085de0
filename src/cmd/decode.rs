//! `imu-emu decode`: frames in, CSV of the decoded values out, a tally on stderr.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

#[derive(clap::Args)]
pub struct DecodeArgs {
    /// Built-in protocol: ln200, ln200-sdlc, hg4930, hg1700-sdlc, kvh1750, kvh1750-b,
    /// imar-ixcom, novatel-rawimusx, stim300 (0x93), stim300-90, stim300-91, stim300-a7,
    /// mavlink-hil-sensor, mavlink-highres-imu.
    #[arg(long, conflicts_with = "protocol_file")]
    pub protocol: Option<String>,
    /// A protocol spec file.
    #[arg(long)]
    pub protocol_file: Option<PathBuf>,
    /// The stream's frame rate (Hz), for counters that advance with it (STIM300)
    /// [default: the protocol's nominal rate].
    #[arg(long)]
    pub rate: Option<f64>,
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
    let (_, mut plan) = imu_emu::protocol::load(&spec)?;
    if let Some(rate) = a.rate {
        plan.set_rate(rate)
            .map_err(|e| anyhow::anyhow!("--rate: {e}"))?;
    }
    let mut input: Box<dyn Read> = match a.input.as_deref() {
        None => Box::new(std::io::stdin().lock()),
        Some(p) if p == Path::new("-") => Box::new(std::io::stdin().lock()),
        Some(p) => {
            Box::new(std::fs::File::open(p).with_context(|| format!("opening {}", p.display()))?)
        }
    };
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    // Columns: every message's value fields, merged by name (plus the message name when the
    // protocol interleaves several); a row leaves the columns its message lacks empty.
    let multi = plan.messages() > 1;
    let mut columns: Vec<String> = Vec::new();
    let slots: Vec<Vec<usize>> = (0..plan.messages())
        .map(|m| {
            plan.value_names_of(m)
                .into_iter()
                .map(|n| match columns.iter().position(|c| c == n) {
                    Some(i) => i,
                    None => {
                        columns.push(n.to_string());
                        columns.len() - 1
                    }
                })
                .collect()
        })
        .collect();
    let names: Vec<String> = (0..plan.messages())
        .map(|m| plan.message_name(m).to_string())
        .collect();
    if multi {
        write!(out, "message,")?;
    }
    writeln!(out, "{}", columns.join(","))?;
    let mut cells: Vec<Option<f64>> = vec![None; columns.len()];
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
            cells.iter_mut().for_each(|c| *c = None);
            for (slot, (_, v)) in slots[d.message].iter().zip(&d.values) {
                cells[*slot] = Some(*v);
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
