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
pub enum Decoder {
    /// CSV lines.
    Csv(Box<csv::CsvDecoder>),
    /// Binary datagrams.
    Binary,
    /// MAVLink frames.
    Mavlink,
}

impl Decoder {
    /// A decoder for `format`.
    pub fn new(format: InputFormat) -> Decoder {
        match format {
            InputFormat::Csv => Decoder::Csv(Box::default()),
            InputFormat::Binary => Decoder::Binary,
            InputFormat::Mavlink => Decoder::Mavlink,
        }
    }

    /// The state in one message (one CSV line, datagram or frame); `None` for a message that
    /// carries none (a CSV header, comment or blank line; another MAVLink message).
    pub fn decode(&mut self, msg: &[u8]) -> Result<Option<Decoded>, Malformed> {
        match self {
            Decoder::Csv(d) => d.decode(msg),
            Decoder::Binary => binary::decode(msg).map(Some),
            Decoder::Mavlink => mavlink::decode(msg),
        }
    }
}
