//! External sample trigger, as KVH's MSYNC input on the 1750/1775 (its technical manual): the
//! unit takes one sample per trigger edge, integrating over the interval since the previous
//! edge. Pure: edge instants in, interval bounds on the run's time axis out.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

/// Turns trigger edges (integer ns on any monotonic clock) into sample intervals relative to
/// the run's t₀, which the first edge marks.
#[derive(Clone, Debug)]
pub struct Trigger {
    origin_ns: Option<i128>,
    last: f64,
    span: f64,
    edges: u64,
}

impl Trigger {
    /// A trigger whose samples may reach `span` seconds after t₀ (the end of the motion).
    pub fn new(span: f64) -> Trigger {
        Trigger {
            origin_ns: None,
            last: 0.0,
            span,
            edges: 0,
        }
    }

    /// Takes the edge at `ns`: the first one sets t₀ and closes no interval (`None`); each later
    /// one closes (previous edge, this edge], relative to t₀ (s). An edge not after the
    /// previous one, or past the motion's end, is an error naming it.
    pub fn edge(&mut self, ns: i128) -> Result<Option<(f64, f64)>, String> {
        self.edges += 1;
        let Some(origin) = self.origin_ns else {
            self.origin_ns = Some(ns);
            return Ok(None);
        };
        let t = (ns - origin) as f64 * 1e-9;
        if t <= self.last {
            return Err(format!(
                "trigger edge {} at {t:.9} s is not after the previous one ({:.9} s)",
                self.edges, self.last
            ));
        }
        if t > self.span {
            return Err(format!(
                "trigger edge {} at {t:.9} s is past the end of the motion ({:.9} s after the first edge)",
                self.edges, self.span
            ));
        }
        let lo = std::mem::replace(&mut self.last, t);
        Ok(Some((lo, t)))
    }

    /// The first edge's instant (ns), once it came.
    pub fn origin_ns(&self) -> Option<i128> {
        self.origin_ns
    }
}

/// Where a triggered producer ([`crate::engine::Producer::with_trigger`]) takes the intervals of its
/// samples from.
pub trait TriggerSource: Send {
    /// The next sample's interval (relative to t₀, s), blocking until its edge; `None` when
    /// the edges end (the run stops), an error when an edge cannot close an interval.
    fn next_interval(&mut self) -> Option<Result<(f64, f64), String>>;
}

/// Intervals queued by whoever receives the edges (a run's driver, through
/// [`crate::engine::frames::WindowSource::edge`]) for the triggered producers that share the
/// queue: a clone is the same queue. A producer takes the intervals queued so far and waits,
/// without blocking, for more.
#[derive(Clone, Default)]
pub struct Queue(Arc<Mutex<VecDeque<(f64, f64)>>>);

impl Queue {
    /// Queues the interval (lo, hi] (s after t₀).
    pub fn push(&self, lo: f64, hi: f64) {
        self.lock().push_back((lo, hi));
    }

    /// Intervals queued and not yet taken.
    pub fn len(&self) -> usize {
        self.lock().len()
    }

    /// Whether no interval is waiting.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, VecDeque<(f64, f64)>> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl TriggerSource for Queue {
    fn next_interval(&mut self) -> Option<Result<(f64, f64), String>> {
        self.lock().pop_front().map(Ok)
    }
}

/// Edges given up front (ns), for tests and replays of recorded edge times.
pub struct EdgeList {
    edges: std::vec::IntoIter<i128>,
    trigger: Trigger,
}

impl EdgeList {
    /// Samples at `edges` (the first marks t₀) over a motion reaching `span` s after t₀.
    pub fn new(edges: Vec<i128>, span: f64) -> EdgeList {
        EdgeList {
            edges: edges.into_iter(),
            trigger: Trigger::new(span),
        }
    }
}

impl TriggerSource for EdgeList {
    fn next_interval(&mut self) -> Option<Result<(f64, f64), String>> {
        loop {
            match self.trigger.edge(self.edges.next()?) {
                Ok(None) => continue,
                Ok(Some(iv)) => return Some(Ok(iv)),
                Err(e) => return Some(Err(e)),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Irregular edges give the intervals between them from the first edge on; a repeated or
    /// backward edge and one past the motion are refused, naming the edge.
    #[test]
    fn intervals_between_edges() {
        let mut t = Trigger::new(1.0);
        let base = 5_000_000_000_123i128;
        assert_eq!(t.edge(base).unwrap(), None);
        assert_eq!(t.origin_ns(), Some(base));
        // Offsets from the first edge in integer ns, then seconds: no rounding accumulates.
        let (a, b) = (3_100_000.0 * 1e-9, 19_700_000.0 * 1e-9);
        assert_eq!(t.edge(base + 3_100_000).unwrap(), Some((0.0, a)));
        assert_eq!(t.edge(base + 19_700_000).unwrap(), Some((a, b)));
        let e = t.edge(base + 19_700_000).unwrap_err();
        assert!(e.contains("edge 4") && e.contains("not after"), "{e}");
        let e = t.edge(base + 1_000_000_001).unwrap_err();
        assert!(e.contains("edge 5") && e.contains("past the end"), "{e}");
    }
}
