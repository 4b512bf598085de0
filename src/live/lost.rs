//! States lost on an input without sequence numbers (CSV lines), told from the time steps:
//! a sender sends at a steady step, so a step that is k times its usual one says k − 1
//! states went missing, as a break of k in the sequence numbers does for the binary
//! datagram. The usual step is the median of the last [`WINDOW`] steps: a lost state, a
//! late one, a burst are a minority there and do not move it, and a sender that changes its
//! rate for good moves it within half the window.

/// Steps between arrived states the usual step is the median of.
pub const WINDOW: usize = 15;

/// Steps seen before a step is judged: fewer say too little about the sender's rate.
pub const MIN_STEPS: usize = 4;

/// How far a step may be from a whole multiple k ≥ 2 of the usual one, as a fraction of the
/// usual step, and still count as k − 1 lost states. A step between multiples (1.5 times
/// the usual one) is a sender changing its step, or its tags jittering, not a loss.
pub const TOLERANCE: f64 = 0.25;

/// The recent steps of the states that arrived in line, and the newest one's time.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StepWatch {
    steps: [f64; WINDOW],
    /// Steps held (up to [`WINDOW`]); the next one goes to `steps[next]`.
    held: usize,
    next: usize,
    newest: Option<f64>,
}

impl StepWatch {
    /// Takes the time of a state that arrived in line (taken, or refused for its values but
    /// on the sender's time line); returns how many states its step says were lost before
    /// it. A time not after the newest one's is ignored.
    pub fn arrived(&mut self, t: f64) -> u64 {
        let Some(newest) = self.newest.filter(|&n| t > n) else {
            if self.newest.is_none() && t.is_finite() {
                self.newest = Some(t);
            }
            return 0;
        };
        let step = t - newest;
        let lost = match self.usual() {
            Some(u) => {
                let r = step / u;
                let k = r.round();
                if k >= 2.0 && (r - k).abs() <= TOLERANCE && k < 1e9 {
                    k as u64 - 1
                } else {
                    0
                }
            }
            None => 0,
        };
        self.steps[self.next] = step;
        self.next = (self.next + 1) % WINDOW;
        self.held = (self.held + 1).min(WINDOW);
        self.newest = Some(t);
        lost
    }

    /// The median of the steps held (the lower middle one of an even count), once there are
    /// [`MIN_STEPS`].
    fn usual(&self) -> Option<f64> {
        if self.held < MIN_STEPS {
            return None;
        }
        let mut s = self.steps;
        let held = &mut s[..self.held];
        let mid = (self.held - 1) / 2;
        let (_, m, _) = held.select_nth_unstable_by(mid, f64::total_cmp);
        (*m > 0.0).then_some(*m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feed(w: &mut StepWatch, times: &[f64]) -> Vec<u64> {
        times.iter().map(|&t| w.arrived(t)).collect()
    }

    /// A step of k usual steps is k − 1 lost states; the first steps, a step between
    /// multiples and a time not after the newest are none.
    #[test]
    fn whole_multiples_of_the_usual_step_are_losses() {
        let mut w = StepWatch::default();
        // Steps 0.01 (four of them: the minimum), then 0.02, 0.04, 0.015, a repeat, 0.01.
        let t = [
            0.0, 0.01, 0.02, 0.03, 0.04, 0.06, 0.10, 0.115, 0.115, 0.11, 0.125,
        ];
        assert_eq!(feed(&mut w, &t), vec![0, 0, 0, 0, 0, 1, 3, 0, 0, 0, 0]);
        // Tags jittered by ±0.5 ms (steps ±10 %): no loss; a double step among them is one.
        let mut w = StepWatch::default();
        let t = [0.0, 0.0105, 0.0195, 0.0305, 0.04, 0.0495, 0.0705, 0.0795];
        assert_eq!(feed(&mut w, &t), vec![0, 0, 0, 0, 0, 0, 1, 0]);
    }

    /// A sender that halves its rate for good: the doubled steps count as losses until they
    /// are the median, after half the window, and not after.
    #[test]
    fn a_lasting_rate_change_moves_the_usual_step() {
        let mut w = StepWatch::default();
        let mut times: Vec<f64> = (0..20).map(|k| f64::from(k) * 0.01).collect();
        times.extend((1..=20).map(|k| 0.19 + f64::from(k) * 0.02));
        let lost = feed(&mut w, &times);
        assert_eq!(lost[20..].iter().sum::<u64>(), (WINDOW / 2 + 1) as u64);
        assert!(lost[20 + WINDOW / 2 + 1..].iter().all(|&l| l == 0));
    }
}
