//! Asynchronous HDLC: byte stuffing (RFC 1662 style) and its streaming decoder.

use serde::{Deserialize, Deserializer};

use super::{ESCAPE, ESCAPE_XOR, FLAG, Fcs, FrameError, verify};

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

    /// Bytes of a frame begun and not yet closed by a flag (a frame cut short if the input ends
    /// here).
    pub fn pending(&self) -> usize {
        if self.clear_next {
            // The buffer still holds the frame a flag just closed.
            return 0;
        }
        match self.state {
            AsyncState::Hunt => 0,
            AsyncState::Frame => self.buf.len(),
            AsyncState::Escaped => self.buf.len() + 1,
        }
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
