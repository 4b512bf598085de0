//! A rig unit with a producer of its own (an output filter, timing errors, a trigger's
//! intervals): its blocks made by the single IMU's `engine::Producer`, then the unit's
//! failures, magnetometer and encoding, and its truth placed at the unit (docs/rig.md,
//! "Timing errors and output filters").

use super::shared::{fail_triads, place_triad, sample_mag, truth_row};
use super::{Body, Scratch, Unit};
use crate::engine::{self, EngineError};
use crate::generator::RotationTerms;
use crate::math::Vec3;
use crate::record::Record;
use crate::rig::geometry::Placement;
use crate::source::AnyMotion;

impl Unit {
    /// A producer-backed unit's next block of up to `max` records: its frames in `s.buf`
    /// (ends in `s.ends`), their emission times in `s.emit` (ns after `origin`, the run's
    /// t₀), and with `truth` its truth rows in `s.side` (ends in `s.side_ends`). Returns the
    /// number of records, 0 when none can be made now (a triggered unit waits for its edge,
    /// or the run is complete). `motion` places the magnetometer's samples.
    pub(super) fn produce(
        &mut self,
        motion: &AnyMotion,
        max: usize,
        origin: f64,
        truth: bool,
        s: &mut Scratch,
    ) -> Result<usize, EngineError> {
        let Body::Produced {
            producer,
            encoding,
            last_tov,
        } = &mut self.body
        else {
            unreachable!("only a producer-backed unit produces on its own")
        };
        let grid = self.grid;
        let dt = 1.0 / grid.rate_hz;
        let offset_ns = ((grid.t0 - origin) * 1e9).round() as i64;
        for v in [&mut s.buf, &mut s.side] {
            v.clear();
        }
        for v in [&mut s.ends, &mut s.side_ends] {
            v.clear();
        }
        s.emit.clear();
        s.spans.clear();
        s.gaps.clear();
        s.times.clear();
        s.marks.clear();
        s.recs.clear();
        s.truth.clear();
        s.masks.clear();
        {
            let Some(b) = producer.next_records(max) else {
                return producer.take_error().map_or(Ok(0), Err);
            };
            s.recs.extend_from_slice(b.records);
            s.truth.extend_from_slice(b.truth);
            match &b.times {
                Some(t) => {
                    for i in 0..b.records.len() {
                        let gap = t.gaps.get(i).copied().unwrap_or(0);
                        s.gaps.push(gap);
                        s.emit.push((t.emit[i] * 1e9).round() as i64 + offset_ns);
                        s.times
                            .push([t.tov[i], t.tov_accel[i], t.emit[i]].map(|x| t.t0 + x));
                        let tov_ns = (t.tov[i] * 1e9).round() as i64 + offset_ns;
                        s.marks.push((b.first + i as u64, tov_ns));
                        // The interval the record's rates are means over: the trigger's, or
                        // the nominal steps it covers (skipped samples folded in).
                        s.spans.push(if self.triggered {
                            t.tov[i] - std::mem::replace(last_tov, t.tov[i])
                        } else {
                            f64::from(gap + 1) * dt
                        });
                    }
                }
                None => {
                    for k in b.first + 1..=b.first + b.records.len() as u64 {
                        let at = offset_ns + (k as f64 * dt * 1e9).round() as i64;
                        s.emit.push(at);
                        s.marks.push((k - 1, at));
                        s.spans.push(dt);
                    }
                }
            }
        }
        let n = s.recs.len();
        fail_triads(&mut self.failures, self.flags, s);
        sample_mag(self.mag.as_deref_mut(), motion, s)?;
        let profile = self.temperature.as_ref();
        let gaps = if s.gaps.is_empty() { &[][..] } else { &s.gaps };
        encoding.encode_with_mag(&s.recs, gaps, profile, &s.mag, &mut s.buf, &mut s.ends);
        super::protocols::encode_extra(&mut self.extra, true, profile, s);
        if truth {
            for (i, (r, m)) in s.truth.iter().zip(&s.masks).enumerate() {
                truth_row(&mut s.side, &r.values(), s.times.get(i).copied(), *m);
                s.side_ends.push(s.side.len());
            }
        }
        debug_assert_eq!(s.ends.len(), n);
        Ok(n)
    }

    /// Records still to make (a producer-backed unit's; `None` for a shared unit).
    pub(super) fn remaining(&self) -> Option<u64> {
        match &self.body {
            Body::Produced { producer, .. } => Some(producer.remaining()),
            _ => None,
        }
    }
}

/// The placement of a producer-backed unit's truth: the same turn into the unit's axes and
/// lever-arm terms as a shared unit's error-free readings get.
impl engine::TruthPlace for Placement {
    fn needs_rotation_terms(&self) -> bool {
        self.lever_b != Vec3::zeros()
    }

    fn place(&self, records: &mut [Record], rot: Option<&[RotationTerms]>, dt: f64) {
        place_triad(self, records, rot, dt);
    }
}
