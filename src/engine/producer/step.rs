//! The producer's steps: one block of records on the grid (with timing errors or not), one
//! through an output filter, one per trigger edge; and the fields frames carry beside them.

use crate::record::Record;

use super::{EngineError, Producer};

impl Producer {
    /// Generates and corrupts the next block of up to `max` records: (first index, count).
    pub(super) fn step(&mut self, max: usize) -> Option<(u64, usize)> {
        if self.k > self.count || max == 0 {
            return None;
        }
        if self.trigger.is_some() {
            return self.step_triggered();
        }
        let n = ((self.count - self.k + 1) as usize).min(max);
        if self.block.len() < n {
            self.block.resize(n, Record::default());
        }
        let first = self.k - 1;
        if self.filtered.is_some() {
            return self.step_filtered(first, n);
        }
        match self.timing.as_mut() {
            Some(t) => {
                let timed = t.instants(self.k, n);
                self.imu
                    .fill_timed(self.k, (&timed.gyro, &timed.accel), &mut self.block[..n]);
            }
            None => self.imu.fill(self.k, &mut self.block[..n]),
        }
        if let Err(e) = Producer::check_finite(&self.block[..n], "in the error-free signal") {
            return self.fail(e);
        }
        let chain_rot = self
            .chain
            .as_ref()
            .is_some_and(|c| c.needs_rotation_terms());
        let place_rot = self.places_with_rotation();
        if chain_rot || place_rot {
            if self.rot.len() < n {
                self.rot.resize(n, Default::default());
            }
            // Under timing errors the accelerometers integrate over their true
            // intervals, and so do the lever-arm terms.
            match self.timing.as_ref() {
                Some(t) => self
                    .imu
                    .rotation_terms_timed(&t.block().accel, &mut self.rot[..n]),
                None => self.imu.rotation_terms(self.k, &mut self.rot[..n]),
            }
        }
        if self.keep_truth {
            self.truth.clear();
            self.truth.extend_from_slice(&self.block[..n]);
            // Rates over the nominal Δt, as the records' (timed records too).
            let (rot, dt) = (std::mem::take(&mut self.rot), 1.0 / self.grid.rate_hz);
            self.place_truth(place_rot.then(|| &rot[..n]), dt);
            self.rot = rot;
        }
        if let Some(c) = self.chain.as_mut() {
            if chain_rot {
                c.apply_with(&mut self.block[..n], Some(&self.rot[..n]));
            } else {
                c.apply(&mut self.block[..n]);
            }
            if let Err(e) = Producer::check_finite(&self.block[..n], "after the error chain") {
                return self.fail(e);
            }
        }
        self.k += n as u64;
        let n = match self.timing.as_mut() {
            Some(t) => {
                let comps = (self.chain.as_mut())
                    .filter(|c| !c.components().is_empty())
                    .map(|c| c.components_mut());
                let truth = if self.keep_truth {
                    &mut self.truth[..]
                } else {
                    &mut [][..]
                };
                let kept = t.compact(&mut self.block[..n], truth, comps);
                self.truth.truncate(kept);
                kept
            }
            None => n,
        };
        Some((first, n))
    }

    /// Whether the kept truth is placed ([`Producer::with_truth_place`]) with the motion's
    /// rotation terms (a lever arm).
    fn places_with_rotation(&self) -> bool {
        self.keep_truth && (self.truth_place.as_ref()).is_some_and(|p| p.needs_rotation_terms())
    }

    /// Turns the kept truth into the readings at the unit's place and in its axes, if it has
    /// one; `rot`: the truth records' rotation terms, normalised by `dt` as their rates are.
    fn place_truth(&mut self, rot: Option<&[crate::generator::RotationTerms]>, dt: f64) {
        if let Some(p) = self.truth_place.as_ref() {
            p.place(&mut self.truth, rot, dt);
        }
    }

    /// [`Producer::step`] for a unit with an output filter: the records from the internal-rate
    /// run, the truth from the output-rate generator. Under timing errors the sensor's clock
    /// sets both: the internal records integrate over its true internal intervals, the truth
    /// over the true output intervals (every decimation-th internal bound), and the skipped
    /// samples fold into the next one taken as without a filter.
    fn step_filtered(&mut self, first: u64, n: usize) -> Option<(u64, usize)> {
        let f = self.filtered.as_mut()?;
        // Emission-only timing leaves the samples on the nominal grid: the nominal path, bit
        // for bit the run without timing errors.
        let timed = match self.timing.as_mut() {
            Some(t) => Some(t.instants(self.k, n)).filter(|b| !b.internal.0.is_empty()),
            None => None,
        };
        let timed_truth = timed.is_some();
        match timed {
            Some(b) => f.fill_timed(self.k, (&b.internal.0, &b.internal.1), &mut self.block[..n]),
            None => f.fill(self.k, &mut self.block[..n]),
        }
        if let Err(e) = Producer::check_finite(&self.block[..n], "after the output filter") {
            return self.fail(e);
        }
        if self.keep_truth {
            self.truth.clear();
            self.truth.resize(n, Record::default());
            let bounds = (self.timing.as_ref())
                .filter(|_| timed_truth)
                .map(|t| (&t.block().gyro, &t.block().accel));
            match bounds {
                Some((g, a)) => self.imu.fill_timed(self.k, (g, a), &mut self.truth),
                None => self.imu.fill(self.k, &mut self.truth),
            }
            if let Err(e) = Producer::check_finite(&self.truth, "in the error-free signal") {
                return self.fail(e);
            }
            let place_rot = self.places_with_rotation();
            if place_rot {
                self.rot.resize(n.max(self.rot.len()), Default::default());
                match self.timing.as_ref().filter(|_| timed_truth) {
                    Some(t) => self
                        .imu
                        .rotation_terms_timed(&t.block().accel, &mut self.rot[..n]),
                    None => self.imu.rotation_terms(self.k, &mut self.rot[..n]),
                }
            }
            let (rot, dt) = (std::mem::take(&mut self.rot), 1.0 / self.grid.rate_hz);
            self.place_truth(place_rot.then(|| &rot[..n]), dt);
            self.rot = rot;
        }
        self.k += n as u64;
        let n = match self.timing.as_mut() {
            Some(t) => {
                let comps = (self.filtered.as_mut()).and_then(|f| f.components_mut());
                let kept = t.compact(&mut self.block[..n], &mut self.truth[..], comps);
                self.truth.truncate(kept);
                kept
            }
            None => n,
        };
        Some((first, n))
    }

    /// One record over the interval the trigger's next edge closes.
    fn step_triggered(&mut self) -> Option<(u64, usize)> {
        let (lo, hi) = match self.trigger.as_mut()?.next_interval()? {
            Ok(iv) => iv,
            Err(e) => return self.fail(EngineError::Trigger(e)),
        };
        let bounds = [lo, hi];
        let span = hi - lo;
        if self.block.is_empty() {
            self.block.push(Record::default());
        }
        self.imu.fill_between(&bounds, &mut self.block[..1]);
        if let Err(e) = Producer::check_finite(&self.block[..1], "in the error-free signal") {
            return self.fail(e);
        }
        let chain_rot = match (&self.filtered, &self.chain) {
            (Some(f), _) => f.needs_rotation_terms(),
            (None, Some(c)) => c.needs_rotation_terms(),
            (None, None) => false,
        };
        let place_rot = self.places_with_rotation();
        if chain_rot || place_rot {
            self.rot.resize(1.max(self.rot.len()), Default::default());
            self.imu.rotation_terms_timed(&bounds, &mut self.rot[..1]);
            // The generator averages ω ωᵀ over the nominal Δt; the record's rates are means
            // over its own interval, and so must the lever-arm terms be.
            let to_mean = 1.0 / (self.grid.rate_hz * span);
            self.rot[0].omega_outer *= to_mean;
            self.rot[0].gravitation *= to_mean;
        }
        if self.keep_truth {
            self.truth.clear();
            self.truth.push(self.block[0]);
            let rot = std::mem::take(&mut self.rot);
            self.place_truth(place_rot.then(|| &rot[..1]), span);
            self.rot = rot;
        }
        let rot = chain_rot.then(|| &self.rot[..1]);
        if let Some(f) = self.filtered.as_mut() {
            // KVH's 1775 IMU technical manual (§8.26): under external sync (MSYNC) the unit switches
            // its output filter to a uniform averager over the interval between the sync
            // edges. The mean of the internal samples over (previous edge, this edge] is the
            // interval mean of the signal (the generator's exact integral over the interval
            // divided by its length), and the errors the unit adds to those samples average
            // over the same interval: the internal-rate chain acts over it (white noise of
            // density N gives σ = N/√T), then the output LSB and range.
            f.apply_over(&mut self.block[..1], rot, span);
            if let Err(e) = Producer::check_finite(&self.block[..1], "after the error chain") {
                return self.fail(e);
            }
        } else if let Some(c) = self.chain.as_mut() {
            // The errors act over the interval since the previous edge, not the nominal step.
            c.apply_over(&mut self.block[..1], rot, span);
            if let Err(e) = Producer::check_finite(&self.block[..1], "after the error chain") {
                return self.fail(e);
            }
        }
        self.trigger_tov = [hi];
        self.k += 1;
        Some((self.k - 2, 1))
    }

    /// The field each of the block's first `n` records' frames carry; `false` (production
    /// ended with the error) when a sample cannot be taken.
    pub(super) fn fill_mag(&mut self, n: usize) -> bool {
        self.mag_block.clear();
        let Some(hold) = self.mag.as_mut() else {
            return true;
        };
        let motion = self.imu.motion();
        let mut error = None;
        for r in &self.block[..n] {
            match hold.at(r.t, motion) {
                Ok(m) => self.mag_block.push(m),
                Err(e) => {
                    error = Some(e);
                    break;
                }
            }
        }
        error.map(|e| self.fail(e.into())).is_none()
    }
}
