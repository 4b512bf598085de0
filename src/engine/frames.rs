//! Frames with emission times: the interface between whatever produces frames (a rig's
//! units, a GNSS receiver, an odometer) and the real-time merger and pacer
//! (`realtime::merge`). A stream is a sequence of (emission time, bytes); a source gives its
//! streams' frames a window of simulated time at a time. No I/O here.

use crate::engine::EngineError;

/// The frames one stream emits in a window: bytes back to back, the end of each frame in
/// `bytes`, and its emission time (simulated ns after the run's t₀).
#[derive(Debug, Default, Clone)]
pub struct Part {
    /// The frames' bytes back to back.
    pub bytes: Vec<u8>,
    /// End offset of each frame in `bytes`.
    pub ends: Vec<usize>,
    /// Emission time of each frame (simulated ns after t₀), non-decreasing.
    pub emit_ns: Vec<i64>,
    /// The stream's frames are an IMU's records, whose time marks and pulses the pacer gives
    /// (kept by [`Part::clear`]).
    pub marks_records: bool,
    /// With `marks_records`: each frame's record index (0-based) and time of validity
    /// (simulated ns after t₀).
    pub records: Vec<(u64, i64)>,
    /// With `marks_records`, when the frames follow another clock than the run's speed (a
    /// live input's): each record's time of validity on the pacer's clock (ns after its
    /// start); empty otherwise.
    pub tov_wall_ns: Vec<i64>,
}

impl Part {
    /// Empties the part, keeping its buffers.
    pub fn clear(&mut self) {
        self.bytes.clear();
        self.ends.clear();
        self.emit_ns.clear();
        self.records.clear();
        self.tov_wall_ns.clear();
    }

    /// Appends one frame emitted at `emit_ns`.
    pub fn push(&mut self, frame: &[u8], emit_ns: i64) {
        self.bytes.extend_from_slice(frame);
        self.ends.push(self.bytes.len());
        self.emit_ns.push(emit_ns);
    }
}

/// The end of a window of simulated time: frames emitted at or before `ns` (after the run's
/// t₀) are due, records whose interval ends at or before `t` (absolute record time, s) are
/// released. The two say the same instant; both are kept so that a source decides on the
/// exact record times it computes (`ns` is `t` rounded up, so a record released by `t` is
/// never held back by the rounding).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Until {
    /// Emission times (ns after the run's t₀) due by the window's end.
    pub ns: i64,
    /// Record time (s) of the window's end.
    pub t: f64,
}

impl Until {
    /// The window ending `ns` after `origin` (the run's t₀, s).
    pub fn ns(origin: f64, ns: i64) -> Until {
        Until {
            ns,
            t: origin + ns as f64 * 1e-9,
        }
    }

    /// The window ending at record time `t`, the run's t₀ being `origin` (s).
    pub fn time(origin: f64, t: f64) -> Until {
        let ns = ((t - origin) * 1e9).ceil();
        Until {
            ns: if ns.is_nan() { i64::MIN } else { ns as i64 },
            t,
        }
    }

    /// The window ending at a state's time tag `t` (the newest the motion is known to): the
    /// records on `t` are released even when their computed time comes out a rounding after
    /// it ([`crate::math::tag_slack`]).
    pub fn state(origin: f64, t: f64) -> Until {
        Until::time(origin, t + crate::math::tag_slack(t, origin))
    }

    /// A window that releases everything.
    pub const ALL: Until = Until {
        ns: i64::MAX,
        t: f64::INFINITY,
    };
}

/// A source of frames for a run: one or more streams, filled a window of simulated time at a
/// time. A source never evaluates its motion past the window's end, so it can follow a live
/// motion that is only known up to now.
pub trait WindowSource: Send {
    /// How many streams this source has (each its own entry in a merged block).
    fn streams(&self) -> usize;
    /// Appends to `parts` (one per stream, cleared by the caller) the frames due by `until`
    /// that were not given before.
    fn fill(&mut self, until: Until, parts: &mut [Part]) -> Result<(), EngineError>;
    /// True once every frame has been given.
    fn done(&self) -> bool;
    /// The earliest emission time (ns after t₀) a frame not yet given can have, if known: a
    /// just-in-time run wakes for it.
    fn next_due_ns(&self) -> Option<i64> {
        None
    }
    /// Status flags (e.g. [`crate::record::FLAG_STALE`]) every record produced from now on
    /// carries, where the source's frames have such bits.
    fn set_flags(&mut self, _flags: u8) {}
    /// An external trigger edge closed the sample interval (lo, hi] (s after t₀): a triggered
    /// source takes one sample over it; others ignore it.
    fn edge(&mut self, _lo: f64, _hi: f64) {}
}

/// A single stream's frames one at a time, each with its emission time: a GNSS receiver's
/// epochs, an odometer's samples. [`EmitWindow`] turns it into a [`WindowSource`].
pub trait Emitter: Send {
    /// The next frame's time of validity (s of record time): it is made only once the window
    /// reaches it, since a frame is never emitted before it is valid. `None`: after the last.
    fn next_time(&self) -> Option<f64>;
    /// Appends the next frame to `out` and returns its emission time (s of record time);
    /// `None` after the last frame.
    fn next_frame(&mut self, out: &mut Vec<u8>) -> Result<Option<f64>, EngineError>;
}

/// An [`Emitter`] as a one-stream [`WindowSource`], its emission times counted from `origin`.
pub struct EmitWindow<E> {
    src: E,
    origin: f64,
    /// The next frame (in `bytes`), made but not yet due, and its emission time (ns).
    pending: Option<i64>,
    bytes: Vec<u8>,
    done: bool,
}

impl<E: Emitter> EmitWindow<E> {
    /// The frames of `src`, emission times in ns after `origin` (the run's t₀, s).
    pub fn new(src: E, origin: f64) -> EmitWindow<E> {
        EmitWindow {
            src,
            origin,
            pending: None,
            bytes: Vec::new(),
            done: false,
        }
    }
}

impl<E: Emitter> WindowSource for EmitWindow<E> {
    fn streams(&self) -> usize {
        1
    }

    fn fill(&mut self, until: Until, parts: &mut [Part]) -> Result<(), EngineError> {
        let until_ns = until.ns;
        while !self.done {
            let at = match self.pending {
                Some(at) => at,
                None => {
                    // Not valid before the window's end: not made yet (its motion may not be
                    // known yet), and not due either.
                    match self.src.next_time() {
                        Some(t) if ((t - self.origin) * 1e9).round() as i64 > until_ns => break,
                        Some(_) => {}
                        None => {
                            self.done = true;
                            break;
                        }
                    }
                    self.bytes.clear();
                    match self.src.next_frame(&mut self.bytes)? {
                        Some(t) => ((t - self.origin) * 1e9).round() as i64,
                        None => {
                            self.done = true;
                            break;
                        }
                    }
                }
            };
            if at > until_ns {
                self.pending = Some(at);
                break;
            }
            self.pending = None;
            parts[0].push(&self.bytes, at);
        }
        Ok(())
    }

    fn done(&self) -> bool {
        self.done
    }

    fn next_due_ns(&self) -> Option<i64> {
        match self.pending {
            Some(at) => Some(at),
            None => (self.src.next_time()).map(|t| ((t - self.origin) * 1e9).round() as i64),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames every 0.3 s from t = 10 s, counted from origin 10 s.
    struct Every(u32);
    impl Emitter for Every {
        fn next_time(&self) -> Option<f64> {
            (self.0 < 5).then(|| 10.0 + 0.3 * (self.0 + 1) as f64)
        }
        fn next_frame(&mut self, out: &mut Vec<u8>) -> Result<Option<f64>, EngineError> {
            if self.0 == 5 {
                return Ok(None);
            }
            self.0 += 1;
            out.push(self.0 as u8);
            Ok(Some(10.0 + 0.3 * self.0 as f64))
        }
    }

    /// A frame due after the window waits for the next one (not lost, not early); a window
    /// ending exactly at an emission time takes that frame.
    #[test]
    fn frames_wait_for_their_window() {
        let mut w = EmitWindow::new(Every(0), 10.0);
        let mut parts = vec![Part::default()];
        w.fill(Until::ns(10.0, 600_000_000), &mut parts).unwrap();
        assert_eq!(parts[0].bytes, [1, 2]);
        assert_eq!(parts[0].emit_ns, [300_000_000, 600_000_000]);
        parts[0].clear();
        w.fill(Until::ns(10.0, 899_999_999), &mut parts).unwrap();
        assert!(parts[0].ends.is_empty() && !w.done());
        w.fill(Until::ns(10.0, 10_000_000_000), &mut parts).unwrap();
        assert_eq!(parts[0].bytes, [3, 4, 5]);
        assert_eq!(parts[0].ends, [1, 2, 3]);
        assert!(w.done());
    }
}
