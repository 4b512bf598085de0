//! What happened to the incoming states: taken, malformed, duplicated, reordered, missing and
//! refused, counted and never fatal; the first problems are kept with their place.

use super::Decoded;
use super::lost::StepWatch;
use super::transport::{Message, Receiver};
use crate::motion::causal::Rejected;

/// Problems kept word for word (the rest are only counted).
pub const KEEP_PROBLEMS: usize = 10;

/// Problems an input that gave too few states names in its error.
pub const WHY_PROBLEMS: usize = 3;

/// Counters of the input.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InputStats {
    /// Messages received (lines, datagrams, frames), with or without a state.
    pub messages: u64,
    /// Messages without a state: CSV headers, comments and blank lines, other MAVLink
    /// messages (counted by [`InputStats::no_state`]).
    pub without_state: u64,
    /// States taken into the motion model.
    pub states: u64,
    /// Messages that could not be decoded.
    pub malformed: u64,
    /// States with the time (or sequence number) of the newest one.
    pub duplicates: u64,
    /// States older than the newest one (reordered or late): too late to be used.
    pub reordered: u64,
    /// Breaks in the sequence numbers, or (CSV, which has none) steps of several of the
    /// sender's usual time steps.
    pub gaps: u64,
    /// States missing by the sequence numbers or the time steps (some may arrive later, as
    /// reordered).
    pub missing: u64,
    /// States refused: beyond the physical limits, or a time tag the run cannot place (a step
    /// too long to bridge, a tag ahead of the sender's clock).
    pub refused: u64,
    /// Stream bytes outside any frame (garbage, a lost frame's remains).
    pub skipped_bytes: u64,
    /// TCP connections accepted (0 for other inputs).
    pub connections: u64,
    /// TCP connections that brought a state taken into the model: the others (a readiness
    /// probe, a sender that closed before its first sound state) brought nothing.
    pub connections_with_state: u64,
    /// The first [`KEEP_PROBLEMS`] problems, each with its place.
    pub problems: Vec<String>,
    last_seq: Option<u64>,
    /// The connection of the message being counted, and the newest one that brought a state.
    connection: u64,
    connection_counted: u64,
    /// The time steps of a format without sequence numbers, for its lost states.
    steps: StepWatch,
}

impl InputStats {
    /// Counts a message, before what it held is counted.
    pub fn message(&mut self, m: &Message) {
        self.messages += 1;
        self.connection = m.connection;
    }

    /// Takes the receiver's own counts: bytes skipped, connections.
    pub fn transport(&mut self, rx: &Receiver) {
        self.skipped_bytes = rx.skipped_bytes();
        self.connections = rx.connections();
    }

    /// Counts a message that decoded to no state (the decoder's `Ok(None)`).
    pub fn no_state(&mut self) {
        self.without_state += 1;
    }

    /// Counts a malformed message.
    pub fn malformed(&mut self, place: &str, message: &str) {
        self.malformed += 1;
        self.note(format!("{place}: {message}"));
    }

    fn note(&mut self, p: String) {
        if self.problems.len() < KEEP_PROBLEMS {
            self.problems.push(p);
        }
    }

    /// Counts a decoded state and what the model did with it; `modulo` is the range of the
    /// format's sequence numbers.
    pub fn state(&mut self, d: &Decoded, outcome: &Result<(), Rejected>, modulo: u64, place: &str) {
        match outcome {
            Ok(()) => {
                self.states += 1;
                self.lost_by_time(d);
                if self.connection != self.connection_counted {
                    self.connections_with_state += 1;
                    self.connection_counted = self.connection;
                }
                if let (Some(s), Some(last)) = (d.seq, self.last_seq) {
                    let ahead = s.wrapping_sub(last) % modulo;
                    if ahead > 1 && ahead < modulo / 2 {
                        self.gaps += 1;
                        self.missing += ahead - 1;
                    }
                }
                if d.seq.is_some() {
                    self.last_seq = d.seq;
                }
            }
            Err(Rejected::NotAfter { newest }) => {
                if d.state.sample.t == *newest {
                    self.duplicates += 1;
                } else {
                    self.reordered += 1;
                }
            }
            Err(e) => {
                self.refused += 1;
                self.note(format!("{place}: {e}"));
                // Refused for its values, it still arrived on the sender's time line.
                if matches!(e, Rejected::Limit(_)) {
                    self.lost_by_time(d);
                }
                // It arrived: the states after it are no gap.
                if let Some(s) = d.seq
                    && self
                        .last_seq
                        .is_none_or(|l| s.wrapping_sub(l) % modulo < modulo / 2)
                {
                    self.last_seq = Some(s);
                }
            }
        }
    }

    /// Counts the states a state without a sequence number says were lost before it, from
    /// its time step ([`super::lost`]), as a break in the sequence numbers counts them.
    fn lost_by_time(&mut self, d: &Decoded) {
        if d.seq.is_some() {
            return;
        }
        let lost = self.steps.arrived(d.state.sample.t);
        if lost > 0 {
            self.gaps += 1;
            self.missing += lost;
        }
    }

    /// Why messages gave no usable state, for a run that ended without enough: the counts and
    /// the first [`WHY_PROBLEMS`] problems with their places; empty when every message gave
    /// a state (or none came).
    pub fn why_unused(&self) -> String {
        if self.messages == 0 {
            return match self.connections {
                0 => "; no message came".into(),
                n => format!("; no message came on {}", connections(n)),
            };
        }
        let mut s = format!("; input: {}", self.summary());
        if !self.problems.is_empty() {
            let first: Vec<&str> = self
                .problems
                .iter()
                .take(WHY_PROBLEMS)
                .map(String::as_str)
                .collect();
            s.push_str(&format!("; first: {}", first.join("; ")));
        }
        s
    }

    /// One line for the summary; the messages without a state are told apart, so that a CSV
    /// header is not taken for a lost state.
    pub fn summary(&self) -> String {
        let without = match self.without_state {
            0 => String::new(),
            n => format!(" ({n} without a state: headers, comments, other messages)"),
        };
        let conns = match self.connections {
            0 => String::new(),
            n => format!(
                "; {}, {} without a state taken",
                connections(n),
                n.saturating_sub(self.connections_with_state)
            ),
        };
        format!(
            "{} messages{without}, {} states taken; {} malformed, {} duplicate, {} reordered/late, {} missing in {} gaps, {} refused, {} bytes skipped{conns}",
            self.messages,
            self.states,
            self.malformed,
            self.duplicates,
            self.reordered,
            self.missing,
            self.gaps,
            self.refused,
            self.skipped_bytes
        )
    }
}

/// "1 connection", "2 connections".
fn connections(n: u64) -> String {
    match n {
        1 => "1 connection".into(),
        n => format!("{n} connections"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Quat, Vec3};
    use crate::motion::causal::LiveSample;
    use crate::motion::sampled::Sample;

    fn at(seq: u64, t: f64) -> Decoded {
        Decoded {
            seq: Some(seq),
            state: LiveSample::plain(Sample {
                t,
                lat: 0.0,
                lon: 0.0,
                h: 0.0,
                v_n: Vec3::zeros(),
                q_b_n: Quat::identity(),
            }),
        }
    }

    /// Gaps count across the wrap of an 8-bit counter; duplicates and reordered states are
    /// told apart by time.
    #[test]
    fn gaps_duplicates_reordering() {
        let mut s = InputStats::default();
        let ok = Ok(());
        s.state(&at(250, 1.0), &ok, 256, "");
        s.state(&at(253, 1.3), &ok, 256, "");
        s.state(&at(2, 1.8), &ok, 256, "");
        assert_eq!((s.gaps, s.missing, s.states), (2, 2 + 4, 3));
        s.state(
            &at(2, 1.8),
            &Err(Rejected::NotAfter { newest: 1.8 }),
            256,
            "",
        );
        s.state(
            &at(1, 1.7),
            &Err(Rejected::NotAfter { newest: 1.8 }),
            256,
            "",
        );
        assert_eq!((s.duplicates, s.reordered), (1, 1));
        // A late state does not move the sequence back: the next one is no gap.
        s.state(&at(3, 1.9), &ok, 256, "");
        assert_eq!(s.gaps, 2);
        // A state refused by the limits arrived: the one after it is no gap either.
        let limit = Err(Rejected::Limit(crate::motion::limits::Violation {
            column: "wx",
            message: "too fast".into(),
        }));
        s.state(&at(4, 2.0), &limit, 256, "x:9");
        s.state(&at(5, 2.1), &ok, 256, "");
        assert_eq!((s.gaps, s.refused), (2, 1));
        assert_eq!(s.problems, vec!["x:9: `wx`: too fast".to_string()]);
        s.malformed("x:3", "bad");
        assert_eq!(s.problems[1], "x:3: bad");
    }

    /// States without sequence numbers (CSV) lost on the way: counted from the time steps
    /// in the same counts as a break in the sequence numbers; a reordered state is missing
    /// when its successor comes and late when it comes, as with sequence numbers; a state
    /// refused for its values arrived, so the step after it is no loss.
    #[test]
    fn csv_losses_from_the_time_steps() {
        let mut s = InputStats::default();
        let csv = |t: f64| Decoded {
            seq: None,
            ..at(0, t)
        };
        let ok = Ok(());
        for k in [0, 1, 2, 3, 4, 6, 7, 8, 12, 13] {
            s.state(&csv(f64::from(k) * 0.01), &ok, 256, "");
        }
        assert_eq!((s.gaps, s.missing), (2, 1 + 3));
        s.state(&csv(0.15), &ok, 256, "");
        let late = Err(Rejected::NotAfter { newest: 0.15 });
        s.state(&csv(0.14), &late, 256, "");
        assert_eq!((s.gaps, s.missing, s.reordered), (3, 5, 1));
        let limit = Err(Rejected::Limit(crate::motion::limits::Violation {
            column: "wx",
            message: "too fast".into(),
        }));
        s.state(&csv(0.16), &limit, 256, "x");
        s.state(&csv(0.17), &ok, 256, "");
        assert_eq!((s.gaps, s.missing), (3, 5));
    }

    /// A CSV header is a message without a state, and the summary says so (issue 23 item 7:
    /// "203 messages, 201 states taken" read as two states lost).
    #[test]
    fn the_summary_tells_headers_from_states() {
        let mut s = InputStats {
            messages: 3,
            ..InputStats::default()
        };
        s.no_state();
        s.state(&at(1, 1.0), &Ok(()), 256, "");
        s.state(&at(2, 1.1), &Ok(()), 256, "");
        assert!(
            s.summary().starts_with(
                "3 messages (1 without a state: headers, comments, other messages), 2 states taken;"
            ),
            "{}",
            s.summary()
        );
    }
}
