//! A rig unit's further protocols: the same records (after its errors and failures) also
//! encoded as another protocol's frames, each with its own counter, on a stream of its own —
//! a unit that puts out its native frames on one port and a standard protocol on another.

use super::{Body, Rig, Scratch, Unit};
use crate::engine::{DEFAULT_FRAME_CELSIUS, Encoding};
use crate::errors::temperature::TemperatureProfile;
use crate::output::Format;
use crate::protocol::{EncoderState, Plan};

impl Rig {
    /// Unit `i` also speaks `plan` ([`Unit::add_protocol`]); its frames are a stream of
    /// [`Rig::stream`] after the units' and their truth streams.
    pub fn add_protocol(&mut self, i: usize, plan: Plan) -> Result<(), String> {
        let n = self.units.len();
        let u = (self.units.get_mut(i)).ok_or_else(|| format!("no unit {i} (the rig has {n})"))?;
        u.add_protocol(plan)
    }
}

impl Unit {
    /// Also encodes the unit's records as `plan`'s frames (compiled at the unit's rate); a
    /// skew-redundant unit's channels are refused (its protocol must carry exactly them).
    pub fn add_protocol(&mut self, plan: Plan) -> Result<(), String> {
        if matches!(self.body, Body::Skew { .. }) {
            return Err(format!(
                "unit `{}` is skew-redundant: its frames carry its own channels (its `format`); a further protocol per unit is built for three-axis units",
                self.name
            ));
        }
        if plan.channels().is_some() {
            return Err(
                "is a skew-redundant unit's frame; the unit's records are three-axis".into(),
            );
        }
        // The GPS time reference of the unit's own frames, if it has any.
        let own = match &self.body {
            Body::Triad { encoding, .. } | Body::Produced { encoding, .. } => match &**encoding {
                Encoding::Frames { state, .. } => Some((state.gps_week0, state.gps_sow0)),
                Encoding::Records(_) => None,
            },
            Body::Skew { .. } => None,
        };
        let (gps_week0, gps_sow0) = own.unwrap_or((0, 0.0));
        self.extra.push(Encoding::Frames {
            plan: Box::new(plan),
            state: EncoderState {
                gps_week0,
                gps_sow0,
                ..Default::default()
            },
            temperature: DEFAULT_FRAME_CELSIUS,
            side: Format::Csv,
        });
        Ok(())
    }

    /// Whether the unit is skew-redundant (channels on their own axes, not a triad).
    pub fn is_skew(&self) -> bool {
        matches!(self.body, Body::Skew { .. })
    }

    /// How many further protocols the unit speaks.
    pub fn protocols(&self) -> usize {
        self.extra.len()
    }
}

/// Encodes the block's records `s.recs` (with the skipped samples `s.gaps` when `gaps`, the
/// temperature `profile` and the magnetometer samples `s.mag`) in each further protocol of
/// `extra`, into `s.extra[j]`, as the unit's own encoding does.
pub(super) fn encode_extra(
    extra: &mut [Encoding],
    gaps: bool,
    profile: Option<&TemperatureProfile>,
    s: &mut Scratch,
) {
    s.extra.resize_with(extra.len(), Default::default);
    let gaps = if gaps { &s.gaps[..] } else { &[][..] };
    for (e, (buf, ends)) in extra.iter_mut().zip(s.extra.iter_mut()) {
        buf.clear();
        ends.clear();
        e.encode_with_mag(&s.recs, gaps, profile, &s.mag, buf, ends);
    }
}
