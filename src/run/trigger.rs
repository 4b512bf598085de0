//! External sample trigger in real time (`run --trigger`): edges from the same sources as the
//! PPS input ([`crate::realtime::pps`]: a UDP edge message, a serial port's DCD or CTS line, a PPS
//! device) become the intervals a triggered producer samples over
//! ([`crate::engine::trigger`]).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};

use crate::engine::trigger::{Trigger, TriggerSource};
use crate::realtime::pps::POLL;

/// Intervals between the edges arriving on a channel (CLOCK_MONOTONIC ns), the first edge
/// already taken as t₀.
pub struct ChannelTrigger {
    rx: Receiver<i128>,
    trigger: Trigger,
    stop: Arc<AtomicBool>,
}

impl ChannelTrigger {
    /// Samples at the edges of `rx` after the first one, `first` (ns), over a motion reaching
    /// `span` s after t₀; stops when `stop` is set or the source ends.
    pub fn new(
        rx: Receiver<i128>,
        first: i128,
        span: f64,
        stop: Arc<AtomicBool>,
    ) -> ChannelTrigger {
        let mut trigger = Trigger::new(span);
        let none = trigger.edge(first);
        debug_assert!(matches!(none, Ok(None)));
        ChannelTrigger { rx, trigger, stop }
    }
}

impl TriggerSource for ChannelTrigger {
    fn next_interval(&mut self) -> Option<Result<(f64, f64), String>> {
        loop {
            if self.stop.load(Ordering::Relaxed) {
                return None;
            }
            match self.rx.recv_timeout(POLL) {
                Ok(ns) => return self.trigger.edge(ns).transpose(),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return None,
            }
        }
    }
}
