//! Frames back into numbers (`imu-emu decode`): a [`Session`] takes a frame stream's bytes in
//! chunks of any size, writes one CSV row per good frame — the record contract's columns
//! (t, gyro, accel, dtheta, dv) then the frame's other fields, or the protocol's own fields —
//! and keeps the tally of what was wrong with the stream; [`capture`] reads the bytes from a
//! file, stdin, a pty or serial device, or UDP, until an end (feature `realtime`).

#[cfg(feature = "realtime")]
pub mod capture;

use std::io::{self, Write};

use crate::protocol::{Decoded, FrameInterval, Plan, StreamDecoder, StreamStats};

/// The stream's frame rate, as the user gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rate {
    /// This many frames per second.
    Hz(f64),
    /// The protocol's nominal rate (`rate_hz`), the one `generate --format NAME` writes.
    Nominal,
}

/// Sets `plan`'s frame rate (for counters that advance with it) from `rate`; returns it in
/// Hz. The messages name `--rate`.
pub fn set_rate(plan: &mut Plan, rate: Option<Rate>) -> Result<Option<f64>, String> {
    let hz = match rate {
        None => return Ok(None),
        Some(Rate::Hz(r)) => r,
        Some(Rate::Nominal) => plan.rate_hz.ok_or_else(|| {
            format!(
                "--rate nominal: the `{}` spec gives no nominal rate (`rate_hz`); give the stream's rate in Hz",
                plan.name
            )
        })?,
    };
    plan.set_rate(hz).map_err(|e| format!("--rate: {e}"))?;
    Ok(Some(hz))
}

/// A warning for frames that nothing in them tells apart from noise (no constant field, no
/// check, no framing of their own).
pub fn unchecked(plan: &Plan) -> Option<String> {
    (plan.evidence_bits() == 0 && matches!(plan.transport, crate::protocol::Transport::Plain))
        .then(|| {
            format!(
                "`{}` frames have neither constant fields nor a check: any bytes decode as frames, noise included",
                plan.name
            )
        })
}

/// What a [`Session`] writes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Options {
    /// The protocol's own fields (wire names, SI units) instead of the record contract.
    pub native: bool,
    /// The stream's frame rate (Hz), for the record columns a frame lacks; `None`: from the
    /// frames' time tags, never the nominal rate (a stream at another rate would be silently
    /// mis-scaled).
    pub rate: Option<f64>,
    /// Write no rows, only count (the tally).
    pub tally_only: bool,
}

/// A frame stream being decoded into CSV rows.
pub struct Session {
    dec: StreamDecoder,
    opts: Options,
    /// The record contract's columns lead (not `native`, and a three-axis frame).
    contract: bool,
    /// The protocol interleaves several messages: rows start with the message's name.
    multi: bool,
    columns: Vec<String>,
    /// Per message, the column of each decoded value (None: carried by the contract columns).
    slots: Vec<Vec<Option<usize>>>,
    names: Vec<String>,
    cells: Vec<Option<f64>>,
    interval: FrameInterval,
    fmt: ryu::Buffer,
    line: String,
}

/// The columns of a decoded table and, per message and value field, its column (`None` for a
/// field the record contract already holds): the contract's columns when `contract`, then
/// every message's other value fields merged by name.
pub fn columns(plan: &Plan, contract: bool) -> (Vec<String>, Vec<Vec<Option<usize>>>) {
    let mut columns: Vec<String> = if contract {
        crate::record::COLUMNS
            .iter()
            .map(|c| c.to_string())
            .collect()
    } else {
        Vec::new()
    };
    let sources = plan.value_sources();
    let slots = (0..plan.messages())
        .map(|m| {
            plan.value_names_of(m)
                .into_iter()
                .zip(&sources[m])
                .map(|(n, s)| {
                    if contract && Decoded::in_contract(*s) {
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
    (columns, slots)
}

impl Session {
    /// A session decoding frames of `plan` (its rate already set, for counters that advance
    /// with it).
    pub fn new(plan: Plan, opts: Options) -> Session {
        // Columns: the record contract (unless native), then every message's other value
        // fields, merged by name (plus the message name when the protocol interleaves
        // several); a row leaves the columns its message lacks empty.
        let multi = plan.messages() > 1;
        // An N-channel frame (a skew-redundant unit's) has no three-axis record: its own fields.
        let contract = !opts.native && plan.channels().is_none();
        let (columns, slots) = columns(&plan, contract);
        let names = (0..plan.messages())
            .map(|m| plan.message_name(m).to_string())
            .collect();
        Session {
            cells: vec![None; columns.len()],
            dec: StreamDecoder::new(plan),
            opts,
            contract,
            multi,
            columns,
            slots,
            names,
            interval: FrameInterval::default(),
            fmt: ryu::Buffer::new(),
            line: String::new(),
        }
    }

    /// The CSV header line (with its newline); `None` when only counting.
    pub fn header(&self) -> Option<String> {
        if self.opts.tally_only {
            return None;
        }
        let lead = if self.multi { "message," } else { "" };
        Some(format!("{lead}{}\n", self.columns.join(",")))
    }

    /// What the user should know before the rows: how the record columns a frame lacks (rates
    /// from increments, or increments from rates) are derived, or that they stay empty.
    pub fn note(&self) -> Option<String> {
        let plan = self.dec.plan();
        if !self.contract || self.opts.tally_only || self.opts.rate.is_some() {
            return None;
        }
        if !plan.needs_interval() {
            return None;
        }
        Some(if plan.carries_time() {
            format!(
                "`{}` frames lack rates or increments: derived over the interval of their time tags (give --rate HZ to set it)",
                plan.name
            )
        } else {
            format!(
                "`{}` frames lack rates or increments and carry no time tag: those columns are left empty; give --rate HZ (the stream's rate), or --rate nominal, to derive them",
                plan.name
            )
        })
    }

    /// Decodes `bytes` (the stream's next chunk), writing a row per good frame to `out`;
    /// returns the number of good frames.
    pub fn feed(&mut self, bytes: &[u8], out: &mut impl Write) -> io::Result<u64> {
        self.decode(Some(bytes), out)
    }

    /// The end of the stream: a frame cut short there is counted, and the frames the end
    /// confirms (a run too short to lock on that ends with the input) are written; returns
    /// their number.
    pub fn finish(&mut self, out: &mut impl Write) -> io::Result<u64> {
        self.decode(None, out)
    }

    /// Feeds `bytes`, or finishes the stream on `None`, writing the frames' rows.
    fn decode(&mut self, bytes: Option<&[u8]>, out: &mut impl Write) -> io::Result<u64> {
        let mut err = Ok(());
        let mut n = 0;
        let Session {
            dec,
            opts,
            contract,
            multi,
            slots,
            names,
            cells,
            interval,
            fmt,
            line,
            ..
        } = self;
        let fixed_dt = opts.rate.map(|r| 1.0 / r);
        let mut each = |d: &Decoded| {
            n += 1;
            if opts.tally_only {
                return;
            }
            line.clear();
            cells.iter_mut().for_each(|c| *c = None);
            if *contract {
                let dt = fixed_dt.or_else(|| interval.observe(d));
                cells[..13].copy_from_slice(&d.contract(dt));
            }
            for (slot, (_, v)) in slots[d.message].iter().zip(&d.values) {
                if let Some(i) = slot {
                    cells[*i] = Some(*v);
                }
            }
            if *multi {
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
        };
        match bytes {
            Some(b) => dec.feed(b, &mut each),
            None => dec.finish_frames(&mut each),
        }
        err.map(|()| n)
    }

    /// The counts so far.
    pub fn stats(&self) -> StreamStats {
        self.dec.stats()
    }

    /// The protocol decoded.
    pub fn plan(&self) -> &Plan {
        self.dec.plan()
    }
}

/// The counts in words, and for live input the time between frame arrivals (`gaps`, a
/// summary of their distribution).
pub fn tally(s: &StreamStats, gaps: Option<&str>) -> String {
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
    if let Some(g) = gaps {
        t += &format!(", inter-frame time {g}");
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::Simulation;

    /// A second of the circle as kvh1750 frames.
    fn frames() -> Vec<u8> {
        let mut bytes = Vec::new();
        Simulation::builder()
            .scene("circle")
            .format("kvh1750")
            .rate(200.0)
            .duration(1.0)
            .build()
            .unwrap()
            .write(&mut bytes)
            .unwrap();
        bytes
    }

    fn session(rate: Option<f64>) -> Session {
        let (_, plan) = crate::protocol::load("kvh1750").unwrap();
        let opts = Options {
            rate,
            ..Options::default()
        };
        Session::new(plan, opts)
    }

    /// The rows do not depend on how the bytes arrive: whole, or 7 bytes at a time (frames
    /// cut anywhere), with the same count and no row lost at the end.
    #[test]
    fn rows_do_not_depend_on_chunking() {
        let bytes = frames();
        let mut whole = Vec::new();
        let mut s = session(Some(200.0));
        let n = s.feed(&bytes, &mut whole).unwrap() + s.finish(&mut whole).unwrap();
        let mut pieces = Vec::new();
        let mut t = session(Some(200.0));
        let mut m = 0;
        for c in bytes.chunks(7) {
            m += t.feed(c, &mut pieces).unwrap();
        }
        m += t.finish(&mut pieces).unwrap();
        assert_eq!((n, m, s.stats().frames), (200, 200, 200));
        assert_eq!(whole, pieces);
        assert_eq!(String::from_utf8(whole).unwrap().lines().count(), 200);
    }

    /// Without a rate or time tags the derived columns stay empty, and the note says so.
    #[test]
    fn the_note_says_when_columns_stay_empty() {
        assert!(session(Some(200.0)).note().is_none());
        let note = session(None).note().unwrap();
        assert!(note.contains("left empty"), "{note}");
    }
}
