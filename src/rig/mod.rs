//! A sensor rig on one clock: several units (three-axis IMUs with an error template, or
//! skew-redundant units of single-axis sensors) on one body, driven by one motion. Each unit
//! has its own placement (mounting and lever arm, `geometry`), rate, seed, output and
//! scheduled sensor failures (`failure`); units at the same rate and time grid share one
//! evaluation of the motion per instant.
//!
//! Built by [`crate::sim::SimulationBuilder::build_rig`] from a scene file's `[[imu]]` list or
//! from code; docs/rig.md describes the scene-file schema and the outputs.

pub mod failure;
pub mod geometry;
mod produced;
mod protocols;
pub mod skew;
mod spec;
pub mod stream;

use std::io::Write;
use std::ops::ControlFlow;

use crate::aiding::mag_samples::{FrameMag, MagHold};
use crate::engine::frames::{Part, Until, WindowSource};
use crate::engine::{self, DEFAULT_FRAME_CELSIUS, Encoding, EngineError, Grid, Producer};
use crate::errors::ErrorChain;
use crate::errors::temperature::TemperatureProfile;
use crate::errors::vibration::Vibration;
use crate::generator::RotationTerms;
use crate::math::Vec3;
use crate::output::Format;
use crate::protocol::{Channels, EncoderState, Plan};
use crate::record::{COLUMNS, Record};
use crate::source::AnyMotion;

pub use crate::output::SinkAddr;
pub use failure::{Failure, FailureKind, FailureSet, FailureSpec, Pick};
pub use geometry::Placement;
pub use skew::{SkewLayout, SkewSensor, dodecahedron_axes};
pub use spec::{UnitModel, UnitSpec};
pub use stream::RigStream;

use skew::ChannelErrors;

/// What a unit is made of.
pub(crate) enum Body {
    /// A three-axis IMU: its template's error chain (without mounting or lever arm, which
    /// the placement applies) and its output encoding.
    Triad {
        chain: Option<Box<ErrorChain>>,
        encoding: Box<Encoding>,
    },
    /// A three-axis IMU whose template has an output filter or timing errors (or under the
    /// scene file's `[timing]`): the single IMU's producer of its own (the template's chain or
    /// filtered chain with the unit's mounting, lever arm, temperature and the body's
    /// vibration, its sampling clock, its truth placed at the unit), which evaluates the
    /// motion itself at the instants it needs; the failures act after it, then the encoding.
    Produced {
        producer: Box<Producer>,
        encoding: Box<Encoding>,
        /// The end of the last triggered sample's interval (s after t₀): the next one's start.
        last_tov: f64,
    },
    /// A skew-redundant unit: its sensors and their error terms; CSV output, or the frames of
    /// an N-channel protocol (its compiled plan and encoder state).
    Skew {
        layout: SkewLayout,
        errors: Vec<ChannelErrors>,
        frames: Option<Box<(Plan, EncoderState)>>,
        /// The body's vibration (body axes), added to the error-free signal at each sensor.
        vibration: Option<Box<Vibration>>,
    },
}

/// One unit of a rig, ready to produce.
pub struct Unit {
    pub(crate) name: String,
    /// The template's name, or the skew unit's sensors in words.
    pub(crate) model: String,
    pub(crate) grid: Grid,
    pub(crate) place: Placement,
    pub(crate) body: Body,
    pub(crate) failures: FailureSet,
    pub(crate) seed: u64,
    pub(crate) path: Option<std::path::PathBuf>,
    pub(crate) sinks: Vec<(SinkAddr, Option<String>)>,
    /// The sensor temperature over the run: the template's thermal terms follow it (in the
    /// chain) and frames with a temperature field carry it.
    pub(crate) temperature: Option<TemperatureProfile>,
    /// The magnetometer whose latest sample (in the unit's axes) the frames carry.
    pub(crate) mag: Option<Box<MagHold>>,
    /// Status flags every record carries from now on (e.g. stale input).
    pub(crate) flags: u8,
    /// The unit samples at external trigger edges ([`RigStream::triggered`]).
    pub(crate) triggered: bool,
    /// Further protocols the same records are encoded in ([`Unit::add_protocol`]).
    pub(crate) extra: Vec<Encoding>,
}

/// Reused per-unit buffers: nothing is allocated per block once they have grown.
#[derive(Default)]
struct Scratch {
    recs: Vec<Record>,
    truth: Vec<Record>,
    rot: Vec<RotationTerms>,
    vals: Vec<f64>,
    tvals: Vec<f64>,
    masks: Vec<u64>,
    buf: Vec<u8>,
    side: Vec<u8>,
    row: Vec<f64>,
    ends: Vec<usize>,
    mag: Vec<FrameMag>,
    /// A producer-backed unit's block: the end of each truth row in `side`, each frame's
    /// emission time (ns after the run's t₀), the interval each record covers (s), the
    /// samples skipped before each (frame counters step over them), and each record's time
    /// of validity, of the accelerometers' validity and of emission (s, record time axis).
    side_ends: Vec<usize>,
    emit: Vec<i64>,
    spans: Vec<f64>,
    gaps: Vec<u32>,
    times: Vec<[f64; 3]>,
    /// Each record's index (0-based) and time of validity (ns after the run's t₀), for the
    /// time marks and pulses that follow the unit's records.
    marks: Vec<(u64, i64)>,
    /// The block's frames in each further protocol, with their ends.
    extra: Vec<(Vec<u8>, Vec<usize>)>,
}

/// Where one unit's outputs go.
pub struct UnitOutputs<'a> {
    /// The unit's readings (records, frames, or a skew unit's channels as CSV).
    pub main: &'a mut dyn Write,
    /// The error-free readings at the unit's place and in its axes, with a `failed` column
    /// (bit i: channel i has an active failure), CSV.
    pub truth: Option<&'a mut dyn Write>,
    /// The resolved failure schedule, CSV (one line per failure).
    pub failures: Option<&'a mut dyn Write>,
}

impl Unit {
    /// The unit's name (unique in its rig).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// What the unit is: `template NAME`, or `skew-redundant, G gyros and A accelerometers`.
    pub fn model_name(&self) -> &str {
        &self.model
    }

    /// The unit's time grid.
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// The unit's placement on the body.
    pub fn placement(&self) -> &Placement {
        &self.place
    }

    /// The unit's seed (its error terms' and failures' random streams).
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The output path the scene file gives, if any.
    pub fn path(&self) -> Option<&std::path::Path> {
        self.path.as_deref()
    }

    /// Where `imu-emu run` streams the unit (the scene file's `sink`), each with its protocol
    /// when it is not the unit's own.
    pub fn sinks(&self) -> &[(SinkAddr, Option<String>)] {
        &self.sinks
    }

    /// The compiled frame of a unit that speaks a protocol.
    pub fn plan(&self) -> Option<&crate::protocol::Plan> {
        match self.encoding()? {
            Encoding::Frames { plan, .. } => Some(plan),
            Encoding::Records(_) => None,
        }
    }

    /// A three-axis unit's output encoding.
    fn encoding(&self) -> Option<&Encoding> {
        match &self.body {
            Body::Triad { encoding, .. } | Body::Produced { encoding, .. } => Some(encoding),
            Body::Skew { .. } => None,
        }
    }

    /// Whether the unit runs a producer of its own (an output filter, timing errors) instead
    /// of sharing its grid's evaluation of the motion.
    pub fn has_own_producer(&self) -> bool {
        matches!(self.body, Body::Produced { .. })
    }

    /// Whether the unit runs its template's output filter.
    pub fn has_output_filter(&self) -> bool {
        matches!(&self.body, Body::Produced { producer, .. } if producer.is_filtered())
    }

    /// Whether the unit's records carry their own times of validity and emission (timing
    /// errors, an output filter's delay, a trigger): its truth then has the `tov`,
    /// `tov_accel` and `emit` columns, as the single IMU's has.
    pub fn is_timed(&self) -> bool {
        self.triggered
            || matches!(&self.body, Body::Produced { producer, .. } if producer.is_timed())
    }

    /// The skew-redundant layout, if the unit is one.
    pub fn skew(&self) -> Option<&SkewLayout> {
        match &self.body {
            Body::Skew { layout, .. } => Some(layout),
            Body::Triad { .. } | Body::Produced { .. } => None,
        }
    }

    /// The failures, their random choices made.
    pub fn failures(&self) -> &[Failure] {
        self.failures.failures()
    }

    /// The resolved failure schedule as CSV: a header, then one line per failure.
    pub fn failure_csv(&self) -> String {
        let names = self.channel_names();
        let mut text = String::from("kind,sensor,channel,start_s,end_s,magnitude\n");
        for x in self.failures() {
            text += &format!(
                "{},{},{},{},{},{}\n",
                x.kind.name(),
                names[x.channel],
                x.channel,
                x.start_s,
                x.end_s,
                x.magnitude
            );
        }
        text
    }

    /// The channel names failures refer to: `gyro_x` … `accel_z`, or `gyro_0` … `accel_N`.
    pub fn channel_names(&self) -> Vec<String> {
        match &self.body {
            Body::Triad { .. } | Body::Produced { .. } => {
                COLUMNS[1..7].iter().map(|s| s.to_string()).collect()
            }
            Body::Skew { layout, .. } => layout.channel_names(),
        }
    }

    /// File extension of the main output: `csv`, or `bin` for binary records and frames.
    pub fn extension(&self) -> &'static str {
        match &self.body {
            Body::Triad { encoding, .. } | Body::Produced { encoding, .. } => match **encoding {
                Encoding::Records(Format::Csv) => "csv",
                _ => "bin",
            },
            Body::Skew { frames, .. } => match frames {
                Some(_) => "bin",
                None => "csv",
            },
        }
    }

    /// Whether this unit needs the rotation terms (a lever arm, offset accelerometers).
    fn needs_rotation_terms(&self) -> bool {
        self.place.lever_b != Vec3::zeros()
            || match &self.body {
                Body::Triad { chain, .. } => {
                    chain.as_ref().is_some_and(|c| c.needs_rotation_terms())
                }
                Body::Skew { layout, .. } => layout.has_offsets(),
                Body::Produced { .. } => false,
            }
    }

    /// The header of the main output (CSV only) and of the truth file.
    pub(crate) fn headers(&self) -> (String, String) {
        let names = match &self.body {
            Body::Triad { .. } | Body::Produced { .. } => {
                COLUMNS[1..].iter().map(|s| s.to_string()).collect()
            }
            Body::Skew { layout, .. } => {
                let ch = layout.channel_names();
                let inc = |c: &String| c.replace("gyro_", "dtheta_").replace("accel_", "dv_");
                let mut v = ch.clone();
                v.extend(ch.iter().map(inc));
                v
            }
        };
        let main = format!("t,{}\n", names.join(","));
        let times = if self.is_timed() {
            ",tov,tov_accel,emit"
        } else {
            ""
        };
        let truth = format!("t,{}{times},failed\n", names.join(","));
        let main = match &self.body {
            Body::Triad { encoding, .. } | Body::Produced { encoding, .. }
                if !matches!(**encoding, Encoding::Records(Format::Csv)) =>
            {
                String::new()
            }
            Body::Skew {
                frames: Some(_), ..
            } => String::new(),
            _ => main,
        };
        (main, truth)
    }

    /// A shared unit's block: `reference` records (reference point, body axes, interval
    /// means over `dt` each — the grid's step, or a trigger's interval) and their rotation
    /// terms (normalised by `dt`) → the unit's error-free readings → errors → failures →
    /// frames, left in `s.buf`, one per record (ends in `s.ends`); the truth rows go to
    /// `truth`. `motion` places the magnetometer's samples.
    fn encode(
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
                protocols::encode_extra(&mut self.extra, false, profile, s);
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
fn sample_mag(
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
fn fail_triads(failures: &mut FailureSet, flags: u8, s: &mut Scratch) {
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
fn place_triad(place: &Placement, recs: &mut [Record], rot: Option<&[RotationTerms]>, dt: f64) {
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
fn truth_row(buf: &mut Vec<u8>, values: &[f64], times: Option<[f64; 3]>, mask: u64) {
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

/// An assembled rig: the motion, the quadrature and the units.
pub struct Rig {
    pub(crate) motion: AnyMotion,
    pub(crate) nodes: usize,
    pub(crate) units: Vec<Unit>,
    pub(crate) warnings: Vec<String>,
    /// The GNSS receiver's settings (scene file `[gnss]`), when given.
    pub(crate) gnss: Option<crate::aiding::GnssConfig>,
    /// The odometer, barometer and magnetometer settings (scene file), when given.
    pub(crate) sensors: crate::aiding::sensors::SensorSet,
    /// The rig's master seed (the receiver's and sensors' errors draw from it).
    pub(crate) seed: u64,
    /// GPS week and second of record time 0, when given.
    pub(crate) gps_time: Option<(u32, f64)>,
    /// True GPS time of record time 0 for the GNSS streams when the units' reference is UTC.
    pub(crate) gnss_time: Option<(u32, f64)>,
}

impl Rig {
    /// Sets the GPS time of record time t = 0 (week, seconds of week) for every unit's frames
    /// and the GNSS streams (a time base chosen after building, as
    /// [`crate::sim::Simulation::set_gps_time`] for one IMU).
    pub fn set_gps_time(&mut self, week: u32, seconds_of_week: f64) {
        self.gps_time = Some((week, seconds_of_week));
        for u in self.units.iter_mut() {
            let state = match &mut u.body {
                Body::Triad { encoding, .. } | Body::Produced { encoding, .. } => {
                    match &mut **encoding {
                        Encoding::Frames { state, .. } => Some(state),
                        Encoding::Records(_) => None,
                    }
                }
                Body::Skew { frames, .. } => frames.as_deref_mut().map(|f| &mut f.1),
            };
            let extra = u.extra.iter_mut().filter_map(|e| match e {
                Encoding::Frames { state, .. } => Some(state),
                Encoding::Records(_) => None,
            });
            for st in state.into_iter().chain(extra) {
                st.gps_week0 = week;
                st.gps_sow0 = seconds_of_week;
            }
        }
    }

    /// Sets the true GPS time of record time t = 0 for the GNSS streams only (see
    /// [`crate::sim::Simulation::set_gnss_gps_time`]).
    pub fn set_gnss_gps_time(&mut self, week: u32, seconds_of_week: f64) {
        self.gnss_time = Some((week, seconds_of_week));
    }

    /// The GPS time (week, seconds of week) of record time 0, when one was set.
    pub fn gps_time(&self) -> Option<(u32, f64)> {
        self.gps_time
    }

    /// The units, in the order given.
    pub fn units(&self) -> &[Unit] {
        &self.units
    }

    /// The motion every unit follows.
    pub fn motion(&self) -> &AnyMotion {
        &self.motion
    }

    /// Things worth telling the user that do not stop the run.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The groups of units that share a time grid (indices into [`Rig::units`]): each group
    /// costs one evaluation of the motion per instant. A unit with a producer of its own
    /// ([`Unit::has_own_producer`]: an output filter, timing errors) is in none.
    pub fn groups(&self) -> Vec<Vec<usize>> {
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for (i, u) in self.units.iter().enumerate() {
            if u.has_own_producer() {
                continue;
            }
            match groups.iter_mut().find(|g| self.units[g[0]].grid == u.grid) {
                Some(g) => g.push(i),
                None => groups.push(vec![i]),
            }
        }
        groups
    }

    /// Writes every unit's outputs (`outs[i]` for unit i); `progress(records_done)`, summed
    /// over units, is called after each window of simulated time and may stop the run
    /// ([`EngineError::Stopped`]). The bytes are those the rig's frame source
    /// ([`Rig::stream`]) gives `imu-emu run` and `generate`.
    pub fn write(
        self,
        outs: &mut [UnitOutputs<'_>],
        mut progress: impl FnMut(u64) -> ControlFlow<()>,
    ) -> Result<(), EngineError> {
        if outs.len() != self.units.len() {
            return Err(EngineError::Outputs {
                given: outs.len(),
                need: self.units.len(),
            });
        }
        let n = self.units.len();
        for (u, o) in self.units.iter().zip(outs.iter_mut()) {
            if let Some(f) = o.failures.as_mut() {
                f.write_all(u.failure_csv().as_bytes())?;
            }
        }
        let fastest = (self.units.iter())
            .map(|u| u.grid.rate_hz)
            .fold(0.0, f64::max);
        let wanted: Vec<bool> = outs.iter().map(|o| o.truth.is_some()).collect();
        let mut stream = self.stream().with_truth(&wanted);
        let preambles = stream.preambles();
        let mut truth_pre = preambles[n..].iter();
        for (o, p) in outs.iter_mut().zip(&preambles) {
            o.main.write_all(p)?;
            if let Some(t) = o.truth.as_mut() {
                t.write_all(truth_pre.next().expect("a truth stream per truth output"))?;
            }
        }
        // Windows of about a block of the fastest unit's records.
        let window = (engine::BLOCK as f64 / fastest * 1e9).clamp(1e6, 1e12) as i64;
        let origin = stream.origin();
        let mut parts = vec![Part::default(); stream.streams()];
        let (mut until, mut done) = (0i64, 0u64);
        while !stream.done() {
            until = until.saturating_add(window);
            parts.iter_mut().for_each(Part::clear);
            stream.fill(Until::ns(origin, until), &mut parts)?;
            for (i, o) in outs.iter_mut().enumerate() {
                o.main.write_all(&parts[i].bytes)?;
                done += parts[i].ends.len() as u64;
                if let (Some(t), Some(w)) = (stream.truth_stream(i), o.truth.as_mut()) {
                    w.write_all(&parts[t].bytes)?;
                }
            }
            if progress(done).is_break() {
                return Err(EngineError::Stopped);
            }
        }
        for o in outs.iter_mut() {
            o.main.flush()?;
            for w in [o.truth.as_mut(), o.failures.as_mut()]
                .into_iter()
                .flatten()
            {
                w.flush()?;
            }
        }
        Ok(())
    }
}
