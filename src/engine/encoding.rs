//! What the main output carries (records or a protocol's frames), and how a block of records
//! is encoded with each record's bytes delimited.

use crate::aiding::mag_samples::FrameMag;
use crate::errors::temperature::TemperatureProfile;
use crate::output::{self, Format};
use crate::record::Record;

/// What the main output carries.
#[derive(Clone, Debug)]
pub enum Encoding {
    /// The record contract: CSV or binary.
    Records(Format),
    /// A protocol's frames, one per record; side files (truth, injected errors) use `side`.
    Frames {
        /// The compiled frame.
        plan: Box<crate::protocol::Plan>,
        /// Counter and GPS time reference.
        state: crate::protocol::EncoderState,
        /// The sensor temperature carried by frames that have one (°C).
        temperature: f64,
        /// Format of the side files.
        side: Format,
    },
}

impl From<Format> for Encoding {
    fn from(f: Format) -> Encoding {
        Encoding::Records(f)
    }
}

impl Encoding {
    /// Format of the side files (truth, injected errors).
    pub(crate) fn side(&self) -> Format {
        match self {
            Encoding::Records(f) => *f,
            Encoding::Frames { side, .. } => *side,
        }
    }

    /// Appends the main output's bytes for `records`, and the end offset of each record's
    /// bytes in `buf` to `ends`; `profile` gives frames their temperature field.
    /// `gaps`: samples skipped before each record (empty: none), which a frame counter
    /// steps over.
    pub fn encode(
        &mut self,
        records: &[Record],
        gaps: &[u32],
        profile: Option<&TemperatureProfile>,
        buf: &mut Vec<u8>,
        ends: &mut Vec<usize>,
    ) {
        self.encode_with_mag(records, gaps, profile, &[], buf, ends);
    }

    /// [`Encoding::encode`] with the magnetic field the frame of record i carries in `mag[i]`
    /// (empty: 0, no magnetometer).
    pub fn encode_with_mag(
        &mut self,
        records: &[Record],
        gaps: &[u32],
        profile: Option<&TemperatureProfile>,
        mag: &[FrameMag],
        buf: &mut Vec<u8>,
        ends: &mut Vec<usize>,
    ) {
        match self {
            Encoding::Records(f) => {
                // One call per block (as fast as before records had ends); each record is one
                // CSV line or 104 bytes, so the ends are found afterwards.
                let start = buf.len();
                output::encode(*f, records, buf);
                match f {
                    Format::Bin => ends.extend((1..=records.len()).map(|i| start + 104 * i)),
                    Format::Csv => ends.extend(
                        (buf[start..].iter().enumerate())
                            .filter(|b| *b.1 == b'\n')
                            .map(|(i, _)| start + i + 1),
                    ),
                }
            }
            Encoding::Frames {
                plan,
                state,
                temperature,
                ..
            } => {
                for (i, r) in records.iter().enumerate() {
                    state.frames += gaps.get(i).copied().unwrap_or(0) as u64;
                    // The sensor temperature the error chain used for this record.
                    let celsius = profile.map_or(*temperature, |p| p.at(r.t));
                    if let Some(m) = mag.get(i) {
                        (state.mag, state.mag_fresh) = (m.field, m.fresh);
                    }
                    plan.encode(r, celsius, state, buf);
                    ends.push(buf.len());
                }
            }
        }
    }
}
