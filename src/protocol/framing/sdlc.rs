//! Synchronous SDLC: zero-bit insertion, flags at any bit offset, line bits packed into bytes,
//! and its streaming decoder.

use serde::Deserialize;

use super::{FLAG, Fcs, FrameError, verify};

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
    /// Level = bit (what the ACFR HG1700 driver's setup uses).
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
    pub(super) fn push(&mut self, bit: bool) {
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

    /// Destuffed bits of a frame begun and not yet closed by a flag (a frame cut short if the
    /// input ends here; up to 7 are the idle marks that pad a stream to a byte boundary).
    pub fn pending_bits(&self) -> usize {
        if self.in_frame { self.frame_bits() } else { 0 }
    }

    /// Feeds packed line bytes, calling `on_frame` for each payload or rejected frame.
    pub fn feed(&mut self, data: &[u8], mut on_frame: impl FnMut(Result<&[u8], FrameError>)) {
        for &byte in data {
            let byte = match self.opts.bit_order {
                BitOrder::LsbFirst => byte,
                BitOrder::MsbFirst => byte.reverse_bits(),
            };
            if self.in_frame || !self.hunt(byte) {
                self.bits_of(byte, &mut on_frame);
            }
        }
    }

    /// One line byte (LSB first), bit by bit.
    fn bits_of(&mut self, byte: u8, on_frame: &mut impl FnMut(Result<&[u8], FrameError>)) {
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
            self.bit(bit, on_frame);
        }
    }

    /// Out of a frame, a line byte (LSB first) that completes no flag changes only the run of
    /// 1s and the NRZI level: taken whole, for a hunt through garbage or idle fill at memory
    /// speed rather than bit by bit. False, with nothing changed, when it may complete a flag.
    fn hunt(&mut self, line: u8) -> bool {
        let data = match self.opts.line_code {
            LineCode::Nrz => line,
            // A 1 is a line level equal to the bit's before.
            LineCode::Nrzi => !(line ^ (line << 1 | u8::from(self.level))),
        };
        let lead = data.trailing_ones();
        // A flag is a 0 after exactly six 1s: at the byte's first 0, counting the run carried
        // in, or within the byte (0 111111 0).
        if lead < 8 && self.ones.saturating_add(lead) == 6 || data == FLAG {
            return false;
        }
        self.ones = match lead {
            8 => self.ones.saturating_add(8),
            _ => data.leading_ones(),
        };
        if self.opts.line_code == LineCode::Nrzi {
            self.level = line >> 7 == 1;
        }
        true
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
            } else if !self.nacc.is_multiple_of(8) {
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

    /// Taking a hunted byte whole is taking it bit by bit: for every byte, run of 1s carried
    /// in and NRZI level, either the byte is left to the bits (it may complete a flag) or
    /// both ways end in the same state, out of a frame, with nothing reported.
    #[test]
    fn a_byte_taken_whole_is_its_bits() {
        for line_code in [LineCode::Nrz, LineCode::Nrzi] {
            let opts = SdlcOptions {
                line_code,
                ..SdlcOptions::default()
            };
            for ones in (0..=9).chain([200, u32::MAX]) {
                for level in [false, true] {
                    for byte in 0..=255u8 {
                        let mut slow = SdlcDecoder::new(&opts);
                        (slow.ones, slow.level) = (ones, level);
                        let mut fast = slow.clone();
                        let mut reported = 0;
                        slow.bits_of(byte, &mut |_| reported += 1);
                        let state = |d: &SdlcDecoder| (d.in_frame, d.ones, d.level);
                        if fast.hunt(byte) {
                            let at = (line_code, ones, level, byte);
                            assert_eq!(state(&fast), state(&slow), "{at:?}");
                            assert_eq!(reported, 0, "{at:?}");
                        } else {
                            assert_eq!((fast.ones, fast.level), (ones, level));
                        }
                    }
                }
            }
        }
    }
}
