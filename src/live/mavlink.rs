//! MAVLink 2 `HIL_STATE_QUATERNION` (message 115, common.xml on mavlink.io), what PX4- and
//! ArduPilot-style simulators send as the vehicle's state, decoded by the project's protocol
//! machinery from its specification `protocols/live/mavlink-hil-state-quaternion.toml`
//! (layout, scales, trailing-zero truncation, CRC-16/MCRF4XX with CRC_EXTRA 4), as the
//! HIL_SENSOR frames of `protocols/mavlink-hil-sensor.toml` are. This module only finds the
//! frame (its length, a signature after the CRC when incompat_flags bit 0 is set), skips other
//! messages and turns the decoded fields into a state.
//!
//! Taken: time, attitude, position, velocity, and the body rates as ω_ib^b (the simulators'
//! gyro-like rates). Not taken: airspeeds and the accelerations (their frame and whether
//! gravity is in them differ between simulators). The altitude is taken as height above the
//! ellipsoid. The message's resolution is coarse (1 cm/s, float32 attitude): see
//! docs/live-input.md for what that costs.

use std::path::Path;
use std::sync::OnceLock;

use super::{Decoded, Malformed};
use crate::math::{Quat, QuatExt, Vec3};
use crate::motion::causal::LiveSample;
use crate::motion::sampled::Sample;
use crate::protocol::check::Check;
use crate::protocol::spec::{Source, StateQty};
use crate::protocol::{DecodeError, Plan};

/// Message id of HIL_STATE_QUATERNION.
pub const MSG_ID: u32 = 115;
/// Its CRC_EXTRA byte (from its field definitions).
pub const CRC_EXTRA: u8 = 4;
/// Its full payload length.
pub const PAYLOAD: usize = 64;
/// MAVLink 2 start byte.
pub const STX: u8 = 0xFD;
/// Header bytes before the payload.
pub const HEADER: usize = 10;
/// Incompatibility flag: the frame is signed (13 more bytes after the CRC).
const SIGNED: u8 = 1;
/// The message's specification.
pub const SPEC: &str = include_str!("../../protocols/live/mavlink-hil-state-quaternion.toml");

/// The compiled specification (compiled once; a test checks it compiles).
fn plan() -> &'static Plan {
    static PLAN: OnceLock<Plan> = OnceLock::new();
    PLAN.get_or_init(|| {
        let path = Path::new("protocols/live/mavlink-hil-state-quaternion.toml");
        crate::protocol::load::compile_text(SPEC, path)
            .expect("the built-in HIL_STATE_QUATERNION spec compiles")
            .1
    })
}

/// Length of the MAVLink 2 frame that starts `b` (header, payload, CRC, signature), if the
/// header is there.
pub fn frame_len(b: &[u8]) -> Option<usize> {
    if b.len() < 3 || b[0] != STX {
        return None;
    }
    let sig = if b[2] & SIGNED != 0 { 13 } else { 0 };
    Some(HEADER + b[1] as usize + 2 + sig)
}

/// Decodes one frame; `None` for a valid frame of another message.
pub fn decode(b: &[u8]) -> Result<Option<Decoded>, Malformed> {
    let Some(len) = frame_len(b) else {
        return Err(Malformed::at(0, "not a MAVLink 2 frame (start byte 0xFD)"));
    };
    if b.len() != len {
        return Err(Malformed::at(
            0,
            format!("{} bytes, the header says {len}", b.len()),
        ));
    }
    let n = b[1] as usize;
    let msgid = u32::from(b[7]) | u32::from(b[8]) << 8 | u32::from(b[9]) << 16;
    if msgid != MSG_ID {
        return Ok(None);
    }
    if n > PAYLOAD {
        return Err(Malformed::at(
            1,
            format!("payload {n} bytes, HIL_STATE_QUATERNION has {PAYLOAD}"),
        ));
    }
    let plan = plan();
    // The signature, if any, follows the CRC: the spec's frame ends at the CRC.
    let d = plan.decode(b).map_err(|e| match e {
        DecodeError::Check { got, computed, .. } => Malformed::at(
            HEADER + n,
            format!("CRC {got:04x}, computed {computed:04x}"),
        ),
        DecodeError::Length { got, max } => {
            Malformed::at(1, format!("payload {got} bytes, expected 1 to {max}"))
        }
        e => Malformed::at(0, e.to_string()),
    })?;
    let get = |s: Source| d.get(s).expect("a field of the HIL_STATE_QUATERNION spec");
    let state = |q: StateQty| get(Source::State(q));
    let at = |s: Source| plan.offset_of(s).expect("a field of the spec");
    let floats = (0..4)
        .map(|i| Source::State(StateQty::Q(i)))
        .chain((0..3).map(Source::Gyro));
    if let Some(s) = floats.into_iter().find(|s| !get(*s).is_finite()) {
        return Err(Malformed::at(at(s), "value is not finite"));
    }
    let q = Quat::new(
        state(StateQty::Q(0)),
        state(StateQty::Q(1)),
        state(StateQty::Q(2)),
        state(StateQty::Q(3)),
    );
    // float32 components: a unit quaternion's norm is within a few 1e-7 of 1.
    let norm = q.norm_squared().sqrt();
    if (norm - 1.0).abs() > 1e-5 {
        return Err(Malformed::at(
            at(Source::State(StateQty::Q(0))),
            format!("quaternion norm {norm}, expected 1"),
        ));
    }
    let lat = state(StateQty::Lat);
    if lat.abs() > 90.0 {
        return Err(Malformed::at(
            at(Source::State(StateQty::Lat)),
            format!("latitude {lat} is outside [-90, 90] degrees"),
        ));
    }
    let sample = Sample {
        t: get(Source::Time),
        lat: lat.to_radians(),
        lon: state(StateQty::Lon).to_radians(),
        h: state(StateQty::Alt),
        v_n: Vec3::new(
            state(StateQty::Vel(0)),
            state(StateQty::Vel(1)),
            state(StateQty::Vel(2)),
        ),
        q_b_n: q.normalized(),
    };
    Ok(Some(Decoded {
        seq: Some(get(Source::Counter) as u64),
        state: LiveSample {
            sample,
            omega_ib_b: Some(Vec3::new(
                get(Source::Gyro(0)),
                get(Source::Gyro(1)),
                get(Source::Gyro(2)),
            )),
            accel_n: None,
        },
    }))
}

/// The raw `time_usec` of a frame [`decode`] took (the first payload field; a truncated
/// payload's missing bytes are zeros): the decoded time in seconds rounds it to a double.
pub fn time_usec(b: &[u8]) -> u64 {
    let n = b.get(1).map_or(0, |&n| usize::from(n)).min(8);
    let mut t = [0u8; 8];
    if let Some(p) = b.get(HEADER..HEADER + n) {
        t[..n].copy_from_slice(p);
    }
    u64::from_le_bytes(t)
}

/// Encodes a HIL_STATE_QUATERNION frame (system 1, component 1), trailing zeros dropped as
/// MAVLink 2 senders do: for tests and replays. Written by hand, independently of the
/// specification the decoder runs, so that each checks the other.
pub fn encode(
    seq: u8,
    time_usec: u64,
    q: [f32; 4],
    rates: [f32; 3],
    pos: [i32; 3],
    vel: [i16; 3],
) -> Vec<u8> {
    let mut p = Vec::with_capacity(PAYLOAD);
    p.extend_from_slice(&time_usec.to_le_bytes());
    for x in q.iter().chain(&rates) {
        p.extend_from_slice(&x.to_le_bytes());
    }
    for x in pos {
        p.extend_from_slice(&x.to_le_bytes());
    }
    for x in vel {
        p.extend_from_slice(&x.to_le_bytes());
    }
    p.resize(PAYLOAD, 0);
    let n = p.iter().rposition(|&x| x != 0).map_or(1, |i| i + 1);
    let mut f = vec![STX, n as u8, 0, 0, seq, 1, 1];
    f.extend_from_slice(&MSG_ID.to_le_bytes()[..3]);
    f.extend_from_slice(&p[..n]);
    let check = Check::named("crc-16/mcrf4xx").expect("a catalogue CRC");
    let c = check.compute_parts(&[&f[1..], &[CRC_EXTRA]]) as u16;
    f.extend_from_slice(&c.to_le_bytes());
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Packed by pymavlink 2.4.50: `MAVLink_hil_state_quaternion_message(1234567, [1,0,0,0],
    /// 0.01, 0.02, -0.03, 451000000, 75000000, 100000, 1000, -200, 30, 0, 0, 10, -20, -1000)`,
    /// system 1, component 1, sequence 3.
    const PYMAVLINK: &str = "fd40000003010173000087d61200000000000000803f0000000000000000000000000ad7233c0ad7a33c8fc2f5bcc0b6e11ac0687804a0860100e80338ff1e00000000000a00ecff18fc4ab7";

    fn hex(s: &str) -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    #[test]
    fn decodes_the_pymavlink_frame() {
        let b = hex(PYMAVLINK);
        assert_eq!(frame_len(&b), Some(b.len()));
        let d = decode(&b).unwrap().unwrap();
        assert_eq!(d.seq, Some(3));
        let s = d.state.sample;
        assert_eq!(s.t, 1.234567);
        assert_eq!(s.lat, 45.1f64.to_radians());
        assert_eq!(s.lon, 7.5f64.to_radians());
        assert_eq!(s.h, 100.0);
        assert_eq!(s.v_n, Vec3::new(10.0, -2.0, 0.3));
        assert_eq!(s.q_b_n, Quat::identity());
        let w = d.state.omega_ib_b.unwrap();
        assert_eq!(w.x, f64::from(0.01f32));
        assert_eq!(w.z, f64::from(-0.03f32));
    }

    /// Our encoder gives pymavlink's bytes but for the accelerations it does not send.
    #[test]
    fn encoder_matches_pymavlink_layout() {
        let f = encode(
            3,
            1_234_567,
            [1.0, 0.0, 0.0, 0.0],
            [0.01, 0.02, -0.03],
            [451_000_000, 75_000_000, 100_000],
            [1000, -200, 30],
        );
        let want = hex(PYMAVLINK);
        // Same header but the length, same payload up to the velocities (ours ends there:
        // its airspeeds and accelerations are zeros, dropped).
        assert_eq!(f.len(), 10 + 53 + 2);
        assert_eq!(&f[2..10], &want[2..10]);
        assert_eq!(&f[10..63], &want[10..63]);
        assert_eq!(
            decode(&f).unwrap().unwrap().state,
            decode(&want).unwrap().unwrap().state
        );
    }

    /// The pymavlink frame re-sent signed (incompat_flags bit 0, 13 signature bytes after
    /// the CRC) by another system and component decodes to the same state; the quaternion's
    /// and the latitude's errors name their byte in the frame.
    #[test]
    fn signed_frames_other_senders_and_bad_values() {
        let plain = hex(PYMAVLINK);
        let reframe = |f: &mut Vec<u8>| {
            let n = HEADER + f[1] as usize;
            let c = Check::named("crc-16/mcrf4xx").unwrap();
            let crc = c.compute_parts(&[&f[1..n], &[CRC_EXTRA]]) as u16;
            f[n..n + 2].copy_from_slice(&crc.to_le_bytes());
        };
        let mut signed = plain.clone();
        signed[2] = SIGNED;
        signed[5] = 42;
        signed[6] = 200;
        reframe(&mut signed);
        signed.extend_from_slice(&[0xAB; 13]);
        assert_eq!(frame_len(&signed), Some(plain.len() + 13));
        assert_eq!(
            decode(&signed).unwrap().unwrap(),
            decode(&plain).unwrap().unwrap()
        );
        // Quaternion w (payload byte 8) = 2.0: norm 2.
        let mut q = plain.clone();
        q[HEADER + 8..HEADER + 12].copy_from_slice(&2.0f32.to_le_bytes());
        reframe(&mut q);
        let e = decode(&q).unwrap_err();
        assert_eq!(e.offset, HEADER + 8, "{e:?}");
        assert!(e.message.contains("quaternion norm 2"), "{e:?}");
        // Latitude (payload byte 36) = 95°; yawspeed (byte 32) NaN.
        let mut lat = plain.clone();
        lat[HEADER + 36..HEADER + 40].copy_from_slice(&950_000_000i32.to_le_bytes());
        reframe(&mut lat);
        assert_eq!(decode(&lat).unwrap_err().offset, HEADER + 36);
        let mut nan = plain;
        nan[HEADER + 32..HEADER + 36].copy_from_slice(&f32::NAN.to_le_bytes());
        reframe(&mut nan);
        let e = decode(&nan).unwrap_err();
        assert_eq!(
            (e.offset, e.message.as_str()),
            (HEADER + 32, "value is not finite")
        );
    }

    #[test]
    fn damage_and_other_messages() {
        let mut b = hex(PYMAVLINK);
        b[20] ^= 4;
        let e = decode(&b).unwrap_err();
        assert_eq!(e.offset, 74, "{e:?}");
        let e = decode(&hex(PYMAVLINK)[..30]).unwrap_err();
        assert!(e.message.contains("30 bytes, the header says 76"), "{e:?}");
        assert_eq!(decode(&[0x55, 1, 2]).unwrap_err().offset, 0);
        // A heartbeat-sized frame of another message id is skipped, whatever its CRC.
        let mut other = hex(PYMAVLINK);
        other[7] = 0;
        assert_eq!(decode(&other).unwrap(), None);
    }
}
