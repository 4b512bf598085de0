//! HDLC transports that wrap an IMU frame: asynchronous byte stuffing and synchronous SDLC bit
//! stuffing (ISO/IEC 13239), each with an encoder and a streaming, resynchronizing decoder.
//!
//! **Why two.** An asynchronous link (UART, PTY, UDP) carries whole bytes, so HDLC transparency
//! is done by *byte* stuffing (RFC 1662 style: `0x7E` flag, `0x7D` escape, XOR `0x20`). The
//! LN-200 and HG1700 class of IMUs instead speak *synchronous* SDLC: a clock line plus a data
//! line carrying a continuous bit stream with no byte boundaries, where transparency is
//! zero-bit insertion after five consecutive 1s and frames are delimited by the bit pattern
//! `01111110` at any bit offset.
//!
//! **What a synchronous-serial card delivers.** In HDLC mode a Commtech SyncCom/FSCC-class card
//! (the hardware the open LN-200 and HG1700 drivers use) finds the flags, removes stuffed zeros,
//! checks and optionally strips the FCS, and hands `read()` the de-framed frame bytes — the
//! "de-framed payload" mode (`protocols/ln200.toml`), which needs nothing from this module but the payload and,
//! optionally, its FCS. In transparent (bit-synchronous) mode, or on a logic analyser or an
//! FPGA/SDR test bench, one sees instead the raw line bits packed into bytes. [`sdlc_encode`]
//! produces that second form and [`SdlcDecoder`] consumes it.
//!
//! **Bit order.** HDLC/SDLC send each octet least-significant bit first (ISO/IEC 13239; that LN-200 words
//! arrive low byte first from an HDLC controller, as the open LN-200 driver reads them, follows
//! from it), and the FCS-16 (CRC-16/IBM-SDLC, reflected, final XOR 0xFFFF) is appended low byte first,
//! so that on the wire the FCS leaves highest-degree coefficient first. The packed stream is,
//! by default, packed LSB-first too: line bit *k* is bit `k % 8` of byte `k / 8`. With that
//! choice a byte-aligned flag reads `0x7E` and an unstuffed stretch of payload reads as the
//! payload bytes themselves, as a card in transparent LSB-first mode would show it;
//! [`BitOrder::MsbFirst`] packs the first bit into bit 7 instead (what many logic analysers
//! and SPI-based captures show).
//!
//! The decoders never panic on arbitrary input; they report aborted, overlong, short,
//! misaligned and FCS-failing frames as [`FrameError`]s and resynchronize on the next flag.

mod hdlc;
mod sdlc;

pub use hdlc::{ByteUnstuffer, EscapeSet, HdlcOptions, hdlc_encode, stuff_bytes};
pub use sdlc::{BitOrder, BitWriter, IdleFill, LineCode, SdlcDecoder, SdlcOptions, sdlc_encode};

use crc::Crc;
use serde::Deserialize;

/// The HDLC flag octet (`01111110`).
pub const FLAG: u8 = 0x7E;
/// The asynchronous-HDLC control-escape octet.
pub const ESCAPE: u8 = 0x7D;
/// XORed into an escaped octet.
pub const ESCAPE_XOR: u8 = 0x20;

static FCS16: Crc<u16> = Crc::<u16>::new(&crc::CRC_16_IBM_SDLC);
static FCS32: Crc<u32> = Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// The HDLC frame check sequence appended after the payload, low byte first.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
pub enum Fcs {
    /// No FCS (the payload carries its own check, or the card strips it).
    #[serde(rename = "none")]
    None,
    /// FCS-16 = CRC-16/IBM-SDLC (X.25), the standard HDLC FCS.
    #[default]
    #[serde(rename = "crc-16/ibm-sdlc", alias = "fcs-16")]
    Fcs16,
    /// FCS-32 = CRC-32/ISO-HDLC.
    #[serde(rename = "crc-32/iso-hdlc", alias = "fcs-32")]
    Fcs32,
}

impl Fcs {
    /// Length of the FCS in bytes.
    pub fn len(self) -> usize {
        match self {
            Fcs::None => 0,
            Fcs::Fcs16 => 2,
            Fcs::Fcs32 => 4,
        }
    }

    /// True for [`Fcs::None`].
    pub fn is_empty(self) -> bool {
        self == Fcs::None
    }

    /// The FCS of `payload` as transmitted: the CRC value little-endian, zero-padded to 4 bytes
    /// (only the first [`Fcs::len`] bytes are sent).
    pub fn bytes(self, payload: &[u8]) -> [u8; 4] {
        match self {
            Fcs::None => [0; 4],
            Fcs::Fcs16 => {
                let [a, b] = FCS16.checksum(payload).to_le_bytes();
                [a, b, 0, 0]
            }
            Fcs::Fcs32 => FCS32.checksum(payload).to_le_bytes(),
        }
    }
}

/// Why a received frame was rejected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// The sender aborted the frame (SDLC: seven or more 1s; async: `7D 7E`).
    #[error("frame aborted after {bytes} bytes")]
    Aborted {
        /// Whole bytes received before the abort.
        bytes: usize,
    },
    /// The FCS carried by the frame differs from the one computed over its payload.
    #[error("FCS mismatch: frame carries {carried:#x}, computed {computed:#x}")]
    FcsMismatch {
        /// FCS in the frame.
        carried: u32,
        /// FCS computed over the payload.
        computed: u32,
    },
    /// Fewer bytes between flags than FCS plus minimum payload.
    #[error("short frame: {len} bytes between flags, at least {min} needed")]
    ShortFrame {
        /// Bytes received.
        len: usize,
        /// Minimum.
        min: usize,
    },
    /// More bytes than the configured maximum before a closing flag.
    #[error("frame longer than {max} bytes")]
    Overlong {
        /// The configured maximum.
        max: usize,
    },
    /// SDLC: the bits between two flags are not a whole number of octets.
    #[error("frame of {bits} bits is not a whole number of octets")]
    NotOctetAligned {
        /// Bits received after removing stuffed zeros.
        bits: usize,
    },
    /// Async: an escape followed by a byte that cannot be escaped.
    #[error("invalid escape sequence 7D {0:02X}")]
    InvalidEscape(u8),
}

/// Splits off and verifies the FCS of a complete de-framed frame.
fn verify(frame: &[u8], fcs: Fcs, min_payload: usize) -> Result<&[u8], FrameError> {
    let min = fcs.len() + min_payload;
    if frame.len() < min {
        return Err(FrameError::ShortFrame {
            len: frame.len(),
            min,
        });
    }
    let (payload, carried) = frame.split_at(frame.len() - fcs.len());
    let (carried, computed) = match fcs {
        Fcs::None => return Ok(payload),
        Fcs::Fcs16 => (
            u16::from_le_bytes([carried[0], carried[1]]).into(),
            FCS16.checksum(payload).into(),
        ),
        Fcs::Fcs32 => (
            u32::from_le_bytes([carried[0], carried[1], carried[2], carried[3]]),
            FCS32.checksum(payload),
        ),
    };
    if carried == computed {
        Ok(payload)
    } else {
        Err(FrameError::FcsMismatch { carried, computed })
    }
}

#[cfg(test)]
mod tests;
