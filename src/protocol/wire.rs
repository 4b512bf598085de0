//! Values to and from wire bytes: integers of 1 to 8 bytes in either byte order, floats, and
//! physical values rounded and saturated to a field's type.

use super::spec::{ByteOrder, WireType};

/// Writes a physical value: floats as they are, integers rounded; both saturated at the type's
/// range (a real unit flags overrange rather than wrapping), NaN as 0: no non-finite value
/// reaches the wire. Returns whether it saturated.
pub(super) fn put_value(dst: &mut [u8], ty: WireType, order: ByteOrder, x: f64) -> bool {
    let x = if x.is_nan() { 0.0 } else { x };
    match ty {
        WireType::F32 => {
            let v = x as f32;
            let saturated = v.is_infinite();
            let v = if saturated { f32::MAX.copysign(v) } else { v };
            put_bytes(dst, &v.to_be_bytes(), order);
            saturated
        }
        WireType::F64 => {
            put_bytes(dst, &x.clamp(f64::MIN, f64::MAX).to_be_bytes(), order);
            x.is_infinite()
        }
        _ => {
            let (lo, hi) = ty.int_range().expect("integer type");
            let v = x.round() as i128;
            put_int(dst, ty, order, v.clamp(lo, hi));
            v < lo || v > hi
        }
    }
}

pub(super) fn get_value(src: &[u8], ty: WireType, order: ByteOrder) -> f64 {
    match ty {
        WireType::F32 => {
            let mut b = [0u8; 4];
            get_bytes(src, &mut b, order);
            f32::from_be_bytes(b) as f64
        }
        WireType::F64 => {
            let mut b = [0u8; 8];
            get_bytes(src, &mut b, order);
            f64::from_be_bytes(b)
        }
        _ => get_int(src, ty, order) as f64,
    }
}

/// Writes the low `ty.bytes()` bytes of v (two's complement) in `order`.
pub(super) fn put_int(dst: &mut [u8], ty: WireType, order: ByteOrder, v: i128) {
    let n = ty.bytes();
    let be = v.to_be_bytes();
    put_bytes(dst, &be[16 - n..], order);
}

pub(super) fn get_int(src: &[u8], ty: WireType, order: ByteOrder) -> i128 {
    let n = ty.bytes();
    let mut be = [0u8; 16];
    get_bytes(src, &mut be[16 - n..], order);
    let raw = i128::from_be_bytes(be);
    match ty.int_range() {
        Some((lo, _)) if lo < 0 && raw >= -lo => raw - 2 * (-lo),
        _ => raw,
    }
}

/// Copies big-endian bytes `be` into `dst` in the wire order.
fn put_bytes(dst: &mut [u8], be: &[u8], order: ByteOrder) {
    match order {
        ByteOrder::Big => dst.copy_from_slice(be),
        ByteOrder::Little => dst
            .iter_mut()
            .zip(be.iter().rev())
            .for_each(|(d, s)| *d = *s),
    }
}

/// Reads wire bytes `src` into big-endian `be`.
fn get_bytes(src: &[u8], be: &mut [u8], order: ByteOrder) {
    match order {
        ByteOrder::Big => be.copy_from_slice(src),
        ByteOrder::Little => be
            .iter_mut()
            .zip(src.iter().rev())
            .for_each(|(d, s)| *d = *s),
    }
}
