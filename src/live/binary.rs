//! The compact binary state datagram (specified in docs/live-input.md, "Binary datagram"):
//! 152 bytes, little-endian, closed by a CRC-32/ISO-HDLC (the zlib/Ethernet CRC) over
//! everything before it, so a sender in any language can use its standard CRC-32.

use super::{Decoded, Malformed};
use crate::earth::{Geodetic, ecef_to_geodetic, omega_en_n};
use crate::math::{Quat, QuatExt, Vec3};
use crate::motion::causal::LiveSample;
use crate::motion::sampled::Sample;
use crate::protocol::check::Check;

/// The first four bytes: `IMUS`.
pub const MAGIC: [u8; 4] = *b"IMUS";
/// The format version this decoder reads.
pub const VERSION: u8 = 1;
/// Bytes in a datagram.
pub const LEN: usize = 152;
/// `week` value meaning "the time tag is simulation seconds, not GPS time".
pub const NO_WEEK: u16 = 0xFFFF;

/// Flag bit: position, velocity, acceleration and attitude are Earth-fixed (ECEF, C_b^e)
/// instead of geodetic, NED and C_b^n.
pub const FLAG_ECEF: u8 = 1;
/// Flag bit: the acceleration field is valid.
pub const FLAG_ACCEL: u8 = 2;
/// Flag bit: the body-rate field is valid.
pub const FLAG_RATE: u8 = 4;

/// Offset of the GPS week field.
pub const WEEK: usize = 6;
/// Offsets of the other fields (docs/live-input.md has the table).
const SEQ: usize = 8;
const TIME: usize = 12;
const POS: usize = 20;
const VEL: usize = 44;
const ACC: usize = 68;
const QUAT: usize = 92;
const RATE: usize = 124;
const CRC: usize = 148;

fn crc() -> Check {
    Check::named("crc-32/iso-hdlc").expect("a catalogue CRC")
}

/// What a datagram carries, in the sender's frame (for [`encode`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Datagram {
    /// Sequence number.
    pub seq: u32,
    /// GPS week, or [`NO_WEEK`].
    pub week: u16,
    /// Time tag: seconds of the week, or simulation seconds.
    pub time: f64,
    /// [`FLAG_ECEF`] | [`FLAG_ACCEL`] | [`FLAG_RATE`].
    pub flags: u8,
    /// Latitude (deg), longitude (deg), height (m); or ECEF x, y, z (m).
    pub pos: [f64; 3],
    /// NED or ECEF velocity (m/s).
    pub vel: [f64; 3],
    /// v̇^n or r̈^e (m/s²).
    pub acc: [f64; 3],
    /// C_b^n or C_b^e as w, x, y, z.
    pub quat: [f64; 4],
    /// ω_ib^b (rad/s).
    pub rate: [f64; 3],
}

/// The datagram's bytes.
pub fn encode(d: &Datagram) -> [u8; LEN] {
    let mut b = [0u8; LEN];
    b[..4].copy_from_slice(&MAGIC);
    b[4] = VERSION;
    b[5] = d.flags;
    b[6..8].copy_from_slice(&d.week.to_le_bytes());
    b[SEQ..SEQ + 4].copy_from_slice(&d.seq.to_le_bytes());
    b[TIME..TIME + 8].copy_from_slice(&d.time.to_le_bytes());
    let mut put = |at: usize, v: &[f64]| {
        for (i, x) in v.iter().enumerate() {
            b[at + 8 * i..at + 8 * i + 8].copy_from_slice(&x.to_le_bytes());
        }
    };
    put(POS, &d.pos);
    put(VEL, &d.vel);
    put(ACC, &d.acc);
    put(QUAT, &d.quat);
    put(RATE, &d.rate);
    let c = crc().compute(&b[..CRC]) as u32;
    b[CRC..].copy_from_slice(&c.to_le_bytes());
    b
}

/// Whether `frame` (at least [`LEN`] bytes) has a correct CRC: how a stream reader tells a
/// frame from garbage that happens to start with the magic.
pub fn crc_ok(frame: &[u8]) -> bool {
    frame.len() >= LEN
        && crc().compute(&frame[..CRC]) as u32
            == u32::from_le_bytes(frame[CRC..LEN].try_into().expect("4 bytes"))
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

fn vec_at(b: &[u8], at: usize) -> Vec3 {
    Vec3::new(f64_at(b, at), f64_at(b, at + 8), f64_at(b, at + 16))
}

/// Decodes one datagram, checking length, magic, version, CRC, finiteness and the quaternion's
/// norm; an error names the byte offset of the field at fault.
pub fn decode(b: &[u8]) -> Result<Decoded, Malformed> {
    decode_since(b, 0)
}

/// [`decode`], with a GPS time tag taken as seconds since the start of GPS week
/// `epoch_week` ([`super::since_week`]).
pub fn decode_since(b: &[u8], epoch_week: u32) -> Result<Decoded, Malformed> {
    let (mut d, week) = decode_tag(b)?;
    if let Some(w) = week {
        d.state.sample.t = super::since_week(w, epoch_week, d.state.sample.t);
    }
    Ok(d)
}

/// [`decode`], with the time tag as sent: the state's time is the seconds of the GPS week
/// returned, or simulation seconds when there is none.
pub fn decode_tag(b: &[u8]) -> Result<(Decoded, Option<u32>), Malformed> {
    if b.len() != LEN {
        return Err(Malformed::at(
            0,
            format!("{} bytes, expected {LEN}", b.len()),
        ));
    }
    if b[..4] != MAGIC {
        return Err(Malformed::at(0, "no `IMUS` magic"));
    }
    if b[4] != VERSION {
        return Err(Malformed::at(
            4,
            format!("version {}, expected {VERSION}", b[4]),
        ));
    }
    let sent = u32::from_le_bytes(b[CRC..].try_into().expect("4 bytes"));
    let c = crc().compute(&b[..CRC]) as u32;
    if sent != c {
        return Err(Malformed::at(
            CRC,
            format!("CRC {sent:08x}, computed {c:08x}"),
        ));
    }
    let flags = b[5];
    if flags & !(FLAG_ECEF | FLAG_ACCEL | FLAG_RATE) != 0 {
        return Err(Malformed::at(5, format!("unknown flag bits {flags:#04x}")));
    }
    if let Some(i) = (TIME..CRC).step_by(8).find(|&i| !f64_at(b, i).is_finite()) {
        return Err(Malformed::at(i, "value is not finite"));
    }
    let week = u16::from_le_bytes([b[WEEK], b[WEEK + 1]]);
    let week = (week != NO_WEEK).then_some(u32::from(week));
    let t = f64_at(b, TIME);
    let q = Quat::new(
        f64_at(b, QUAT),
        f64_at(b, QUAT + 8),
        f64_at(b, QUAT + 16),
        f64_at(b, QUAT + 24),
    );
    // A sender's float32 quaternion normalised in float64 is within ~1e-7 of unit norm.
    if (q.norm_squared().sqrt() - 1.0).abs() > 1e-6 {
        return Err(Malformed::at(
            QUAT,
            format!("quaternion norm {}, expected 1", q.norm_squared().sqrt()),
        ));
    }
    let q = q.normalized();
    let (pos, vel, acc) = (vec_at(b, POS), vec_at(b, VEL), vec_at(b, ACC));
    let (sample, accel_n) = if flags & FLAG_ECEF != 0 {
        let g = ecef_to_geodetic(pos);
        let c_n_e = g.c_n_e();
        let v_n = c_n_e.tr_mul(&vel);
        // r̈^e = C_n^e (v̇^n + ω_en^n × v^n), solved for v̇^n.
        let w_en = omega_en_n(g.sin_lat, g.cos_lat, g.h, v_n);
        let a_n = c_n_e.tr_mul(&acc) - w_en.cross(&v_n);
        let s = Sample {
            t,
            lat: g.lat(),
            lon: g.lon(),
            h: g.h,
            v_n,
            q_b_n: g.q_n_e().conjugate() * q,
        };
        (s, a_n)
    } else {
        if pos.x.abs() > 90.0 {
            return Err(Malformed::at(
                POS,
                format!("latitude {} is outside [-90, 90] degrees", pos.x),
            ));
        }
        let g = Geodetic::from_radians(pos.x.to_radians(), pos.y.to_radians(), pos.z);
        let s = Sample {
            t,
            lat: g.lat(),
            lon: g.lon(),
            h: pos.z,
            v_n: vel,
            q_b_n: q,
        };
        (s, acc)
    };
    let seq = u32::from_le_bytes(b[SEQ..SEQ + 4].try_into().expect("4 bytes"));
    let d = Decoded {
        seq: Some(u64::from(seq)),
        state: LiveSample {
            sample,
            omega_ib_b: (flags & FLAG_RATE != 0).then(|| vec_at(b, RATE)),
            accel_n: (flags & FLAG_ACCEL != 0).then_some(accel_n),
        },
    };
    Ok((d, week))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::quat_from_euler;

    fn geodetic() -> Datagram {
        let q = quat_from_euler(0.1, -0.2, 2.5);
        Datagram {
            seq: 7,
            week: NO_WEEK,
            time: 12.25,
            flags: FLAG_ACCEL | FLAG_RATE,
            pos: [45.0, 7.5, 250.0],
            vel: [10.0, -3.0, 0.5],
            acc: [0.1, 0.2, -0.3],
            quat: [q.w, q.i, q.j, q.k],
            rate: [0.01, -0.02, 0.03],
        }
    }

    /// The layout of the spec: magic, version, flags, week, sequence and CRC at their offsets,
    /// and the CRC is zlib's (CRC-32 of the first 148 bytes, checked here against the
    /// standard check value of the catalogue's algorithm on "123456789").
    #[test]
    fn layout_and_crc_are_the_documented_ones() {
        assert_eq!(crc().compute(b"123456789"), 0xCBF4_3926);
        let b = encode(&geodetic());
        assert_eq!(&b[..6], b"IMUS\x01\x06");
        assert_eq!(&b[6..12], &[0xFF, 0xFF, 7, 0, 0, 0]);
        assert_eq!(f64::from_le_bytes(b[12..20].try_into().unwrap()), 12.25);
        assert_eq!(f64::from_le_bytes(b[20..28].try_into().unwrap()), 45.0);
        let c = u32::from_le_bytes(b[148..].try_into().unwrap());
        assert_eq!(c, crc().compute(&b[..148]) as u32);
    }

    #[test]
    fn geodetic_round_trip() {
        let d = geodetic();
        let s = decode(&encode(&d)).unwrap();
        assert_eq!(s.seq, Some(7));
        let x = s.state.sample;
        assert_eq!(x.t, 12.25);
        assert!((x.lat - 45f64.to_radians()).abs() < 1e-16);
        assert_eq!(x.v_n, Vec3::new(10.0, -3.0, 0.5));
        assert_eq!(s.state.accel_n, Some(Vec3::new(0.1, 0.2, -0.3)));
        assert_eq!(s.state.omega_ib_b, Some(Vec3::new(0.01, -0.02, 0.03)));
        let mut w = d;
        w.week = 2400;
        w.flags = 0;
        let s = decode(&encode(&w)).unwrap();
        assert_eq!(s.state.sample.t, 2400.0 * 604_800.0 + 12.25);
        assert_eq!((s.state.accel_n, s.state.omega_ib_b), (None, None));
    }

    /// Seconds of week with sub-µs digits survive only when counted from a week start: from
    /// the GPS epoch the sum (≈ 1.45e9 s) is rounded to its 2.4e-7 s ulp.
    #[test]
    fn gps_tags_keep_their_precision_from_a_week_start() {
        let mut w = geodetic();
        (w.week, w.time) = (2400, 345_600.123_456_789);
        let b = encode(&w);
        assert_eq!(decode_since(&b, 2400).unwrap().state.sample.t, w.time);
        assert_eq!(
            decode_since(&b, 2399).unwrap().state.sample.t,
            604_800.0 + w.time
        );
        let from_epoch = decode(&b).unwrap().state.sample.t - 2400.0 * 604_800.0;
        assert!((from_epoch - w.time).abs() > 1e-9, "{from_epoch}");
    }

    /// The same state sent in ECEF decodes to the geodetic one (to the round-off of the
    /// conversions): position, velocity, attitude and the NED acceleration. A wrong sign of
    /// the transport-rate term would show in the acceleration (ω_en × v is ~1e-6 m/s² here,
    /// so the bound is 1e-9).
    #[test]
    fn ecef_equals_geodetic() {
        let d = geodetic();
        let g = Geodetic::from_radians(45f64.to_radians(), 7.5f64.to_radians(), 250.0);
        let c_n_e = g.c_n_e();
        let v_n = Vec3::new(10.0, -3.0, 0.5);
        let a_n = Vec3::new(0.1, 0.2, -0.3);
        let w_en = omega_en_n(g.sin_lat, g.cos_lat, 250.0, v_n);
        let q = g.q_n_e() * Quat::new(d.quat[0], d.quat[1], d.quat[2], d.quat[3]);
        let e = Datagram {
            flags: d.flags | FLAG_ECEF,
            pos: g.to_ecef().into(),
            vel: (c_n_e * v_n).into(),
            acc: (c_n_e * (a_n + w_en.cross(&v_n))).into(),
            quat: [q.w, q.i, q.j, q.k],
            ..d
        };
        let a = decode(&encode(&d)).unwrap().state;
        let b = decode(&encode(&e)).unwrap().state;
        assert!((a.sample.lat - b.sample.lat).abs() < 1e-15);
        assert!((a.sample.lon - b.sample.lon).abs() < 1e-15);
        assert!((a.sample.h - b.sample.h).abs() < 1e-8);
        assert!((a.sample.v_n - b.sample.v_n).amax() < 1e-12);
        assert!((a.accel_n.unwrap() - b.accel_n.unwrap()).amax() < 1e-9);
        assert!(a.sample.q_b_n.dot(&b.sample.q_b_n).abs() > 1.0 - 1e-15);
    }

    /// Every kind of damage is refused with the offset of the field at fault.
    #[test]
    fn damage_names_the_offset() {
        let good = encode(&geodetic());
        let e = decode(&good[..100]).unwrap_err();
        assert_eq!(
            (e.offset, e.message.as_str()),
            (0, "100 bytes, expected 152")
        );
        let mut b = good;
        b[0] = b'X';
        assert_eq!(decode(&b).unwrap_err().offset, 0);
        let mut b = good;
        b[4] = 2;
        assert_eq!(decode(&b).unwrap_err().offset, 4);
        let mut b = good;
        b[30] ^= 1;
        let e = decode(&b).unwrap_err();
        assert_eq!(e.offset, 148, "{e:?}");
        // Valid CRC over bad contents: a NaN velocity, an unnormalised quaternion.
        let mut d = geodetic();
        d.vel[1] = f64::NAN;
        assert_eq!(decode(&encode(&d)).unwrap_err().offset, VEL + 8);
        let mut d = geodetic();
        d.quat[0] *= 1.01;
        assert_eq!(decode(&encode(&d)).unwrap_err().offset, QUAT);
        let mut d = geodetic();
        d.flags = 0x80;
        assert_eq!(decode(&encode(&d)).unwrap_err().offset, 5);
    }
}
