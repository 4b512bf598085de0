//! Live motion input for hardware-in-the-loop runs: states of a vehicle simulation arriving
//! over UDP, TCP, a pipe or a file, decoded ([`csv`], [`binary`], [`mavlink`]), checked and
//! counted ([`stats`]), fed to the causal motion model ([`crate::motion::causal`]), and turned
//! into records or frames in step with them ([`lockstep`]) or with the host clock
//! ([`realtime`], [`clockmap`]). docs/live-input.md is the user's
//! guide and specifies the binary datagram.
//!
//! Decoding is pure (bytes in, states out); [`transport`] is the only I/O.

pub mod binary;
pub mod clockmap;
pub mod csv;
pub mod lockstep;
pub mod mavlink;
pub mod realtime;
pub mod stats;
pub mod target;
pub mod transport;

use crate::motion::causal::LiveSample;

/// The wire format of the incoming states.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputFormat {
    /// Text lines with the trajectory CSV columns (and optional extras).
    Csv,
    /// The binary datagram of docs/live-input.md.
    Binary,
    /// MAVLink 2 `HIL_STATE_QUATERNION` (message 115).
    Mavlink,
}

impl InputFormat {
    /// The format named `csv`, `bin` or `mavlink`.
    pub fn from_name(name: &str) -> Option<InputFormat> {
        match name {
            "csv" => Some(InputFormat::Csv),
            "bin" | "binary" => Some(InputFormat::Binary),
            "mavlink" => Some(InputFormat::Mavlink),
            _ => None,
        }
    }
}

/// One decoded state and the sequence number it carried, if its format has one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decoded {
    /// The sender's sequence number (binary: 32 bits, MAVLink: 8 bits).
    pub seq: Option<u64>,
    /// The state.
    pub state: LiveSample,
}

/// A message that could not be decoded: what is wrong and where inside the message (byte
/// offset for binary formats, column for CSV).
#[derive(Clone, Debug, PartialEq)]
pub struct Malformed {
    /// Byte offset inside the message of the offending part (0 when the whole is wrong).
    pub offset: usize,
    /// What is wrong.
    pub message: String,
}

impl Malformed {
    fn at(offset: usize, message: impl Into<String>) -> Malformed {
        Malformed {
            offset,
            message: message.into(),
        }
    }
}

/// Decodes messages of one format; the CSV decoder remembers the last header.
pub struct Decoder {
    kind: Kind,
    epoch_week: u32,
}

enum Kind {
    Csv(Box<csv::CsvDecoder>),
    Binary,
    Mavlink,
}

impl Decoder {
    /// A decoder for `format`; GPS time tags become GPS seconds since the GPS epoch.
    pub fn new(format: InputFormat) -> Decoder {
        Decoder::since_week(format, 0)
    }

    /// A decoder for `format` whose GPS time tags (binary week + seconds, CSV
    /// `gps_week,gps_sow`) become seconds since the start of GPS week `epoch_week`: exact to
    /// 1e-10 s, where seconds since 1980 in an f64 resolve only 2.4e-7 s.
    pub fn since_week(format: InputFormat, epoch_week: u32) -> Decoder {
        let kind = match format {
            InputFormat::Csv => {
                let mut d = csv::CsvDecoder::default();
                d.epoch_week = epoch_week;
                Kind::Csv(Box::new(d))
            }
            InputFormat::Binary => Kind::Binary,
            InputFormat::Mavlink => Kind::Mavlink,
        };
        Decoder { kind, epoch_week }
    }

    /// True for CSV text (messages are lines).
    pub fn is_csv(&self) -> bool {
        matches!(self.kind, Kind::Csv(_))
    }

    /// The state in one message (one CSV line, datagram or frame); `None` for a message that
    /// carries none (a CSV header, comment or blank line; another MAVLink message).
    pub fn decode(&mut self, msg: &[u8]) -> Result<Option<Decoded>, Malformed> {
        match &mut self.kind {
            Kind::Csv(d) => d.decode(msg),
            Kind::Binary => binary::decode_since(msg, self.epoch_week).map(Some),
            Kind::Mavlink => mavlink::decode(msg),
        }
    }
}
