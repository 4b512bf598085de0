//! The time-mark side channel: per frame its record index, time of validity, and when it was
//! due and written, as a UDP datagram or a line (CSV) or record (binary) of a file — what a
//! receiver's event-time log or a rig's recorder matches the frames with.
//!
//! Binary record (one per datagram, or back to back in a file), 40 bytes little-endian:
//! `u64 index`, `i64 tov_sim_ns` (time of validity after the run's t₀ on the records' own
//! time axis, the truth's `tov`), `i64 tov_utc_ns`, `i64 due_utc_ns`, `i64 emit_utc_ns`
//! (CLOCK_REALTIME, ns since the Unix epoch: the time of validity, when the frame's first byte
//! was due, and when the pacer began writing it to the sinks). CSV has the same columns in that
//! order, with the header [`CSV_HEADER`].

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::net::UdpSocket;

use super::hook::{FrameHook, FrameTime};

/// Bytes of one binary time mark.
pub const MARK_LEN: usize = 40;

/// The CSV columns.
pub const CSV_HEADER: &str = "index,tov_sim_ns,tov_utc_ns,due_utc_ns,emit_utc_ns";

/// One time mark, instants in CLOCK_REALTIME ns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mark {
    /// Record index (0-based).
    pub index: u64,
    /// Time of validity after t₀ on the records' time axis (ns).
    pub tov_sim_ns: i64,
    /// Time of validity (UTC ns).
    pub tov_utc_ns: i64,
    /// When the first byte was due (UTC ns).
    pub due_utc_ns: i64,
    /// When the frame was handed to the sinks (UTC ns).
    pub emit_utc_ns: i64,
}

impl Mark {
    /// The 40-byte little-endian record.
    pub fn to_bytes(&self) -> [u8; MARK_LEN] {
        let mut b = [0u8; MARK_LEN];
        b[0..8].copy_from_slice(&self.index.to_le_bytes());
        for (i, v) in [
            self.tov_sim_ns,
            self.tov_utc_ns,
            self.due_utc_ns,
            self.emit_utc_ns,
        ]
        .iter()
        .enumerate()
        {
            b[8 + 8 * i..16 + 8 * i].copy_from_slice(&v.to_le_bytes());
        }
        b
    }

    /// Reads a 40-byte record; `None` if `b` is not 40 bytes.
    pub fn from_bytes(b: &[u8]) -> Option<Mark> {
        if b.len() != MARK_LEN {
            return None;
        }
        let f = |i: usize| i64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
        Some(Mark {
            index: f(0) as u64,
            tov_sim_ns: f(8),
            tov_utc_ns: f(16),
            due_utc_ns: f(24),
            emit_utc_ns: f(32),
        })
    }

    /// The CSV line (no newline).
    pub fn to_csv(&self) -> String {
        format!(
            "{},{},{},{},{}",
            self.index, self.tov_sim_ns, self.tov_utc_ns, self.due_utc_ns, self.emit_utc_ns
        )
    }
}

enum Out {
    Udp(UdpSocket),
    Csv(BufWriter<File>),
    Bin(BufWriter<File>),
}

/// The time-mark hook.
pub struct TimeMarks {
    out: Out,
    label: String,
    /// CLOCK_REALTIME − CLOCK_MONOTONIC (ns), from [`utc_minus_mono`].
    utc_minus_mono: i128,
}

/// CLOCK_REALTIME − CLOCK_MONOTONIC (ns), read once per process: every mark of every
/// `--time-marks` target uses the same conversion, so a UDP mark and the file's mark of the
/// same frame are equal to the nanosecond (two reads differ by the tens of ns between them).
fn utc_minus_mono() -> i128 {
    super::clock::host_offset().utc_minus_mono
}

impl TimeMarks {
    /// Marks to `udp://HOST:PORT`, or to a file (CSV when its name ends in `.csv`, else
    /// binary records).
    pub fn open(target: &str) -> io::Result<TimeMarks> {
        let out = match target.strip_prefix("udp://") {
            Some(dest) => {
                let sock = UdpSocket::bind("0.0.0.0:0")?;
                sock.connect(dest)
                    .map_err(|e| io::Error::new(e.kind(), format!("--time-marks {target}: {e}")))?;
                sock.set_nonblocking(true)?;
                Out::Udp(sock)
            }
            None => {
                let f = File::create(target)
                    .map_err(|e| io::Error::new(e.kind(), format!("creating {target}: {e}")))?;
                if target.ends_with(".csv") {
                    let mut w = BufWriter::new(f);
                    writeln!(w, "{CSV_HEADER}")?;
                    Out::Csv(w)
                } else {
                    Out::Bin(BufWriter::new(f))
                }
            }
        };
        Ok(TimeMarks {
            out,
            label: target.to_string(),
            utc_minus_mono: utc_minus_mono(),
        })
    }

    /// The mark of frame `f`.
    pub fn mark(&self, f: &FrameTime) -> Mark {
        let utc = |m: i128| (m + self.utc_minus_mono) as i64;
        Mark {
            index: f.index,
            tov_sim_ns: f.tov_sim_ns,
            tov_utc_ns: utc(f.tov_ns),
            due_utc_ns: utc(f.due_ns),
            emit_utc_ns: utc(f.written_ns),
        }
    }
}

impl FrameHook for TimeMarks {
    fn written(&mut self, f: &FrameTime) -> io::Result<()> {
        let m = self.mark(f);
        let r = match &mut self.out {
            // Nobody listening, or a full socket buffer, loses the mark, never the frame.
            Out::Udp(s) => {
                let _ = s.send(&m.to_bytes());
                Ok(())
            }
            Out::Csv(w) => writeln!(w, "{}", m.to_csv()),
            Out::Bin(w) => w.write_all(&m.to_bytes()),
        };
        r.map_err(|e| io::Error::new(e.kind(), format!("--time-marks {}: {e}", self.label)))
    }

    fn finish(&mut self) -> io::Result<()> {
        match &mut self.out {
            Out::Udp(_) => Ok(()),
            Out::Csv(w) | Out::Bin(w) => w
                .flush()
                .map_err(|e| io::Error::new(e.kind(), format!("--time-marks {}: {e}", self.label))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The binary record round-trips, with every field at its documented offset.
    #[test]
    fn binary_layout() {
        let m = Mark {
            index: 7,
            tov_sim_ns: -2,
            tov_utc_ns: 1 << 60,
            due_utc_ns: 3,
            emit_utc_ns: 4,
        };
        let b = m.to_bytes();
        assert_eq!(b[0], 7);
        assert_eq!(&b[8..16], &(-2i64).to_le_bytes());
        assert_eq!(b[16 + 7], 0x10);
        assert_eq!((b[24], b[32]), (3, 4));
        assert_eq!(Mark::from_bytes(&b), Some(m));
        assert_eq!(Mark::from_bytes(&b[..39]), None);
        assert_eq!(m.to_csv(), format!("7,-2,{},3,4", 1i64 << 60));
    }
}
