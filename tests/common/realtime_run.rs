//! Helpers of the tests that run the emulator in real time: one such test at a time in a test
//! binary, and what a live run's summary says about where its output left its input.
//!
//! A real-time live run follows its input exactly while every state arrives within the output
//! delay; on a loaded machine one may not (the sender's thread, or the emulator's input thread,
//! not scheduled for longer than the delay), and the run then extrapolates and later bridges
//! back. The run reports the first frame past the newest state of the moment and the longest
//! extrapolation it corrected; the tests compare with a lockstep replay up to that frame and
//! bound the corrections by that span — bounds derived from the run's own report, not from an
//! assumption about the machine.
#![allow(dead_code)]

use std::sync::{Mutex, MutexGuard};

/// Held by each real-time test of a binary, so that its emulators do not load the machine
/// for each other.
pub fn serial() -> MutexGuard<'static, ()> {
    static ONE: Mutex<()> = Mutex::new(());
    ONE.lock().unwrap_or_else(|p| p.into_inner())
}

/// The number right after `key` in `text`, if `key` is there.
fn after(text: &str, key: &str) -> Option<f64> {
    let i = text.find(key)? + key.len();
    let word: String = text[i..]
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_digit() || ".e-+".contains(*c))
        .collect();
    Some(
        word.parse()
            .unwrap_or_else(|_| panic!("a number after `{key}` in {text}")),
    )
}

/// The time (s) of the first frame the run made past the newest state of the moment: up to
/// it, the output is the input's exactly; `None` if it never left the input.
pub fn departed(summary: &str) -> Option<f64> {
    after(summary, "first frame past the newest state at t =")
}

/// The longest extrapolation the run corrected (s): 0 without a correction.
pub fn longest_corrected(summary: &str) -> f64 {
    after(summary, "longest extrapolation corrected").map_or(0.0, |ms| ms * 1e-3)
}

/// How many records of a grid from `t0` at `rate` end at or before `t` (record k, 1-based,
/// ends at t0 + k/rate): those a run that left its input at `t` made from the input.
pub fn records_to(t0: f64, rate: f64, t: f64) -> usize {
    // A record on `t` itself is the input's; 1e-6 of a period covers the times' rounding.
    ((t - t0) * rate + 1e-6).floor().max(0.0) as usize
}

/// How well the run read the host's UTC − monotonic offset (ns), from its note "host clocks:
/// UTC − monotonic read to ±N ns": every UTC or GPS instant it converts is within this of the
/// host's clocks.
pub fn clock_reading_ns(stderr: &str) -> i128 {
    let key = "UTC − monotonic read to ±";
    let at = stderr
        .find(key)
        .unwrap_or_else(|| panic!("`{key}` in {stderr}"))
        + key.len();
    let digits: String = stderr[at..]
        .chars()
        .take_while(char::is_ascii_digit)
        .collect();
    digits.parse().unwrap()
}

/// Where the run's latest correction rejoined the input (s): its output follows the input from
/// there until it next leaves it; `None` without a correction.
pub fn rejoined(summary: &str) -> Option<f64> {
    after(summary, "back on the input from t =")
}
