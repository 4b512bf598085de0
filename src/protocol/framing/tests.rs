//! Round trips, hand vectors and garbage for both transports.

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
        toml::from_str("extra_escapes = [0x11, 0x13]\nfcs = \"fcs-32\"\nmax_frame = 100").unwrap();
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
