//! MAVLink 2 HIL_GPS (message 113) of a GNSS epoch: what PX4 and ArduPilot take as simulated
//! GPS input (common.xml, <https://mavlink.io/en/messages/common.html#HIL_GPS>).
//!
//! Packet: STX 0xFD, payload length as sent (trailing zero bytes dropped, at least one kept),
//! incompat and compat flags 0, sequence, system id 1, component id 1, 24-bit message id,
//! payload with its fields sorted by size (extensions `id`, `yaw` last), CRC-16/MCRF4XX over
//! the bytes after STX then the message's CRC_EXTRA 124.

use crc::{CRC_16_MCRF4XX, Crc};

use super::gnss::{Fix, GnssEpoch};
use super::nmea::course;

/// HIL_GPS message id.
pub const MSG_ID: u32 = 113;
/// HIL_GPS CRC_EXTRA (from its field names and types, as pymavlink 2.4.50 generates it).
pub const CRC_EXTRA: u8 = 124;
/// Full payload length with the extension fields.
pub const PAYLOAD_LEN: usize = 39;

static X25: Crc<u16> = Crc::<u16>::new(&CRC_16_MCRF4XX);

/// The HIL_GPS packet of epoch `e` with sequence number `seq`, appended to `out`. `time_usec`
/// is the time of validity in µs of record time. Velocities beyond ±327.67 m/s saturate
/// (the fields are i16 cm/s).
pub fn encode(e: &GnssEpoch, seq: u8, out: &mut Vec<u8>) {
    let mut p = [0u8; PAYLOAD_LEN];
    let m = &e.measured;
    let fix = e.fix.is_valid();
    let (speed, cog) = course(m.v_n.x, m.v_n.y);
    let cm_s = |v: f64| (v * 100.0).round().clamp(i16::MIN as f64, i16::MAX as f64) as i16;
    p[0..8].copy_from_slice(&((e.t * 1e6).round() as u64).to_le_bytes());
    if fix {
        let e7 = |rad: f64| (rad.to_degrees() * 1e7).round() as i32;
        p[8..12].copy_from_slice(&e7(m.lat).to_le_bytes());
        p[12..16].copy_from_slice(&e7(m.lon).to_le_bytes());
        p[16..20].copy_from_slice(&((m.h * 1000.0).round() as i32).to_le_bytes());
    }
    let dop = |d: f64| {
        if fix {
            (d * 100.0).round().min(65534.0) as u16
        } else {
            u16::MAX
        }
    };
    p[20..22].copy_from_slice(&dop(e.hdop).to_le_bytes());
    p[22..24].copy_from_slice(&dop(e.vdop).to_le_bytes());
    let vel = if fix {
        (speed * 100.0).round().min(65534.0) as u16
    } else {
        u16::MAX
    };
    p[24..26].copy_from_slice(&vel.to_le_bytes());
    if fix {
        for (i, v) in m.v_n.iter().enumerate() {
            p[26 + 2 * i..28 + 2 * i].copy_from_slice(&cm_s(*v).to_le_bytes());
        }
    }
    let cog = if fix {
        ((cog * 100.0).round() as u16) % 36_000
    } else {
        u16::MAX
    };
    p[32..34].copy_from_slice(&cog.to_le_bytes());
    p[34] = fix_type(e.fix);
    p[35] = e.satellites;
    // p[36] id = 0 (first GPS), p[37..39] yaw = 0 (not available).
    let len = p.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
    let start = out.len();
    out.extend_from_slice(&[0xFD, len as u8, 0, 0, seq, 1, 1]);
    out.extend_from_slice(&MSG_ID.to_le_bytes()[..3]);
    out.extend_from_slice(&p[..len]);
    let mut d = X25.digest();
    d.update(&out[start + 1..]);
    d.update(&[CRC_EXTRA]);
    out.extend_from_slice(&d.finalize().to_le_bytes());
}

/// MAVLink GPS_FIX_TYPE: 1 no fix, 3 3-D, 4 DGPS, 5 RTK float, 6 RTK fixed.
pub fn fix_type(f: Fix) -> u8 {
    match f {
        Fix::None => 1,
        Fix::Autonomous => 3,
        Fix::Differential => 4,
        Fix::RtkFloat => 5,
        Fix::RtkFixed => 6,
    }
}
