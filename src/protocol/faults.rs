//! Fault injection in the encoding stage: corrupted checks, dropped and duplicated frames,
//! frozen counters and status (BIT) failures, at given times or at a mean rate, seeded so a
//! run is reproducible. [`super::Plan::encode`] asks the injector what happens to each frame;
//! [`super::StreamDecoder`] tallies the same five kinds, so a decode of a faulted stream
//! reports exactly what was injected (one fault per frame, see [`FaultInjector::frame`]).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use super::spec::compact;

/// What can go wrong with a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FaultKind {
    /// The frame's check (or, without one, its transport FCS) does not match.
    CorruptCheck,
    /// The frame is not sent (its counter value is skipped).
    Drop,
    /// The frame is sent twice, byte for byte.
    Duplicate,
    /// The counter does not advance on this frame (and continues from there).
    StaleCounter,
    /// The status word shows a built-in-test failure.
    Status,
}

impl FaultKind {
    /// All kinds, in the order faults are resolved when several fall on one frame.
    pub const ALL: [FaultKind; 5] = [
        FaultKind::Drop,
        FaultKind::CorruptCheck,
        FaultKind::Duplicate,
        FaultKind::StaleCounter,
        FaultKind::Status,
    ];

    /// The name used in scene files and flags.
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::CorruptCheck => "corrupt-check",
            FaultKind::Drop => "drop",
            FaultKind::Duplicate => "duplicate",
            FaultKind::StaleCounter => "stale-counter",
            FaultKind::Status => "status",
        }
    }

    /// Parses a name of [`FaultKind::name`].
    pub fn from_name(s: &str) -> Option<FaultKind> {
        FaultKind::ALL.into_iter().find(|k| k.name() == s)
    }

    fn index(self) -> usize {
        FaultKind::ALL.iter().position(|k| *k == self).unwrap_or(0)
    }
}

/// When a fault happens.
#[derive(Clone, Debug, PartialEq)]
pub enum When {
    /// On the first frame at or after each time (s, record time).
    At(Vec<f64>),
    /// Independently on each frame with probability rate/frame-rate (mean events per second).
    Rate(f64),
}

/// One fault entry: a kind, when, and (for `status`) how long each event lasts.
#[derive(Clone, Debug, PartialEq)]
pub struct FaultSpec {
    /// What goes wrong.
    pub kind: FaultKind,
    /// When.
    pub when: When,
    /// Status failures: the failure lasts this long from each event (s); 0 = one frame.
    pub duration_s: f64,
}

/// A checked fault entry cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FaultError {
    /// A time or rate out of range.
    #[error("{0}")]
    Value(String),
    /// The protocol cannot show this fault.
    #[error("protocol `{protocol}` cannot show `{kind}` faults: {why}")]
    Unsupported {
        /// Protocol name.
        protocol: String,
        /// Fault name.
        kind: &'static str,
        /// What the protocol lacks.
        why: &'static str,
    },
}

impl FaultSpec {
    /// Checks times, rate and duration against the frame rate (Hz).
    pub fn validate(&self, frame_rate: f64) -> Result<(), FaultError> {
        match &self.when {
            When::At(ts) => {
                if let Some(t) = ts.iter().find(|t| !t.is_finite()) {
                    return Err(FaultError::Value(format!("time {t} is not finite")));
                }
            }
            When::Rate(r) => {
                if !(r.is_finite() && *r >= 0.0 && *r <= frame_rate) {
                    return Err(FaultError::Value(format!(
                        "rate {}/s: expected 0 to the frame rate {}/s",
                        compact(*r),
                        compact(frame_rate)
                    )));
                }
            }
        }
        if !(self.duration_s.is_finite() && self.duration_s >= 0.0) {
            return Err(FaultError::Value(format!(
                "duration {} s: expected a non-negative time",
                compact(self.duration_s)
            )));
        }
        if self.duration_s > 0.0 && self.kind != FaultKind::Status {
            return Err(FaultError::Value(format!(
                "a duration applies to `status` faults only, not `{}`",
                self.kind.name()
            )));
        }
        Ok(())
    }

    /// Parses the flag form `KIND@T1,T2,…` (times in s) or `KIND~RATE` (events per second).
    pub fn parse_flag(s: &str) -> Result<FaultSpec, String> {
        let names = || {
            FaultKind::ALL
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let (kind, when) = if let Some((k, ts)) = s.split_once('@') {
            let times = ts
                .split(',')
                .map(|t| {
                    t.trim()
                        .parse::<f64>()
                        .map_err(|_| format!("time `{t}` is not a number"))
                })
                .collect::<Result<Vec<_>, _>>()?;
            (k, When::At(times))
        } else if let Some((k, r)) = s.split_once('~') {
            let r = r
                .trim()
                .parse::<f64>()
                .map_err(|_| format!("rate `{r}` is not a number"))?;
            (k, When::Rate(r))
        } else {
            return Err(format!(
                "expected KIND@T1,T2,… or KIND~RATE_PER_S (KIND: {})",
                names()
            ));
        };
        let kind = FaultKind::from_name(kind.trim())
            .ok_or_else(|| format!("unknown fault `{kind}` (expected {})", names()))?;
        Ok(FaultSpec {
            kind,
            when,
            duration_s: 0.0,
        })
    }
}

/// What happens to one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameFaults {
    /// Not sent.
    pub drop: bool,
    /// Check corrupted.
    pub corrupt: bool,
    /// Sent twice.
    pub duplicate: bool,
    /// Counter not advanced.
    pub stale: bool,
    /// Status word shows a failure.
    pub status: bool,
}

/// Faults injected so far, by kind (shared between clones of an injector, so the caller that
/// handed an injector to a job can read the tally afterwards).
#[derive(Clone, Debug, Default)]
pub struct FaultTally(Arc<[AtomicU64; 5]>);

impl FaultTally {
    /// Count of one kind.
    pub fn get(&self, k: FaultKind) -> u64 {
        self.0[k.index()].load(Ordering::Relaxed)
    }

    fn add(&self, k: FaultKind) {
        self.0[k.index()].fetch_add(1, Ordering::Relaxed);
    }

    /// `drop 3, corrupt-check 1, …` for messages.
    pub fn summary(&self) -> String {
        FaultKind::ALL
            .iter()
            .map(|k| format!("{} {}", k.name(), self.get(*k)))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Decides, frame by frame, which faults apply.
#[derive(Clone, Debug)]
pub struct FaultInjector {
    specs: Vec<FaultSpec>,
    /// Per spec: index of the next time of `When::At` (times sorted).
    next: Vec<usize>,
    /// Per spec: end time of a status failure in progress.
    until: Vec<f64>,
    /// SplitMix64 sequence state: uniform draws for the rate-based faults.
    rng: u64,
    frame_rate: f64,
    tally: FaultTally,
}

impl FaultInjector {
    /// An injector for frames at `frame_rate` Hz; `seed` drives the rate-based faults.
    /// The specs must have passed [`FaultSpec::validate`].
    pub fn new(mut specs: Vec<FaultSpec>, frame_rate: f64, seed: u64) -> FaultInjector {
        for s in &mut specs {
            if let When::At(ts) = &mut s.when {
                ts.sort_by(f64::total_cmp);
            }
        }
        FaultInjector {
            next: vec![0; specs.len()],
            until: vec![f64::NEG_INFINITY; specs.len()],
            specs,
            rng: seed ^ crate::rng::fnv1a64("faults"),
            frame_rate,
            tally: FaultTally::default(),
        }
    }

    /// The kinds this injector can produce.
    pub fn kinds(&self) -> impl Iterator<Item = FaultKind> + '_ {
        self.specs.iter().map(|s| s.kind)
    }

    /// The faults in words (`drop@1,2; corrupt-check~0.5/s`), for a run's description.
    pub fn describe(&self) -> String {
        let parts: Vec<String> = (self.specs.iter())
            .map(|s| match &s.when {
                When::At(t) => {
                    let t: Vec<String> = t.iter().map(|x| x.to_string()).collect();
                    format!("{}@{}", s.kind.name(), t.join(","))
                }
                When::Rate(r) => format!("{}~{r}/s", s.kind.name()),
            })
            .collect();
        parts.join("; ")
    }

    /// The shared tally of faults injected.
    pub fn tally(&self) -> FaultTally {
        self.tally.clone()
    }

    /// The faults of the frame of record time `t` (frames in time order). At most one fault per
    /// frame, the first of [`FaultKind::ALL`] that falls on it (a dropped frame cannot also be
    /// corrupted); a status failure in progress yields to the others too. Every random draw is
    /// made whatever the outcome, so one spec's events do not depend on the others'.
    pub fn frame(&mut self, t: f64) -> FrameFaults {
        let mut hit = [false; 5];
        for (i, s) in self.specs.iter().enumerate() {
            let fires = match &s.when {
                When::At(ts) => {
                    let mut fired = false;
                    while self.next[i] < ts.len() && ts[self.next[i]] <= t + 1e-9 {
                        self.next[i] += 1;
                        fired = true;
                    }
                    fired
                }
                When::Rate(r) => {
                    self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
                    let u = (crate::rng::splitmix64(self.rng) >> 11) as f64 / (1u64 << 53) as f64;
                    u < r / self.frame_rate
                }
            };
            if fires && s.kind == FaultKind::Status {
                self.until[i] = t + s.duration_s;
            }
            let active = s.kind == FaultKind::Status && t <= self.until[i] + 1e-9;
            hit[s.kind.index()] |= fires || active;
        }
        let Some(k) = FaultKind::ALL.into_iter().find(|k| hit[k.index()]) else {
            return FrameFaults::default();
        };
        self.tally.add(k);
        let mut f = FrameFaults::default();
        match k {
            FaultKind::Drop => f.drop = true,
            FaultKind::CorruptCheck => f.corrupt = true,
            FaultKind::Duplicate => f.duplicate = true,
            FaultKind::StaleCounter => f.stale = true,
            FaultKind::Status => f.status = true,
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_fire_once_on_the_first_frame_at_or_after() {
        let mut inj = FaultInjector::new(
            vec![FaultSpec {
                kind: FaultKind::Drop,
                when: When::At(vec![0.35, 0.1]),
                duration_s: 0.0,
            }],
            10.0,
            1,
        );
        let dropped: Vec<usize> = (0..10)
            .filter(|k| inj.frame(*k as f64 * 0.1).drop)
            .collect();
        assert_eq!(dropped, vec![1, 4]);
        assert_eq!(inj.tally().get(FaultKind::Drop), 2);
    }

    #[test]
    fn status_lasts_its_duration_and_yields_to_drops() {
        let mut inj = FaultInjector::new(
            vec![
                FaultSpec {
                    kind: FaultKind::Status,
                    when: When::At(vec![0.2]),
                    duration_s: 0.3,
                },
                FaultSpec {
                    kind: FaultKind::Drop,
                    when: When::At(vec![0.3]),
                    duration_s: 0.0,
                },
            ],
            10.0,
            1,
        );
        let f: Vec<FrameFaults> = (0..8).map(|k| inj.frame(k as f64 * 0.1)).collect();
        let status: Vec<usize> = (0..8).filter(|&k| f[k].status).collect();
        assert_eq!(status, vec![2, 4, 5]);
        assert!(f[3].drop && !f[3].status);
    }

    /// Rate-based faults: reproducible for a seed, and the count is binomial(n, p): 10 000
    /// frames at p = 0.05 give 500 ± 22 (1σ); 5σ bounds.
    #[test]
    fn rates_are_seeded_and_binomial() {
        let run = |seed| {
            let mut inj = FaultInjector::new(
                vec![FaultSpec {
                    kind: FaultKind::Duplicate,
                    when: When::Rate(5.0),
                    duration_s: 0.0,
                }],
                100.0,
                seed,
            );
            (0..10_000)
                .map(|k| inj.frame(k as f64 * 0.01).duplicate)
                .collect::<Vec<_>>()
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7), run(8));
        let n = run(7).iter().filter(|x| **x).count() as f64;
        assert!(
            (n - 500.0).abs() < 5.0 * (10_000.0f64 * 0.05 * 0.95).sqrt(),
            "{n}"
        );
    }

    #[test]
    fn flag_syntax() {
        assert_eq!(
            FaultSpec::parse_flag("drop@1.5,2").unwrap().when,
            When::At(vec![1.5, 2.0])
        );
        assert_eq!(
            FaultSpec::parse_flag("status~0.5").unwrap(),
            FaultSpec {
                kind: FaultKind::Status,
                when: When::Rate(0.5),
                duration_s: 0.0
            }
        );
        assert!(
            FaultSpec::parse_flag("melt@1")
                .unwrap_err()
                .contains("unknown fault `melt`")
        );
        assert!(FaultSpec::parse_flag("drop").is_err());
    }
}
