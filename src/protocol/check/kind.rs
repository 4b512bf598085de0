//! What a check is called or described as: the catalogue names and aliases, a custom CRC's
//! parameters, and reading either from a protocol spec.

use std::fmt;
use std::str::FromStr;

use serde::Deserialize;
use serde::de::{self, Deserializer, MapAccess, Visitor};

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
pub(super) const NAMED: &[(&str, CheckKind)] = &[
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
