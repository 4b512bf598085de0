//! u-blox UBX NAV-PVT (class 0x01, id 0x07, 92-byte payload) of a GNSS epoch: sync 0xB5 0x62,
//! class, id, little-endian length, payload, and the 8-bit Fletcher checksum over class to
//! payload end (u-blox 8 / M8 receiver description, UBX-13003221, §32.17.15.1).

use super::gnss::{Fix, GnssEpoch};
use super::nmea::course;
use super::time::{GpsTime, Utc};

/// Payload length of NAV-PVT.
pub const NAV_PVT_LEN: usize = 92;

/// Time accuracy the frames claim (ns): a receiver with a fix knows GPS time to tens of ns.
pub const TIME_ACCURACY_NS: u32 = 30;

/// The NAV-PVT frame of epoch `e` at GPS time `time` (UTC = GPS − `leap` s), appended to `out`.
pub fn encode(e: &GnssEpoch, time: GpsTime, leap: i64, out: &mut Vec<u8>) {
    let mut p = [0u8; NAV_PVT_LEN];
    let u = Utc::from_units(time.utc_units(leap, 1_000_000_000), 1_000_000_000);
    let m = &e.measured;
    let fix = e.fix.is_valid();
    put(&mut p, 0, &time.tow_ms().to_le_bytes());
    put(&mut p, 4, &(u.year as u16).to_le_bytes());
    p[6] = u.month as u8;
    p[7] = u.day as u8;
    p[8] = u.hour as u8;
    p[9] = u.minute as u8;
    p[10] = u.second as u8;
    p[11] = 0x07; // validDate | validTime | fullyResolved
    put(&mut p, 12, &TIME_ACCURACY_NS.to_le_bytes());
    put(&mut p, 16, &(u.sub as i32).to_le_bytes());
    p[20] = if fix { 3 } else { 0 };
    p[21] = match e.fix {
        Fix::None => 0,
        Fix::Autonomous => 0x01,
        Fix::Differential => 0x03,
        Fix::RtkFloat => 0x03 | 1 << 6,
        Fix::RtkFixed => 0x03 | 2 << 6,
    };
    p[22] = 0xE0; // flags2: confirmedAvai | confirmedDate | confirmedTime
    p[23] = e.satellites;
    if fix {
        let s = e.sigma_pos;
        let sv = e.sigma_vel;
        let (speed, cog) = course(m.v_n.x, m.v_n.y);
        put(&mut p, 24, &deg_e7(m.lon).to_le_bytes());
        put(&mut p, 28, &deg_e7(m.lat).to_le_bytes());
        put(&mut p, 32, &mm(m.h).to_le_bytes());
        put(&mut p, 36, &mm(m.h).to_le_bytes());
        put(&mut p, 40, &(mm(s.x.hypot(s.y)) as u32).to_le_bytes());
        put(&mut p, 44, &(mm(s.z) as u32).to_le_bytes());
        for (i, v) in m.v_n.iter().enumerate() {
            put(&mut p, 48 + 4 * i, &mm(*v).to_le_bytes());
        }
        put(&mut p, 60, &mm(speed).to_le_bytes());
        // Rounded, then wrapped: a course a rounding below 360° reads 0, not 360.
        put(
            &mut p,
            64,
            &(((cog * 1e5).round() as i32) % 36_000_000).to_le_bytes(),
        );
        put(&mut p, 68, &(mm(sv.norm()) as u32).to_le_bytes());
        // Course σ ≈ horizontal speed σ / speed, at most 180°.
        let head_acc = if speed > 0.0 {
            (sv.x.hypot(sv.y) / speed).to_degrees().min(180.0)
        } else {
            180.0
        };
        put(&mut p, 72, &((head_acc * 1e5).round() as u32).to_le_bytes());
        let pdop = (e.pdop() * 100.0).round().min(u16::MAX as f64) as u16;
        put(&mut p, 76, &pdop.to_le_bytes());
    } else {
        put(&mut p, 76, &u16::MAX.to_le_bytes());
        p[78] = 0x01; // flags3: invalidLlh
    }
    frame(0x01, 0x07, &p, out);
}

/// A UBX frame of `class`, `id` and `payload`, appended to `out`.
pub fn frame(class: u8, id: u8, payload: &[u8], out: &mut Vec<u8>) {
    let start = out.len();
    out.extend_from_slice(&[0xB5, 0x62, class, id]);
    out.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    out.extend_from_slice(payload);
    let (a, b) = out[start + 2..].iter().fold((0u8, 0u8), |(a, b), &x| {
        let a = a.wrapping_add(x);
        (a, b.wrapping_add(a))
    });
    out.extend_from_slice(&[a, b]);
}

fn put(p: &mut [u8], at: usize, bytes: &[u8]) {
    p[at..at + bytes.len()].copy_from_slice(bytes);
}

fn deg_e7(rad: f64) -> i32 {
    (rad.to_degrees() * 1e7).round() as i32
}

fn mm(m: f64) -> i32 {
    (m * 1000.0).round() as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// UBX-MON-VER poll (class 0x0A, id 0x04, empty payload) is B5 62 0A 04 00 00 0E 34 in
    /// the u-blox receiver description.
    #[test]
    fn checksum_of_a_published_poll() {
        let mut out = Vec::new();
        frame(0x0A, 0x04, &[], &mut out);
        assert_eq!(out, [0xB5, 0x62, 0x0A, 0x04, 0x00, 0x00, 0x0E, 0x34]);
    }
}
