//! Cutting what arrives into messages: a datagram (one message, or a CSV line each), a
//! stream's lines (CSV, with over-long lines cut and skipped), a stream's binary datagrams or
//! MAVLink frames (found by magic or start byte, garbage between them skipped and counted).

use std::time::Instant;

use super::{Message, Place, Receiver};
use crate::live::csv::MAX_LINE_BYTES;
use crate::live::{InputFormat, binary, mavlink};

impl Receiver {
    /// Queues a datagram's messages: the datagram, or each of its CSV lines.
    pub(super) fn datagram(&mut self, b: Vec<u8>) {
        self.datagrams += 1;
        let n = self.datagrams;
        let arrival = Instant::now();
        if self.format != InputFormat::Csv {
            self.pending.push_back(Message {
                bytes: b,
                place: Place::Datagram(n, 0),
                arrival,
                connection: 0,
            });
            return;
        }
        for (l, line) in b.split(|&c| c == b'\n').enumerate() {
            if line.is_empty() {
                continue;
            }
            let kept = capped(line.len());
            self.skipped += (line.len() - kept) as u64;
            self.pending.push_back(Message {
                bytes: line[..kept].to_vec(),
                place: Place::Datagram(n, l as u64 + 1),
                arrival,
                connection: 0,
            });
        }
    }

    /// Cuts complete lines off the front of the buffer (everything at the end of input). A
    /// line longer than [`MAX_LINE_BYTES`] becomes a message of its first `MAX_LINE_BYTES + 1`
    /// bytes, which the decoder refuses as too long, as soon as that many are in; the rest of
    /// it is skipped and counted as it arrives, so the buffer never holds more than one
    /// read beyond the limit and every byte is searched for the line end once.
    pub(super) fn cut_lines(&mut self) {
        let arrival = Instant::now();
        let mut at = 0;
        loop {
            let rest = &self.buf[at..];
            if self.discarding {
                let (n, end) = match rest.iter().position(|&c| c == b'\n') {
                    Some(i) => (i + 1, true),
                    None => (rest.len(), false),
                };
                self.skipped += n as u64;
                at += n;
                self.discarding = !end;
                if !end {
                    break;
                }
                continue;
            }
            let from = self.scanned.min(rest.len());
            let len = match rest[from..].iter().position(|&c| c == b'\n') {
                Some(i) => from + i + 1,
                None if rest.len() > MAX_LINE_BYTES || (self.eof && !rest.is_empty()) => rest.len(),
                None => {
                    self.scanned = rest.len();
                    break;
                }
            };
            self.scanned = 0;
            let line = &rest[..len];
            let ended = line.last() == Some(&b'\n');
            let text = trim_line_end(line);
            let kept = capped(text.len());
            // A line beyond the limit is not one a simulation sends: its head goes to the
            // decoder, which refuses it, and the rest of it is skipped.
            self.skipped += (text.len() - kept) as u64;
            self.discarding = kept < text.len() && !ended && !self.eof;
            let bytes = text[..kept].to_vec();
            self.lines += 1;
            self.pending.push_back(Message {
                bytes,
                place: Place::Line(self.lines),
                arrival,
                connection: self.connections,
            });
            at += len;
        }
        self.buf.drain(..at);
        self.offset += at as u64;
    }

    /// Cuts complete binary datagrams or MAVLink frames off the front of the buffer
    /// (everything at the end of input).
    pub(super) fn cut_frames(&mut self) {
        let arrival = Instant::now();
        let datagrams = self.format == InputFormat::Binary;
        let mut at = 0;
        loop {
            let rest = &self.buf[at..];
            let (start, len) = if datagrams {
                match find(rest, &binary::MAGIC) {
                    // A candidate that fails its CRC and holds another magic is a damaged or
                    // short frame: it ends where the next one starts.
                    Some(s) if rest.len() >= s + binary::LEN && !binary::crc_ok(&rest[s..]) => {
                        let inner = find(&rest[s + 1..s + binary::LEN], &binary::MAGIC);
                        (s, inner.map_or(binary::LEN, |j| j + 1))
                    }
                    Some(s) => (s, binary::LEN),
                    None => (rest.len().saturating_sub(3), 0),
                }
            } else {
                match rest.iter().position(|&c| c == mavlink::STX) {
                    Some(s) => match mavlink::frame_len(&rest[s..]) {
                        Some(l) => (s, l),
                        None => (s, usize::MAX),
                    },
                    None => (rest.len(), 0),
                }
            };
            // Bytes before a frame's start are garbage; keep a possible partial magic.
            let start = if self.eof {
                start.min(rest.len())
            } else {
                start
            };
            self.skipped += start as u64;
            at += start;
            let rest = &self.buf[at..];
            if len == 0 || len == usize::MAX || rest.len() < len {
                if self.eof {
                    self.skipped += rest.len() as u64;
                    at = self.buf.len();
                }
                break;
            }
            self.pending.push_back(Message {
                bytes: rest[..len].to_vec(),
                place: Place::Byte(self.offset + at as u64),
                arrival,
                connection: self.connections,
            });
            at += len;
        }
        self.buf.drain(..at);
        self.offset += at as u64;
    }
}

/// Bytes of a line of `len` bytes a message keeps: all of them, or one past the limit so the
/// decoder sees that it is too long.
pub(super) fn capped(len: usize) -> usize {
    len.min(MAX_LINE_BYTES + 1)
}

fn trim_line_end(mut b: &[u8]) -> &[u8] {
    while let [rest @ .., b'\n' | b'\r'] = b {
        b = rest;
    }
    b
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}
