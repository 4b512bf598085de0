//! Where a frame cannot start: every message has a byte of a constant field (a sync word, an
//! ID) at a fixed offset from its start, so a decoder hunting through garbage need only try
//! the places where one of those bytes is — found with `memchr`, at memory speed, instead of
//! trying a whole decode at every byte.

use super::layout::{Layout, What};
use super::wire::{get_int, put_int};

/// One anchor byte per message: (offset in the frame, value).
#[derive(Clone, Debug)]
pub(super) struct Anchors {
    each: Vec<(usize, u8)>,
    /// The largest offset: a place this close to the end of the bytes at hand is never
    /// skipped (its anchor has not arrived).
    reach: usize,
}

impl Anchors {
    /// The anchors of `layouts`; `None` when some message has no constant field (its frames
    /// can start anywhere).
    pub(super) fn of(layouts: &[Layout]) -> Option<Anchors> {
        let each = layouts.iter().map(anchor).collect::<Option<Vec<_>>>()?;
        let reach = each.iter().map(|a| a.0).max()?;
        Some(Anchors { each, reach })
    }

    /// How many of the first places in `bytes` start no frame of any message: at each, every
    /// message's anchor lies within `bytes` and differs.
    pub(super) fn no_frame_before(&self, bytes: &[u8]) -> usize {
        let end = bytes.len().saturating_sub(self.reach);
        let off = self.each[0].0;
        if self.each.iter().all(|a| a.0 == off) {
            // Anchors all at one offset (every built-in protocol): memchr over that column.
            let hay = &bytes[off..off + end];
            let mut set: Vec<u8> = self.each.iter().map(|a| a.1).collect();
            set.sort_unstable();
            set.dedup();
            let found = match set[..] {
                [a] => memchr::memchr(a, hay),
                [a, b] => memchr::memchr2(a, b, hay),
                [a, b, c] => memchr::memchr3(a, b, c, hay),
                _ => hay.iter().position(|x| set.contains(x)),
            };
            return found.unwrap_or(end);
        }
        (0..end)
            .find(|&p| self.each.iter().any(|&(o, b)| bytes[p + o] == b))
            .unwrap_or(end)
    }
}

/// A byte of one of the constant fields a decoder checks (those before a truncated frame's
/// payload), preferring one other than 0x00 and 0xFF, which fill idle lines and padding.
fn anchor(l: &Layout) -> Option<(usize, u8)> {
    let end = l.truncate.map_or(usize::MAX, |t| t.from);
    let mut best: Option<(usize, u8)> = None;
    for op in l.ops.iter().filter(|op| op.offset < end) {
        let What::Constant(v) = op.what else {
            continue;
        };
        let n = op.ty.bytes();
        let mut wire = [0u8; 8];
        put_int(&mut wire[..n], op.ty, op.order, i128::from(v));
        // Only bytes that are the constant's as the decoder reads it back.
        if get_int(&wire[..n], op.ty, op.order) as i64 != v {
            continue;
        }
        for (i, &b) in wire[..n].iter().enumerate() {
            let common = |b: u8| b == 0 || b == 0xFF;
            if best.is_none_or(|(_, k)| common(k) && !common(b)) {
                best = Some((op.offset + i, b));
            }
        }
    }
    best
}
