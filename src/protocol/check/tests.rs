//! Catalogue check values, vendor hand vectors, incremental equals whole, custom CRCs.

use super::kind::NAMED;
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
    let f =
        hex("FE81FF55 B3D0BBE7 32193EF4 30AC19A5 BA8F78D6 3A290594 3F7ECBD4 77 68 001D ADC5F651");
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
    let f =
        hex("80 7e00 00000000 00000000 00000000 00420004 00000000 00000000 09c40000 04d2 8cdc 0d");
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
