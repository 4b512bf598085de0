//! A unit that shares its grid's evaluation of the motion: the reference point's records →
//! the unit's error-free readings (placement) → its errors → failures → frames or CSV rows,
//! and the helpers a producer-backed unit (`produced`) uses for the same steps.

use std::io::Write;

use super::{Body, Scratch, Unit, geometry};
use crate::aiding::mag_samples::MagHold;
use crate::engine::{DEFAULT_FRAME_CELSIUS, EngineError, Producer};
use crate::generator::RotationTerms;
use crate::math::Vec3;
use crate::protocol::Channels;
use crate::record::Record;
use crate::rig::{FailureSet, Placement};
use crate::source::AnyMotion;

impl Unit {
    /// A shared unit's block: `reference` records (reference point, body axes, interval
    /// means over `dt` each — the grid's step, or a trigger's interval) and their rotation
    /// terms (normalised by `dt`) → the unit's error-free readings → errors → failures →
    /// frames, left in `s.buf`, one per record (ends in `s.ends`); the truth rows go to
    /// `truth`. `motion` places the magnetometer's samples.
    pub(super) fn encode(
        &mut self,
        motion: &AnyMotion,
        reference: &[Record],
        rot: Option<&[RotationTerms]>,
        dt: f64,
        s: &mut Scratch,
        truth: &mut Option<&mut dyn Write>,
    ) -> Result<(), EngineError> {
        let n = reference.len();
        // A triggered record is valid, and sent, at its edge: its time tag.
        let times = self.triggered;
        s.masks.clear();
        s.buf.clear();
        s.ends.clear();
        match &mut self.body {
            Body::Triad { chain, encoding } => {
                s.recs.clear();
                s.recs.extend_from_slice(reference);
                place_triad(&self.place, &mut s.recs, rot, dt);
                s.truth.clear();
                if truth.is_some() {
                    s.truth.extend_from_slice(&s.recs);
                }
                if let Some(c) = chain.as_mut() {
                    let terms = match (rot, c.needs_rotation_terms()) {
                        (Some(r), true) => {
                            s.rot.clear();
                            s.rot.extend(r.iter().map(|t| match &self.place.c_b_c {
                                Some(m) => geometry::rotate_terms(t, m),
                                None => *t,
                            }));
                            Some(&s.rot[..])
                        }
                        _ => None,
                    };
                    if self.triggered {
                        c.apply_over(&mut s.recs, terms, dt);
                    } else {
                        c.apply_with(&mut s.recs, terms);
                    }
                    Producer::check_finite(&s.recs, "after the error chain")?;
                }
                s.spans.clear();
                s.spans.resize(n, dt);
                fail_triads(&mut self.failures, self.flags, s);
                sample_mag(self.mag.as_deref_mut(), motion, s)?;
                let profile = self.temperature.as_ref();
                encoding.encode_with_mag(&s.recs, &[], profile, &s.mag, &mut s.buf, &mut s.ends);
                super::protocols::encode_extra(&mut self.extra, false, profile, s);
                if let Some(w) = truth.as_mut() {
                    s.side.clear();
                    for (r, m) in s.truth.iter().zip(&s.masks) {
                        let t = times.then_some([r.t; 3]);
                        truth_row(&mut s.side, &r.values(), t, *m);
                    }
                    w.write_all(&s.side)?;
                }
            }
            Body::Produced { .. } => unreachable!("a producer-backed unit shares no evaluation"),
            Body::Skew {
                layout,
                errors,
                frames,
                vibration,
            } => {
                let ch = layout.channels();
                s.vals.clear();
                s.tvals.clear();
                for (i, r) in reference.iter().enumerate() {
                    let w_c = self.place.to_case(r.gyro);
                    for g in &layout.gyros {
                        s.tvals.push(g.axis.dot(&w_c));
                    }
                    for a in &layout.accels {
                        let p = self.place.point_b(a.position_m);
                        let f_b = match rot {
                            Some(rot) => geometry::force_at(r.accel, &rot[i], 1.0 / dt, p),
                            None => r.accel,
                        };
                        s.tvals.push(a.axis.dot(&self.place.to_case(f_b)));
                    }
                }
                let ng = layout.gyros.len();
                let triggered = self.triggered;
                for (row, r) in s.tvals.chunks(ch).zip(reference) {
                    let start = s.vals.len();
                    // The body's vibration in the unit's axes, on each sense axis.
                    let (vg, va) = vibration
                        .as_mut()
                        .map_or((Vec3::zeros(), Vec3::zeros()), |v| {
                            let (g, a) = v.next();
                            (self.place.to_case(g), self.place.to_case(a))
                        });
                    let axes = layout.gyros.iter().chain(&layout.accels).map(|x| x.axis);
                    s.vals
                        .extend(row.iter().zip(errors.iter_mut()).zip(axes).enumerate().map(
                            |(i, ((x, e), u))| {
                                let x = x + u.dot(if i < ng { &vg } else { &va });
                                if triggered {
                                    e.read_over(x, dt)
                                } else {
                                    e.read(x)
                                }
                            },
                        ));
                    s.masks.push(self.failures.apply(r.t, &mut s.vals[start..]));
                }
                check_values(&s.vals, reference, ch)?;
                let row = &mut s.row;
                for (i, r) in reference.iter().enumerate() {
                    let vals = &s.vals[i * ch..(i + 1) * ch];
                    if let Some(f) = frames.as_mut() {
                        let (plan, state) = &mut **f;
                        let c = Channels {
                            values: vals,
                            gyros: layout.gyros.len(),
                            dt,
                            failed: s.masks[i],
                        };
                        let rec = Record {
                            t: r.t,
                            flags: self.flags,
                            ..Record::default()
                        };
                        let celsius = (self.temperature.as_ref())
                            .map_or(DEFAULT_FRAME_CELSIUS, |p| p.at(r.t));
                        plan.encode_with(&rec, Some(&c), celsius, state, &mut s.buf);
                        s.ends.push(s.buf.len());
                        continue;
                    }
                    row.clear();
                    row.push(r.t);
                    row.extend_from_slice(vals);
                    row.extend(vals.iter().map(|v| v * dt));
                    truth_row(&mut s.buf, row, None, u64::MAX);
                    s.ends.push(s.buf.len());
                }
                if let Some(w) = truth.as_mut() {
                    s.side.clear();
                    for (i, r) in reference.iter().enumerate() {
                        row.clear();
                        row.push(r.t);
                        row.extend_from_slice(&s.tvals[i * ch..(i + 1) * ch]);
                        row.extend(s.tvals[i * ch..(i + 1) * ch].iter().map(|v| v * dt));
                        truth_row(&mut s.side, row, times.then_some([r.t; 3]), s.masks[i]);
                    }
                    w.write_all(&s.side)?;
                }
            }
        }
        debug_assert_eq!(s.masks.len(), n);
        debug_assert_eq!(s.ends.len(), n);
        Ok(())
    }
}

/// The unit's magnetometer (`hold`, if its frames carry one) sampled at each record of
/// `s.recs` into `s.mag`: the latest sample at the record's time on `motion`.
pub(super) fn sample_mag(
    hold: Option<&mut MagHold>,
    motion: &AnyMotion,
    s: &mut Scratch,
) -> Result<(), EngineError> {
    s.mag.clear();
    if let Some(hold) = hold {
        for r in &s.recs {
            s.mag.push(hold.at(r.t, motion)?);
        }
    }
    Ok(())
}

/// A three-axis unit's failures on the records of `s.recs` (each over `s.spans[i]` s): the
/// channels read what the failures make of them, the increments follow; every record gets
/// `flags`; each record's failed-channel mask goes to `s.masks`.
pub(super) fn fail_triads(failures: &mut FailureSet, flags: u8, s: &mut Scratch) {
    s.masks.clear();
    for (r, span) in s.recs.iter_mut().zip(&s.spans) {
        let (g, a) = (r.gyro, r.accel);
        let mut v = [g[0], g[1], g[2], a[0], a[1], a[2]];
        let mask = failures.apply(r.t, &mut v);
        if mask != 0 {
            r.gyro = Vec3::new(v[0], v[1], v[2]);
            r.accel = Vec3::new(v[3], v[4], v[5]);
            r.dtheta = r.gyro * *span;
            r.dv = r.accel * *span;
        }
        r.flags |= flags;
        s.masks.push(mask);
    }
}

/// Turns reference-point records into a three-axis unit's error-free readings: the rate
/// and the specific force at its lever arm, in its axes.
pub(super) fn place_triad(
    place: &Placement,
    recs: &mut [Record],
    rot: Option<&[RotationTerms]>,
    dt: f64,
) {
    if place.is_identity() {
        return;
    }
    for (i, r) in recs.iter_mut().enumerate() {
        let f = match rot {
            Some(rot) if place.lever_b != Vec3::zeros() => {
                geometry::force_at(r.accel, &rot[i], 1.0 / dt, place.lever_b)
            }
            _ => r.accel,
        };
        r.gyro = place.to_case(r.gyro);
        r.accel = place.to_case(f);
        r.dtheta = r.gyro * dt;
        r.dv = r.accel * dt;
    }
}

/// A skew unit's readings are finite, or the error names the record and the channel.
fn check_values(vals: &[f64], reference: &[Record], ch: usize) -> Result<(), EngineError> {
    match vals.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(EngineError::NonFinite {
            t: reference[i / ch].t,
            quantity: "a skew-redundant sensor's reading",
            value: vals[i],
            stage: "after its error terms and failures",
        }),
    }
}

/// Appends one CSV row: `values`, then the three `times` when given (time of validity, of
/// the accelerometers' validity, of emission), then `mask` unless it is `u64::MAX`.
pub(super) fn truth_row(buf: &mut Vec<u8>, values: &[f64], times: Option<[f64; 3]>, mask: u64) {
    let mut f = ryu::Buffer::new();
    let extra = times.iter().flatten();
    for (i, v) in values.iter().chain(extra).enumerate() {
        if i > 0 {
            buf.push(b',');
        }
        buf.extend_from_slice(f.format(*v).as_bytes());
    }
    if mask != u64::MAX {
        buf.push(b',');
        buf.extend_from_slice(itoa(mask, &mut [0; 20]));
    }
    buf.push(b'\n');
}

/// The decimal digits of `x`, written into the end of `digits`.
fn itoa(mut x: u64, digits: &mut [u8; 20]) -> &[u8] {
    let mut i = digits.len();
    loop {
        i -= 1;
        digits[i] = b'0' + (x % 10) as u8;
        x /= 10;
        if x == 0 {
            return &digits[i..];
        }
    }
}
