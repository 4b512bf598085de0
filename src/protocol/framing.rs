//! HDLC transports that wrap an IMU frame: asynchronous byte stuffing and synchronous SDLC bit
//! stuffing (PROTOCOLS.md §8), each with an encoder and a streaming, resynchronizing decoder.
//!
//! **Why two.** An asynchronous link (UART, PTY, UDP) carries whole bytes, so HDLC transparency
//! is done by *byte* stuffing (RFC 1662 style: `0x7E` flag, `0x7D` escape, XOR `0x20`). The
//! LN-200 and HG1700 class of IMUs instead speak *synchronous* SDLC: a clock line plus a data
//! line carrying a continuous bit stream with no byte boundaries, where transparency is
//! zero-bit insertion after five consecutive 1s and frames are delimited by the bit pattern
//! `01111110` at any bit offset (PROTOCOLS.md §1.1, §2.2, §8).
//!
//! **What a synchronous-serial card delivers.** In HDLC mode a Commtech SyncCom/FSCC-class card
//! (the hardware the open LN-200 and HG1700 drivers use) finds the flags, removes stuffed zeros,
//! checks and optionally strips the FCS, and hands `read()` the de-framed frame bytes — the
//! "de-framed payload" mode of §8, which needs nothing from this module but the payload and,
//! optionally, its FCS. In transparent (bit-synchronous) mode, or on a logic analyser or an
//! FPGA/SDR test bench, one sees instead the raw line bits packed into bytes. [`sdlc_encode`]
//! produces that second form and [`SdlcDecoder`] consumes it.
//!
//! **Bit order.** HDLC/SDLC send each octet least-significant bit first (ISO/IEC 13239; the
//! §1.1 observation that LN-200 words arrive low byte first from an HDLC controller follows from
//! it), and the FCS-16 (CRC-16/IBM-SDLC, reflected, final XOR 0xFFFF) is appended low byte first,
//! so that on the wire the FCS leaves highest-degree coefficient first. The packed stream is,
//! by default, packed LSB-first too: line bit *k* is bit `k % 8` of byte `k / 8`. With that
//! choice a byte-aligned flag reads `0x7E` and an unstuffed stretch of payload reads as the
//! payload bytes themselves, as a card in transparent LSB-first mode would show it;
//! [`BitOrder::MsbFirst`] packs the first bit into bit 7 instead (what many logic analysers
//! and SPI-based captures show).
//!
//! The decoders never panic on arbitrary input; they report aborted, overlong, short,
//! misaligned and FCS-failing frames as [`FrameError`]s and resynchronize on the next flag.

use crc::Crc;
use serde::{Deserialize, Deserializer};

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

// ---------------------------------------------------------------------------------------------
// Asynchronous HDLC: byte stuffing
// ---------------------------------------------------------------------------------------------

/// The set of bytes escaped by asynchronous HDLC (always `7E` and `7D`, plus extras).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EscapeSet([u64; 4]);

impl EscapeSet {
    /// Only the flag and the escape octet.
    pub const HDLC: EscapeSet = EscapeSet::empty().with(FLAG).with(ESCAPE);

    const fn empty() -> EscapeSet {
        EscapeSet([0; 4])
    }

    /// Whether `byte` can be escaped: not `0x5D`/`0x5E`, which would become `7D 7D` / `7D 7E`.
    pub const fn escapable(byte: u8) -> bool {
        !matches!(byte ^ ESCAPE_XOR, FLAG | ESCAPE)
    }

    /// This set plus `byte` (e.g. XON/XOFF `0x11`/`0x13`, or control characters for PPP).
    ///
    /// # Panics
    /// If `byte` is not [`EscapeSet::escapable`].
    pub const fn with(mut self, byte: u8) -> EscapeSet {
        assert!(
            EscapeSet::escapable(byte),
            "0x5D and 0x5E cannot be escaped"
        );
        self.0[(byte >> 6) as usize] |= 1 << (byte & 63);
        self
    }

    /// Whether `byte` is escaped.
    #[inline]
    pub const fn contains(&self, byte: u8) -> bool {
        self.0[(byte >> 6) as usize] >> (byte & 63) & 1 == 1
    }
}

impl Default for EscapeSet {
    fn default() -> EscapeSet {
        EscapeSet::HDLC
    }
}

/// Deserializes from the list of *extra* bytes to escape (`[0x11, 0x13]`).
impl<'de> Deserialize<'de> for EscapeSet {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let extra = Vec::<u8>::deserialize(d)?;
        if let Some(b) = extra.iter().find(|&&b| !EscapeSet::escapable(b)) {
            return Err(serde::de::Error::custom(format!(
                "byte {b:#04x} cannot be escaped (it would read as 7D {:02X})",
                b ^ ESCAPE_XOR
            )));
        }
        Ok(extra.into_iter().fold(EscapeSet::HDLC, EscapeSet::with))
    }
}

/// Options of asynchronous (byte-stuffed) HDLC framing, shared by encoder and decoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HdlcOptions {
    /// Bytes to escape: `7E`, `7D` and the extra ones listed as `extra_escapes = [..]`.
    #[serde(rename = "extra_escapes")]
    pub escapes: EscapeSet,
    /// Frame check sequence appended to the payload before stuffing.
    pub fcs: Fcs,
    /// Decoder: most bytes accepted between flags after unstuffing, FCS included.
    pub max_frame: usize,
    /// Decoder: fewest payload bytes of a valid frame (empty flag pairs are always skipped).
    pub min_payload: usize,
}

impl Default for HdlcOptions {
    fn default() -> HdlcOptions {
        HdlcOptions {
            escapes: EscapeSet::HDLC,
            fcs: Fcs::Fcs16,
            max_frame: 4096,
            min_payload: 1,
        }
    }
}

/// Appends `payload` byte-stuffed (no flags): each byte of `escapes` becomes `7D, byte ^ 0x20`.
pub fn stuff_bytes(payload: &[u8], escapes: &EscapeSet, out: &mut Vec<u8>) {
    out.reserve(payload.len() + payload.len() / 8 + 2);
    for &b in payload {
        if escapes.contains(b) {
            out.extend_from_slice(&[ESCAPE, b ^ ESCAPE_XOR]);
        } else {
            out.push(b);
        }
    }
}

/// Appends one asynchronous HDLC frame: flag, stuffed payload and FCS, flag.
pub fn hdlc_encode(payload: &[u8], opts: &HdlcOptions, out: &mut Vec<u8>) {
    out.push(FLAG);
    stuff_bytes(payload, &opts.escapes, out);
    stuff_bytes(
        &opts.fcs.bytes(payload)[..opts.fcs.len()],
        &opts.escapes,
        out,
    );
    out.push(FLAG);
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AsyncState {
    /// Waiting for a flag (start, or after an error).
    Hunt,
    /// Inside a frame.
    Frame,
    /// Inside a frame, after `7D`.
    Escaped,
}

/// Streaming asynchronous-HDLC decoder: yields unstuffed, FCS-checked payloads.
///
/// Bytes before the first flag are discarded; after an error it waits for the next flag. An
/// escape may precede any byte (extra escapes are accepted whatever the set); `7D 7E` is an
/// abort and `7D 7D` an invalid escape.
#[derive(Clone, Debug)]
pub struct ByteUnstuffer {
    opts: HdlcOptions,
    state: AsyncState,
    buf: Vec<u8>,
    clear_next: bool,
}

impl ByteUnstuffer {
    /// A decoder hunting for the first flag.
    pub fn new(opts: &HdlcOptions) -> ByteUnstuffer {
        ByteUnstuffer {
            opts: *opts,
            state: AsyncState::Hunt,
            buf: Vec::with_capacity(opts.max_frame.min(1 << 16)),
            clear_next: false,
        }
    }

    /// Forgets any partial frame and hunts for a flag.
    pub fn reset(&mut self) {
        self.state = AsyncState::Hunt;
        self.buf.clear();
        self.clear_next = false;
    }

    /// Feeds every byte of `data`, calling `on_frame` for each payload or rejected frame.
    pub fn feed(&mut self, data: &[u8], mut on_frame: impl FnMut(Result<&[u8], FrameError>)) {
        for &b in data {
            if let Some(r) = self.push(b) {
                on_frame(r);
            }
        }
    }

    /// Feeds one byte; returns a payload (borrowed until the next call) or an error when a
    /// frame ends.
    pub fn push(&mut self, b: u8) -> Option<Result<&[u8], FrameError>> {
        if self.clear_next {
            self.buf.clear();
            self.clear_next = false;
        }
        match (self.state, b) {
            (AsyncState::Hunt, FLAG) => {
                self.buf.clear();
                self.state = AsyncState::Frame;
                None
            }
            (AsyncState::Hunt, _) => None,
            (AsyncState::Frame, FLAG) => {
                if self.buf.is_empty() {
                    return None; // back-to-back or shared flags
                }
                self.clear_next = true;
                Some(verify(&self.buf, self.opts.fcs, self.opts.min_payload))
            }
            (AsyncState::Frame, ESCAPE) => {
                self.state = AsyncState::Escaped;
                None
            }
            (AsyncState::Frame, _) => self.append(b),
            (AsyncState::Escaped, FLAG) => {
                // The flag of an abort sequence opens the next frame.
                self.state = AsyncState::Frame;
                self.clear_next = true;
                Some(Err(FrameError::Aborted {
                    bytes: self.buf.len(),
                }))
            }
            (AsyncState::Escaped, ESCAPE) => {
                self.state = AsyncState::Hunt;
                self.clear_next = true;
                Some(Err(FrameError::InvalidEscape(ESCAPE)))
            }
            (AsyncState::Escaped, _) => {
                self.state = AsyncState::Frame;
                self.append(b ^ ESCAPE_XOR)
            }
        }
    }

    fn append(&mut self, b: u8) -> Option<Result<&[u8], FrameError>> {
        if self.buf.len() >= self.opts.max_frame {
            self.state = AsyncState::Hunt;
            self.clear_next = true;
            return Some(Err(FrameError::Overlong {
                max: self.opts.max_frame,
            }));
        }
        self.buf.push(b);
        None
    }
}

// ---------------------------------------------------------------------------------------------
// Synchronous SDLC: bit stuffing
// ---------------------------------------------------------------------------------------------

/// How line bits are packed into bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BitOrder {
    /// First bit on the line in bit 0 (HDLC order: byte-aligned data reads unchanged).
    #[default]
    LsbFirst,
    /// First bit on the line in bit 7.
    MsbFirst,
}

/// Line code of the synchronous data line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LineCode {
    /// Level = bit (what the ACFR HG1700 setup uses, PROTOCOLS.md §2.2).
    #[default]
    Nrz,
    /// IBM SDLC NRZI: a 0 toggles the level, a 1 keeps it.
    Nrzi,
}

/// What the line carries between frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IdleFill {
    /// Repeated flags (a bit count that is not a multiple of 8 ends with 1s).
    #[default]
    Flags,
    /// Continuous 1s (marking).
    Marks,
}

/// Options of synchronous SDLC framing, shared by encoder and decoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SdlcOptions {
    /// Frame check sequence appended to the payload.
    pub fcs: Fcs,
    /// Flags sent before each frame (at least 1).
    pub opening_flags: u32,
    /// Let the previous frame's closing flag open this frame when nothing came in between.
    pub share_flags: bool,
    /// Idle fill sent after each closing flag.
    pub idle: IdleFill,
    /// Bits of idle fill after each closing flag.
    pub idle_bits: u32,
    /// Packing of line bits into bytes.
    pub bit_order: BitOrder,
    /// Line code.
    pub line_code: LineCode,
    /// Decoder: most bytes accepted between flags after destuffing, FCS included.
    pub max_frame: usize,
    /// Decoder: fewest payload bytes of a valid frame (empty flag pairs are always skipped).
    pub min_payload: usize,
}

impl Default for SdlcOptions {
    fn default() -> SdlcOptions {
        SdlcOptions {
            fcs: Fcs::Fcs16,
            opening_flags: 1,
            share_flags: false,
            idle: IdleFill::Flags,
            idle_bits: 0,
            bit_order: BitOrder::LsbFirst,
            line_code: LineCode::Nrz,
            max_frame: 4096,
            min_payload: 1,
        }
    }
}

/// Packs a synchronous bit stream into bytes (in a `u64` shift register), applying the line
/// code; successive frames need not be byte-aligned.
#[derive(Clone, Debug)]
pub struct BitWriter {
    out: Vec<u8>,
    acc: u64,
    n: u32,
    order: BitOrder,
    line: LineCode,
    level: bool,
    after_flag: bool,
    bits: u64,
}

impl BitWriter {
    /// An empty stream; an NRZI line starts at the mark (1) level.
    pub fn new(order: BitOrder, line: LineCode) -> BitWriter {
        BitWriter {
            out: Vec::new(),
            acc: 0,
            n: 0,
            order,
            line,
            level: true,
            after_flag: false,
            bits: 0,
        }
    }

    /// An empty stream with the packing and line code of `opts`.
    pub fn for_options(opts: &SdlcOptions) -> BitWriter {
        BitWriter::new(opts.bit_order, opts.line_code)
    }

    /// Appends one data-level bit (before the line code).
    #[inline]
    fn push(&mut self, bit: bool) {
        let line = match self.line {
            LineCode::Nrz => bit,
            LineCode::Nrzi => {
                self.level ^= !bit;
                self.level
            }
        };
        self.acc |= u64::from(line) << self.n;
        self.n += 1;
        self.bits += 1;
        self.after_flag = false;
        if self.n == 64 {
            self.flush_whole_bytes();
        }
    }

    /// Moves the complete bytes of the shift register to `out`.
    fn flush_whole_bytes(&mut self) {
        let whole = self.n / 8;
        for _ in 0..whole {
            let b = self.acc as u8;
            self.out.push(match self.order {
                BitOrder::LsbFirst => b,
                BitOrder::MsbFirst => b.reverse_bits(),
            });
            self.acc >>= 8;
            self.n -= 8;
        }
    }

    /// Appends a flag `01111110` (never stuffed).
    pub fn write_flag(&mut self) {
        for i in 0..8 {
            self.push(FLAG >> i & 1 == 1);
        }
        self.after_flag = true;
    }

    /// Appends `bits` 1s (never stuffed).
    pub fn write_marks(&mut self, bits: u64) {
        for _ in 0..bits {
            self.push(true);
        }
    }

    /// Appends `bits` of idle fill: whole flags then 1s, or all 1s.
    pub fn write_idle(&mut self, fill: IdleFill, bits: u64) {
        match fill {
            IdleFill::Flags => {
                for _ in 0..bits / 8 {
                    self.write_flag();
                }
                self.write_marks(bits % 8);
            }
            IdleFill::Marks => self.write_marks(bits),
        }
    }

    /// Appends the payload bits LSB first with a 0 after every five consecutive 1s.
    fn write_stuffed(&mut self, bytes: &[u8], ones: &mut u32) {
        for &byte in bytes {
            for i in 0..8 {
                let bit = byte >> i & 1 == 1;
                self.push(bit);
                if bit {
                    *ones += 1;
                    if *ones == 5 {
                        self.push(false);
                        *ones = 0;
                    }
                } else {
                    *ones = 0;
                }
            }
        }
    }

    /// Bits written so far.
    pub fn bit_len(&self) -> u64 {
        self.bits
    }

    /// Whether the last bits written are a complete flag.
    pub fn ends_with_flag(&self) -> bool {
        self.after_flag
    }

    /// Moves the complete bytes written so far to `out`, keeping a partial byte for later.
    pub fn drain_into(&mut self, out: &mut Vec<u8>) {
        self.flush_whole_bytes();
        out.append(&mut self.out);
    }

    /// Completes the last byte with 1s (marks) and returns the bytes.
    pub fn finish(mut self) -> Vec<u8> {
        let pad = (8 - self.n % 8) % 8;
        self.write_marks(u64::from(pad));
        self.flush_whole_bytes();
        self.out
    }
}

/// Appends one SDLC frame to `w`: opening flag(s), payload and FCS bit-stuffed LSB first,
/// closing flag, then the idle fill of `opts`.
pub fn sdlc_encode(payload: &[u8], opts: &SdlcOptions, w: &mut BitWriter) {
    let mut flags = opts.opening_flags.max(1);
    if opts.share_flags && w.ends_with_flag() {
        flags -= 1;
    }
    for _ in 0..flags {
        w.write_flag();
    }
    let mut ones = 0;
    w.write_stuffed(payload, &mut ones);
    w.write_stuffed(&opts.fcs.bytes(payload)[..opts.fcs.len()], &mut ones);
    w.write_flag();
    w.write_idle(opts.idle, opts.idle_bits.into());
}

/// Streaming SDLC decoder over packed line bytes: finds flags at any bit offset, removes
/// stuffed zeros, checks the FCS and yields payloads or typed errors.
///
/// Destuffed bits wait in a `u64` shift register; at least the six most recent stay there so
/// that the start of a closing flag (`0` + five `1`s, taken for data until the sixth `1`) can
/// be withdrawn. Seven 1s inside a frame abort it (silently if no data bit preceded them, which
/// is how marking idle after a closing flag looks); fewer than eight 1s between two flags are
/// interframe fill and are skipped silently too.
#[derive(Clone, Debug)]
pub struct SdlcDecoder {
    opts: SdlcOptions,
    in_frame: bool,
    ones: u32,
    zero_before_run: bool,
    acc: u64,
    nacc: u32,
    buf: Vec<u8>,
    level: bool,
}

/// Destuffed bits kept back in the shift register (the longest flag prefix taken for data).
const HOLD_BITS: u32 = 6;

impl SdlcDecoder {
    /// A decoder hunting for the first flag.
    pub fn new(opts: &SdlcOptions) -> SdlcDecoder {
        SdlcDecoder {
            opts: *opts,
            in_frame: false,
            ones: 0,
            zero_before_run: false,
            acc: 0,
            nacc: 0,
            buf: Vec::with_capacity(opts.max_frame.min(1 << 16)),
            level: true,
        }
    }

    /// Forgets any partial frame and hunts for a flag.
    pub fn reset(&mut self) {
        self.in_frame = false;
        self.ones = 0;
        self.zero_before_run = false;
        self.acc = 0;
        self.nacc = 0;
        self.buf.clear();
        self.level = true;
    }

    /// Feeds packed line bytes, calling `on_frame` for each payload or rejected frame.
    pub fn feed(&mut self, data: &[u8], mut on_frame: impl FnMut(Result<&[u8], FrameError>)) {
        for &byte in data {
            let byte = match self.opts.bit_order {
                BitOrder::LsbFirst => byte,
                BitOrder::MsbFirst => byte.reverse_bits(),
            };
            for i in 0..8 {
                let line = byte >> i & 1 == 1;
                let bit = match self.opts.line_code {
                    LineCode::Nrz => line,
                    LineCode::Nrzi => {
                        let bit = line == self.level;
                        self.level = line;
                        bit
                    }
                };
                self.bit(bit, &mut on_frame);
            }
        }
    }

    /// Processes one data-level bit.
    #[inline]
    fn bit(&mut self, bit: bool, f: &mut impl FnMut(Result<&[u8], FrameError>)) {
        if bit {
            self.ones = self.ones.saturating_add(1);
            if !self.in_frame {
                return;
            }
            match self.ones {
                1..=5 => self.append(true, f),
                6 => {} // a flag or an abort: decided by the next bit
                _ => {
                    // Seven 1s. The five 1s taken for data are not data.
                    let bits = self.frame_bits().saturating_sub(5);
                    if bits > 0 {
                        f(Err(FrameError::Aborted { bytes: bits / 8 }));
                    }
                    self.in_frame = false;
                }
            }
        } else {
            let ones = std::mem::replace(&mut self.ones, 0);
            match ones {
                6 => self.flag(f),
                _ if !self.in_frame => {}
                5 => self.zero_before_run = false, // stuffed zero
                _ => {
                    self.append(false, f);
                    self.zero_before_run = true;
                }
            }
        }
    }

    /// Destuffed bits of the current frame.
    fn frame_bits(&self) -> usize {
        self.buf.len() * 8 + self.nacc as usize
    }

    fn append(&mut self, bit: bool, f: &mut impl FnMut(Result<&[u8], FrameError>)) {
        self.acc |= u64::from(bit) << self.nacc;
        self.nacc += 1;
        if self.nacc >= 8 + HOLD_BITS {
            if self.buf.len() >= self.opts.max_frame {
                f(Err(FrameError::Overlong {
                    max: self.opts.max_frame,
                }));
                self.in_frame = false;
                return;
            }
            self.buf.push(self.acc as u8);
            self.acc >>= 8;
            self.nacc -= 8;
        }
    }

    /// A flag: closes the current frame, if any, and opens the next.
    fn flag(&mut self, f: &mut impl FnMut(Result<&[u8], FrameError>)) {
        if self.in_frame {
            // Withdraw the flag's five 1s, and its leading 0 if that was taken for data.
            let withdraw = 5 + u32::from(self.zero_before_run);
            debug_assert!(self.nacc >= withdraw);
            self.nacc = self.nacc.saturating_sub(withdraw);
            let bits = self.frame_bits();
            let fill = (1u64 << bits.min(8)) - 1;
            if bits == 0 || (bits < 8 && self.acc & fill == fill) {
                // Back-to-back or shared flags, or a few marks of interframe fill.
            } else if self.nacc % 8 != 0 {
                f(Err(FrameError::NotOctetAligned { bits }));
            } else if self.buf.len() + (self.nacc / 8) as usize > self.opts.max_frame {
                f(Err(FrameError::Overlong {
                    max: self.opts.max_frame,
                }));
            } else {
                while self.nacc >= 8 {
                    self.buf.push(self.acc as u8);
                    self.acc >>= 8;
                    self.nacc -= 8;
                }
                f(verify(&self.buf, self.opts.fcs, self.opts.min_payload));
            }
        }
        self.in_frame = true;
        self.buf.clear();
        self.acc = 0;
        self.nacc = 0;
        self.zero_before_run = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SplitMix64: a tiny deterministic PRNG for property loops.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }
        fn below(&mut self, n: u64) -> u64 {
            self.next() % n
        }
        fn byte(&mut self) -> u8 {
            self.next() as u8
        }
        fn coin(&mut self) -> bool {
            self.next() & 1 == 1
        }
    }

    /// A payload of 1..=max bytes rich in bytes that stress stuffing (runs of FF, 7E, 7D, 1F).
    fn payload(rng: &mut Rng, max: u64) -> Vec<u8> {
        const SPECIAL: [u8; 8] = [0xFF, 0x7E, 0x7D, 0x1F, 0xF8, 0x3F, 0xFC, 0x00];
        let len = 1 + rng.below(max) as usize;
        let mut p = Vec::with_capacity(len);
        while p.len() < len {
            let b = match rng.below(4) {
                0 | 1 => SPECIAL[rng.below(8) as usize],
                _ => rng.byte(),
            };
            let run = if rng.below(4) == 0 {
                1 + rng.below(9)
            } else {
                1
            };
            for _ in 0..run {
                p.push(b);
            }
        }
        p.truncate(len);
        p
    }

    fn fcs_of(rng: &mut Rng) -> Fcs {
        [Fcs::None, Fcs::Fcs16, Fcs::Fcs32][rng.below(3) as usize]
    }

    fn decode_async(opts: &HdlcOptions, data: &[u8]) -> Vec<Result<Vec<u8>, FrameError>> {
        let mut d = ByteUnstuffer::new(opts);
        let mut out = Vec::new();
        d.feed(data, |r| out.push(r.map(<[u8]>::to_vec)));
        out
    }

    fn decode_sdlc(opts: &SdlcOptions, data: &[u8]) -> Vec<Result<Vec<u8>, FrameError>> {
        let mut d = SdlcDecoder::new(opts);
        let mut out = Vec::new();
        d.feed(data, |r| out.push(r.map(<[u8]>::to_vec)));
        out
    }

    // ----- FCS -----------------------------------------------------------------------------

    /// The FCS is appended low byte first: running the register over payload + FCS without the
    /// final XOR leaves the standard "good FCS" residues 0xF0B8 (RFC 1662) and 0xDEBB20E3.
    #[test]
    fn fcs_byte_order_gives_good_residue() {
        let residue16 = Crc::<u16>::new(&crc::CRC_16_MCRF4XX);
        let residue32 = Crc::<u32>::new(&crc::CRC_32_JAMCRC);
        let mut rng = Rng(7);
        for _ in 0..200 {
            let p = payload(&mut rng, 40);
            let mut f = p.clone();
            f.extend_from_slice(&Fcs::Fcs16.bytes(&p)[..2]);
            assert_eq!(residue16.checksum(&f), 0xF0B8);
            let mut f = p.clone();
            f.extend_from_slice(&Fcs::Fcs32.bytes(&p));
            assert_eq!(residue32.checksum(&f), 0xDEBB_20E3);
        }
        assert_eq!(FCS16.checksum(b"123456789"), 0x906E);
    }

    // ----- async HDLC ----------------------------------------------------------------------

    #[test]
    fn stuffing_hand_vectors() {
        let mut out = Vec::new();
        stuff_bytes(&[0x7E, 0x01, 0x7D, 0x20, 0x11], &EscapeSet::HDLC, &mut out);
        assert_eq!(out, [0x7D, 0x5E, 0x01, 0x7D, 0x5D, 0x20, 0x11]);
        out.clear();
        stuff_bytes(
            &[0x11, 0x13, 0x12],
            &EscapeSet::HDLC.with(0x11).with(0x13),
            &mut out,
        );
        assert_eq!(out, [0x7D, 0x31, 0x7D, 0x33, 0x12]);
        let opts = HdlcOptions {
            fcs: Fcs::None,
            ..HdlcOptions::default()
        };
        out.clear();
        hdlc_encode(&[0x7E], &opts, &mut out);
        assert_eq!(out, [0x7E, 0x7D, 0x5E, 0x7E]);
    }

    #[test]
    fn async_round_trip_property() {
        let mut rng = Rng(1);
        for _ in 0..3000 {
            let mut escapes = EscapeSet::HDLC;
            for _ in 0..rng.below(4) {
                let b = rng.byte();
                if EscapeSet::escapable(b) {
                    escapes = escapes.with(b);
                }
            }
            let opts = HdlcOptions {
                escapes,
                fcs: fcs_of(&mut rng),
                ..HdlcOptions::default()
            };
            let frames: Vec<Vec<u8>> = (0..1 + rng.below(3))
                .map(|_| payload(&mut rng, 80))
                .collect();
            let mut wire = Vec::new();
            for p in &frames {
                hdlc_encode(p, &opts, &mut wire);
                if rng.coin() {
                    wire.push(FLAG); // extra idle flag
                }
            }
            // Outside escape sequences, only flags come from the escape set.
            let mut i = 0;
            while i < wire.len() {
                match wire[i] {
                    ESCAPE => i += 2,
                    b => {
                        assert!(b == FLAG || !escapes.contains(b), "unescaped {b:#x}");
                        i += 1;
                    }
                }
            }
            let got = decode_async(&opts, &wire);
            let want: Vec<_> = frames.into_iter().map(Ok).collect();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn async_resyncs_after_garbage() {
        let mut rng = Rng(2);
        let opts = HdlcOptions {
            fcs: Fcs::Fcs32,
            max_frame: 300,
            ..HdlcOptions::default()
        };
        for _ in 0..1000 {
            let mut wire: Vec<u8> = (0..rng.below(400)).map(|_| rng.byte()).collect();
            let frames: Vec<Vec<u8>> = (0..1 + rng.below(3))
                .map(|_| payload(&mut rng, 60))
                .collect();
            for p in &frames {
                hdlc_encode(p, &opts, &mut wire);
            }
            let oks: Vec<Vec<u8>> = decode_async(&opts, &wire)
                .into_iter()
                .filter_map(Result::ok)
                .collect();
            assert_eq!(oks, frames);
        }
    }

    #[test]
    fn async_errors() {
        let o16 = HdlcOptions::default();
        // Abort: 7D 7E; the abort's flag opens the next frame.
        let mut wire = vec![FLAG, 1, 2, ESCAPE, FLAG];
        hdlc_encode(&[9], &o16, &mut wire);
        wire.remove(5); // share the abort's flag as the opening flag
        assert_eq!(
            decode_async(&o16, &wire),
            [Err(FrameError::Aborted { bytes: 2 }), Ok(vec![9])]
        );
        // Invalid escape, then resync.
        let mut wire = vec![FLAG, 1, ESCAPE, ESCAPE, 3];
        hdlc_encode(&[4, 5], &o16, &mut wire);
        assert_eq!(
            decode_async(&o16, &wire),
            [Err(FrameError::InvalidEscape(ESCAPE)), Ok(vec![4, 5])]
        );
        // Short: one byte cannot hold FCS-16 + 1 payload byte.
        assert_eq!(
            decode_async(&o16, &[FLAG, 0x55, FLAG]),
            [Err(FrameError::ShortFrame { len: 1, min: 3 })]
        );
        // FCS mismatch.
        let mut wire = Vec::new();
        hdlc_encode(&[1, 2, 3], &o16, &mut wire);
        wire[2] ^= 0x01;
        assert!(matches!(
            decode_async(&o16, &wire)[..],
            [Err(FrameError::FcsMismatch { .. })]
        ));
        // Overlong, then resync on the closing flag.
        let small = HdlcOptions {
            max_frame: 4,
            fcs: Fcs::None,
            ..o16
        };
        let mut wire = Vec::new();
        hdlc_encode(&[1, 2, 3, 4, 5], &small, &mut wire);
        hdlc_encode(&[6, 7, 8, 9], &small, &mut wire);
        assert_eq!(
            decode_async(&small, &wire),
            [Err(FrameError::Overlong { max: 4 }), Ok(vec![6, 7, 8, 9])]
        );
        // Garbage before the first flag is ignored; empty flag pairs are skipped.
        let mut wire = vec![1, 2, ESCAPE, 3, FLAG, FLAG, FLAG];
        hdlc_encode(&[7], &o16, &mut wire);
        assert_eq!(decode_async(&o16, &wire), [Ok(vec![7])]);
    }

    #[test]
    fn async_garbage_never_panics() {
        let mut rng = Rng(3);
        for _ in 0..300 {
            let opts = HdlcOptions {
                fcs: fcs_of(&mut rng),
                max_frame: 1 + rng.below(64) as usize,
                min_payload: rng.below(3) as usize,
                ..HdlcOptions::default()
            };
            let mut d = ByteUnstuffer::new(&opts);
            let data: Vec<u8> = (0..2000)
                .map(|_| match rng.below(8) {
                    0 => FLAG,
                    1 => ESCAPE,
                    _ => rng.byte(),
                })
                .collect();
            let mut n = 0;
            d.feed(&data, |r| {
                if let Ok(p) = r {
                    assert!(p.len() + opts.fcs.len() <= opts.max_frame);
                }
                n += 1;
            });
            assert!(n <= data.len());
        }
    }

    #[test]
    fn options_deserialize() {
        let o: HdlcOptions =
            toml::from_str("extra_escapes = [0x11, 0x13]\nfcs = \"fcs-32\"\nmax_frame = 100")
                .unwrap();
        assert!(o.escapes.contains(0x11) && o.escapes.contains(0x7E) && !o.escapes.contains(0x12));
        assert_eq!(o.fcs, Fcs::Fcs32);
        assert_eq!(o.max_frame, 100);
        let e = toml::from_str::<HdlcOptions>("extra_escapes = [0x5e]").unwrap_err();
        assert!(e.to_string().contains("cannot be escaped"), "{e}");
        let s: SdlcOptions = toml::from_str(
            "fcs = \"none\"\nidle = \"marks\"\nidle_bits = 12\nbit_order = \"msb-first\"\nline_code = \"nrzi\"",
        )
        .unwrap();
        assert_eq!(s.fcs, Fcs::None);
        assert_eq!(s.idle, IdleFill::Marks);
        assert_eq!(s.bit_order, BitOrder::MsbFirst);
        assert_eq!(s.line_code, LineCode::Nrzi);
        assert_eq!(s.opening_flags, 1);
        assert!(toml::from_str::<SdlcOptions>("flags = 2").is_err());
    }

    // ----- SDLC ----------------------------------------------------------------------------

    /// Hand-computed: payload FF, no FCS. Line bits: flag 0 1111110, data 11111 0 111, flag,
    /// then marks to the byte boundary; packed LSB-first → 7E DF FD FE.
    #[test]
    fn sdlc_hand_vector() {
        let opts = SdlcOptions {
            fcs: Fcs::None,
            ..SdlcOptions::default()
        };
        let mut w = BitWriter::for_options(&opts);
        sdlc_encode(&[0xFF], &opts, &mut w);
        assert_eq!(w.bit_len(), 25);
        assert_eq!(w.finish(), [0x7E, 0xDF, 0xFD, 0xFE]);
        let msb = SdlcOptions {
            bit_order: BitOrder::MsbFirst,
            ..opts
        };
        let mut w = BitWriter::for_options(&msb);
        sdlc_encode(&[0xFF], &msb, &mut w);
        let bytes = w.finish();
        assert_eq!(bytes, [0x7E, 0xFB, 0xBF, 0x7F]);
        assert_eq!(decode_sdlc(&msb, &bytes), [Ok(vec![0xFF])]);
        // Byte-aligned unstuffed data reads unchanged: 7E 41 42 7E.
        let mut w = BitWriter::for_options(&opts);
        sdlc_encode(b"AB", &opts, &mut w);
        assert_eq!(w.finish(), [0x7E, 0x41, 0x42, 0x7E]);
    }

    fn random_sdlc_opts(rng: &mut Rng) -> SdlcOptions {
        SdlcOptions {
            fcs: fcs_of(rng),
            opening_flags: 1 + rng.below(3) as u32,
            share_flags: rng.coin(),
            idle: if rng.coin() {
                IdleFill::Flags
            } else {
                IdleFill::Marks
            },
            idle_bits: rng.below(30) as u32,
            bit_order: if rng.coin() {
                BitOrder::LsbFirst
            } else {
                BitOrder::MsbFirst
            },
            line_code: if rng.below(4) == 0 {
                LineCode::Nrzi
            } else {
                LineCode::Nrz
            },
            ..SdlcOptions::default()
        }
    }

    /// decode(encode(x)) == x for random payloads and options, with the first frame starting at
    /// every bit offset 0..16 (a prefix of idle 1s) and several frames per stream.
    #[test]
    fn sdlc_round_trip_property_every_offset() {
        let mut rng = Rng(4);
        for i in 0..2000 {
            let opts = random_sdlc_opts(&mut rng);
            let frames: Vec<Vec<u8>> = (0..1 + rng.below(3))
                .map(|_| payload(&mut rng, 64))
                .collect();
            let offset = i % 16;
            let mut w = BitWriter::for_options(&opts);
            w.write_marks(offset);
            for p in &frames {
                sdlc_encode(p, &opts, &mut w);
            }
            let mut bytes = Vec::new();
            w.drain_into(&mut bytes);
            let bytes = {
                let mut rest = w.finish();
                bytes.append(&mut rest);
                bytes
            };
            let got = decode_sdlc(&opts, &bytes);
            let want: Vec<_> = frames.into_iter().map(Ok).collect();
            assert_eq!(got, want, "case {i} {opts:?}");
        }
    }

    /// Streaming: encoding frame by frame and draining whole bytes, then decoding in random
    /// chunks, gives the same frames.
    #[test]
    fn sdlc_streaming_chunks() {
        let mut rng = Rng(5);
        let opts = SdlcOptions {
            share_flags: true,
            ..SdlcOptions::default()
        };
        let mut w = BitWriter::for_options(&opts);
        let mut wire = Vec::new();
        let mut frames = Vec::new();
        for _ in 0..500 {
            let p = payload(&mut rng, 40);
            sdlc_encode(&p, &opts, &mut w);
            w.write_marks(rng.below(3)); // non-byte-aligned gaps
            w.drain_into(&mut wire);
            frames.push(p);
        }
        wire.extend(w.finish());
        let mut d = SdlcDecoder::new(&opts);
        let mut got = Vec::new();
        let mut rest = &wire[..];
        while !rest.is_empty() {
            let (a, b) = rest.split_at((1 + rng.below(50) as usize).min(rest.len()));
            d.feed(a, |r| got.push(r.unwrap().to_vec()));
            rest = b;
        }
        assert_eq!(got, frames);
    }

    /// Writes a flag, raw (unstuffed) bits, and returns the writer.
    fn raw(opts: &SdlcOptions, bits: &[u8]) -> BitWriter {
        let mut w = BitWriter::for_options(opts);
        w.write_flag();
        for &b in bits {
            w.push(b == 1);
        }
        w
    }

    #[test]
    fn sdlc_errors() {
        let o16 = SdlcOptions::default();
        // Abort: data then seven 1s; the next frame still decodes.
        let mut w = raw(&o16, &[1, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1]);
        w.write_marks(9);
        sdlc_encode(&[0x42], &o16, &mut w);
        assert_eq!(
            decode_sdlc(&o16, &w.finish()),
            [Err(FrameError::Aborted { bytes: 1 }), Ok(vec![0x42])]
        );
        // Marking idle right after a closing flag is not an abort.
        let mut w = BitWriter::for_options(&o16);
        sdlc_encode(&[1], &o16, &mut w);
        w.write_marks(40);
        sdlc_encode(&[2], &o16, &mut w);
        assert_eq!(decode_sdlc(&o16, &w.finish()), [Ok(vec![1]), Ok(vec![2])]);
        // Not octet aligned: 3 bits between flags.
        let mut w = raw(&o16, &[1, 0, 1]);
        w.write_flag();
        assert_eq!(
            decode_sdlc(&o16, &w.finish()),
            [Err(FrameError::NotOctetAligned { bits: 3 })]
        );
        // Short: one byte with FCS-16 configured.
        let none = SdlcOptions {
            fcs: Fcs::None,
            ..o16
        };
        let mut w = BitWriter::for_options(&none);
        sdlc_encode(&[0x55], &none, &mut w);
        assert_eq!(
            decode_sdlc(&o16, &w.finish()),
            [Err(FrameError::ShortFrame { len: 1, min: 3 })]
        );
        // FCS mismatch: the same bytes with a wrong FCS.
        let mut w = BitWriter::for_options(&none);
        sdlc_encode(&[1, 2, 3, 0x00, 0x00], &none, &mut w);
        assert!(matches!(
            decode_sdlc(&o16, &w.finish())[..],
            [Err(FrameError::FcsMismatch { .. })]
        ));
        // Overlong (5 bytes > 4), then a frame of exactly 4 bytes is accepted.
        let small = SdlcOptions {
            max_frame: 4,
            ..none
        };
        let mut w = BitWriter::for_options(&small);
        sdlc_encode(&[0xFF; 5], &small, &mut w);
        sdlc_encode(&[0xFF; 4], &small, &mut w);
        assert_eq!(
            decode_sdlc(&small, &w.finish()),
            [Err(FrameError::Overlong { max: 4 }), Ok(vec![0xFF; 4])]
        );
        // Shared flags and repeated flags produce no empty frames.
        let shared = SdlcOptions {
            share_flags: true,
            opening_flags: 3,
            idle: IdleFill::Flags,
            idle_bits: 20,
            ..o16
        };
        let mut w = BitWriter::for_options(&shared);
        for p in [&[1u8][..], &[2, 3], &[0x7E, 0x7E]] {
            sdlc_encode(p, &shared, &mut w);
        }
        assert_eq!(
            decode_sdlc(&shared, &w.finish()),
            [Ok(vec![1]), Ok(vec![2, 3]), Ok(vec![0x7E, 0x7E])]
        );
    }

    /// A closing flag right after a stuffed zero: data ending in five 1s.
    #[test]
    fn sdlc_stuffed_zero_before_flag() {
        let opts = SdlcOptions {
            fcs: Fcs::None,
            ..SdlcOptions::default()
        };
        for p in [[0x1F], [0xF8], [0x3E], [0x7C]] {
            let mut w = BitWriter::for_options(&opts);
            sdlc_encode(&p, &opts, &mut w);
            assert_eq!(decode_sdlc(&opts, &w.finish()), [Ok(p.to_vec())], "{p:x?}");
        }
    }

    #[test]
    fn sdlc_garbage_never_panics() {
        let mut rng = Rng(6);
        for _ in 0..300 {
            let mut opts = random_sdlc_opts(&mut rng);
            opts.max_frame = 1 + rng.below(64) as usize;
            opts.min_payload = rng.below(3) as usize;
            let mut d = SdlcDecoder::new(&opts);
            let data: Vec<u8> = (0..1000)
                .map(|_| match rng.below(6) {
                    0 => FLAG,
                    1 => 0xFF,
                    _ => rng.byte(),
                })
                .collect();
            d.feed(&data, |r| {
                if let Ok(p) = r {
                    assert!(p.len() + opts.fcs.len() <= opts.max_frame);
                }
            });
        }
        // Bit errors in valid streams: never a panic.
        for _ in 0..1000 {
            let opts = random_sdlc_opts(&mut rng);
            let mut w = BitWriter::for_options(&opts);
            for _ in 0..3 {
                sdlc_encode(&payload(&mut rng, 30), &opts, &mut w);
            }
            let mut bytes = w.finish();
            for _ in 0..1 + rng.below(3) {
                let k = rng.below(bytes.len() as u64 * 8);
                bytes[(k / 8) as usize] ^= 1 << (k % 8);
            }
            let mut d = SdlcDecoder::new(&opts);
            d.feed(&bytes, |_| {});
            d.reset();
            d.feed(&bytes[bytes.len() / 2..], |_| {});
        }
    }
}
