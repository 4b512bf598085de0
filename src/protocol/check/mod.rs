//! Integrity checks of IMU and GNSS frames: catalogue CRCs, vendor CRCs and simple sums.
//!
//! A protocol names its check (`"crc-32/mpeg-2"`, `"sum-16/le"`, …) or describes a custom CRC
//! by its Rocksoft/reveng parameters; [`Check::new`] validates that once and compiles it, and
//! [`Check::compute`] is then pure and allocation-free on the per-frame path.
//!
//! Why names and not polynomials: the IMU world uses several CRCs that share a polynomial and
//! differ only in init/reflection/final XOR (KVH's CRC-32/MPEG-2, zlib's CRC-32/ISO-HDLC and
//! NovAtel's CRC-32 all use 0x04C11DB7 and give three different results). Names from the reveng catalogue
//! (<https://reveng.sourceforge.io/crc-catalogue/all.htm>) are unambiguous, and every CRC here is
//! unit-tested against its catalogue check value over `"123456789"`.
//!
//! The value returned by [`Check::compute`] is the number the frame carries; its byte order on
//! the wire is the protocol's business (KVH: big-endian, NovAtel: little-endian, …). Two-byte
//! sums whose bytes are sent in a fixed order are packed so that writing them little-endian
//! gives the wire order (see [`CheckKind::Fletcher16Ubx`]).

mod kind;

use std::fmt;

use crc::{Algorithm, Crc};
use serde::Deserialize;

pub use kind::{CheckError, CheckKind, CustomCrc};

/// NovAtel OEM CRC-32: reflected 0x04C11DB7 (0xEDB88320), init 0, no final XOR. Not in the
/// reveng catalogue (CRC-32/JAMCRC has init 0xFFFFFFFF); NovAtel's OEM7 documentation ("32-bit
/// CRC") gives the algorithm; its check value is 0x2DFD2D88.
pub const CRC_32_NOVATEL: Algorithm<u32> = Algorithm {
    width: 32,
    poly: 0x04c1_1db7,
    init: 0,
    refin: true,
    refout: true,
    xorout: 0,
    check: 0x2dfd_2d88,
    residue: 0,
};

static CRC32_MPEG2: Crc<u32> = Crc::<u32>::new(&crc::CRC_32_MPEG_2);
static CRC32_ISO_HDLC: Crc<u32> = Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
static CRC32_ISCSI: Crc<u32> = Crc::<u32>::new(&crc::CRC_32_ISCSI);
static CRC32_JAMCRC: Crc<u32> = Crc::<u32>::new(&crc::CRC_32_JAMCRC);
static CRC32_NOVATEL: Crc<u32> = Crc::<u32>::new(&CRC_32_NOVATEL);
static CRC16_XMODEM: Crc<u16> = Crc::<u16>::new(&crc::CRC_16_XMODEM);
static CRC16_IBM_SDLC: Crc<u16> = Crc::<u16>::new(&crc::CRC_16_IBM_SDLC);
static CRC16_MCRF4XX: Crc<u16> = Crc::<u16>::new(&crc::CRC_16_MCRF4XX);
static CRC16_KERMIT: Crc<u16> = Crc::<u16>::new(&crc::CRC_16_KERMIT);
static CRC16_IBM_3740: Crc<u16> = Crc::<u16>::new(&crc::CRC_16_IBM_3740);

/// The input over which a CRC's catalogue `check` value is defined.
pub const CHECK_INPUT: &[u8] = b"123456789";

/// The compiled engine of a check.
#[derive(Clone, Copy)]
enum Engine {
    Crc8(&'static Crc<u8>),
    Crc16(&'static Crc<u16>),
    Crc32(&'static Crc<u32>),
    Crc64(&'static Crc<u64>),
    Sum8,
    Xor8,
    ZeroSum8,
    Fletcher16,
    Sum16 { big: bool, negate: bool },
}

/// A validated, compiled integrity check; cheap to copy.
#[derive(Clone, Copy)]
pub struct Check {
    kind: CheckKind,
    engine: Engine,
    width_bits: u8,
}

impl fmt::Debug for Check {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Check")
            .field("kind", &self.kind)
            .field("width_bits", &self.width_bits)
            .finish()
    }
}

impl Check {
    /// Compiles `kind`, validating a custom CRC against its stated check value (a custom CRC's
    /// tables are leaked once: build checks at load time, not per frame).
    pub fn new(kind: CheckKind) -> Result<Check, CheckError> {
        use CheckKind as K;
        let (engine, width_bits) = match kind {
            K::Crc32Mpeg2 => (Engine::Crc32(&CRC32_MPEG2), 32),
            K::Crc32IsoHdlc => (Engine::Crc32(&CRC32_ISO_HDLC), 32),
            K::Crc32Iscsi => (Engine::Crc32(&CRC32_ISCSI), 32),
            K::Crc32Jamcrc => (Engine::Crc32(&CRC32_JAMCRC), 32),
            K::Crc32Novatel => (Engine::Crc32(&CRC32_NOVATEL), 32),
            K::Crc16Xmodem => (Engine::Crc16(&CRC16_XMODEM), 16),
            K::Crc16IbmSdlc => (Engine::Crc16(&CRC16_IBM_SDLC), 16),
            K::Crc16Mcrf4xx => (Engine::Crc16(&CRC16_MCRF4XX), 16),
            K::Crc16Kermit => (Engine::Crc16(&CRC16_KERMIT), 16),
            K::Crc16Ibm3740 => (Engine::Crc16(&CRC16_IBM_3740), 16),
            K::Sum8 => (Engine::Sum8, 8),
            K::Xor8 => (Engine::Xor8, 8),
            K::ZeroSum8 => (Engine::ZeroSum8, 8),
            K::Fletcher16Ubx => (Engine::Fletcher16, 16),
            K::Sum16Le => (
                Engine::Sum16 {
                    big: false,
                    negate: false,
                },
                16,
            ),
            K::Sum16Be => (
                Engine::Sum16 {
                    big: true,
                    negate: false,
                },
                16,
            ),
            K::ZeroSum16Le => (
                Engine::Sum16 {
                    big: false,
                    negate: true,
                },
                16,
            ),
            K::Custom(c) => (compile_custom(&c)?, c.width),
        };
        Ok(Check {
            kind,
            engine,
            width_bits,
        })
    }

    /// Compiles a named check (`"crc-32/mpeg-2"`, an alias, `"sum-16/le"`, …).
    pub fn named(name: &str) -> Result<Check, CheckError> {
        Check::new(name.parse()?)
    }

    /// Compiles the check of a TOML value: a name string or a custom-CRC table.
    pub fn from_toml(value: &toml::Value) -> Result<Check, CheckError> {
        match value {
            toml::Value::String(s) => Check::named(s),
            toml::Value::Table(_) => {
                let c = CustomCrc::deserialize(value.clone())
                    .map_err(|e| CheckError::Invalid(e.to_string()))?;
                Check::new(CheckKind::Custom(c))
            }
            other => Err(CheckError::Invalid(format!(
                "expected a name or a table, found {}",
                other.type_str()
            ))),
        }
    }

    /// What this check is.
    pub fn kind(&self) -> CheckKind {
        self.kind
    }

    /// Width of the check value in bits.
    pub fn width_bits(&self) -> u8 {
        self.width_bits
    }

    /// Bytes needed to carry the check value.
    pub fn width_bytes(&self) -> usize {
        usize::from(self.width_bits).div_ceil(8)
    }

    /// The check value of `data`. Word sums pad an odd trailing byte with a zero byte.
    pub fn compute(&self, data: &[u8]) -> u64 {
        match self.engine {
            Engine::Crc8(c) => c.checksum(data).into(),
            Engine::Crc16(c) => c.checksum(data).into(),
            Engine::Crc32(c) => c.checksum(data).into(),
            Engine::Crc64(c) => c.checksum(data),
            Engine::Sum8 => data.iter().fold(0u8, |s, &b| s.wrapping_add(b)).into(),
            Engine::Xor8 => data.iter().fold(0u8, |s, &b| s ^ b).into(),
            Engine::ZeroSum8 => {
                let s = data.iter().fold(0u8, |s, &b| s.wrapping_add(b));
                s.wrapping_neg().into()
            }
            Engine::Fletcher16 => {
                let (a, b) = fletcher(0, 0, data);
                u64::from(a) | u64::from(b) << 8
            }
            Engine::Sum16 { big, negate } => {
                let mut chunks = data.chunks_exact(2);
                let mut s = 0u16;
                for w in &mut chunks {
                    s = s.wrapping_add(word(w[0], w[1], big));
                }
                if let [last] = chunks.remainder() {
                    s = s.wrapping_add(word(*last, 0, big));
                }
                if negate { s.wrapping_neg() } else { s }.into()
            }
        }
    }

    /// The check value of the concatenation of `parts` (e.g. MAVLink's bytes then CRC_EXTRA,
    /// or STIM300's datagram then its untransmitted zero pad) without copying them.
    pub fn compute_parts(&self, parts: &[&[u8]]) -> u64 {
        let mut r = self.start();
        for p in parts {
            r.update(p);
        }
        r.finish()
    }

    /// Starts an incremental computation.
    pub fn start(&self) -> Running {
        let state = match self.engine {
            Engine::Crc8(c) => State::Crc8(c.digest()),
            Engine::Crc16(c) => State::Crc16(c.digest()),
            Engine::Crc32(c) => State::Crc32(c.digest()),
            Engine::Crc64(c) => State::Crc64(c.digest()),
            Engine::Sum8 => State::Sum8(0),
            Engine::Xor8 => State::Xor8(0),
            Engine::ZeroSum8 => State::ZeroSum8(0),
            Engine::Fletcher16 => State::Fletcher(0, 0),
            Engine::Sum16 { big, negate } => State::Sum16 {
                sum: 0,
                big,
                negate,
                pending: None,
            },
        };
        Running(state)
    }
}

/// An incremental check computation ([`Check::start`]); equals [`Check::compute`] over the
/// concatenated updates.
#[derive(Clone)]
pub struct Running(State);

#[derive(Clone)]
enum State {
    Crc8(crc::Digest<'static, u8>),
    Crc16(crc::Digest<'static, u16>),
    Crc32(crc::Digest<'static, u32>),
    Crc64(crc::Digest<'static, u64>),
    Sum8(u8),
    Xor8(u8),
    ZeroSum8(u8),
    Fletcher(u8, u8),
    Sum16 {
        sum: u16,
        big: bool,
        negate: bool,
        pending: Option<u8>,
    },
}

impl Running {
    /// Feeds more bytes.
    pub fn update(&mut self, data: &[u8]) {
        match &mut self.0 {
            State::Crc8(d) => d.update(data),
            State::Crc16(d) => d.update(data),
            State::Crc32(d) => d.update(data),
            State::Crc64(d) => d.update(data),
            State::Sum8(s) | State::ZeroSum8(s) => {
                *s = data.iter().fold(*s, |s, &b| s.wrapping_add(b))
            }
            State::Xor8(s) => *s = data.iter().fold(*s, |s, &b| s ^ b),
            State::Fletcher(a, b) => (*a, *b) = fletcher(*a, *b, data),
            State::Sum16 {
                sum, big, pending, ..
            } => {
                for &b in data {
                    match pending.take() {
                        Some(first) => *sum = sum.wrapping_add(word(first, b, *big)),
                        None => *pending = Some(b),
                    }
                }
            }
        }
    }

    /// The check value.
    pub fn finish(self) -> u64 {
        match self.0 {
            State::Crc8(d) => d.finalize().into(),
            State::Crc16(d) => d.finalize().into(),
            State::Crc32(d) => d.finalize().into(),
            State::Crc64(d) => d.finalize(),
            State::Sum8(s) | State::Xor8(s) => s.into(),
            State::ZeroSum8(s) => s.wrapping_neg().into(),
            State::Fletcher(a, b) => u64::from(a) | u64::from(b) << 8,
            State::Sum16 {
                mut sum,
                big,
                negate,
                pending,
            } => {
                if let Some(last) = pending {
                    sum = sum.wrapping_add(word(last, 0, big));
                }
                if negate { sum.wrapping_neg() } else { sum }.into()
            }
        }
    }
}

/// A 16-bit word from two bytes in wire order.
#[inline]
fn word(first: u8, second: u8, big: bool) -> u16 {
    if big {
        u16::from_be_bytes([first, second])
    } else {
        u16::from_le_bytes([first, second])
    }
}

/// UBX running sums: `A += byte; B += A`, both mod 256.
#[inline]
fn fletcher(mut a: u8, mut b: u8, data: &[u8]) -> (u8, u8) {
    for &x in data {
        a = a.wrapping_add(x);
        b = b.wrapping_add(a);
    }
    (a, b)
}

/// Validates a custom CRC and leaks its algorithm and tables once.
fn compile_custom(c: &CustomCrc) -> Result<Engine, CheckError> {
    if !(1..=64).contains(&c.width) {
        return Err(CheckError::BadWidth(c.width));
    }
    let mask = u64::MAX >> (64 - u32::from(c.width));
    for (field, value) in [
        ("poly", c.poly),
        ("init", c.init),
        ("xorout", c.xorout),
        ("check", c.check),
    ] {
        if value & !mask != 0 {
            return Err(CheckError::TooWide {
                field,
                value,
                width: c.width,
            });
        }
    }
    if c.poly & 1 == 0 {
        return Err(CheckError::EvenPoly(c.poly));
    }
    // The `as` casts are exact: every value was checked to fit in `width` bits above.
    macro_rules! leak {
        ($w:ty, $variant:ident) => {{
            let alg: &'static Algorithm<$w> = Box::leak(Box::new(Algorithm {
                width: c.width,
                poly: c.poly as $w,
                init: c.init as $w,
                refin: c.refin,
                refout: c.refout,
                xorout: c.xorout as $w,
                check: c.check as $w,
                residue: 0, // informative only; the `crc` crate does not use it
            }));
            let crc: &'static Crc<$w> = Box::leak(Box::new(Crc::<$w>::new(alg)));
            (Engine::$variant(crc), u64::from(crc.checksum(CHECK_INPUT)))
        }};
    }
    let (engine, computed) = match c.width {
        1..=8 => leak!(u8, Crc8),
        9..=16 => leak!(u16, Crc16),
        17..=32 => leak!(u32, Crc32),
        _ => leak!(u64, Crc64),
    };
    if computed != c.check {
        return Err(CheckError::CheckMismatch {
            expected: c.check,
            computed,
        });
    }
    Ok(engine)
}

#[cfg(test)]
mod tests;
