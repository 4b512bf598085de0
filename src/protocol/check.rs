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

use std::fmt;
use std::str::FromStr;

use crc::{Algorithm, Crc};
use serde::Deserialize;
use serde::de::{self, Deserializer, MapAccess, Visitor};

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

/// A custom CRC in the Rocksoft/reveng parameter model, with its check value over `"123456789"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CustomCrc {
    /// Register width in bits, 1..=64.
    pub width: u8,
    /// Generator polynomial, normal (MSB-first) form without the x^width term; must be odd.
    #[serde(deserialize_with = "de_u64")]
    pub poly: u64,
    /// Register value before the first message bit.
    #[serde(deserialize_with = "de_u64")]
    pub init: u64,
    /// Bytes are fed LSB first.
    pub refin: bool,
    /// The register is reflected before the final XOR.
    pub refout: bool,
    /// Final XOR.
    #[serde(deserialize_with = "de_u64")]
    pub xorout: u64,
    /// Stated CRC of `"123456789"`; must equal the computed one.
    #[serde(deserialize_with = "de_u64")]
    pub check: u64,
}

/// Which integrity check a frame carries (names are the reveng catalogue's, lower case).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CheckKind {
    /// `crc-32/mpeg-2`: KVH 1750/1775, STIM300.
    Crc32Mpeg2,
    /// `crc-32/iso-hdlc`: zlib/Ethernet CRC-32, HDLC FCS-32, ADIS16495 burst.
    Crc32IsoHdlc,
    /// `crc-32/iscsi`: CRC-32C (Castagnoli).
    Crc32Iscsi,
    /// `crc-32/jamcrc`: zlib CRC-32 without the final XOR (not NovAtel's: init differs).
    Crc32Jamcrc,
    /// `crc-32/novatel`: NovAtel OEM logs; not a catalogue entry, see [`CRC_32_NOVATEL`].
    Crc32Novatel,
    /// `crc-16/xmodem`: iXCOM, VectorNav.
    Crc16Xmodem,
    /// `crc-16/ibm-sdlc`: HDLC/SDLC FCS-16, X.25.
    Crc16IbmSdlc,
    /// `crc-16/mcrf4xx`: MAVLink's "X.25" accumulator, before CRC_EXTRA.
    Crc16Mcrf4xx,
    /// `crc-16/kermit`: the "true" CCITT CRC.
    Crc16Kermit,
    /// `crc-16/ibm-3740`: "CCITT-FALSE".
    Crc16Ibm3740,
    /// `sum-8`: 8-bit sum of the bytes, wrapping (KVH extended-BIT message).
    Sum8,
    /// `xor-8`: XOR of the bytes.
    Xor8,
    /// `zero-sum-8`: the byte that makes the 8-bit sum of data and check 0 (Xsens).
    ZeroSum8,
    /// `fletcher-16/ubx`: u-blox's two running 8-bit sums (mod 256, not RFC 1146's mod 255),
    /// returned as `CK_A | CK_B << 8` so that little-endian writes CK_A first.
    Fletcher16Ubx,
    /// `sum-16/le`: wrapping sum of little-endian 16-bit words (Honeywell HG4930).
    Sum16Le,
    /// `sum-16/be`: wrapping sum of big-endian 16-bit words (Epson UART burst).
    Sum16Be,
    /// `zero-sum-16/le`: the word that makes the LE word sum of data and check 0 (an LN-200
    /// checksum candidate [U]).
    ZeroSum16Le,
    /// A CRC given by its parameters.
    Custom(CustomCrc),
}

/// Canonical names of the named checks, in the order of [`CheckKind`].
const NAMED: &[(&str, CheckKind)] = &[
    ("crc-32/mpeg-2", CheckKind::Crc32Mpeg2),
    ("crc-32/iso-hdlc", CheckKind::Crc32IsoHdlc),
    ("crc-32/iscsi", CheckKind::Crc32Iscsi),
    ("crc-32/jamcrc", CheckKind::Crc32Jamcrc),
    ("crc-32/novatel", CheckKind::Crc32Novatel),
    ("crc-16/xmodem", CheckKind::Crc16Xmodem),
    ("crc-16/ibm-sdlc", CheckKind::Crc16IbmSdlc),
    ("crc-16/mcrf4xx", CheckKind::Crc16Mcrf4xx),
    ("crc-16/kermit", CheckKind::Crc16Kermit),
    ("crc-16/ibm-3740", CheckKind::Crc16Ibm3740),
    ("sum-8", CheckKind::Sum8),
    ("xor-8", CheckKind::Xor8),
    ("zero-sum-8", CheckKind::ZeroSum8),
    ("fletcher-16/ubx", CheckKind::Fletcher16Ubx),
    ("sum-16/le", CheckKind::Sum16Le),
    ("sum-16/be", CheckKind::Sum16Be),
    ("zero-sum-16/le", CheckKind::ZeroSum16Le),
];

/// Other names accepted for the same algorithms (reveng catalogue aliases).
const ALIASES: &[(&str, &str)] = &[
    ("crc-32", "crc-32/iso-hdlc"),
    ("crc-32/adccp", "crc-32/iso-hdlc"),
    ("crc-32/v-42", "crc-32/iso-hdlc"),
    ("crc-32/xz", "crc-32/iso-hdlc"),
    ("pkzip", "crc-32/iso-hdlc"),
    ("crc-32c", "crc-32/iscsi"),
    ("crc-32/castagnoli", "crc-32/iscsi"),
    ("crc-32/interlaken", "crc-32/iscsi"),
    ("crc-32/base91-c", "crc-32/iscsi"),
    ("jamcrc", "crc-32/jamcrc"),
    ("crc-16/acorn", "crc-16/xmodem"),
    ("crc-16/lte", "crc-16/xmodem"),
    ("crc-16/v-41-msb", "crc-16/xmodem"),
    ("xmodem", "crc-16/xmodem"),
    ("zmodem", "crc-16/xmodem"),
    ("crc-16/iso-hdlc", "crc-16/ibm-sdlc"),
    ("crc-16/iso-iec-14443-3-b", "crc-16/ibm-sdlc"),
    ("crc-16/x-25", "crc-16/ibm-sdlc"),
    ("crc-b", "crc-16/ibm-sdlc"),
    ("x-25", "crc-16/ibm-sdlc"),
    ("crc-16/ccitt", "crc-16/kermit"),
    ("crc-16/ccitt-true", "crc-16/kermit"),
    ("crc-16/v-41-lsb", "crc-16/kermit"),
    ("crc-ccitt", "crc-16/kermit"),
    ("kermit", "crc-16/kermit"),
    ("crc-16/autosar", "crc-16/ibm-3740"),
    ("crc-16/ccitt-false", "crc-16/ibm-3740"),
];

impl CheckKind {
    /// The canonical name (`"custom"` for a custom CRC).
    pub fn name(&self) -> &'static str {
        match self {
            CheckKind::Custom(_) => "custom",
            k => NAMED
                .iter()
                .find(|(_, n)| n == k)
                .map_or("custom", |(s, _)| s),
        }
    }

    /// Canonical names of all named checks.
    pub fn names() -> impl Iterator<Item = &'static str> {
        NAMED.iter().map(|(s, _)| *s)
    }
}

impl fmt::Display for CheckKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for CheckKind {
    type Err = CheckError;

    /// Looks a name up case-insensitively among the canonical names and catalogue aliases.
    fn from_str(s: &str) -> Result<Self, CheckError> {
        let lower = s.trim().to_ascii_lowercase();
        let canonical = ALIASES
            .iter()
            .find(|(a, _)| *a == lower)
            .map_or(lower.as_str(), |(_, c)| c);
        NAMED
            .iter()
            .find(|(n, _)| *n == canonical)
            .map(|(_, k)| *k)
            .ok_or_else(|| CheckError::UnknownName(s.to_string()))
    }
}

/// Deserializes from a name (`"crc-32/mpeg-2"`) or from a table of [`CustomCrc`] parameters.
impl<'de> Deserialize<'de> for CheckKind {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = CheckKind;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(
                    "a check name such as \"crc-32/mpeg-2\" or a table \
                     {width, poly, init, refin, refout, xorout, check}",
                )
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<CheckKind, E> {
                s.parse().map_err(E::custom)
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<CheckKind, A::Error> {
                CustomCrc::deserialize(de::value::MapAccessDeserializer::new(map))
                    .map(CheckKind::Custom)
            }
        }
        d.deserialize_any(V)
    }
}

/// Why a check cannot be built.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CheckError {
    /// The name is not a known check.
    #[error("unknown check `{0}`; known: {known}", known = CheckKind::names().collect::<Vec<_>>().join(", "))]
    UnknownName(String),
    /// A custom CRC's width is outside 1..=64.
    #[error("custom CRC width {0} is outside 1..=64")]
    BadWidth(u8),
    /// A custom CRC parameter does not fit in the register width.
    #[error("custom CRC `{field}` = {value:#x} does not fit in {width} bits")]
    TooWide {
        /// Parameter name.
        field: &'static str,
        /// Its value.
        value: u64,
        /// The CRC width.
        width: u8,
    },
    /// A custom CRC polynomial without the x^0 term (often a reflected polynomial by mistake).
    #[error(
        "custom CRC poly {0:#x} is even: give the normal MSB-first form \
         (e.g. 0x04c11db7, not the reflected 0xedb88320) and set refin/refout"
    )]
    EvenPoly(u64),
    /// A custom CRC's computed check value differs from the stated one.
    #[error(
        "custom CRC check value mismatch over \"123456789\": stated {expected:#x}, \
         computed {computed:#x}"
    )]
    CheckMismatch {
        /// The value stated in the specification.
        expected: u64,
        /// The value the parameters produce.
        computed: u64,
    },
    /// The TOML value is neither a name nor a parameter table.
    #[error("invalid check: {0}")]
    Invalid(String),
}

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

/// Deserializes a u64 from a non-negative integer or a string (`"0x…"`, `"0b…"` or decimal),
/// because TOML integers stop at 2^63 − 1 and 64-bit CRC parameters often do not.
fn de_u64<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
    struct V;
    impl Visitor<'_> for V {
        type Value = u64;
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a non-negative integer or a string such as \"0xffffffffffffffff\"")
        }
        fn visit_u64<E: de::Error>(self, v: u64) -> Result<u64, E> {
            Ok(v)
        }
        fn visit_i64<E: de::Error>(self, v: i64) -> Result<u64, E> {
            u64::try_from(v).map_err(|_| E::custom(format!("{v} is negative")))
        }
        fn visit_str<E: de::Error>(self, s: &str) -> Result<u64, E> {
            let t = s.trim().replace('_', "");
            let r = if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
                u64::from_str_radix(h, 16)
            } else if let Some(b) = t.strip_prefix("0b").or_else(|| t.strip_prefix("0B")) {
                u64::from_str_radix(b, 2)
            } else {
                t.parse()
            };
            r.map_err(|e| E::custom(format!("`{s}`: {e}")))
        }
    }
    d.deserialize_any(V)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(s: &str) -> Vec<u8> {
        let s: String = s.chars().filter(|c| !c.is_whitespace()).collect();
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    fn named(name: &str) -> Check {
        Check::named(name).unwrap()
    }

    /// Catalogue check values over "123456789" from the reveng catalogue (NovAtel's from its
    /// CRC-32 routine).
    #[test]
    fn catalogue_check_values() {
        let cases: &[(&str, u64)] = &[
            ("crc-32/mpeg-2", 0x0376_E6E7),
            ("crc-32/novatel", 0x2DFD_2D88),
            ("crc-32/iso-hdlc", 0xCBF4_3926),
            ("crc-16/xmodem", 0x31C3),
            ("crc-16/mcrf4xx", 0x6F91),
            ("crc-16/ibm-sdlc", 0x906E),
            ("crc-16/kermit", 0x2189),
            ("crc-16/ibm-3740", 0x29B1),
            ("crc-32/iscsi", 0xE306_9283),
            ("crc-32/jamcrc", 0x340B_C6D9),
        ];
        for &(name, check) in cases {
            assert_eq!(named(name).compute(CHECK_INPUT), check, "{name}");
        }
        // Every named CRC is covered above.
        for n in CheckKind::names().filter(|n| n.starts_with("crc-")) {
            assert!(cases.iter().any(|c| c.0 == n), "{n} untested");
        }
    }

    #[test]
    fn novatel_is_not_jamcrc_nor_zlib() {
        let n = named("crc-32/novatel").compute(CHECK_INPUT);
        assert_ne!(n, named("crc-32/jamcrc").compute(CHECK_INPUT));
        assert_ne!(n, named("crc-32/iso-hdlc").compute(CHECK_INPUT));
    }

    #[test]
    fn widths() {
        assert_eq!(named("crc-32/mpeg-2").width_bytes(), 4);
        assert_eq!(named("crc-16/xmodem").width_bytes(), 2);
        assert_eq!(named("sum-8").width_bytes(), 1);
        assert_eq!(named("zero-sum-8").width_bytes(), 1);
        assert_eq!(named("fletcher-16/ubx").width_bytes(), 2);
        assert_eq!(named("sum-16/le").width_bytes(), 2);
    }

    #[test]
    fn names_and_aliases() {
        for n in CheckKind::names() {
            let k: CheckKind = n.parse().unwrap();
            assert_eq!(k.name(), n);
            assert_eq!(Check::named(n).unwrap().kind(), k);
        }
        assert_eq!(
            "CRC-16/X-25".parse::<CheckKind>(),
            Ok(CheckKind::Crc16IbmSdlc)
        );
        assert_eq!(
            "crc-16/ccitt-false".parse::<CheckKind>(),
            Ok(CheckKind::Crc16Ibm3740)
        );
        assert_eq!("crc-32".parse::<CheckKind>(), Ok(CheckKind::Crc32IsoHdlc));
        assert!(matches!(
            "crc-32/foo".parse::<CheckKind>(),
            Err(CheckError::UnknownName(_))
        ));
        let msg = Check::named("crc-99").unwrap_err().to_string();
        assert!(
            msg.contains("crc-99") && msg.contains("crc-32/mpeg-2"),
            "{msg}"
        );
    }

    /// Real KVH 1750 Format A frame (TRECVT/ros_kvh1750 test/utest.cpp
    /// "basic"), CRC-32/MPEG-2 over bytes 0..32, stored big-endian.
    #[test]
    fn kvh1750_real_frame() {
        let f = hex(
            "FE81FF55 B3D0BBE7 32193EF4 30AC19A5 BA8F78D6 3A290594 3F7ECBD4 77 68 001D ADC5F651",
        );
        assert_eq!(f.len(), 36);
        let crc = named("crc-32/mpeg-2").compute(&f[..32]);
        assert_eq!(crc, 0xADC5_F651);
        assert_eq!(
            crc,
            u64::from(u32::from_be_bytes(f[32..].try_into().unwrap()))
        );
    }

    /// KVH extended-BIT message `FE 81 00 AA` + 6 bytes + 1-byte additive
    /// checksum over all preceding bytes (the documented normal message).
    #[test]
    fn kvh_extended_bit_sum8() {
        let f = hex("FE 81 00 AA 7F 7F 7F 7F 7F 7F 23");
        assert_eq!(named("sum-8").compute(&f[..10]), 0x23);
    }

    /// Real iXCOM IMURAW frame (swift-nav/gnss-converters capture),
    /// CRC-16/XMODEM over bytes 0..42, stored little-endian `49 10`.
    #[test]
    fn ixcom_imuraw_real_frame() {
        let f = hex(
            "7e0072012c003208440f0400e6f20600de2bcebd0816f4bdc5d11cc18c8cb33ae3d4353b62f2073a00644910",
        );
        assert_eq!(f.len(), 44);
        let crc = named("crc-16/xmodem").compute(&f[..42]);
        assert_eq!(crc, 0x1049);
        assert_eq!(crc, u64::from(u16::from_le_bytes([f[42], f[43]])));
    }

    /// NovAtel RAWIMUSXB worked example (EDIE round trip), NovAtel CRC-32 over
    /// sync..payload, stored little-endian (0xAB4CDC13).
    #[test]
    fn novatel_rawimusxb_example() {
        let f = hex(
            "aa441328b605a1089e594e1d 0429a108541c070e68021e41 00fe59ea 70d7a013 09b2d6ff \
             e5ca4400 60fe0200 725d0600 7bbaf0ff 13dc4cab",
        );
        assert_eq!(f.len(), 56);
        let crc = named("crc-32/novatel").compute(&f[..52]);
        assert_eq!(crc, 0xAB4C_DC13);
        assert_eq!(
            crc,
            u64::from(u32::from_le_bytes(f[52..].try_into().unwrap()))
        );
    }

    /// pymavlink HIL_SENSOR; CRC-16/MCRF4XX over the bytes after STX, then
    /// CRC_EXTRA 108; stored little-endian (0x9D52).
    #[test]
    fn mavlink_hil_sensor_example() {
        let f = hex(
            "fd3e00000001c86b000040420f000000000000000000000000000ae81cc10ad7233c000000000000\
             0000cdcc4c3e00000000cdcccc3e00507d44000000000000c8420000c841ff1f529d",
        );
        assert_eq!(f.len(), 10 + 62 + 2);
        let n = f.len();
        let c = named("crc-16/mcrf4xx");
        let crc = c.compute_parts(&[&f[1..n - 2], &[108]]);
        assert_eq!(crc, 0x9D52);
        assert_eq!(crc, u64::from(u16::from_le_bytes([f[n - 2], f[n - 1]])));
        // Without CRC_EXTRA it does not match.
        assert_ne!(c.compute(&f[1..n - 2]), 0x9D52);
    }

    /// Constructed example (from the datasheet, not a capture): STIM300 0x93,
    /// CRC-32/MPEG-2 over the 34 bytes plus two untransmitted zero bytes = 0x0BC9E7B7.
    #[test]
    fn stim300_constructed_example_with_padding() {
        let f = hex(
            "93 0000a4 fffeb8 000052 00 000000 000000 080000 00 000000 000000 400000 00 2a 01f4 \
             0bc9e7b7",
        );
        assert_eq!(f.len(), 38);
        let c = named("crc-32/mpeg-2");
        assert_eq!(c.compute_parts(&[&f[..34], &[0, 0]]), 0x0BC9_E7B7);
        let mut padded = f[..34].to_vec();
        padded.extend([0, 0]);
        assert_eq!(c.compute(&padded), 0x0BC9_E7B7);
    }

    /// Constructed example: HG4930 control message 0x01, 16-bit sum of
    /// the 9 little-endian words before the checksum (address+ID word included) = 0xFDB1.
    #[test]
    fn hg4930_constructed_example() {
        let f = hex("0e 01 1100 0000 0000 0000 0000 91fc 0100 0000 b1fd");
        assert_eq!(f.len(), 20);
        let s = named("sum-16/le").compute(&f[..18]);
        assert_eq!(s, 0xFDB1);
        assert_eq!(s, u64::from(u16::from_le_bytes([f[18], f[19]])));
    }

    /// Constructed example: Epson G370 burst, 16-bit sum of the
    /// big-endian words between header 0x80 and the checksum = 0x8CDC.
    #[test]
    fn epson_constructed_example() {
        let f = hex(
            "80 7e00 00000000 00000000 00000000 00420004 00000000 00000000 09c40000 04d2 8cdc 0d",
        );
        assert_eq!(f.len(), 36);
        assert_eq!(named("sum-16/be").compute(&f[1..33]), 0x8CDC);
    }

    /// Hand-computed: UBX-NAV-PVT poll `B5 62 01 07 00 00` → CK_A 0x08, CK_B 0x19.
    #[test]
    fn fletcher_ubx_hand_vector() {
        let c = named("fletcher-16/ubx");
        let v = c.compute(&[0x01, 0x07, 0x00, 0x00]);
        assert_eq!((v as u16).to_le_bytes(), [0x08, 0x19]);
        // Mod 256, not mod 255: A = 0xFF + 0x02 = 0x01, B = 0xFF + 0x01 = 0x00.
        assert_eq!(c.compute(&[0xFF, 0x02]), 0x0001);
        assert_eq!(c.compute(&[]), 0);
    }

    /// Hand-computed small vectors for the sums.
    #[test]
    fn sums_hand_vectors() {
        assert_eq!(named("sum-8").compute(&[0x80, 0x80, 0x05]), 0x05);
        assert_eq!(named("xor-8").compute(&[0x0F, 0xF0, 0x01]), 0xFE);
        assert_eq!(named("xor-8").compute(&[]), 0);
        // Xsens GoToConfig `FA FF 30 00 D1`: FF + 30 + 00 + D1 = 0x200 ≡ 0.
        assert_eq!(named("zero-sum-8").compute(&[0xFF, 0x30, 0x00]), 0xD1);
        assert_eq!(named("zero-sum-8").compute(&[]), 0);
        // Words 0x0201 + 0xFFFF (LE) wrap to 0x0200; BE: 0x0102 + 0xFFFF = 0x0101.
        let d = [0x01, 0x02, 0xFF, 0xFF];
        assert_eq!(named("sum-16/le").compute(&d), 0x0200);
        assert_eq!(named("sum-16/be").compute(&d), 0x0101);
        // Odd length pads a zero: LE 0x0201 + 0x0003, BE 0x0102 + 0x0300.
        assert_eq!(named("sum-16/le").compute(&[1, 2, 3]), 0x0204);
        assert_eq!(named("sum-16/be").compute(&[1, 2, 3]), 0x0402);
        // Zero-sum words: data + check sums to 0.
        let z = named("zero-sum-16/le").compute(&d);
        assert_eq!(z, 0x0200u16.wrapping_neg().into());
        let mut with = d.to_vec();
        with.extend((z as u16).to_le_bytes());
        assert_eq!(named("sum-16/le").compute(&with), 0);
    }

    /// Incremental computation equals one-shot for every kind and any split, odd splits too.
    #[test]
    fn running_equals_compute() {
        let data: Vec<u8> = (0..61u32)
            .map(|i| (i.wrapping_mul(37) ^ 0x5A) as u8)
            .collect();
        let mut kinds: Vec<CheckKind> = NAMED.iter().map(|n| n.1).collect();
        kinds.push(CheckKind::Custom(CustomCrc {
            width: 5,
            poly: 0x05,
            init: 0x1f,
            refin: true,
            refout: true,
            xorout: 0x1f,
            check: 0x19,
        }));
        for k in kinds {
            let c = Check::new(k).unwrap();
            let whole = c.compute(&data);
            for split in [0, 1, 2, 3, 17, 60, 61] {
                let (a, b) = data.split_at(split);
                assert_eq!(c.compute_parts(&[a, b]), whole, "{k} split {split}");
                let (b1, b2) = b.split_at(b.len() / 3);
                assert_eq!(c.compute_parts(&[a, b1, b2]), whole, "{k} split3 {split}");
            }
        }
    }

    fn custom(width: u8, poly: u64, init: u64, refl: bool, xorout: u64, check: u64) -> CustomCrc {
        CustomCrc {
            width,
            poly,
            init,
            refin: refl,
            refout: refl,
            xorout,
            check,
        }
    }

    /// Custom CRCs of every register size reproduce their reveng catalogue check values.
    #[test]
    fn custom_crcs_match_catalogue() {
        let cases = [
            custom(3, 0x3, 0, false, 0x7, 0x4),                    // CRC-3/GSM
            custom(5, 0x05, 0x1f, true, 0x1f, 0x19),               // CRC-5/USB
            custom(8, 0x07, 0, false, 0, 0xf4),                    // CRC-8/SMBUS
            custom(11, 0x385, 0x1a, false, 0, 0x5a3),              // CRC-11/FLEXRAY
            custom(12, 0x80f, 0, false, 0, 0xf5b),                 // CRC-12/DECT
            custom(16, 0x1021, 0xffff, false, 0, 0x29b1),          // CRC-16/IBM-3740
            custom(16, 0x8005, 0xffff, true, 0, 0x4b37),           // CRC-16/MODBUS
            custom(24, 0x86_4cfb, 0xb7_04ce, false, 0, 0x21_cf02), // CRC-24/OPENPGP
            custom(
                31,
                0x04c1_1db7,
                0x7fff_ffff,
                false,
                0x7fff_ffff,
                0x0ce9_e46c,
            ), // CRC-31/PHILIPS
            custom(32, 0x04c1_1db7, 0, true, 0, 0x2dfd_2d88),      // NovAtel
            custom(40, 0x0482_0009, 0, false, 0xff_ffff_ffff, 0xd4_164f_c646), // CRC-40/GSM
            custom(
                64,
                0x42f0_e1eb_a9ea_3693,
                u64::MAX,
                true,
                u64::MAX,
                0x995d_c9bb_df19_39fa,
            ), // CRC-64/XZ
        ];
        for c in cases {
            let chk = Check::new(CheckKind::Custom(c)).unwrap_or_else(|e| panic!("{c:?}: {e}"));
            assert_eq!(chk.compute(CHECK_INPUT), c.check, "{c:?}");
            assert_eq!(chk.width_bytes(), usize::from(c.width).div_ceil(8));
        }
    }

    #[test]
    fn custom_crc_errors() {
        let good = custom(16, 0x1021, 0xffff, false, 0, 0x29b1);
        assert_eq!(
            Check::new(CheckKind::Custom(CustomCrc {
                check: 0x29b2,
                ..good
            }))
            .unwrap_err(),
            CheckError::CheckMismatch {
                expected: 0x29b2,
                computed: 0x29b1
            }
        );
        assert_eq!(
            Check::new(CheckKind::Custom(CustomCrc { width: 0, ..good })).unwrap_err(),
            CheckError::BadWidth(0)
        );
        assert_eq!(
            Check::new(CheckKind::Custom(CustomCrc { width: 65, ..good })).unwrap_err(),
            CheckError::BadWidth(65)
        );
        assert!(matches!(
            Check::new(CheckKind::Custom(CustomCrc {
                init: 0x1ffff,
                ..good
            }))
            .unwrap_err(),
            CheckError::TooWide { field: "init", .. }
        ));
        // The reflected form of a polynomial is even: rejected with a hint.
        let e = Check::new(CheckKind::Custom(CustomCrc {
            poly: 0x8408,
            ..good
        }))
        .unwrap_err();
        assert_eq!(e, CheckError::EvenPoly(0x8408));
        assert!(e.to_string().contains("reflected"));
    }

    #[test]
    fn from_toml_names_and_tables() {
        let v: toml::Table = toml::from_str(
            r#"
            a = "crc-32/mpeg-2"
            b = { width = 16, poly = 0x1021, init = 0xffff, refin = false, refout = false, xorout = 0, check = 0x29b1 }
            c = { width = 64, poly = 0x42f0e1eba9ea3693, init = "0xffff_ffff_ffff_ffff", refin = true, refout = true, xorout = "0xffffffffffffffff", check = "0x995dc9bbdf1939fa" }
            d = "nope"
            e = { width = 16, poly = 0x1021, init = 0xffff, refin = false, refout = false, xorout = 0, check = 0x29b1, extra = 1 }
            f = 3
            g = { width = 16, poly = 0x1021, init = 0xffff, refin = false, refout = false, xorout = 0, check = 0x1234 }
            "#,
        )
        .unwrap();
        assert_eq!(
            Check::from_toml(&v["a"]).unwrap().kind(),
            CheckKind::Crc32Mpeg2
        );
        assert_eq!(
            Check::from_toml(&v["b"]).unwrap().compute(CHECK_INPUT),
            0x29b1
        );
        assert_eq!(
            Check::from_toml(&v["c"]).unwrap().compute(CHECK_INPUT),
            0x995d_c9bb_df19_39fa
        );
        assert!(matches!(
            Check::from_toml(&v["d"]),
            Err(CheckError::UnknownName(_))
        ));
        let e = Check::from_toml(&v["e"]).unwrap_err().to_string();
        assert!(e.contains("extra"), "{e}");
        assert!(matches!(
            Check::from_toml(&v["f"]),
            Err(CheckError::Invalid(_))
        ));
        assert!(matches!(
            Check::from_toml(&v["g"]),
            Err(CheckError::CheckMismatch { .. })
        ));
    }

    #[test]
    fn serde_deserialize_check_kind() {
        #[derive(Deserialize)]
        struct S {
            k: CheckKind,
        }
        let s: S = toml::from_str(r#"k = "CRC-16/XMODEM""#).unwrap();
        assert_eq!(s.k, CheckKind::Crc16Xmodem);
        let s: S = toml::from_str(
            "k = { width = 8, poly = 7, init = 0, refin = false, refout = false, xorout = 0, check = 0xf4 }",
        )
        .unwrap();
        assert!(matches!(s.k, CheckKind::Custom(CustomCrc { width: 8, .. })));
        let e = toml::from_str::<S>(r#"k = "crc-7/what""#)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("unknown check"), "{e}");
    }
}
