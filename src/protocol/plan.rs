//! A frame specification compiled once into flat plans of byte offsets and conversions (one
//! per message layout, [`super::layout`]), run per frame to encode records and decode frames
//! (as fast as hand-written code, and a user's TOML file needs no recompiling). The plan strings the layouts together: the schedule of messages, Δθ/ΔV
//! accumulation, the SDLC/HDLC transport and injected faults.

use std::path::Path;

use super::anchor::Anchors;
use super::compile::{compile_layout, tick_step};
use super::faults::{FaultError, FaultKind, FrameFaults};
use super::frame::{Channels, DecodeError, Decoded, EncoderState};
use super::framing::{self, BitWriter, Fcs, HdlcOptions, SdlcOptions};
use super::layout::{Layout, What};
use super::spec::{FrameSpec, MAX_MESSAGES, MAX_RATE_HZ, ScheduleBy, Source, SpecError, compact};
use crate::math::Vec3;
use crate::record::{FLAG_ACCEL_SATURATED, FLAG_GYRO_SATURATED, FLAG_INVALID, Record};

/// A decoder hunting for a frame boundary believes a run of frames once random bytes would
/// pass its constants and checks by chance less than once in 2^LOCK_BITS positions (about once
/// in 4 GB of noise).
pub const LOCK_BITS: u32 = 32;

/// What carries the frame on the line.
#[derive(Clone, Debug)]
pub enum Transport {
    /// The frame bytes as they are (byte-synchronised by constants).
    Plain,
    /// Bit-stuffed synchronous SDLC packed into bytes; each frame ends with marks to a byte
    /// boundary.
    Sdlc(SdlcOptions),
    /// Byte-stuffed asynchronous HDLC.
    Hdlc(HdlcOptions),
}

/// A compiled protocol: encode records, decode frames.
#[derive(Clone, Debug)]
pub struct Plan {
    /// Protocol name.
    pub name: String,
    /// Nominal rate (Hz), if the spec gives one.
    pub rate_hz: Option<f64>,
    /// Nominal link speed (bit/s), if given.
    pub baud: Option<u64>,
    /// How frames travel on the line.
    pub transport: Transport,
    layouts: Vec<Layout>,
    /// Layout index of each frame, repeating.
    schedule: Vec<usize>,
    /// The schedule is indexed by the frame's counter value rather than its position.
    by_counter: bool,
    /// Where no frame can start (`None` when some message has no constant field).
    anchors: Option<Anchors>,
}

impl Plan {
    /// Validates and compiles a spec (`path` for messages).
    pub fn compile(spec: &FrameSpec, path: &Path) -> Result<Plan, SpecError> {
        let syntax = |message: String| SpecError::Syntax {
            path: path.to_path_buf(),
            message,
        };
        if let Some(r) = spec.rate_hz
            && !(r.is_finite() && r > 0.0 && r <= MAX_RATE_HZ)
        {
            return Err(syntax(format!(
                "`rate_hz` = {}: expected a rate in (0, {}] Hz",
                compact(r),
                compact(MAX_RATE_HZ)
            )));
        }
        if spec.baud == Some(0) {
            return Err(syntax("`baud` = 0: expected a link speed in bit/s".into()));
        }
        let (messages, entries) = (
            spec.message.len(),
            spec.schedule.as_ref().map_or(0, Vec::len),
        );
        if messages.max(entries) > MAX_MESSAGES {
            return Err(syntax(format!(
                "{messages} messages, {entries} schedule entries: at most {MAX_MESSAGES} of each"
            )));
        }
        if let Some((i, m)) = spec
            .message
            .iter()
            .enumerate()
            .find(|(i, m)| spec.message[..*i].iter().any(|o| o.name == m.name))
        {
            return Err(syntax(format!(
                "`[[message]]` {}: a second message named `{}`",
                i + 1,
                m.name
            )));
        }
        let layouts = if spec.message.is_empty() {
            vec![compile_layout(
                &spec.name,
                &spec.field,
                spec.check.as_ref(),
                spec.truncate.as_ref(),
                false,
                spec.byte_order,
                spec.rate_hz,
                path,
            )?]
        } else {
            if !spec.field.is_empty() || spec.check.is_some() || spec.truncate.is_some() {
                return Err(syntax(
                    "give the fields in `[[message]]` entries or at the top level, not both".into(),
                ));
            }
            spec.message
                .iter()
                .map(|m| {
                    compile_layout(
                        &m.name,
                        &m.field,
                        m.check.as_ref(),
                        m.truncate.as_ref(),
                        m.accumulate,
                        spec.byte_order,
                        spec.rate_hz,
                        path,
                    )
                })
                .collect::<Result<Vec<_>, _>>()?
        };
        let schedule = match &spec.schedule {
            None => (0..layouts.len()).collect(),
            Some(names) => {
                if names.is_empty() {
                    return Err(syntax("`schedule` is empty".into()));
                }
                names
                    .iter()
                    .map(|n| {
                        layouts
                            .iter()
                            .position(|l| &l.name == n)
                            .ok_or_else(|| syntax(format!("`schedule`: no message named `{n}`")))
                    })
                    .collect::<Result<Vec<_>, _>>()?
            }
        };
        let by_counter = spec.schedule_by == ScheduleBy::Counter;
        if by_counter {
            check_counter_schedule(&layouts, schedule.len()).map_err(syntax)?;
        }
        let transport = match (spec.sdlc, spec.hdlc) {
            (Some(_), Some(_)) => return Err(syntax("give `[sdlc]` or `[hdlc]`, not both".into())),
            (Some(o), None) => Transport::Sdlc(o),
            (None, Some(o)) => Transport::Hdlc(o),
            (None, None) => Transport::Plain,
        };
        Ok(Plan {
            name: spec.name.clone(),
            rate_hz: spec.rate_hz,
            baud: spec.baud,
            transport,
            anchors: Anchors::of(&layouts),
            layouts,
            schedule,
            by_counter,
        })
    }

    /// Sets the frame rate of a run (Hz): counters of internal ticks advance by ticks/rate per
    /// frame. Refuses a rate that does not divide their tick rate.
    pub fn set_rate(&mut self, rate: f64) -> Result<(), String> {
        for op in self.layouts.iter_mut().flat_map(|l| &mut l.ops) {
            if let What::Counter {
                step,
                ticks: Some(t),
                ..
            } = &mut op.what
            {
                *step = tick_step(*t, rate).ok_or_else(|| {
                    format!(
                        "`{}` counts {t} ticks/s, so the rate must divide {t} (got {} Hz)",
                        self.name,
                        compact(rate)
                    )
                })?;
            }
        }
        Ok(())
    }

    /// The single-axis channels the frames carry, (gyros, accelerometers) (the highest
    /// `gyro[i]`/`dtheta[i]` and `accel[i]`/`dv[i]` index + 1 over every message); `None`
    /// for a frame of a three-axis IMU.
    pub fn channels(&self) -> Option<(usize, usize)> {
        let (g, a) = self.layouts.iter().fold((0, 0), |acc, l| {
            let (g, a) = super::compile::channel_counts(&l.ops);
            (acc.0.max(g), acc.1.max(a))
        });
        (g + a > 0).then_some((g, a))
    }

    /// Byte offset in the (untruncated) frame of the first message's field carrying `s`.
    pub fn offset_of(&self, s: Source) -> Option<usize> {
        self.layouts[0].ops.iter().find_map(|op| match op.what {
            What::Quantity { source, .. } if source == s => Some(op.offset),
            What::Counter { .. } if s == Source::Counter => Some(op.offset),
            _ => None,
        })
    }

    /// Whether some field carries a three-axis rate, force or increment (`gyro.x`, `dv.z`, …).
    pub fn carries_triad(&self) -> bool {
        self.value_sources().iter().flatten().any(|s| {
            matches!(
                s,
                Source::Gyro(_) | Source::Accel(_) | Source::DTheta(_) | Source::Dv(_)
            )
        })
    }

    /// Full length in bytes of the first message (the only one of most protocols).
    pub fn len(&self) -> usize {
        self.layouts[0].len
    }

    /// Always false: a frame has at least one field.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Number of message layouts.
    pub fn messages(&self) -> usize {
        self.layouts.len()
    }

    /// Whether every frame has the same length on the line (layouts of one length, no
    /// truncation, no bit stuffing).
    pub fn fixed_len(&self) -> Option<usize> {
        let len = self.layouts[0].len;
        (self
            .layouts
            .iter()
            .all(|l| l.len == len && l.truncate.is_none())
            && matches!(self.transport, Transport::Plain))
        .then_some(len)
    }

    /// Appends the line bytes of the frame of `r` to `out`, with the faults the state's
    /// injector decides (none, one frame, two identical frames). Values beyond a field's range
    /// saturate and raise the status overrange bits, as do the record's saturation flags. A
    /// value that is not finite (or the record's [`FLAG_INVALID`]) raises the status word's
    /// failure bits; a message without a status word with a failure model is then not sent
    /// (counted in [`EncoderState::withheld`]).
    /// `temperature` is the sensor temperature (°C) if the frame carries one.
    pub fn encode(
        &self,
        r: &Record,
        temperature: f64,
        state: &mut EncoderState,
        out: &mut Vec<u8>,
    ) {
        self.encode_with(r, None, temperature, state, out);
    }

    /// [`Plan::encode`] of a frame that also carries single-axis channels (`gyro[i]`,
    /// `dv[i]`, … fields) from `ch`, with their failure bits in a status word's
    /// `failed_channels`; `r` gives the time tag and the rest. A channel field without `ch`
    /// is not a measurement (the status word's failure bits, or the frame withheld).
    pub fn encode_with(
        &self,
        r: &Record,
        ch: Option<&Channels<'_>>,
        temperature: f64,
        state: &mut EncoderState,
        out: &mut Vec<u8>,
    ) {
        let f = match state.faults.as_mut() {
            Some(inj) => inj.frame(r.t),
            None => FrameFaults::default(),
        };
        if f.stale {
            state.stalled += 1;
        }
        // Selected by counter: the value this frame carries (a stale frame repeats the last).
        let slot = match (self.by_counter, self.counter()) {
            (true, Some((modulo, step))) => {
                state.frames.wrapping_sub(state.stalled).wrapping_mul(step) % modulo
            }
            _ => state.frames,
        };
        let layout = &self.layouts[self.schedule[(slot % self.schedule.len() as u64) as usize]];
        let mut rec = *r;
        if self.layouts.iter().any(|l| l.accumulate) {
            state.sums[0] += r.dtheta;
            state.sums[1] += r.dv;
            if layout.accumulate {
                rec.dtheta = state.sums[0];
                rec.dv = state.sums[1];
                state.sums = [Vec3::default(); 2];
            }
        }
        if f.drop {
            state.frames += 1;
            return;
        }
        // A corrupted frame carries a wrong check; without one, its transport FCS is wrong.
        let corrupt_fcs = f.corrupt && layout.check.is_none();
        // A value that is not a measurement in a message with no status word to report it: the
        // frame is withheld like a dropped one (its counter value skipped, a gap for a receiver)
        // rather than sent as if healthy.
        let withhold = |flags: u8| flags & FLAG_INVALID != 0 && !layout.reports_failure();
        let unreported = |flags: u8| {
            [FLAG_GYRO_SATURATED, FLAG_ACCEL_SATURATED]
                .into_iter()
                .any(|s| flags & s != 0 && !layout.reports_saturation(s))
        };
        match &self.transport {
            Transport::Plain => {
                let start = out.len();
                let flags = layout.encode(&rec, ch, temperature, state, f, out);
                state.unreported += u64::from(unreported(flags));
                if withhold(flags) {
                    out.truncate(start);
                    state.withheld += 1;
                } else if f.duplicate {
                    out.extend_from_within(start..);
                }
            }
            transport => {
                let mut frame = std::mem::take(&mut state.scratch);
                frame.clear();
                let flags = layout.encode(&rec, ch, temperature, state, f, &mut frame);
                state.unreported += u64::from(unreported(flags));
                let sends = if withhold(flags) {
                    state.withheld += 1;
                    0
                } else {
                    1 + usize::from(f.duplicate)
                };
                for _ in 0..sends {
                    match transport {
                        Transport::Sdlc(o) => {
                            let w = state
                                .line
                                .get_or_insert_with(|| Box::new(BitWriter::for_options(o)));
                            sdlc_frame(&frame, o, corrupt_fcs, w);
                            w.drain_into(out);
                        }
                        Transport::Hdlc(o) => hdlc_frame(&frame, o, corrupt_fcs, out),
                        Transport::Plain => unreachable!("handled above"),
                    }
                }
                state.scratch = frame;
            }
        }
        state.frames += 1;
    }

    /// Whether frames of this plan can show a fault kind (a counter to freeze or to reveal a
    /// drop, a check or FCS to corrupt, a status word with a failure model).
    pub fn supports(&self, kind: FaultKind) -> Result<(), FaultError> {
        let fcs = match &self.transport {
            Transport::Sdlc(o) => o.fcs != Fcs::None,
            Transport::Hdlc(o) => o.fcs != Fcs::None,
            Transport::Plain => false,
        };
        let failure = |w: &What| match w {
            What::Status(m) => m.failure.is_some(),
            What::Counter {
                status: Some(m), ..
            } => m.failure.is_some(),
            _ => false,
        };
        let why = match kind {
            FaultKind::Drop | FaultKind::StaleCounter if self.counter().is_none() => {
                "the frame has no counter"
            }
            FaultKind::CorruptCheck if !fcs && self.layouts.iter().any(|l| l.check.is_none()) => {
                "the frame has no check and no FCS"
            }
            FaultKind::Status
                if !self
                    .layouts
                    .iter()
                    .all(|l| l.ops.iter().any(|op| failure(&op.what))) =>
            {
                "no status field has a `failure` model"
            }
            _ => return Ok(()),
        };
        Err(FaultError::Unsupported {
            protocol: self.name.clone(),
            kind: kind.name(),
            why,
        })
    }

    /// Frames in a row a decoder hunting for a frame boundary must find before it believes
    /// the first: enough that random bytes pass their constants and checks together by chance
    /// less than once in 2^[`LOCK_BITS`] positions. 1 for frames that are that strong alone
    /// (every built-in but `ln200`, whose 16-bit sum and no sync word noise passes once in
    /// 65 536 positions: 2), and 1 for frames with neither constants nor a check, which no
    /// run of frames tells from noise.
    pub fn frames_to_lock(&self) -> usize {
        match self.evidence_bits() {
            0 => 1,
            b => LOCK_BITS.div_ceil(b).min(8) as usize,
        }
    }

    /// Bits of a frame that random bytes match only by chance (its constant fields and its
    /// check), for the weakest message: 0 when some message has neither, and then no decoder
    /// tells noise from frames.
    pub fn evidence_bits(&self) -> u32 {
        self.layouts
            .iter()
            .map(Layout::evidence_bits)
            .min()
            .unwrap_or(0)
    }

    /// Whether the frames have constant fields (sync words, IDs) that mark their start.
    pub fn has_sync(&self) -> bool {
        self.layouts
            .iter()
            .all(|l| l.ops.iter().any(|op| matches!(op.what, What::Constant(_))))
    }

    /// True when the constant fields (sync words, fixed IDs) at the start of `bytes` match
    /// some message's: a frame boundary, whether or not the rest of the frame is intact.
    pub fn constants_match(&self, bytes: &[u8]) -> bool {
        self.layouts
            .iter()
            .any(|l| l.constants_match(bytes).is_ok())
    }

    /// How many of the first places in `bytes` start no frame: the places a decoder hunting
    /// for a boundary may skip at once (0 for frames without constant fields).
    pub fn no_frame_before(&self, bytes: &[u8]) -> usize {
        self.anchors
            .as_ref()
            .map_or(0, |a| a.no_frame_before(bytes))
    }

    /// The plan hunting byte by byte: the reference a test holds the skipping hunt to.
    #[cfg(test)]
    pub(crate) fn without_anchors(mut self) -> Plan {
        self.anchors = None;
        self
    }

    /// True when `bytes` start with the constants of some message (at least one of them
    /// whole): the start of a frame, however short.
    pub fn starts_frame(&self, bytes: &[u8]) -> bool {
        self.layouts.iter().any(|l| l.starts_frame(bytes))
    }

    /// The counter's (modulo, step), if the frames carry one.
    pub fn counter(&self) -> Option<(u64, u64)> {
        self.layouts
            .iter()
            .flat_map(|l| &l.ops)
            .find_map(|op| match op.what {
                What::Counter { modulo, step, .. } => Some((modulo, step)),
                _ => None,
            })
    }

    /// The smallest step an integer field carrying `source` can express (|lsb|), `None` for
    /// float fields or absent sources.
    pub fn quantum(&self, source: Source) -> Option<f64> {
        self.layouts
            .iter()
            .flat_map(|l| &l.ops)
            .find_map(|op| match op.what {
                What::Quantity {
                    source: s, scale, ..
                } if s == source && op.ty.int_range().is_some() => Some(1.0 / scale.abs()),
                _ => None,
            })
    }

    /// Per message, the source quantity of each decoded value, in the order of
    /// [`Decoded::values`].
    pub fn value_sources(&self) -> Vec<Vec<Source>> {
        self.layouts
            .iter()
            .map(|l| {
                l.ops
                    .iter()
                    .filter_map(|op| match &op.what {
                        What::Constant(_) | What::Length => None,
                        What::Counter { .. } => Some(Source::Counter),
                        What::Quantity { source, .. } => Some(*source),
                        What::Status(_) => Some(Source::Status),
                    })
                    .collect()
            })
            .collect()
    }

    /// Names of the decoded values' fields of message `m`, in the order of
    /// [`Decoded::values`].
    pub fn value_names_of(&self, m: usize) -> Vec<&str> {
        self.layouts[m]
            .ops
            .iter()
            .filter(|op| !matches!(op.what, What::Constant(_) | What::Length))
            .map(|op| op.name.as_str())
            .collect()
    }

    /// Names of the decoded values' fields of the first message.
    pub fn value_names(&self) -> Vec<&str> {
        self.value_names_of(0)
    }

    /// Whether some message carries a rate without its increment or an increment without its
    /// rate, so that [`Decoded::contract`] needs the frame interval.
    pub fn needs_interval(&self) -> bool {
        self.value_sources().iter().any(|m| {
            (0..3).any(|a| {
                let has = |s: Source| m.contains(&s);
                has(Source::Gyro(a)) != has(Source::DTheta(a))
                    || has(Source::Accel(a)) != has(Source::Dv(a))
            })
        })
    }

    /// Whether every message carries a time tag [`Decoded::time`] reads.
    pub fn carries_time(&self) -> bool {
        self.value_sources().iter().all(|m| {
            let has = |s: Source| m.contains(&s);
            has(Source::Time)
                || has(Source::GpsSeconds)
                || (has(Source::GpsWholeSeconds)
                    && (has(Source::GpsMicros) || has(Source::GpsMillis)))
        })
    }

    /// Whether message `m` carries Δθ/ΔV summed since it was last sent.
    pub fn accumulates(&self, m: usize) -> bool {
        self.layouts[m].accumulate
    }

    /// Name of message `m`.
    pub fn message_name(&self, m: usize) -> &str {
        &self.layouts[m].name
    }

    /// Decodes one frame at the start of `bytes` (after any transport), trying each message
    /// layout: a good frame, else the most telling error (a check failure at a frame
    /// boundary, then too few bytes, then a constant mismatch).
    pub fn decode(&self, bytes: &[u8]) -> Result<Decoded, DecodeError> {
        let mut best: Option<DecodeError> = None;
        for (i, l) in self.layouts.iter().enumerate() {
            match l.decode(bytes) {
                Ok(d) if self.by_counter => return self.decode_by_counter(bytes, i, d),
                Ok(mut d) => {
                    d.message = i;
                    return Ok(d);
                }
                Err(e) => {
                    let rank = |e: &DecodeError| match e {
                        DecodeError::Check { .. } => 3,
                        DecodeError::Short { .. } => 2,
                        DecodeError::Length { .. } => 1,
                        DecodeError::Constant { .. } => 0,
                    };
                    if best.as_ref().is_none_or(|b| rank(&e) > rank(b)) {
                        best = Some(e);
                    }
                }
            }
        }
        Err(best.expect("a plan has at least one layout"))
    }

    /// The frame as the message its counter selects, given that it decoded as message `i`
    /// (`schedule_by = "counter"`: the layouts agree on the counter's place, checked at
    /// compile).
    fn decode_by_counter(
        &self,
        bytes: &[u8],
        i: usize,
        d: Decoded,
    ) -> Result<Decoded, DecodeError> {
        let c = d.get(Source::Counter).expect("checked at compile") as u64;
        let m = self.schedule[(c % self.schedule.len() as u64) as usize];
        let mut d = if m == i {
            d
        } else {
            self.layouts[m].decode(bytes)?
        };
        d.message = m;
        Ok(d)
    }

    /// Bytes a decoder must hold before giving up on a frame start (the longest frame).
    pub fn max_len(&self) -> usize {
        self.layouts.iter().map(|l| l.len).max().unwrap_or(0)
    }

    /// Bytes below which no frame can be complete.
    pub fn shortest(&self) -> usize {
        self.layouts.iter().map(Layout::shortest).min().unwrap_or(1)
    }
}

/// A schedule indexed by the counter needs the same counter (place, type, modulo, step) in
/// every message, wrapping at a multiple of the schedule's length so the slots stay in step.
fn check_counter_schedule(layouts: &[Layout], slots: usize) -> Result<(), String> {
    let counter = |l: &Layout| {
        l.ops.iter().find_map(|op| match op.what {
            What::Counter {
                modulo,
                step,
                ticks,
                ..
            } => Some((op.offset, op.ty, op.order, modulo, step, ticks)),
            _ => None,
        })
    };
    let first = counter(&layouts[0]);
    let Some((_, _, _, modulo, _, _)) = first else {
        return Err("`schedule_by = \"counter\"` needs a counter field".into());
    };
    if let Some(l) = layouts.iter().find(|l| counter(l) != first) {
        return Err(format!(
            "`schedule_by = \"counter\"`: message `{}` does not carry the same counter as `{}`",
            l.name, layouts[0].name
        ));
    }
    if modulo % slots as u64 != 0 {
        return Err(format!(
            "`schedule_by = \"counter\"`: the counter's modulo {modulo} is not a multiple of the schedule's {slots} entries"
        ));
    }
    Ok(())
}

/// `frame` followed by a wrong `fcs` (its first byte flipped): sent with the transport's own
/// FCS off, a frame whose FCS does not match.
fn with_wrong_fcs(frame: &[u8], fcs: Fcs) -> Vec<u8> {
    let mut bad = frame.to_vec();
    let mut wrong = fcs.bytes(frame);
    wrong[0] ^= 1;
    bad.extend_from_slice(&wrong[..fcs.len()]);
    bad
}

/// One SDLC frame on the line, then marks to the next byte boundary (idle), optionally with a
/// wrong FCS.
fn sdlc_frame(frame: &[u8], o: &SdlcOptions, corrupt_fcs: bool, w: &mut BitWriter) {
    if corrupt_fcs {
        let no_fcs = SdlcOptions {
            fcs: Fcs::None,
            ..*o
        };
        framing::sdlc_encode(&with_wrong_fcs(frame, o.fcs), &no_fcs, w);
    } else {
        framing::sdlc_encode(frame, o, w);
    }
    w.write_marks((8 - w.bit_len() % 8) % 8);
}

/// One asynchronous HDLC frame, optionally with a wrong FCS.
fn hdlc_frame(frame: &[u8], o: &HdlcOptions, corrupt_fcs: bool, out: &mut Vec<u8>) {
    if corrupt_fcs {
        let no_fcs = HdlcOptions {
            fcs: Fcs::None,
            ..*o
        };
        framing::hdlc_encode(&with_wrong_fcs(frame, o.fcs), &no_fcs, out);
    } else {
        framing::hdlc_encode(frame, o, out);
    }
}
